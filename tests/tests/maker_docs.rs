//! The maker's path as the documents write it: every command of `docs/raspberry-pi.md`'s
//! "Calibrate on the Pi" and "Over SSH instead of a cable" blocks, and every complete
//! `scanner-device`/`scanner-host` command of the README's "Build your scanner" section, is read
//! from the document and run through the real binaries. Only the hardware is stood in for: the
//! camera `/dev/video0` becomes a folder of rendered shots (the target, then the board) or the
//! virtual rig for the scan (cut to 40 frames), `ssh` a local pipe, and `sudo install` a copy into
//! the test's folder. A command edited in the document is the command this test runs.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn bin(name: &str) -> PathBuf {
    scanner_tests::workspace_bin(name)
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The lines of the fenced `sh` blocks under the heading `section` (continuations joined,
/// comments cut).
fn commands(doc: &str, section: &str) -> Vec<String> {
    let start = doc
        .find(&format!("\n{section}\n"))
        .unwrap_or_else(|| panic!("no section {section:?}"));
    let body = &doc[start + section.len() + 2..];
    let body = &body[..body.find("\n## ").unwrap_or(body.len())];
    let mut out = Vec::new();
    let (mut inside, mut line) = (false, String::new());
    for l in body.lines() {
        if l.starts_with("```") {
            inside = l.starts_with("```sh");
            continue;
        }
        if !inside {
            continue;
        }
        let l = match l.find(" #") {
            Some(i) if !l[..i].contains('\'') || l[i..].contains('\'') => &l[..i],
            _ => l,
        };
        match l.trim_end().strip_suffix('\\') {
            Some(part) => line += part.trim_start(),
            None => {
                line += l.trim();
                if !line.is_empty() {
                    out.push(std::mem::take(&mut line));
                }
            }
        }
    }
    out
}

/// Runs `words` (a binary of ours first) in `dir` with the hardware stood in for; panics with
/// the output when it fails.
fn run(dir: &Path, words: &[String]) -> String {
    let (exe, args) = stand_in(words);
    let out = Command::new(&exe)
        .args(&args)
        .current_dir(dir)
        .output()
        .expect("binary runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{} failed:\n{text}\n{}",
        words.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// Our binary for the first word, and the arguments with the camera and `/etc` stood in for.
fn stand_in(words: &[String]) -> (PathBuf, Vec<String>) {
    let exe = match words[0].as_str() {
        "scanner-device" | "scanner-host" => bin(&words[0]),
        other => panic!("a command of the document that is not ours: {other}"),
    };
    let capture_board = words.iter().any(|w| w == "--board");
    let mut args: Vec<String> = words[1..]
        .iter()
        .map(|w| match w.as_str() {
            "/dev/video0" if words[1] == "scan" => "rig:1280x960".into(),
            "/dev/video0" if capture_board => "dir:board-camera".into(),
            "/dev/video0" => "dir:target-camera".into(),
            w => w.replace("/etc/scanner/", "etc/scanner/"),
        })
        .collect();
    if words[1] == "scan" {
        args.extend(["--frames".into(), "40".into()]);
    }
    (exe, args)
}

/// The words of a command line, a `DIR/PREFIX*SUFFIX` word expanded as the shell would (in
/// `dir`, sorted).
fn split_in(dir: &Path, line: &str) -> Vec<String> {
    let mut out = Vec::new();
    for w in line.split_whitespace() {
        let Some((prefix, suffix)) = w.split_once('*') else {
            out.push(w.to_string());
            continue;
        };
        let (folder, start) = prefix.rsplit_once('/').unwrap_or((".", prefix));
        let mut names: Vec<String> = std::fs::read_dir(dir.join(folder))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(start) && n.ends_with(suffix))
            .map(|n| format!("{folder}/{n}"))
            .collect();
        names.sort();
        assert!(!names.is_empty(), "{w} matches nothing");
        out.extend(names);
    }
    out
}

fn split(line: &str) -> Vec<String> {
    split_in(Path::new("."), line)
}

#[test]
fn the_pi_guide_and_the_build_section_run_as_written() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    // The "camera": the rig's calibration shots at the scan's size, the target and the board.
    let scene = repo().join("scanner-device/scenes/scan-demo.toml");
    let shots = d.join("rendered");
    let rendered = Command::new(bin("scanner-device"))
        .args(["render-calibration", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(&shots)
        .output()
        .unwrap();
    assert!(rendered.status.success());
    for (folder, prefix) in [("target-camera", "grid-"), ("board-camera", "board.png")] {
        std::fs::create_dir(d.join(folder)).unwrap();
        for e in std::fs::read_dir(&shots).unwrap() {
            let name = e.unwrap().file_name();
            if name.to_string_lossy().starts_with(prefix) {
                std::fs::copy(shots.join(&name), d.join(folder).join(&name)).unwrap();
            }
        }
    }

    // The README's build section: its complete commands (`…` marks an elided one).
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let build = &readme[readme.find("## Build your scanner").unwrap()..];
    let build = &build[..build[3..].find("\n## ").unwrap()];
    let spans: Vec<&str> = build
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| {
            (s.starts_with("scanner-device ") || s.starts_with("scanner-host ")) && !s.contains('…')
        })
        .collect();
    assert!(
        spans.contains(&"scanner-device board --out board") && spans.len() >= 2,
        "{spans:?}"
    );
    for span in &spans {
        run(d, &split(span));
    }
    assert!(d.join("board/target.svg").exists() && d.join("board/left-sheet.svg").exists());

    // docs/raspberry-pi.md, "Calibrate on the Pi".
    let pi = std::fs::read_to_string(repo().join("docs/raspberry-pi.md")).unwrap();
    let calibrate = commands(&pi, "## Calibrate on the Pi");
    assert!(calibrate.len() >= 6, "{calibrate:?}");
    for line in &calibrate {
        let words = split_in(d, line);
        if words[0] == "sudo" {
            // `sudo install -D FILE /etc/scanner/…`: a copy into this folder's etc/scanner.
            assert_eq!(words[1..3], ["install", "-D"], "{line}");
            let to = d.join(words[4].trim_start_matches('/'));
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(d.join(&words[3]), &to).unwrap();
            continue;
        }
        let out = run(d, &words);
        if words[1] == "capture" && !words.contains(&"--board".to_string()) {
            let r = scanner_tests::json(&d.join("shots/capture-report.json"));
            assert_eq!(r["kept"], 12, "{out}");
        }
    }
    let cal = std::fs::read_to_string(d.join("etc/scanner/calibration.toml")).unwrap();
    assert!(cal.contains("fx"), "{cal}");

    // "Over SSH instead of a cable": ssh HOST 'the head' | the host.
    let ssh = commands(&pi, "## Over SSH instead of a cable");
    assert_eq!(ssh.len(), 1, "{ssh:?}");
    let line = &ssh[0];
    let head = line
        .split('\'')
        .nth(1)
        .expect("the head's command in quotes");
    let host = line.rsplit_once('|').expect("a pipe").1.trim();
    let (exe, args) = stand_in(&split(head));
    let mut device = Command::new(exe)
        .args(&args)
        .current_dir(d)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (exe, args) = stand_in(&split(host));
    let host = Command::new(exe)
        .args(&args)
        .current_dir(d)
        .stdin(device.stdout.take().unwrap())
        .output()
        .unwrap();
    let device = device.wait_with_output().unwrap();
    let summary = String::from_utf8_lossy(&host.stdout);
    assert!(
        device.status.success() && host.status.success(),
        "{summary}\n{}\n{}",
        String::from_utf8_lossy(&host.stderr),
        String::from_utf8_lossy(&device.stderr)
    );
    let data = scanner_tests::summary(&d.join("scan1"));
    assert_eq!(data["point_packets"], 40, "{summary}");
    let losses = scanner_tests::link_losses(&data);
    assert!(losses.is_empty(), "{losses:?}");
    for f in ["scan.obj", "scan.ply", "journal.stream"] {
        assert!(d.join("scan1").join(f).exists(), "{f}");
    }
}
