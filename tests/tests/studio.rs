//! The studio (`scanner-host studio`) driven through its page alone in a headless Chromium, as a
//! maker would: the set-up check, calibration from the shots the page asks for, three views on
//! the turntable disc and one on the object's side, the merge, and the 3MF downloaded. The head
//! is the virtual rig, started by the studio as a child. Needs Debian's `chromium` (see
//! `scanner_tests::browser`).

use std::path::Path;
use std::time::Duration;

use scanner_tests::browser::{Browser, chromium};

/// The job's scene: the turntable part (`scanner-device/scenes/turntable.toml`'s objects) on
/// the A3 disc at 640×480, three turns 120° apart, then laid on its side without the disc.
const SCENE: &str = r#"
width = 640
height = 480
tilt_deg = 30.0
tilt_pivot = [0.0, 60.0, 560.0]

[board]
pitch_deg = 0.0

[laser]
frames = 200

[[objects]]
shape = "turntable"
paper = "a3"
centre = [0.0, 60.0, 560.0]

[[objects]]
shape = "box"
centre = [0.0, 52.0, 560.0]
size = [70.0, 16.0, 45.0]
yaw_deg = 20.0
albedo = [0.7, 0.7, 0.72]

[[objects]]
shape = "cylinder"
base = [18.0, 44.0, 565.0]
axis = [0.0, -1.0, 0.0]
radius = 11.0
height = 55.0
albedo = [0.65, 0.6, 0.55]

[[objects]]
shape = "sphere"
centre = [-22.0, 28.0, 555.0]
radius = 16.0
albedo = [0.6, 0.65, 0.6]

[[views]]
pivot = [0.0, 60.0, 560.0]

[[views]]
angle_deg = 121.0
pivot = [0.0, 60.0, 560.0]

[[views]]
angle_deg = 238.0
pivot = [0.0, 60.0, 560.0]

[[views]]
axis = [0.0, 0.0, 1.0]
angle_deg = 90.0
pivot = [0.0, 40.0, 560.0]
disc = false
"#;

/// Starts the studio in `dir` on the rig scene.
fn start(dir: &Path) -> scanner_tests::StudioProcess {
    std::fs::write(dir.join("job.toml"), SCENE).unwrap();
    scanner_tests::StudioProcess::on_rig(dir, "--scene job.toml")
}

/// Clicks a button of the page.
fn click(b: &mut Browser, id: &str) {
    let done = b.eval(&format!(
        "(() => {{ const e = document.getElementById('{id}'); if (!e) return false; e.click(); return true; }})()"
    ));
    assert_eq!(done, serde_json::Value::Bool(true), "no button #{id}");
}

/// Waits for a condition on the page's state (`s`).
fn wait(b: &mut Browser, cond: &str, secs: u64, what: &str) {
    let expr = format!("(() => {{ const s = window.studio.state; return !!s && !!({cond}); }})()");
    if !b.wait_for(&expr, Duration::from_secs(secs)) {
        let state = b.eval("JSON.stringify(window.studio.state)");
        let answer = b.eval("JSON.stringify(window.studio.lastAnswer)");
        panic!("{what}: not within {secs} s\nstate {state}\nlast answer {answer}");
    }
}

fn count(b: &mut Browser, expr: &str) -> u64 {
    b.eval(&format!(
        "(() => {{ const s = window.studio.state; return {expr}; }})()"
    ))
    .as_u64()
    .unwrap_or(0)
}

#[test]
fn a_whole_job_through_the_page_alone_set_up_calibration_four_views_merge_and_3mf() {
    let Some(exe) = chromium() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let studio = start(tmp.path());
    let url = studio.url.clone();
    let mut b = Browser::launch(&exe);
    b.navigate(&url);
    wait(&mut b, "s.head !== undefined", 30, "the page reads the job");

    // Set-up: the picture, the verdict.
    click(&mut b, "preview-on");
    wait(
        &mut b,
        "s.preview && s.head.state === 'previewing'",
        60,
        "the preview shows",
    );
    wait(&mut b, "s.preview.verdict === 'good'", 60, "a good set-up");
    // the picture at the camera's resolution, its focus figure, a zoom to full resolution
    wait(
        &mut b,
        "s.sharpness && s.sharpness.edge_px > 1 && s.sharpness.edge_px < 8",
        60,
        "a sharp picture with its focus figure",
    );
    // the pictures the page showed in 3 s (printed: the rate depends on the machine)
    let before = b.eval("window.studio.pictures").as_u64().unwrap_or(0);
    std::thread::sleep(Duration::from_secs(3));
    let shown = b.eval("window.studio.pictures").as_u64().unwrap_or(0) - before;
    eprintln!("pictures shown by the page: {:.1}/s", shown as f64 / 3.0);
    assert!(shown > 0, "the page shows the pictures as they come");
    click(&mut b, "picture");
    wait(
        &mut b,
        "s.sharpness.region[2] === 320 && s.sharpness.scale === 1",
        60,
        "a zoom at full resolution",
    );
    click(&mut b, "picture");
    wait(
        &mut b,
        "s.sharpness.region[2] === 640",
        60,
        "the whole picture again",
    );
    click(&mut b, "laser-off");
    wait(
        &mut b,
        "s.preview.verdict === 'laser_not_seen'",
        60,
        "the laser switched off is seen as such",
    );
    click(&mut b, "laser-on");
    wait(
        &mut b,
        "s.preview.verdict === 'good'",
        60,
        "the laser back on",
    );
    click(&mut b, "preview-off");
    wait(&mut b, "s.head.state === 'idle'", 60, "the preview stops");

    // Calibration: the shots the page asks for, then the calibration.
    let mut guard = 0;
    loop {
        let more: u64 = b
            .eval("Number(document.getElementById('asked').dataset.more)")
            .as_u64()
            .unwrap_or(99);
        if more == 0 {
            break;
        }
        guard += 1;
        assert!(guard < 20, "the page keeps asking for shots");
        let targets = count(&mut b, "s.shots.filter(x => x.kept && !x.board).length");
        let before = count(&mut b, "s.shots.length");
        click(
            &mut b,
            if targets < 6 {
                "shot-target"
            } else {
                "shot-board"
            },
        );
        wait(
            &mut b,
            &format!("s.shots.length > {before} && s.head.state !== 'calibrating'"),
            60,
            "a shot is taken and judged",
        );
    }
    let cover = count(&mut b, "s.cover");
    assert!(
        cover.count_ones() >= 16,
        "the coverage map fills: {cover:064b}"
    );
    click(&mut b, "calibrate");
    wait(
        &mut b,
        "s.calibration && s.calibration.result === 'calibrated'",
        180,
        "the calibration",
    );
    let rms = b
        .eval("window.studio.state.calibration.rms_px")
        .as_f64()
        .unwrap();
    assert!(rms < 0.2, "the intrinsics fit: {rms} px");

    // Three views on the disc (the scene's is printed on A3; the page starts at A4, as the
    // README prints it), turned between them, and one on the side.
    b.eval("document.getElementById('disc').value = '2'");
    for k in 1..=4u64 {
        click(&mut b, "sweep");
        wait(
            &mut b,
            &format!("s.views.length === {k} && s.views[{}].done", k - 1),
            300,
            "a sweep",
        );
        // the sweep's points reached the page's live picture
        assert!(
            b.wait_for("window.studio.livePoints > 500", Duration::from_secs(30)),
            "view {k}: points drawn as they came: {}",
            b.eval("window.studio.livePoints")
        );
        let disc = b.eval(&format!("window.studio.state.views[{}].disc", k - 1));
        assert_eq!(
            disc.as_str(),
            Some(if k < 4 { "found" } else { "too_few_dots" }),
            "view {k}: the disc found, or why not"
        );
        click(&mut b, "turn");
        wait(&mut b, "s.head.state === 'idle'", 30, "the turn");
    }

    // The merge: refused at first (the side view shares a third of its points with the
    // others), with its reason on the page; lowered overlap, then merged.
    click(&mut b, "merge");
    wait(
        &mut b,
        "s.merge && s.merge.state !== 'running'",
        600,
        "the merge",
    );
    let first = b.eval("window.studio.state.merge.state");
    if first.as_str() != Some("merged") {
        let shown = b.eval(
            "document.getElementById('merge-result').textContent.includes(window.studio.state.merge.error)",
        );
        assert_eq!(
            shown,
            serde_json::Value::Bool(true),
            "the refusal, as the merge gave it, on the page"
        );
        b.eval("document.getElementById('min-overlap').value = '0.25'");
        click(&mut b, "merge");
        wait(
            &mut b,
            "s.merge && s.merge.state === 'running'",
            30,
            "the merge again",
        );
        wait(
            &mut b,
            "s.merge && s.merge.state !== 'running'",
            600,
            "the merge again",
        );
    }
    // still refused (a side view thinned by a busy machine): untick it and merge the rest
    let mut views = 4;
    if b.eval("window.studio.state.merge.state").as_str() != Some("merged") {
        click(&mut b, "merge-view-4");
        wait(
            &mut b,
            "s.views[3].left_out === true",
            30,
            "the side view left out",
        );
        click(&mut b, "merge");
        wait(
            &mut b,
            "s.merge && s.merge.state === 'running'",
            30,
            "the merge without it",
        );
        wait(
            &mut b,
            "s.merge && s.merge.state !== 'running'",
            600,
            "the merge without it",
        );
        views = 3;
    }
    eprintln!("merged {views} views");
    let state = b.eval("window.studio.state.merge.state");
    assert_eq!(
        state.as_str(),
        Some("merged"),
        "{}",
        b.eval("JSON.stringify(window.studio.state.merge)")
    );
    let report = b.eval("window.studio.state.merge.report");
    assert_eq!(
        report["views"].as_array().map(Vec::len),
        Some(4),
        "{report}"
    );
    // the 3-D viewer: the model's triangles, then one view's points
    click(&mut b, "viewer-model");
    assert!(
        b.wait_for(
            "window.studioViewer && window.studioViewer.model > 1000",
            Duration::from_secs(60)
        ),
        "the model in the 3-D viewer: {}",
        b.eval("JSON.stringify(window.studioViewer)")
    );
    click(&mut b, "viewer-view-1");
    assert!(
        b.wait_for(
            "window.studioViewer.view === 1 && window.studioViewer.points > 1000",
            Duration::from_secs(60)
        ),
        "view 1's points in the 3-D viewer: {}",
        b.eval("JSON.stringify(window.studioViewer)")
    );
    // the download, read by the page: its length, first bytes and a checksum
    let got = b.eval_await(
        "fetch(document.querySelector('#downloads a[href*=\"model.3mf\"]').href).then(r => r.arrayBuffer()).then(b => { const u = new Uint8Array(b); let a = 1, c = 0; for (const x of u) { a = (a + x) % 65521; c = (c + a) % 65521; } return [u.length, u[0], u[1], c * 65536 + a]; })",
    );
    let on_disk = std::fs::read(tmp.path().join("project/model/model.3mf")).unwrap();
    let (mut a, mut c) = (1u64, 0u64);
    for &x in &on_disk {
        a = (a + u64::from(x)) % 65521;
        c = (c + a) % 65521;
    }
    assert!(on_disk.starts_with(b"PK"), "a 3MF is a zip");
    assert_eq!(
        got,
        serde_json::json!([on_disk.len(), b'P', b'K', c * 65536 + a]),
        "the download is the model's file"
    );

    // The page as the maker sees it at the end (`STUDIO_SHOTS=folder` keeps it: docs/studio.md's
    // picture is made so).
    b.call(
        "Emulation.setDeviceMetricsOverride",
        serde_json::json!({"width": 1000, "height": 1250, "deviceScaleFactor": 1, "mobile": false}),
    );
    std::thread::sleep(Duration::from_millis(500));
    let shot = b.screenshot();
    if let Some(dir) = std::env::var_os("STUDIO_SHOTS") {
        shot.save(Path::new(&dir).join("studio.png")).unwrap();
    }

    // Nothing is lost with the page: the job is on disk and opens again.
    let job = scanner_tests::json(&tmp.path().join("project/job.json"));
    assert_eq!(job["views"].as_array().map(Vec::len), Some(4));
    assert_eq!(job["merge"]["state"].as_str(), Some("merged"));
}
