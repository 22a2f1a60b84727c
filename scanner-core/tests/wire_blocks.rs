//! The camera and the board as the wire's header carries them: exact round trips, and refusals
//! of what no camera or plane is (a head sending garbage).

use scanner_core::geometry::Board;
use scanner_core::{Camera, Distortion};
use scanner_wire::{CameraBlock, PlaneBlock};

fn blocks() -> (CameraBlock, [PlaneBlock; 2]) {
    let camera = CameraBlock {
        fx: 1400.0,
        fy: 1400.5,
        cx: 799.5,
        cy: 600.25,
        k1: -0.1,
        k2: 0.02,
        p1: 0.001,
        p2: -0.002,
        k3: 0.0,
    };
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let board = [
        PlaneBlock {
            normal: [s, 0.0, -s],
            offset: 500.0,
        },
        PlaneBlock {
            normal: [-s, 0.0, -s],
            offset: 500.0,
        },
    ];
    (camera, board)
}

#[test]
fn the_headers_camera_and_board_round_trip() {
    let (camera, board) = blocks();
    let cam = Camera::<f32>::try_from(camera).unwrap();
    assert_eq!(CameraBlock::from(&cam), camera);
    assert_eq!(
        *cam.distortion(),
        Distortion {
            k1: -0.1,
            k2: 0.02,
            p1: 0.001,
            p2: -0.002,
            k3: 0.0
        }
    );
    let b = Board::<f32>::try_from(board).unwrap();
    let back: [PlaneBlock; 2] = (&b).into();
    for (got, want) in back.iter().zip(&board) {
        for (g, w) in got.normal.iter().zip(&want.normal) {
            assert!((g - w).abs() < 1e-6, "{got:?} {want:?}");
        }
        assert!((got.offset - want.offset).abs() < 1e-3, "{got:?} {want:?}");
    }
}

#[test]
fn what_no_camera_or_board_is_refused() {
    let (mut camera, mut board) = blocks();
    camera.fx = -1.0;
    assert!(Camera::<f32>::try_from(camera).is_err());
    board[0].normal = [0.0; 3];
    assert!(Board::<f32>::try_from(board).is_err());
    let (_, mut parallel) = blocks();
    parallel[1] = parallel[0];
    assert!(
        Board::<f32>::try_from(parallel).is_err(),
        "planes that do not meet"
    );
}
