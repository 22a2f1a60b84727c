//! The maker's path as the documents write it: every command of `docs/hardware.md` (the
//! walk-through, whose commands include every command of the README's steps), and of
//! `docs/raspberry-pi.md`'s "Calibrate on the Pi" and "Over SSH instead of a cable" blocks, is
//! read from the document and run through the real binaries, in order. Only the hardware is
//! stood in for: the camera `/dev/video0` becomes a folder of rendered shots (the target, then
//! the board) for `capture`, a folder of the scan demo's sweep rendered in 40 frames for `scan`
//! and `preview` (with `--disc`, the virtual rig: the turntable scene's view of the sweep's
//! number, its sweep shortened to 80 frames), `ssh` a local pipe,
//! `sudo install` a copy into the test's folder, and a page kept up until Ctrl-C ends at once.
//! A command edited in a document is the command this test runs.

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

/// What the stand-ins need: the turntable scene's copy and its calibration.
struct Stage {
    /// The folder of rendered laser frames (and `reference.png`) a scan without the disc reads.
    scan_camera: PathBuf,
    /// The turntable scene, its sweeps shortened.
    turntable: PathBuf,
    /// Its true calibration.
    turntable_calibration: PathBuf,
}

/// Runs `words` (a binary of ours first) in `dir` with the hardware stood in for; panics with
/// the output when it fails.
fn run(dir: &Path, stage: &Stage, words: &[String]) -> String {
    let (exe, args) = stand_in(stage, words, None);
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

/// Runs `head | host` in `dir`, the head's standard output into the host's standard input;
/// panics with both outputs when either fails.
fn run_pipe(dir: &Path, stage: &Stage, head: &[String], host: &[String]) {
    // The sweep's number: the host's `--out viewN` is the turntable's view N − 1.
    let view = host
        .iter()
        .skip_while(|w| *w != "--out")
        .nth(1)
        .and_then(|o| o.strip_prefix("view"))
        .and_then(|n| n.parse::<usize>().ok())
        .map(|n| n - 1);
    let (exe, args) = stand_in(stage, head, view);
    let mut device = Command::new(exe)
        .args(&args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (exe, args) = stand_in(stage, host, None);
    let host_out = Command::new(exe)
        .args(&args)
        .current_dir(dir)
        .stdin(device.stdout.take().unwrap())
        .output()
        .unwrap();
    let device = device.wait_with_output().unwrap();
    assert!(
        device.status.success() && host_out.status.success(),
        "{} | {}\n{}\n{}\n{}",
        head.join(" "),
        host.join(" "),
        String::from_utf8_lossy(&host_out.stdout),
        String::from_utf8_lossy(&host_out.stderr),
        String::from_utf8_lossy(&device.stderr)
    );
}

/// Our binary for the first word, and the arguments with the camera, `/etc` and a page that
/// waits for Ctrl-C stood in for. `view`: the turntable's view a `--disc` sweep scans.
fn stand_in(stage: &Stage, words: &[String], view: Option<usize>) -> (PathBuf, Vec<String>) {
    let exe = match words[0].as_str() {
        "scanner-device" | "scanner-host" => bin(&words[0]),
        other => panic!("a command of the document that is not ours: {other}"),
    };
    let command = words[1].as_str();
    let capture_board = words.iter().any(|w| w == "--board");
    let disc = words.iter().any(|w| w == "--disc");
    let mut args = Vec::new();
    let mut rest = words[1..].iter();
    while let Some(w) = rest.next() {
        match w.as_str() {
            "/dev/video0" if command == "studio" => args.push("rig".into()),
            // the rig's size is its scene's
            "--size" if command == "studio" => {
                rest.next();
            }
            "/dev/video0" if (command == "scan" || command == "preview") && disc => {
                args.extend(["rig".into(), "--scene".into()]);
                args.push(stage.turntable.display().to_string());
                args.extend(["--view".into(), view.unwrap_or(0).to_string()]);
            }
            "/dev/video0" if command == "scan" || command == "preview" => {
                args.push(format!("dir:{}", stage.scan_camera.display()));
            }
            "/dev/video0" if capture_board => args.push("dir:board-camera".into()),
            "/dev/video0" => args.push("dir:target-camera".into()),
            // The rig's scene sets the size.
            "--size" if disc => {
                rest.next();
            }
            "calibration.toml" if disc => {
                args.push(stage.turntable_calibration.display().to_string())
            }
            w => args.push(w.replace("/etc/scanner/", "etc/scanner/")),
        }
    }
    match command {
        "preview" => args.extend(["--every".into(), "10".into()]),
        "receive" if words.iter().any(|w| w == "--view") => {
            args.extend(["--view-for".into(), "0".into()])
        }
        "studio" => args.extend(
            ["--listen", "127.0.0.1:0", "--for-secs", "2"]
                .iter()
                .map(|s| (*s).to_string()),
        ),
        _ => {}
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

/// The commands of the fenced `sh` blocks of a whole document, in order.
fn all_commands(doc: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (i, _) in doc.match_indices("\n## ") {
        let heading = doc[i + 1..].lines().next().unwrap();
        out.extend(commands(doc, heading));
    }
    out
}

/// Runs one line of a document: a command, or `head | host`.
fn run_line(d: &Path, stage: &Stage, line: &str) {
    match line.split_once(" | ") {
        Some((head, host)) => run_pipe(d, stage, &split_in(d, head), &split_in(d, host)),
        None => {
            run(d, stage, &split_in(d, line));
        }
    }
}

/// The "camera" in `d`: the rig's calibration shots at the scan's size, the target's in
/// `target-camera/` and the board's in `board-camera/`.
fn camera_folders(d: &Path) {
    let scene = repo().join("scanner-device/scenes/scan-demo.toml");
    let shots = d.join("rendered");
    let rendered = Command::new(bin("scanner-device"))
        .args(["render-calibration", "--shots", "24", "--scene"])
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
}

/// Copies the scene `name` of `scanner-device/scenes` into `d` with its sweep's `frames = from`
/// set to `to` frames.
fn shortened_scene(d: &Path, name: &str, from: u32, to: u32) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("scanner-device/scenes").join(name))
        .unwrap()
        .replace(&format!("frames = {from}\n"), &format!("frames = {to}\n"));
    assert!(text.contains(&format!("frames = {to}\n")), "{name}");
    std::fs::write(d.join(name), text).unwrap();
    d.join(name)
}

/// Runs `scanner-device` with `args`; panics with its error output when it fails.
fn device(args: &[&std::ffi::OsStr]) {
    let out = Command::new(bin("scanner-device"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The scan's "camera" in `d`: the scan demo's sweep rendered in 40 frames to a folder.
fn scan_camera(d: &Path) -> PathBuf {
    std::fs::copy(
        repo().join("scanner-device/scenes/bunny.obj"),
        d.join("bunny.obj"),
    )
    .unwrap();
    let scene = shortened_scene(d, "scan-demo.toml", 400, 40);
    let out = d.join("scan-camera");
    device(&[
        "render".as_ref(),
        "-q".as_ref(),
        "--scene".as_ref(),
        scene.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    out
}

/// The stand-ins of a document without a turntable.
fn no_turntable(d: &Path) -> Stage {
    Stage {
        scan_camera: scan_camera(d),
        turntable: PathBuf::from("no-turntable.toml"),
        turntable_calibration: PathBuf::from("no-turntable-calibration.toml"),
    }
}

#[test]
fn the_walk_through_and_the_readmes_steps_run_as_written() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    camera_folders(d);
    // The turntable: its scene with sweeps of 80 frames, and its true calibration.
    let turntable = shortened_scene(d, "turntable.toml", 300, 80);
    let cal = d.join("turntable-cal");
    device(&[
        "render-calibration".as_ref(),
        "--shots".as_ref(),
        "3".as_ref(),
        "--scene".as_ref(),
        turntable.as_os_str(),
        "--out".as_ref(),
        cal.as_os_str(),
    ]);
    let stage = Stage {
        scan_camera: scan_camera(d),
        turntable,
        turntable_calibration: d.join("turntable-cal/truth-calibration.toml"),
    };

    // The README's steps are the walk-through's commands, word for word.
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let steps = commands(&readme, "## From parts to a model");
    let hardware = std::fs::read_to_string(repo().join("docs/hardware.md")).unwrap();
    let walk = all_commands(&hardware);
    assert!(
        steps.iter().any(|l| l.starts_with("scanner-host studio "))
            && walk.len() >= steps.len() + 8,
        "the README's steps start the studio; the walk-through goes the terminal's way too: {steps:?}\n{walk:?}"
    );
    for line in &steps {
        assert!(
            walk.contains(line),
            "the README's {line:?} is not in docs/hardware.md"
        );
    }
    // …and its inline commands of three words or more.
    let inline: Vec<&str> = readme
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| {
            (s.starts_with("scanner-device ") || s.starts_with("scanner-host "))
                && s.split_whitespace().count() >= 3
        })
        .collect();

    // The walk-through, in order. A merge of views not swept yet sweeps them as the last
    // `--disc` sweep did ("view2, view3, …").
    let mut disc_sweep: Option<String> = None;
    for line in &walk {
        if line.contains("--disc") && line.contains(" | ") {
            disc_sweep = Some(line.clone());
        }
        if line.starts_with("scanner-host merge ") {
            let sweep = disc_sweep.as_ref().expect("a disc sweep before the merge");
            for w in line.split_whitespace().filter(|w| w.starts_with("view")) {
                if !d.join(w).exists() {
                    run_line(
                        d,
                        &stage,
                        &sweep.replace("--out view1", &format!("--out {w}")),
                    );
                }
            }
        }
        run_line(d, &stage, line);
    }
    for span in &inline {
        assert!(
            walk.iter().any(|l| l == span),
            "{span:?} is not in docs/hardware.md"
        );
    }
    let kept = scanner_tests::json(&d.join("shots/capture-report.json"));
    assert!(kept["kept"].as_u64().unwrap() >= 1, "{kept}");
    assert!(d.join("board/target.svg").exists() && d.join("board/turntable-a4.svg").exists());
    assert!(d.join("calibration.toml").exists());
    let data = scanner_tests::summary(&d.join("scan1"));
    assert_eq!(data["point_packets"], 40);
    assert!(data["points"].as_u64().unwrap() > 1000, "{data}");
    for f in ["scan.obj", "scan.ply", "journal.stream"] {
        assert!(d.join("scan1").join(f).exists(), "{f}");
    }
    assert!(d.join("scan1-again/scan.obj").exists());
    // The preview reached the host: its summary counts the thumbnails.
    let aim = scanner_tests::summary(&d.join("aim"));
    assert!(aim["previews"].as_u64().unwrap() >= 1, "{aim}");
    // The merge posed the three sweeps by the disc and wrote a model.
    let report = scanner_tests::json(&d.join("model/merge-report.json"));
    let posed = report["disc"].as_array().expect("disc views");
    assert_eq!(posed.len(), 3, "{report}");
    assert!(posed.iter().all(|v| v["by_disc"] == true), "{report}");
    assert!(d.join("model/model.3mf").exists());
    // The studio started, served and ended, its job kept in its project folder.
    assert!(d.join("vase/job.json").exists());
}

#[test]
fn the_pi_guide_runs_as_written() {
    // docs/raspberry-pi.md, "Calibrate on the Pi".
    let p = tempfile::tempdir().unwrap();
    let pd = p.path();
    camera_folders(pd);
    let stage = no_turntable(pd);
    let pi = std::fs::read_to_string(repo().join("docs/raspberry-pi.md")).unwrap();
    let calibrate = commands(&pi, "## Calibrate on the Pi");
    assert!(calibrate.len() >= 6, "{calibrate:?}");
    for line in &calibrate {
        let words = split_in(pd, line);
        if words[0] == "sudo" {
            // `sudo install -D FILE /etc/scanner/…`: a copy into this folder's etc/scanner.
            assert_eq!(words[1..3], ["install", "-D"], "{line}");
            let to = pd.join(words[4].trim_start_matches('/'));
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(pd.join(&words[3]), &to).unwrap();
            continue;
        }
        let out = run(pd, &stage, &words);
        if words[1] == "capture" && !words.contains(&"--board".to_string()) {
            let r = scanner_tests::json(&pd.join("shots/capture-report.json"));
            assert_eq!(r["kept"], 24, "{out}");
        }
    }
    let cal = std::fs::read_to_string(pd.join("etc/scanner/calibration.toml")).unwrap();
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
    run_pipe(pd, &stage, &split(head), &split(host));
    let data = scanner_tests::summary(&pd.join("scan1"));
    assert_eq!(data["point_packets"], 40);
    let losses = scanner_tests::link_losses(&data);
    assert!(losses.is_empty(), "{losses:?}");
}
