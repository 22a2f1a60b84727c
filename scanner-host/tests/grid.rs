//! The structured grid's cells: a robust mean, and on an object's outline the better-supported of
//! two depths instead of their average.

use scanner_core::nalgebra::Point3;
use scanner_core::{Camera, Distortion};
use scanner_host::grid::{Cell, Grid};

fn grid() -> Grid {
    let cam = Camera::new(500.0, 500.0, 319.5, 239.5, Distortion::none()).unwrap();
    Grid::new(cam, 640, 480, Cell::Pixels(4.0), 1000.0, 2.0).unwrap()
}

#[test]
fn a_cell_keeps_the_better_supported_depth() {
    let mut g = grid();
    // Two samples of the board behind, then three of the object's edge, in the same cell.
    let board = Point3::new(0.0, 0.0, 800.0);
    let object = Point3::new(0.0, 0.0, 500.0);
    assert!(
        g.insert(&board, None)
            && g.insert(
                &(board + scanner_core::nalgebra::Vector3::new(0.3, 0.0, 0.4)),
                None
            )
    );
    for k in 0..3 {
        g.insert(
            &(object + scanner_core::nalgebra::Vector3::new(0.0, 0.0, 0.1 * f32::from(k as u8))),
            None,
        );
    }
    let (c, r) = g.locate(&object).unwrap();
    let cell = g.at(c, r);
    assert_eq!(cell.count, 3);
    assert!((cell.mean[2] - 500.1).abs() < 0.01, "{:?}", cell.mean);
    assert_eq!(g.rejected(), 2, "the board's samples are the other depth");
}

#[test]
fn an_outlier_among_many_is_rejected() {
    let mut g = grid();
    let p = Point3::new(10.0, 5.0, 700.0);
    for k in 0..10 {
        g.insert(
            &(p + scanner_core::nalgebra::Vector3::new(0.0, 0.0, 0.05 * (k % 3) as f32)),
            None,
        );
    }
    g.insert(
        &(p + scanner_core::nalgebra::Vector3::new(0.0, 0.0, 30.0)),
        None,
    );
    g.insert(
        &(p + scanner_core::nalgebra::Vector3::new(0.0, 0.0, -40.0)),
        None,
    );
    let (c, r) = g.locate(&p).unwrap();
    assert_eq!(g.at(c, r).count, 10);
    assert!((g.at(c, r).mean[2] - 700.05).abs() < 0.05);
    assert_eq!(g.rejected(), 2);
}
