//! The laser plane when a surface in front of the board (a stand, a table, the turntable disc)
//! carries most of the stripe: that stripe, carried along its rays onto the sheets, lies in the
//! plane through it and the camera, and must never be fitted as the laser plane.

use scanner_core::geometry::{Board, LaserFitConfig, Plane, Surface, laser};
use scanner_core::nalgebra::{Point3, Vector3};

/// A right-angled board 1000 mm away (its halves are `z = 1000 − |x|`).
fn board() -> Board<f64> {
    Board::new(
        Plane::new(Vector3::new(1.0, 0.0, -1.0), 1000.0).unwrap(),
        Plane::new(Vector3::new(-1.0, 0.0, -1.0), 1000.0).unwrap(),
    )
    .unwrap()
}

/// The laser plane `y = 250 − 0.2 z`: from above the camera, down towards the board.
fn laser_plane() -> Plane<f64> {
    Plane::new(Vector3::new(0.0, 1.0, 0.2), 250.0).unwrap()
}

/// A small deterministic wobble, mm, for point `k`.
fn noise(k: usize) -> f64 {
    0.05 * ((k as f64 * 12.9898).sin() * 43_758.545).fract()
}

/// The laser's line on the board where `|x|` runs from `from` to `to`, `n` points a side.
fn on_board(from: f64, to: f64, n: usize) -> [Vec<Point3<f64>>; 2] {
    [-1.0, 1.0].map(|side| {
        (0..n)
            .map(|k| {
                let x = side * (from + (to - from) * k as f64 / (n - 1) as f64);
                let z = 1000.0 - x.abs();
                Point3::new(x, 250.0 - 0.2 * z + noise(k), z)
            })
            .collect()
    })
}

/// The laser's line on a table top `y = 150` (it meets the plane at `z = 500`), `|x| ≤ half`,
/// `n` points, each carried along its ray onto the board: the points a head would take for board
/// points, split by sheet.
fn table_on_board(half: f64, n: usize) -> [Vec<Point3<f64>>; 2] {
    let b = board();
    let mut sides = [Vec::new(), Vec::new()];
    for k in 0..n {
        let x = -half + 2.0 * half * k as f64 / (n - 1) as f64;
        let p = Point3::new(x, 150.0 + noise(k), 500.0);
        let (q, s) = b.intersect_ray(&p.coords, 0.01).unwrap();
        match s {
            Surface::Left => sides[0].push(q),
            Surface::Right => sides[1].push(q),
            Surface::Object => {}
        }
    }
    sides
}

fn degrees(p: &Plane<f64>) -> f64 {
    let a = p.normal().angle(laser_plane().normal()).to_degrees();
    a.min(180.0 - a)
}

#[test]
fn a_table_outnumbering_the_board_is_never_the_laser_plane() {
    let cfg = LaserFitConfig::default();
    // The board's stripe only at its outer edges, 25 points a side, against 400 on the table.
    let [mut left, mut right] = on_board(420.0, 500.0, 25);
    let [tl, tr] = table_on_board(250.0, 400);
    assert!(tl.len() > 5 * left.len() && tr.len() > 5 * right.len());
    left.extend(tl);
    right.extend(tr);
    let fit = laser::least_squares(&left, &right, &cfg).expect("the laser plane");
    let off = (fit.plane.offset() - laser_plane().offset() / laser_plane().normal().norm()).abs();
    assert!(degrees(&fit.plane) < 0.05, "{}°", degrees(&fit.plane));
    assert!(off < 0.5, "{off} mm");
    // Its inliers are the board's, not the table's.
    assert!(fit.quality.used <= 60, "{} points used", fit.quality.used);
}

#[test]
fn a_table_alone_is_no_laser_plane() {
    // Nothing of the board's own stripe: only the table's, carried onto both sheets. Its plane
    // is through the camera, and no other plane fits both sheets.
    let cfg = LaserFitConfig::default();
    let [left, right] = table_on_board(250.0, 400);
    let err = laser::least_squares(&left, &right, &cfg).unwrap_err();
    assert_eq!(err, scanner_core::GeomError::PlaneThroughCamera);
}

#[test]
fn the_disc_and_one_sheet_fix_the_plane() {
    // The stripe on the left sheet and on a disc in front (its plane `y = 150` known): two known
    // surfaces, two lines, one plane; the right sheet hidden.
    let cfg = LaserFitConfig::default();
    let [left, _] = on_board(200.0, 500.0, 60);
    let disc: Vec<Point3<f64>> = (0..120)
        .map(|k| Point3::new(-120.0 + 2.0 * k as f64, 150.0, 500.0 + noise(k)))
        .collect();
    assert_eq!(
        laser::least_squares(&left, &[], &cfg).unwrap_err(),
        scanner_core::GeomError::OnePlaneOnly
    );
    let fit = laser::least_squares_on(&[&left, &[], &disc], &cfg).expect("the laser plane");
    assert!(degrees(&fit.plane) < 0.05, "{}°", degrees(&fit.plane));
    // One known surface alone fixes nothing.
    assert_eq!(
        laser::least_squares_on(&[&[], &[], &disc], &cfg).unwrap_err(),
        scanner_core::GeomError::OnePlaneOnly
    );
}

#[test]
fn bad_input_to_the_fit_on_known_surfaces_is_refused_by_name() {
    let cfg = LaserFitConfig::default();
    let [left, right] = on_board(200.0, 500.0, 20);
    // fewer than two surfaces, or more than three
    assert!(matches!(
        laser::least_squares_on(&[&left], &cfg),
        Err(scanner_core::GeomError::TooFewPoints { .. })
    ));
    assert!(matches!(
        laser::least_squares_on(&[&left, &right, &left, &right], &cfg),
        Err(scanner_core::GeomError::TooFewPoints { .. })
    ));
    // empty surfaces
    assert!(laser::least_squares_on(&[&[], &[], &[]], &cfg).is_err());
    // a NaN among the points
    let mut bad = right.clone();
    bad[3].x = f64::NAN;
    assert_eq!(
        laser::least_squares_on(&[&left, &bad], &cfg).unwrap_err(),
        scanner_core::GeomError::NotFinite
    );
}
