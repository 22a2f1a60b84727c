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

/// A browser on the studio's page, once the page has heard the head.
fn open_page(exe: &Path, url: &str) -> Browser {
    let mut b = Browser::launch(exe);
    b.navigate(url);
    wait(
        &mut b,
        "s.head !== undefined && s.head.heard",
        30,
        "the page reads the job",
    );
    b
}

/// The frames counted in the first status of a view's journal.
fn first_status_frames(journal: &Path) -> Option<u32> {
    let bytes = std::fs::read(journal).ok()?;
    let mut d = Box::new(scanner_wire::Decoder::<{ scanner_wire::MAX_ENCODED }>::new());
    let mut first = None;
    d.feed(&bytes, |m| {
        if let (None, Ok(scanner_wire::Message::Status(st))) = (first, m) {
            first = Some(st.frames);
        }
    });
    first
}

/// The regions a list of the guide's asks names, in its order.
fn regions_asked(asks: &serde_json::Value) -> Vec<u64> {
    asks.as_array()
        .map(|a| a.iter().filter_map(|a| a["region"].as_u64()).collect())
        .unwrap_or_default()
}

/// Switches the preview on and waits for a good set-up.
fn preview_good(b: &mut Browser) {
    click(b, "preview-on");
    wait(
        b,
        "s.preview && s.preview.verdict === 'good'",
        60,
        "a good set-up",
    );
}

/// Starts a sweep without the disc from the page; when it was accepted.
fn sweep_without_disc(b: &mut Browser) -> std::time::Instant {
    b.eval("document.getElementById('disc').value = '0'");
    let answer = click_answer(b, "sweep");
    assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
    std::time::Instant::now()
}

/// Makes view `n`'s own model from the page (its *model* button) and waits for it: its
/// record, made.
fn view_model(b: &mut Browser, n: usize) -> serde_json::Value {
    let answer = click_answer(b, &format!("view-model-{n}"));
    assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
    let k = n - 1;
    wait(
        b,
        &format!("s.views[{k}].model && s.views[{k}].model.state !== 'running'"),
        300,
        "the view's model",
    );
    let model = b.eval(&format!("window.studio.state.views[{k}].model"));
    assert_eq!(model["state"].as_str(), Some("made"), "{model}");
    model
}

/// Clicks a button and waits for the answer to the request it made.
fn click_answer(b: &mut Browser, id: &str) -> serde_json::Value {
    b.eval("window.studio.lastAnswer = null");
    click(b, id);
    assert!(
        b.wait_for("window.studio.lastAnswer !== null", Duration::from_secs(30)),
        "#{id}: no answer"
    );
    b.eval("window.studio.lastAnswer")
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

/// Takes the shots the page's guide asks for, one by one, until it asks for none: a target
/// shot for a region, a tilt or more shots; the board's shot when that is what it asks.
fn follow_the_guide(b: &mut Browser, most: usize) {
    for _ in 0..most {
        let next = b.eval("document.getElementById('asked').dataset.next");
        let next = next.as_str().unwrap_or("");
        if next == "calibrate" {
            return;
        }
        let before = count(b, "s.shots.length");
        let answer = click_answer(
            b,
            if next == "board_shot" {
                "shot-board"
            } else {
                "shot-target"
            },
        );
        assert_eq!(
            answer["outcome"].as_str(),
            Some("accepted"),
            "the shot is taken: {answer}"
        );
        wait(
            b,
            &format!("s.shots.length > {before} && s.head.state !== 'calibrating'"),
            60,
            "a shot is taken and judged",
        );
    }
    panic!(
        "the page keeps asking for shots: {}",
        b.eval("JSON.stringify(window.studio.state.guide)")
    );
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
    follow_the_guide(&mut b, 20);
    let cells = count(&mut b, "s.guide.regions.reduce((n, r) => n + r.covered, 0)");
    assert!(cells >= 16, "the coverage map fills: {cells} cells");
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
        // the page says the sweep starts, then counts its frames (the times printed: they
        // are the machine's)
        let t0 = std::time::Instant::now();
        wait(
            &mut b,
            &format!("s.sweep_starting || s.views.length === {k}"),
            30,
            "the sweep shown starting",
        );
        let starting = t0.elapsed().as_secs_f64();
        wait(
            &mut b,
            &format!("s.views.length === {k} && s.views[{}].frames > 0", k - 1),
            60,
            "the sweep's first progress",
        );
        eprintln!(
            "view {k}: shown starting {starting:.1} s and its frames counted {:.1} s after the click",
            t0.elapsed().as_secs_f64()
        );
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
        let answer = click_answer(&mut b, "turn");
        wait(&mut b, "s.head.state === 'idle'", 30, "the turn");
        // the turn's answer says where the disc stands and the angle it turned (the scene's
        // views at 0°, 121°, 238°, then the side view; the rig's turntable goes round)
        assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
        assert_eq!(answer["field"].as_u64(), Some(k % 4 + 1), "{answer}");
        if k < 3 {
            let want = [12100, 11700][k as usize - 1];
            assert_eq!(answer["detail"].as_i64(), Some(want), "{answer}");
        }
    }
    // each sweep's first status came with its first frame
    for k in 1..=4 {
        assert_eq!(
            first_status_frames(&tmp.path().join(format!("project/views/view-{k}.stream"))),
            Some(1),
            "view {k}"
        );
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

/// A maker who holds the target in one corner only: four shots, taken while the preview runs,
/// all in the top left (then the rig's maker follows the guide: `TargetPose::guided`). The page asks for the other regions (the other corners first), the
/// studio refuses to calibrate until they are covered, the shots the guide then asks for fill
/// the map, and the calibration ends with a verdict per figure.
const CORNER_SCENE: &str = r#"
width = 640
height = 480
objects = []

[laser]
frames = 40

[[shots]]
centre = [-334.0, -243.0, 850.0]
turn_deg = [3.0, 2.0, 0.0]

[[shots]]
centre = [-330.0, -240.0, 860.0]
turn_deg = [-2.0, 4.0, 0.0]

[[shots]]
centre = [-338.0, -246.0, 840.0]
turn_deg = [4.0, -3.0, 0.0]

[[shots]]
centre = [-334.0, -243.0, 850.0]
turn_deg = [0.0, 0.0, 6.0]

"#;

#[test]
fn a_guided_calibration_asks_for_the_regions_its_corner_shots_missed_and_judges_each_figure() {
    let Some(exe) = chromium() else { return };
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("job.toml"), CORNER_SCENE).unwrap();
    let studio = scanner_tests::StudioProcess::on_rig(tmp.path(), "--scene job.toml");
    let mut b = open_page(&exe, &studio.url);
    preview_good(&mut b);

    // four shots in the top left corner, each taken while the preview runs (it comes back)
    for k in 1..=4u64 {
        let answer = click_answer(&mut b, "shot-target");
        assert_eq!(
            answer["outcome"].as_str(),
            Some("accepted"),
            "shot {k}: {answer}"
        );
        wait(
            &mut b,
            &format!("s.shots.length === {k} && s.head.state === 'previewing'"),
            60,
            "the shot judged and the preview back",
        );
    }
    let guide = b.eval("window.studio.state.guide");
    assert_eq!(guide["target_shots"].as_u64(), Some(4), "{guide}");
    assert_eq!(guide["ready"].as_bool(), Some(false), "{guide}");
    assert_eq!(guide["regions"][0]["done"].as_bool(), Some(true), "{guide}");
    let asked = regions_asked(&guide["asks"]);
    assert_eq!(
        asked[..3],
        [2, 6, 8],
        "the other corners asked for first: {guide}"
    );
    assert_eq!(
        b.eval("document.getElementById('asked').dataset.next")
            .as_str(),
        Some("region")
    );
    // "calibrate" is refused while regions are missing, with what is missing
    let answer = click_answer(&mut b, "calibrate");
    assert_eq!(answer["outcome"].as_str(), Some("not_ready"), "{answer}");
    let refused = regions_asked(&answer["asks"]);
    assert_eq!(
        refused, asked,
        "the refusal names the regions the page asks for"
    );
    assert!(b.eval("window.studio.state.calibration").is_null());
    keep_picture(&mut b, "studio-guide.png");

    // the shots the guide asks for, then the calibration, the preview still on
    follow_the_guide(&mut b, 10);
    let guide = b.eval("window.studio.state.guide");
    assert!(
        guide["regions"]
            .as_array()
            .unwrap()
            .iter()
            .all(|r| r["done"] == true),
        "every region covered: {guide}"
    );
    // the map's last row reaches the page (a 64-bit number would not)
    let last_row = b.eval("window.studio.state.cover.slice(56)");
    assert!(
        last_row.as_str().is_some_and(|r| r.contains('1')),
        "the coverage map's bottom row: {last_row}"
    );
    let answer = click_answer(&mut b, "calibrate");
    assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
    wait(
        &mut b,
        "s.calibration && s.calibration.result === 'calibrated'",
        180,
        "the calibration",
    );
    wait(
        &mut b,
        "s.head.state === 'previewing'",
        60,
        "the preview back after it",
    );
    let verdicts = b.eval("window.studio.state.verdicts");
    let figures: Vec<(&str, &str)> = verdicts
        .as_array()
        .unwrap()
        .iter()
        .map(|v| (v["figure"].as_str().unwrap(), v["grade"].as_str().unwrap()))
        .collect();
    assert_eq!(
        figures.iter().map(|f| f.0).collect::<Vec<_>>(),
        [
            "rms_px",
            "halves_px",
            "regions",
            "board_rms_px",
            "board_angle_deg",
            "laser_lines_pct"
        ],
        "{verdicts}"
    );
    // five of the shots show about one pose: the two halves' calibrations may disagree
    // (printed); every other figure is good
    let shots = count(&mut b, "s.calibration.shots");
    eprintln!(
        "halves of {shots} shots (5 in one corner): {} px, {}",
        verdicts[1]["value"], verdicts[1]["grade"]
    );
    for (figure, grade) in figures.iter().filter(|f| f.0 != "halves_px") {
        assert_eq!(*grade, "good", "{figure}: {verdicts}");
    }
    // more shots elsewhere (the regions' edges, the centre), calibrated again: all good
    for k in 0..5 {
        let answer = click_answer(&mut b, "shot-target");
        assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
        wait(
            &mut b,
            &format!(
                "s.shots.filter(x => x.kept && !x.board).length === {} && s.head.state === 'previewing'",
                shots + 1 + k
            ),
            60,
            "a shot more",
        );
    }
    let answer = click_answer(&mut b, "calibrate");
    assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
    wait(
        &mut b,
        &format!(
            "s.calibration && s.calibration.shots === {} && s.head.state === 'previewing'",
            shots + 5
        ),
        180,
        "the calibration again",
    );
    let verdicts = b.eval("window.studio.state.verdicts");
    eprintln!("halves of {} shots: {} px", shots + 5, verdicts[1]["value"]);
    for v in verdicts.as_array().unwrap() {
        assert_eq!(v["grade"].as_str(), Some("good"), "{verdicts}");
    }
    // and the page shows each with its unit and verdict
    let shown = b.eval(
        "Array.from(document.querySelectorAll('#verdicts tbody tr')).map(r => r.dataset.figure + ':' + r.dataset.grade + ':' + (r.cells[2].textContent.split(' ')[1] || ''))",
    );
    assert_eq!(
        shown,
        serde_json::json!([
            "rms_px:good:px",
            "halves_px:good:px",
            "regions:good:of",
            "board_rms_px:good:px",
            "board_angle_deg:good:°",
            "laser_lines_pct:good:%"
        ])
    );
    keep_picture(&mut b, "studio-verdicts.png");
    drop(studio);
}

/// The page as the maker sees it now, kept as `name` in `STUDIO_SHOTS=folder` (docs/studio.md's
/// pictures are made so).
fn keep_picture(b: &mut Browser, name: &str) {
    let Some(dir) = std::env::var_os("STUDIO_SHOTS") else {
        return;
    };
    b.call(
        "Emulation.setDeviceMetricsOverride",
        serde_json::json!({"width": 1000, "height": 1250, "deviceScaleFactor": 1, "mobile": false}),
    );
    std::thread::sleep(Duration::from_millis(700));
    b.screenshot().save(Path::new(&dir).join(name)).unwrap();
}

/// The camera's controls from the page, on the rig's simulated camera (exposure and gain scale
/// its signal; it has no focus): a short exposure makes the laser faint and the page asks for
/// a longer one, a long one clips the picture and the page offers half, applied with one
/// click; what the camera has not got or not at that value is refused by kind; the values are
/// kept with the job and sent to the head again when the studio opens it.
#[test]
fn camera_controls_from_the_page_change_the_picture_and_are_kept_with_the_job() {
    let Some(exe) = chromium() else { return };
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("job.toml"), CORNER_SCENE).unwrap();
    let laser_dn = |b: &mut Browser| count(b, "s.preview.laser_dn");
    let set = |b: &mut Browser, id: &str, value: i64| -> serde_json::Value {
        b.eval(&format!(
            "document.getElementById('{id}').value = '{value}'"
        ));
        let button = if id == "focus-value" {
            "set-focus".to_string()
        } else {
            format!("set-{id}")
        };
        click_answer(b, &button)
    };
    let dn_10 = {
        let studio = scanner_tests::StudioProcess::on_rig(tmp.path(), "--scene job.toml");
        let mut b = open_page(&exe, &studio.url);
        preview_good(&mut b);
        let dn0 = laser_dn(&mut b);

        // short: the laser faint, a longer exposure asked for
        let answer = set(&mut b, "exposure", 10);
        assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
        wait(
            &mut b,
            &format!(
                "s.preview.laser_dn < {} && s.camera_advice && s.camera_advice.why === 'laser_faint'",
                dn0 / 2
            ),
            60,
            "a faint laser at a short exposure, and the advice",
        );
        assert_eq!(
            b.eval("window.studio.state.camera_advice.value").as_i64(),
            Some(20)
        );
        // long: the picture clipped; the advice applied until the verdict is good
        let answer = set(&mut b, "exposure", 400);
        assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
        wait(
            &mut b,
            "s.preview.verdict === 'too_bright' && s.camera_advice && s.camera_advice.why === 'clipped'",
            60,
            "a clipped picture at a long exposure, and the advice",
        );
        for _ in 0..4 {
            if b.eval("window.studio.state.preview.verdict").as_str() == Some("good") {
                break;
            }
            let asked = count(&mut b, "s.camera_advice.value");
            let answer = click_answer(&mut b, "apply-advice");
            assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
            wait(
                &mut b,
                &format!("s.camera.exposure === {asked}"),
                30,
                "the advice applied",
            );
            std::thread::sleep(Duration::from_secs(2));
        }
        wait(&mut b, "s.preview.verdict === 'good'", 60, "good again");
        assert!(count(&mut b, "s.camera.exposure") < 400);
        // refused by kind: no focus on the rig, a gain below its range (with its limit)
        let answer = set(&mut b, "focus-value", 50);
        assert_eq!(answer["outcome"].as_str(), Some("not_here"), "{answer}");
        let answer = set(&mut b, "gain", 5);
        assert_eq!(
            (
                answer["outcome"].as_str(),
                answer["field"].as_u64(),
                answer["detail"].as_i64()
            ),
            (Some("out_of_range"), Some(2), Some(10)),
            "{answer}"
        );
        // a value kept for the next studio
        let answer = set(&mut b, "exposure", 10);
        assert_eq!(answer["outcome"].as_str(), Some("accepted"), "{answer}");
        wait(&mut b, "s.camera.exposure === 10", 30, "exposure 10 kept");
        std::thread::sleep(Duration::from_secs(2));
        let dn = laser_dn(&mut b);
        eprintln!("laser: {dn0} DN at the rig's own exposure, {dn} DN at 10");
        assert!(dn < dn0 / 2, "{dn} DN at 10 against {dn0}");
        dn
    };
    let job = scanner_tests::json(&tmp.path().join("project/job.json"));
    assert_eq!(job["camera"]["exposure"].as_i64(), Some(10), "{job}");

    // the studio again on the same project: the head is told the kept exposure
    let studio = scanner_tests::StudioProcess::on_rig(tmp.path(), "--scene job.toml");
    let mut b = open_page(&exe, &studio.url);
    click(&mut b, "preview-on");
    wait(
        &mut b,
        "s.preview && s.head.state === 'previewing'",
        60,
        "the preview",
    );
    std::thread::sleep(Duration::from_secs(2));
    let again = laser_dn(&mut b);
    eprintln!("laser at 10 after the studio started again: {again} DN");
    assert!(
        again.abs_diff(dn_10) * 4 <= dn_10,
        "the kept exposure reached the head: {again} DN against {dn_10}"
    );
}

/// A fixed-laser turntable through the page: the head reads a turntable's recording (rendered
/// by the rig: a sphere and a cylinder on a turning platform, 100 frames a turn) with its
/// calibration; the page's sweep shows progress from the start, and the view's own model is
/// the turntable's closed model, downloaded as the file the host wrote.
#[test]
fn a_fixed_laser_turntable_scan_through_the_page_ends_in_its_closed_model() {
    let Some(exe) = chromium() else { return };
    let scan = scanner_rig::TurningScan::demo(640, 480);
    let tmp = tempfile::tempdir().unwrap();
    let frames = tmp.path().join("frames");
    scanner_tests::write_turning_frames(&scan, &frames);
    let cal = tmp.path().join("cal.toml");
    scan.truth_calibration().save(&cal).unwrap();
    let head_args = format!(
        "--calibration {} --fixed-laser 0 --frames-per-turn 100 --rows",
        cal.display()
    );
    let studio =
        scanner_tests::StudioProcess::on_source(tmp.path(), frames.to_str().unwrap(), &head_args);
    let mut b = open_page(&exe, &studio.url);
    // no disc: the turntable's own turn places the points
    let t0 = sweep_without_disc(&mut b);
    let expr = "(() => { const s = window.studio.state; return s.views.length === 1 && s.views[0].frames > 0; })()";
    if !b.wait_for(expr, Duration::from_secs(60)) {
        panic!(
            "no progress; the head said:\n{}",
            std::fs::read_to_string(tmp.path().join("project/head.log")).unwrap_or_default()
        );
    }
    eprintln!(
        "turntable: first progress {:.1} s after the click",
        t0.elapsed().as_secs_f64()
    );
    wait(
        &mut b,
        "s.views.length === 1 && s.views[0].done",
        300,
        "the sweep",
    );
    let ended = b.eval("window.studio.state.views[0].ended");
    assert_eq!(ended.as_str(), Some("completed"));
    let model = view_model(&mut b, 1);
    let fixed = &model["summary"]["fixed"];
    assert_eq!(fixed["watertight"], true, "{model}");
    assert_eq!(fixed["frames"].as_u64(), Some(101), "{model}");
    // the download, read by the page, is the file the host wrote
    let got = b.eval_await(
        "fetch(document.getElementById('view-1-scan-stl').href).then(r => r.arrayBuffer()).then(b => b.byteLength)",
    );
    assert_eq!(
        b.eval("document.getElementById('next').dataset.kind")
            .as_str(),
        Some("model_ready"),
        "the page says the model is ready"
    );
    let on_disk = std::fs::metadata(tmp.path().join("project/views/view-1/scan.stl"))
        .unwrap()
        .len();
    assert_eq!(got.as_u64(), Some(on_disk));
    keep_picture(&mut b, "studio-turntable.png");
}

/// Shadow scanning through the page: a lamp and a rod's shadow swept over the rig's demo
/// objects, read through time (`--shadow --temporal` in the head's arguments, with the rig's
/// true calibration). Its points come at the sweep's end, so the page shows the frames from the
/// start; the view's own model is made from them.
#[test]
fn a_shadow_sweep_through_the_page_shows_its_frames_and_ends_in_a_model() {
    let Some(exe) = chromium() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let scene = "width = 640\nheight = 480\n\n[laser]\nframes = 120\n\n[shadow]\n";
    std::fs::write(tmp.path().join("job.toml"), scene).unwrap();
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::from_toml_in(scene, tmp.path()).unwrap())
        .unwrap();
    rig.truth_calibration()
        .save(&tmp.path().join("cal.toml"))
        .unwrap();
    let studio = scanner_tests::StudioProcess::on_rig(
        tmp.path(),
        "--scene job.toml --calibration cal.toml --shadow --temporal",
    );
    let mut b = open_page(&exe, &studio.url);
    let t0 = sweep_without_disc(&mut b);
    // at once: the page says the head takes its reference (the rig renders a lamp-lit
    // reference for some seconds), then counts the frames
    wait(
        &mut b,
        "s.sweep_starting || s.views.length === 1",
        30,
        "the sweep shown starting",
    );
    wait(
        &mut b,
        "s.views.length === 1 && s.views[0].frames > 0",
        60,
        "the sweep's first progress",
    );
    eprintln!(
        "shadow: first frames counted {:.1} s after the click (the reference first)",
        t0.elapsed().as_secs_f64()
    );
    // read through time: frames counted while no point has come yet
    wait(
        &mut b,
        "s.views[0].frames >= 30 && s.views[0].points === 0 && !s.views[0].done",
        120,
        "frames counted before the points",
    );
    wait(&mut b, "s.views[0].done", 300, "the sweep");
    let points = count(&mut b, "s.views[0].points");
    assert!(points > 20_000, "{points} points");
    let model = view_model(&mut b, 1);
    assert!(
        model["summary"]["faces"].as_u64().unwrap_or(0) > 10_000,
        "{model}"
    );
    assert!(
        b.eval("document.getElementById('view-1-scan-stl') !== null")
            .as_bool()
            .unwrap_or(false),
        "the model's download on the page"
    );
}
