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
        g.insert(&board, None, None)
            && g.insert(
                &(board + scanner_core::nalgebra::Vector3::new(0.3, 0.0, 0.4)),
                None,
                None
            )
    );
    for k in 0..3 {
        g.insert(
            &(object + scanner_core::nalgebra::Vector3::new(0.0, 0.0, 0.1 * f32::from(k as u8))),
            None,
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
            None,
        );
    }
    g.insert(
        &(p + scanner_core::nalgebra::Vector3::new(0.0, 0.0, 30.0)),
        None,
        None,
    );
    g.insert(
        &(p + scanner_core::nalgebra::Vector3::new(0.0, 0.0, -40.0)),
        None,
        None,
    );
    let (c, r) = g.locate(&p).unwrap();
    assert_eq!(g.at(c, r).count, 10);
    assert!((g.at(c, r).mean[2] - 700.05).abs() < 0.05);
    assert_eq!(g.rejected(), 2);
}

#[test]
fn a_cell_weighs_its_samples_by_their_uncertainty() {
    let mut g = grid();
    let p = Point3::new(10.0, 5.0, 700.0);
    let dz = |z: f32| p + scanner_core::nalgebra::Vector3::new(0.0, 0.0, z);
    // a good sample (u 0.1 mm) at +0, a poor one (u 0.5 mm) at +1: weights 100 and 4
    assert!(g.insert(&dz(0.0), None, Some(0.1)));
    assert!(g.insert(&dz(1.0), None, Some(0.5)));
    let (c, r) = g.locate(&p).unwrap();
    let cell = g.at(c, r);
    let want = 700.0 + 4.0 / 104.0;
    assert!(
        (cell.mean[2] - want).abs() < 1e-3,
        "{} vs {want}",
        cell.mean[2]
    );
    // the mean's uncertainty: 1/√(100 + 4)
    assert!((cell.uncertainty() - 1.0 / 104f32.sqrt()).abs() < 1e-4);
    // without uncertainties the two would weigh alike
    let mut h = grid();
    h.insert(&dz(0.0), None, None);
    h.insert(&dz(1.0), None, None);
    assert!((h.at(c, r).mean[2] - 700.5).abs() < 1e-3);
    // a zero, negative or NaN uncertainty counts as none, never as an infinite weight
    let mut k = grid();
    k.insert(&dz(0.0), None, Some(0.0));
    k.insert(&dz(1.0), None, Some(f32::NAN));
    k.insert(&dz(2.0), None, Some(-1.0));
    assert!((k.at(c, r).mean[2] - 701.0).abs() < 1e-3);
}
