//! Board fringes: where an object's shadow clips the light sheet on the board, the board keeps
//! only the sheet's tail for a few lines, whose centres land just beyond the board tolerance
//! (measured on the accuracy report's scene at 800 mm: runs of 1–4 lines, 3.8–4.9 mm in front of
//! the board, where the rig's truth says the sheet's centre lies in an object's shadow). The head
//! counts such short runs next to board points as board (`HeadConfig::board_fringe`).

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, StripeConfig};
use scanner_rig::Rig;
use scanner_tests::accuracy as report;

/// Points sent nearer a board sheet than any object (with their distance off the board, mm),
/// and object points within 0.1 % of the distance of their surface.
fn scan(rig: &Rig, board_fringe: usize) -> (Vec<f64>, usize) {
    let scene = rig.scene();
    let d = scene.board.distance;
    let planes = rig.board_planes();
    let (mut board, mut good) = (Vec::new(), 0);
    let cfg = HeadConfig {
        board_fringe,
        ..HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns))
    };
    report::scan_truth(rig, cfg, |_, pts| {
        for (p, _) in pts {
            let off_board = planes
                .iter()
                .map(|pl| pl.signed_distance(p).abs())
                .fold(f64::INFINITY, f64::min);
            let off_object = scene
                .objects
                .iter()
                .filter_map(|o| o.shape.distance(p))
                .fold(f64::INFINITY, f64::min);
            if off_board < off_object {
                board.push(off_board);
            } else if off_object <= 0.001 * d {
                good += 1;
            }
        }
    });
    (board, good)
}

#[test]
fn board_fringes_in_an_objects_shadow_are_not_sent_as_object_points() {
    let (scene, _) = report::scene(1600, 1200, 800.0, 80);
    let rig = Rig::new(scene).unwrap();
    let (before, good_before) = scan(&rig, 0);
    let (after, good_after) = scan(
        &rig,
        HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)).board_fringe,
    );
    println!(
        "board points sent: {} without the fringe rule ({:?} mm off the board), {} with it; object points within 0.1 %: {good_before} → {good_after}",
        before.len(),
        before,
        after.len()
    );
    assert!(before.len() >= 5, "the scene shows the fringe: {before:?}");
    assert!(after.is_empty(), "{after:?}");
    // the price: hardly an object point
    assert!(
        good_after * 1000 >= good_before * 998,
        "{good_before} → {good_after}"
    );
}
