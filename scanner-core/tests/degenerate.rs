//! Degenerate and hostile input (issue item 7): each degenerate configuration gives its typed
//! error, and arbitrary floats (NaN, ±inf, subnormals, huge values) never panic and never come
//! out as a NaN or an infinity.

use proptest::prelude::*;
use scanner_core::calib::{CrossShot, image_distance};
use scanner_core::geometry::{
    Board, LaserFitConfig, Limits, Line, Plane, collinear, fit_line, fit_plane, laser, pose,
    triangulate,
};
use scanner_core::nalgebra::{Point2, Point3, Vector2, Vector3};
use scanner_core::{Camera, Distortion, GeomError};

fn right_angle_board() -> Board<f64> {
    Board::new(
        Plane::new(Vector3::new(1.0, 0.0, -1.0), 1000.0).unwrap(),
        Plane::new(Vector3::new(-1.0, 0.0, -1.0), 1000.0).unwrap(),
    )
    .unwrap()
}

/// Stripe points on the right-angle board (its halves are `z = 1000 − |x|`) for the laser plane
/// `y = 0.2 z − 100`; `side` −1 gives the left half, +1 the right.
fn stripe(side: f64, n: usize) -> Vec<Point3<f64>> {
    (1..=n)
        .map(|k| {
            let x = side * 40.0 * k as f64;
            let z = 1000.0 - x.abs();
            Point3::new(x, 0.2 * z - 100.0, z)
        })
        .collect()
}

#[test]
fn stripe_fixture_is_on_the_board() {
    let b = right_angle_board();
    for p in stripe(-1.0, 5) {
        assert!(b.left().signed_distance(&p).abs() < 1e-9);
    }
    for p in stripe(1.0, 5) {
        assert!(b.right().signed_distance(&p).abs() < 1e-9);
    }
}

#[test]
fn coincident_image_points() {
    // a line through the camera centre: all three markers image to one point
    let r = Vector3::new(0.1, 0.2, 1.0);
    assert_eq!(
        collinear::solve(&[r, r * 2.0, r * 3.0], 50.0),
        Err(GeomError::CoincidentPoints)
    );
    assert_eq!(
        collinear::paper(&[r, r * 2.0, r * 3.0], 50.0),
        Err(GeomError::CoincidentPoints)
    );
    // out of order: B' not between A' and C'
    let (a, b, c) = (
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.2, 0.0, 1.0),
        Vector3::new(0.1, 0.0, 1.0),
    );
    assert_eq!(
        collinear::solve(&[a, b, c], 50.0),
        Err(GeomError::IllConditioned)
    );
    assert_eq!(
        collinear::paper(&[a, b, c], 50.0),
        Err(GeomError::IllConditioned)
    );
    assert!(matches!(
        collinear::solve(&[a, b, c], 0.0),
        Err(GeomError::BadParameter(_))
    ));
}

#[test]
fn parallel_planes() {
    let p = Plane::new(Vector3::new(0.0, 0.0, -1.0), 1000.0).unwrap();
    let q = Plane::new(Vector3::new(0.0, 0.0, -2.0), 2400.0).unwrap();
    assert_eq!(Board::new(p, q), Err(GeomError::Parallel));
    assert_eq!(Board::new(p, p), Err(GeomError::Parallel));
    // 1° apart is still parallel for a board (below the 2° floor)
    let r = Plane::new(Vector3::new(0.0175, 0.0, -1.0), 1000.0).unwrap();
    assert_eq!(Board::new(p, r), Err(GeomError::Parallel));
    assert_eq!(
        p.intersection(&q, 1e-6).map(|_| ()),
        Err(GeomError::Parallel)
    );
    // a board plane through the camera centre
    let o = Plane::new(Vector3::new(1.0, 0.0, -1.0), 0.0).unwrap();
    assert_eq!(Board::new(o, p), Err(GeomError::PlaneThroughCamera));
}

#[test]
fn ray_parallel_to_plane() {
    let laser = Plane::new(Vector3::new(0.0, 1.0, 0.0), -100.0).unwrap();
    assert_eq!(
        laser.intersect_ray(&Vector3::new(0.3, 0.0, 1.0), 0.0),
        Err(GeomError::Grazing)
    );
    assert_eq!(
        laser.intersect_ray(&Vector3::new(0.3, 0.01, 1.0), 0.035),
        Err(GeomError::Grazing)
    );
    assert_eq!(
        laser.intersect_ray(&Vector3::zeros(), 0.0).map(|_| ()),
        Err(GeomError::BadParameter("ray must be non-zero"))
    );
    let a = Line::new(Point3::origin(), Vector3::x()).unwrap();
    let b = Line::new(Point3::new(0.0, 1.0, 0.0), Vector3::x() * 3.0).unwrap();
    assert_eq!(a.closest_points(&b, 1e-9), Err(GeomError::Parallel));
}

#[test]
fn laser_plane_through_camera_centre() {
    let board = right_angle_board();
    // the plane y = 0 contains the camera centre: its stripe is a line through the image centre
    let on = |side: f64| -> Vec<Point3<f64>> {
        (1..=8)
            .map(|k| {
                let x = side * 40.0 * k as f64;
                Point3::new(x, 0.0, 1000.0 - x.abs())
            })
            .collect()
    };
    let cfg = LaserFitConfig::default();
    assert_eq!(
        laser::least_squares(&on(-1.0), &on(1.0), &cfg).map(|_| ()),
        Err(GeomError::PlaneThroughCamera)
    );
    assert_eq!(
        laser::paper(&board, &on(-1.0), &on(1.0), &cfg).map(|_| ()),
        Err(GeomError::PlaneThroughCamera)
    );
    // and triangulating with such a plane
    let cam = Camera::<f64>::paper(1400.0, 1600, 1200).unwrap();
    let through = Plane::new(Vector3::new(0.0, 1.0, 0.0), 0.0).unwrap();
    assert_eq!(
        triangulate::triangulate(
            &cam,
            &board,
            &through,
            &Point2::new(700.0, 700.0),
            &Limits::default()
        ),
        Err(GeomError::PlaneThroughCamera)
    );
}

#[test]
fn stripe_on_one_plane_only() {
    let board = right_angle_board();
    let cfg = LaserFitConfig::default();
    let left = stripe(-1.0, 12);
    for right in [vec![], stripe(1.0, 2)] {
        assert_eq!(
            laser::least_squares(&left, &right, &cfg).map(|_| ()),
            Err(GeomError::OnePlaneOnly)
        );
        assert_eq!(
            laser::paper(&board, &left, &right, &cfg).map(|_| ()),
            Err(GeomError::OnePlaneOnly)
        );
    }
    assert_eq!(
        laser::least_squares(&[], &[], &cfg).map(|_| ()),
        Err(GeomError::TooFewPoints { needed: 5, got: 0 })
    );
    // a good frame for contrast
    let ok = laser::least_squares(&left, &stripe(1.0, 12), &cfg).unwrap();
    assert!(ok.quality.rms < 1e-9);
}

#[test]
fn stripe_parallel_to_the_crease() {
    // a vertical laser plane: its lines on both halves run parallel to the (vertical) crease, so
    // S and T do not exist.
    let board = right_angle_board();
    let side = |s: f64| -> Vec<Point3<f64>> {
        (0..8)
            .map(|k| {
                let y = -150.0 + 40.0 * k as f64;
                let x = if s < 0.0 { -80.0 } else { 120.0 };
                Point3::new(x, y, 1000.0 - x.abs())
            })
            .collect()
    };
    let cfg = LaserFitConfig::default();
    assert_eq!(
        laser::paper(&board, &side(-1.0), &side(1.0), &cfg).map(|_| ()),
        Err(GeomError::Parallel)
    );
}

#[test]
fn collinear_layouts_and_points() {
    let cam = Camera::<f64>::paper(1400.0, 1600, 1200).unwrap();
    let layout: Vec<_> = (0..6).map(|i| Point2::new(40.0 * i as f64, 0.0)).collect();
    let px: Vec<_> = (0..6)
        .map(|i| Point2::new(500.0 + 30.0 * i as f64, 600.0))
        .collect();
    assert_eq!(
        pose::plane_pose(&cam, &layout, &px).map(|_| ()),
        Err(GeomError::Collinear)
    );
    assert_eq!(
        pose::plane_pose(&cam, &layout[..3], &px[..3]).map(|_| ()),
        Err(GeomError::TooFewPoints { needed: 4, got: 3 })
    );
    assert_eq!(
        pose::plane_pose(&cam, &layout, &px[..5]).map(|_| ()),
        Err(GeomError::LengthMismatch)
    );
    let pts: Vec<_> = (0..6)
        .map(|i| Point3::new(i as f64, 2.0 * i as f64, 1000.0))
        .collect();
    assert_eq!(
        fit_plane(pts.iter().copied()).map(|_| ()),
        Err(GeomError::Collinear)
    );
    let same = [Point3::new(1.0, 2.0, 3.0); 4];
    assert_eq!(fit_line(same).map(|_| ()), Err(GeomError::Collinear));
    assert_eq!(
        fit_plane(same[..2].iter().copied()).map(|_| ()),
        Err(GeomError::TooFewPoints { needed: 3, got: 2 })
    );
}

#[test]
fn undistortion_outside_the_invertible_region() {
    // strong barrel distortion folds back beyond r ≈ 0.58: a pixel out there has no ray
    let cam = Camera::new(
        1000.0,
        1000.0,
        800.0,
        600.0,
        Distortion {
            k1: -1.0,
            ..Distortion::none()
        },
    )
    .unwrap();
    assert_eq!(
        cam.undistort(&Point2::new(800.0 + 900.0, 600.0)),
        Err(GeomError::NoConvergence)
    );
    assert!(cam.undistort(&Point2::new(800.0 + 100.0, 600.0)).is_ok());
}

#[test]
fn image_distance_degenerate_shots() {
    let s = CrossShot {
        tape_mm: 500.0,
        span_px: 300.0,
    };
    assert!(matches!(
        image_distance(200.0, s, s),
        Err(GeomError::BadParameter(_))
    ));
    // farther but larger in the image: contradicts the model
    let far = CrossShot {
        tape_mm: 900.0,
        span_px: 400.0,
    };
    assert!(matches!(
        image_distance(200.0, s, far),
        Err(GeomError::BadParameter(_))
    ));
    assert_eq!(image_distance(f64::NAN, s, far), Err(GeomError::NotFinite));
    assert!(matches!(
        image_distance(-1.0, s, far),
        Err(GeomError::BadParameter(_))
    ));
}

#[test]
fn camera_parameter_checks() {
    assert!(matches!(
        Camera::new(0.0, 1.0, 0.0, 0.0, Distortion::none()),
        Err(GeomError::BadParameter(_))
    ));
    assert_eq!(
        Camera::new(f64::INFINITY, 1.0, 0.0, 0.0, Distortion::none()),
        Err(GeomError::NotFinite)
    );
    assert!(matches!(
        Camera::<f32>::paper(1000.0, 0, 480),
        Err(GeomError::BadParameter(_))
    ));
    let cam = Camera::<f64>::paper(1000.0, 640, 480).unwrap();
    assert_eq!(
        cam.project(&Point3::new(0.0, 0.0, 0.0)),
        Err(GeomError::BehindCamera)
    );
    assert_eq!(
        cam.project(&Point3::new(1.0, 0.0, -5.0)),
        Err(GeomError::BehindCamera)
    );
    assert_eq!(
        cam.project(&Point3::new(f64::NAN, 0.0, 5.0)),
        Err(GeomError::NotFinite)
    );
    assert_eq!(
        cam.pixel_to_ray(&Point2::new(f64::INFINITY, 0.0)),
        Err(GeomError::NotFinite)
    );
}

#[test]
fn errors_have_messages() {
    let all = [
        GeomError::NotFinite,
        GeomError::BadParameter("x"),
        GeomError::TooFewPoints { needed: 3, got: 1 },
        GeomError::LengthMismatch,
        GeomError::BehindCamera,
        GeomError::Grazing,
        GeomError::BeyondRange,
        GeomError::BehindBoard,
        GeomError::NoConvergence,
        GeomError::CoincidentPoints,
        GeomError::Collinear,
        GeomError::Parallel,
        GeomError::PlaneThroughCamera,
        GeomError::OnePlaneOnly,
        GeomError::IllConditioned,
    ];
    let texts: std::collections::HashSet<String> = all.iter().map(|e| e.to_string()).collect();
    assert_eq!(texts.len(), all.len(), "every error has its own message");
    assert!(texts.iter().all(|t| !t.is_empty()));
}

// ---- arbitrary floats: no panic, no NaN out ----

/// Any f64 at all, mixed with ordinary values so that deeper code is reached too.
fn float() -> impl Strategy<Value = f64> {
    prop_oneof![
        3 => -2000.0..2000.0f64,
        2 => any::<f64>(),
        1 => Just(0.0),
        1 => prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY), Just(f64::MIN_POSITIVE / 4.0), Just(1e300)],
    ]
}

fn v3() -> impl Strategy<Value = Vector3<f64>> {
    (float(), float(), float()).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}
fn p3() -> impl Strategy<Value = Point3<f64>> {
    v3().prop_map(Point3::from)
}
fn p2() -> impl Strategy<Value = Point2<f64>> {
    (float(), float()).prop_map(|(x, y)| Point2::new(x, y))
}
fn camera() -> impl Strategy<Value = Camera<f64>> {
    (
        float(),
        float(),
        float(),
        float(),
        [float(), float(), float(), float(), float()],
    )
        .prop_filter_map("invalid camera", |(fx, fy, cx, cy, d)| {
            Camera::new(
                fx,
                fy,
                cx,
                cy,
                Distortion {
                    k1: d[0],
                    k2: d[1],
                    p1: d[2],
                    p2: d[3],
                    k3: d[4],
                },
            )
            .ok()
        })
}
fn plane() -> impl Strategy<Value = Plane<f64>> {
    (v3(), float()).prop_filter_map("invalid plane", |(n, d)| Plane::new(n, d).ok())
}

fn finite3(p: &Point3<f64>) -> bool {
    p.iter().all(|v| v.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig {
        failure_persistence: None,
        max_local_rejects: 1 << 24,
        ..ProptestConfig::default()
    })]

    #[test]
    fn camera_never_nan(cam in camera(), p in p3(), px in p2()) {
        if let Ok(q) = cam.project(&p) { prop_assert!(q.x.is_finite() && q.y.is_finite()); }
        if let Ok(r) = cam.pixel_to_ray(&px) { prop_assert!(r.iter().all(|v| v.is_finite())); }
        let c32 = cam.cast::<f32>();
        if let Ok(r) = c32.pixel_to_ray(&px.cast()) { prop_assert!(r.iter().all(|v| v.is_finite())); }
    }

    #[test]
    fn planes_and_lines_never_nan(a in plane(), b in plane(), ray in v3(), p in p3(), s in float()) {
        if let Ok(q) = a.intersect_ray(&ray, s) { prop_assert!(finite3(&q)); }
        if let Ok(l) = a.intersection(&b, s.abs()) {
            prop_assert!(finite3(l.point()) && l.direction().iter().all(|v| v.is_finite()));
        }
        if let Ok(q) = Plane::from_point_normal(&p, &ray) { prop_assert!(q.offset().is_finite()); }
        if let (Ok(l1), Ok(l2)) = (Line::new(p, ray), Line::new(Point3::from(ray), p.coords))
            && let Ok((x, y)) = l1.closest_points(&l2, 1e-9) { prop_assert!(finite3(&x) && finite3(&y)); }
        if let Ok(board) = Board::new(a, b) {
            prop_assert!(board.angle().is_finite());
            let _ = board.locate(&p, 1.0);
        }
    }

    #[test]
    fn fits_never_nan(pts in prop::collection::vec(p3(), 0..12)) {
        if let Ok(f) = fit_plane(pts.iter().copied()) { prop_assert!(f.rms.is_finite() && f.plane.offset().is_finite()); }
        if let Ok(f) = fit_line(pts.iter().copied()) { prop_assert!(f.rms.is_finite() && finite3(f.line.point())); }
    }

    #[test]
    fn collinear_and_calib_never_nan(r in [v3(), v3(), v3()], m in float(), d in [float(), float(), float(), float(), float()]) {
        for p in [collinear::paper(&r, m), collinear::solve(&r, m)].into_iter().flatten() { prop_assert!(p.iter().all(finite3)); }
        let shot = |a: f64, b: f64| CrossShot { tape_mm: a, span_px: b };
        if let Ok(r) = image_distance(d[0], shot(d[1], d[2]), shot(d[3], d[4])) {
            prop_assert!(r.d_z.is_finite() && r.epsilon_mm.is_finite());
        }
    }

    #[test]
    fn pose_never_nan(cam in camera(), pts in prop::collection::vec((p2(), p2()), 0..10)) {
        let (layout, px): (Vec<_>, Vec<_>) = pts.into_iter().unzip();
        if let Ok(h) = pose::homography(&layout, &px.iter().map(|p| p.coords).collect::<Vec<Vector2<f64>>>()) {
            prop_assert!(h.iter().all(|v| v.is_finite()));
        }
        if let Ok(f) = pose::plane_pose(&cam, &layout, &px) {
            prop_assert!(f.rms_px.is_finite() && f.pose.translation.iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn laser_and_triangulation_never_nan(a in plane(), b in plane(), cam in camera(),
                                         l in prop::collection::vec(p3(), 0..12), r in prop::collection::vec(p3(), 0..12),
                                         px in p2(), laser_plane in plane()) {
        let cfg = LaserFitConfig::default();
        if let Ok(f) = laser::least_squares(&l, &r, &cfg) { prop_assert!(f.quality.rms.is_finite() && f.plane.offset().is_finite()); }
        if let Ok(board) = Board::new(a, b) {
            if let Ok(f) = laser::paper(&board, &l, &r, &cfg) {
                prop_assert!(f.quality.rms.is_finite() && f.quality.st_gap.is_some_and(f64::is_finite));
            }
            if let Ok((p, _)) = triangulate::triangulate(&cam, &board, &laser_plane, &px, &Limits::default()) { prop_assert!(finite3(&p)); }
            if let Ok((p, _)) = triangulate::board_point(&cam, &board, &px, &Limits::default()) { prop_assert!(finite3(&p)); }
            // the f32 per-frame path
            let (c, bd, lp) = (cam.cast::<f32>(), board.cast::<f32>(), laser_plane.cast::<f32>());
            if let Ok((p, _)) = triangulate::triangulate(&c, &bd, &lp, &px.cast(), &Limits::default()) {
                prop_assert!(p.iter().all(|v| v.is_finite()));
            }
            let l32: Vec<Point3<f32>> = l.iter().map(|p| p.cast()).collect();
            let r32: Vec<Point3<f32>> = r.iter().map(|p| p.cast()).collect();
            if let Ok(f) = laser::least_squares(&l32, &r32, &LaserFitConfig::default()) { prop_assert!(f.quality.rms.is_finite()); }
            if let Ok(f) = laser::paper(&bd, &l32, &r32, &LaserFitConfig::default()) { prop_assert!(f.quality.max.is_finite()); }
        }
    }
}

/// The laser plane's tilt uncertainty is honest: with noisy board points, the normal's actual
/// error stays within 3 reported σ, and a stripe that is short on one side (the late frames of a
/// sweep, where it barely reaches past the crease) reports a far larger uncertainty — enough for
/// the head's default limit to refuse it — although its points fit just as well.
#[test]
fn a_short_stripe_gives_an_uncertain_plane() {
    let truth = Plane::new(Vector3::new(0.0, 1.0, -0.2), 100.0).unwrap();
    // a small deterministic normal generator (xorshift + Box–Muller)
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut normal = move || {
        let (a, b) = (uniform(), uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * core::f64::consts::PI * b).cos()
    };
    let sigma = 0.3;
    let mut side = |sign: f64, from: f64, step: f64, n: usize| -> Vec<Point3<f64>> {
        (0..n)
            .map(|k| {
                let x = sign * (from + step * k as f64);
                let z = 1000.0 - x.abs();
                Point3::new(x, 0.2 * z - 100.0 + sigma * normal(), z)
            })
            .collect()
    };
    let cfg = LaserFitConfig::default();
    let limit = scanner_core::pipeline::HeadConfig::new(scanner_core::stripe::StripeConfig::new(
        scanner_core::stripe::Method::Dim,
        scanner_core::stripe::Axis::Columns,
    ))
    .max_plane_tilt;
    let mut medians = Vec::new();
    for (name, from, step) in [("long", 40.0, 40.0), ("short", 5.0, 5.0)] {
        let (mut tilts, mut within) = (Vec::new(), 0);

        let trials = 300;
        for _ in 0..trials {
            let left = side(-1.0, 40.0, 40.0, 12);
            let right = side(1.0, from, step, 10);
            let fit =
                laser::least_squares(&left, &right, &cfg).unwrap_or_else(|e| panic!("{name}: {e}"));
            let n = fit.plane.normal();
            let err = n.angle(truth.normal()).min(n.angle(&-truth.normal()));
            // the reported σ is the worse of the two tilt directions; the error combines both
            if err <= 3.0 * core::f64::consts::SQRT_2 * fit.quality.tilt {
                within += 1;
            }
            tilts.push(fit.quality.tilt);
        }
        tilts.sort_by(f64::total_cmp);

        let median = tilts[trials / 2];
        println!(
            "{name}: median tilt σ {:.4}°, {within}/{trials} errors within 3σ",
            median.to_degrees()
        );
        assert!(within * 100 >= trials * 95, "{name}: {within}/{trials}");
        medians.push(median);
    }
    assert!(medians[1] >= 5.0 * medians[0], "{medians:?}");
    assert!(medians[0] < f64::from(limit) && medians[1] > f64::from(limit));
}
