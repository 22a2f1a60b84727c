//! Scenes with views (a 360° scan): each view moves the objects by its pose about the pivot; the
//! truth of a view maps back onto the scene's own surfaces by the inverse pose; the binaries
//! render a view with its pose and refuse a view the scene lacks.

use scanner_core::nalgebra::{Point3, Vector3};
use scanner_rig::surface::Shape;
use scanner_rig::{Rig, Scene};

const SCENE: &str = r#"
width = 320
height = 240
[laser]
frames = 30
[[objects]]
shape = "sphere"
centre = [-20.0, 10.0, 520.0]
radius = 45.0
[[objects]]
shape = "box"
centre = [50.0, 20.0, 540.0]
size = [40.0, 60.0, 30.0]
[[views]]
[[views]]
angle_deg = 90.0
[[views]]
angle_deg = 180.0
axis = [0.0, 1.0, 0.0]
[[views]]
angle_deg = 180.0
axis = [1.0, 0.0, 0.0]
translate = [0.0, -5.0, 0.0]
"#;

#[test]
fn views_move_the_objects_about_their_centre_and_the_truth_maps_back() {
    let scene = Scene::from_toml(SCENE).unwrap();
    assert_eq!(scene.view_count(), 4);
    let pivot = Point3::new(15.0, 15.0, 530.0); // the mean of the two objects' centres
    for k in 0..4 {
        let v = scene.view(k).unwrap();
        let pose = v.object_pose;
        // The pivot stays (up to the translation), the sphere's centre turns about it.
        let t = if k == 3 {
            Vector3::new(0.0, -5.0, 0.0)
        } else {
            Vector3::zeros()
        };
        assert!((pose * pivot - (pivot + t)).norm() < 1e-9, "view {k}");
        let Shape::Sphere { centre, .. } = v.objects[0].shape else {
            panic!("a sphere")
        };
        assert!((centre - pose * Point3::new(-20.0, 10.0, 520.0)).norm() < 1e-9);
        // Every object point the laser lights in this view lies on the scene's own surfaces
        // once moved back by the inverse pose.
        let (original, moved) = (
            Rig::new(scene.view(0).unwrap()).unwrap(),
            Rig::new(v).unwrap(),
        );
        let mut n = 0;
        for f in (0..30).step_by(3) {
            for t in moved.truth(f).unwrap().into_iter().flatten() {
                if matches!(t.surface, scanner_rig::SurfaceId::Object(_)) {
                    let back = pose.inverse_transform_point(&t.point);
                    let d = original.surface_distance(&back);
                    assert!(d < 1e-6, "view {k} frame {f}: {d} mm off");
                    n += 1;
                }
            }
        }
        assert!(n > 100, "view {k}: only {n} object points lit");
    }
    // Upside down: the box's "up" points down.
    let Shape::Cuboid { axes, .. } = scene.view(3).unwrap().objects[1].shape else {
        panic!("a box")
    };
    assert!(axes[1].y < -0.999, "{axes:?}");
    assert!(scene.view(4).unwrap_err().to_string().contains("4 view(s)"));
}

#[test]
fn render_writes_a_views_pose_and_refuses_a_view_the_scene_lacks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("views.toml"), SCENE).unwrap();
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_scanner-device"))
            .args(args)
            .env(scanner_io::ERRORS_ENV, "json")
            .current_dir(d)
            .output()
            .unwrap()
    };
    let out = run(&[
        "render",
        "--scene",
        "views.toml",
        "--view",
        "1",
        "--frames",
        "2",
        "--out",
        "v1",
        "-q",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pose = std::fs::read_to_string(d.join("v1/view-pose.txt")).unwrap();
    // 90° about +y: x goes to −z.
    assert!(
        pose.contains("R = [[0.000000000000, 0.000000000000, 1.000000000000]"),
        "{pose}"
    );
    let out = run(&[
        "render",
        "--scene",
        "views.toml",
        "--view",
        "7",
        "--out",
        "v7",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && scanner_tests::has_kind(&err, "Scene"),
        "{err}"
    );
    let out = run(&["scan", "--view", "1", "--calibration", "x.toml"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && scanner_tests::has_kind(&err, "ViewWithoutScene"),
        "{err}"
    );
}

#[test]
fn the_bunny_360_scene_has_seven_views_that_all_show_the_bunny() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny-360.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let scene = Scene::from_toml_in(&text, path.parent().unwrap()).unwrap();
    assert_eq!(scene.view_count(), 7);
    for k in 0..7 {
        let mut v = scene.view(k).unwrap();
        // Smaller and shorter for the test: the same geometry at 320×240.
        v.camera = Scene::demo(320, 240).camera;
        (v.width, v.height) = (320, 240);
        let rig = Rig::new(v).unwrap();
        let lit: usize = (0..300)
            .step_by(10)
            .map(|f| {
                rig.truth(f)
                    .unwrap()
                    .into_iter()
                    .flatten()
                    .filter(|t| matches!(t.surface, scanner_rig::SurfaceId::Object(_)))
                    .count()
            })
            .sum();
        assert!(
            lit > 300,
            "view {k}: the laser lights only {lit} bunny points"
        );
    }
}
