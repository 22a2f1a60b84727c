//! The preview's picture: its edge width (the focus figure) grows with the blur of the lens,
//! and a sharp picture reads as sharp.

use scanner_device::preview::edge_width;
use scanner_rig::{Rig, Scene};

/// The rig's board at 1280×960 with the lens blurred by `sigma` pixels: its edge width.
fn width_at(sigma: f64) -> f64 {
    let mut scene = Scene::demo(1280, 960);
    scene.blur_px = sigma;
    let rig = Rig::new(scene).unwrap();
    edge_width(&rig.reference().to_gray_image()).expect("the board has edges")
}

#[test]
fn the_edge_width_grows_with_the_blur_and_reads_sharp_when_sharp() {
    let widths: Vec<(f64, f64)> = [0.3, 1.0, 2.0, 4.0]
        .iter()
        .map(|&s| (s, width_at(s)))
        .collect();
    eprintln!("blur σ px → edge width px: {widths:?}");
    for w in widths.windows(2) {
        assert!(w[1].1 > w[0].1, "{widths:?}");
    }
    // sharp: about 2 px; blurred by σ ≫ 1: about 2.5 σ
    assert!(widths[0].1 < 3.0, "{widths:?}");
    let (s, w) = widths[3];
    assert!((w / (2.5 * s) - 1.0).abs() < 0.3, "{widths:?}");
}

/// On real photographs (not tuned on): the real webcam chessboards and the real two-plane
/// board read as in focus, within the range the rig's sharp lenses give.
#[test]
fn real_photographs_in_focus_read_as_sharp() {
    let shared = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    let files = [
        "real-calibration/right01.jpg",
        "real-calibration/right02.jpg",
        "real-two-plane/20220331_faa7cdf/laser-off.png",
        "real-two-plane/20220405_9eb8eaa/laser-off.png",
    ];
    for f in files {
        let img = image::open(shared.join(f))
            .unwrap_or_else(|e| panic!("{f}: {e}"))
            .to_luma8();
        let w = edge_width(&img).expect("edges");
        eprintln!("{f}: edges {w:.2} px wide");
        assert!((2.0..8.0).contains(&w), "{f}: {w}");
    }
}
