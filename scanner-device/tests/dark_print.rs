//! A board printed with chessboards on both sheets (dark squares under the stripe nearly
//! everywhere it goes) and nothing in front of it, rendered by the rig and swept by the laser:
//! not one object point, in every pixel format, and the stripe still found on the board in most
//! frames. A check the dark-print rules were not tuned on (they were set on the real two-plane
//! frames, `tests/real_two_plane.rs`).

use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_device::link::Link;
use scanner_device::session::{ScanOptions, run_scan, truth_calibration};
use scanner_device::source::RigSource;

/// The rig's demo scene with nothing in front of the board and a chessboard of 30 mm squares on
/// each sheet, at 640×480, its sweep in 60 frames.
fn scene(dir: &std::path::Path) -> scanner_rig::Scene {
    let mut board = scanner_calib::board::BoardFile::default();
    for sheet in [&mut board.left, &mut board.right] {
        sheet.grid = None;
        sheet.markers = None;
        sheet.chessboard = Some(scanner_calib::board::Chessboard {
            cols: 12,
            rows: 9,
            square: 30.0,
            u0: 60.0,
            v0: -105.0,
        });
    }
    std::fs::write(dir.join("board.toml"), board.to_toml().unwrap()).unwrap();
    let text = "width = 640\nheight = 480\nobjects = []\n[laser]\nframes = 60\n[board]\nlayout = \"board.toml\"\n";
    scanner_rig::Scene::from_toml_in(text, dir).unwrap()
}

#[test]
fn a_chessboard_board_with_nothing_in_front_gives_no_object_point() {
    let t = tempfile::tempdir().unwrap();
    let scene = scene(t.path());
    for format in [PixelFormat::Rgb24, PixelFormat::Yuyv, PixelFormat::Gray8] {
        for keep_board in [false, true] {
            let rig = scanner_rig::Rig::new(scene.clone()).unwrap();
            let cal = truth_calibration(&rig);
            let mut source = RigSource::new(rig, format);
            let mut head = HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns));
            head.keep_board = keep_board;
            let opts = ScanOptions {
                head,
                header_every: 30,
                status_every: 30,
                scan_id: 1,
                find_axis: true,
                find_colour: false,
                disc: None,
                fixed: None,
                markers: None,
                shadow: false,
                temporal: false,
            };
            let mut link = Link::spawn(
                Box::new(std::io::sink()),
                scanner_device::link::MAX_DEPTH,
                scanner_wire::MAX_ENCODED,
            );
            let mut points = 0usize;
            let report = run_scan(
                &mut source,
                &cal,
                opts,
                &mut link,
                |_| {},
                |_, p| {
                    points += p.len();
                },
            )
            .unwrap();
            link.finish().unwrap();
            let s = report.status;
            let skipped: u32 = s.skipped.iter().sum();
            println!(
                "{format:?} keep_board {keep_board}: {} frames, {skipped} skipped, {points} points",
                s.frames
            );
            if keep_board {
                // The stripe found on the board (its points sent) in most frames.
                assert!(
                    skipped * 4 < s.frames && points > 100 * s.frames as usize,
                    "{format:?}: {s:?}"
                );
            } else {
                assert_eq!(points, 0, "{format:?}: object points with no object");
            }
        }
    }
}
