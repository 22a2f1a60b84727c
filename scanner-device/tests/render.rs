//! The scene file and the render command: the documented example is exactly the demo scene;
//! `scanner-device render` writes the frames and their ground truth; bad scene files are refused
//! with the file and the field named.

use std::process::Command;

use scanner_rig::{Rig, Scene, SurfaceId};

const DEMO: &str = include_str!("../scenes/demo.toml");

#[test]
fn the_documented_scene_file_is_the_demo_scene() {
    assert_eq!(Scene::from_toml(DEMO).unwrap(), Scene::demo(640, 480));
    // an empty file is the demo too, at the default size
    assert_eq!(Scene::from_toml("").unwrap(), Scene::demo(640, 480));
    // every shape parses
    let s = Scene::from_toml(
        r#"
        width = 320
        height = 240
        [[objects]]
        shape = "box"
        centre = [0.0, 50.0, 450.0]
        size = [80.0, 60.0, 40.0]
        yaw_deg = 30.0
        [[objects]]
        shape = "plane"
        centre = [0.0, 0.0, 550.0]
        size = [120.0, 90.0]
        tilt_x_deg = 20.0
        "#,
    )
    .unwrap();
    assert_eq!(s.objects.len(), 2);
    assert_eq!(s.width, 320);
    // and renders with truth on them
    let mut s = s;
    s.laser.frames = 12;
    let rig = Rig::new(s).unwrap();
    let on_objects = (0..12)
        .flat_map(|k| rig.truth(k).unwrap())
        .flatten()
        .filter(|t| matches!(t.surface, SurfaceId::Object(_)))
        .count();
    assert!(
        on_objects > 50,
        "only {on_objects} truth columns on the box and the plane"
    );
}

#[test]
fn bad_scene_files_name_what_is_wrong() {
    for (text, want) in [
        ("widht = 3", "widht"),
        ("[board]\nangle_deg = \"ninety\"", "angle_deg"),
        ("[[objects]]\nshape = \"torus\"", "torus"),
        (
            "[[objects]]\nshape = \"sphere\"\ncentre = [0.0, 0.0, 500.0]\nradius = -1.0",
            "radius must be positive",
        ),
        ("[camera]\nfx = 0.0", "[camera]"),
    ] {
        let err = Scene::from_toml(text).unwrap_err().to_string();
        assert!(err.contains(want), "{text:?}: {err}");
    }
}

#[test]
fn render_writes_frames_and_truth() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("small.toml");
    std::fs::write(&scene, "width = 96\nheight = 72\n[laser]\nframes = 30\n").unwrap();
    let out = dir.path().join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_scanner-device"))
        .args(["render", "--frames", "3", "--quiet", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for name in [
        "reference.png",
        "frame-0000.png",
        "frame-0001.png",
        "frame-0002.png",
        "truth.csv",
        "lasers.csv",
    ] {
        assert!(out.join(name).exists(), "{name} missing");
    }
    assert!(!out.join("frame-0003.png").exists());
    // the PNG is the rig's frame, byte for byte
    let rig =
        Rig::new(Scene::from_toml(&std::fs::read_to_string(&scene).unwrap()).unwrap()).unwrap();
    let png = image::open(out.join("frame-0001.png")).unwrap().to_rgb8();
    assert_eq!(png.into_raw(), rig.frame(1).unwrap().data);
    let truth = std::fs::read_to_string(out.join("truth.csv")).unwrap();
    let rows = truth
        .lines()
        .skip(1)
        .filter(|l| l.starts_with("2,"))
        .count();
    assert_eq!(rows, rig.truth(2).unwrap().iter().flatten().count());
    assert_eq!(
        std::fs::read_to_string(out.join("lasers.csv"))
            .unwrap()
            .lines()
            .count(),
        4
    );

    // a missing scene file is named
    let run = Command::new(env!("CARGO_BIN_EXE_scanner-device"))
        .args([
            "render",
            "--quiet",
            "--scene",
            "/no/such/scene.toml",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&run.stderr).contains("/no/such/scene.toml"));
}
