//! The accuracy report (the paper's Table 3) as a library, so that the report command and a
//! quick test run the same code: the paper's setup on the virtual rig at several distances —
//! calibrate from rendered images, scan two spheres and a tilted plane, measure.
//!
//! `cargo run --release -p scanner-device --example accuracy_report` prints it.

use crate::{Object, Rig, Scene, Shape};
use scanner_calib::board::{BoardFile, Cross, Grid, SheetLayout, SheetSize};
use scanner_calib::{DotGrid, Target, board_planes, intrinsics};
use scanner_core::Camera;
use scanner_core::calib::Free;
use scanner_core::geometry::Board;
use scanner_core::nalgebra::{Matrix4, Point3, Unit, Vector3, Vector4};
use scanner_core::pipeline::{Head, HeadConfig};
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_core::wire::points::dequantise;

/// The paper's mean errors (mm) at 280, 400, 800, 1600 and 3200 mm.
pub const PAPER_MEAN_MM: [(f64, f64); 5] = [
    (280.0, 0.16),
    (400.0, 0.24),
    (800.0, 0.49),
    (1600.0, 0.99),
    (3200.0, 1.97),
];

/// One row of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Camera–board distance, mm.
    pub distance: f64,
    /// "layout" or "paper".
    pub board: &'static str,
    /// Points measured.
    pub points: usize,
    /// Mean point-to-surface error, mm.
    pub mean_mm: f64,
    /// 99th percentile, mm.
    pub p99_mm: f64,
    /// Sphere diameter errors, mm (each sphere).
    pub diameter_mm: [f64; 2],
    /// Sphere-centre spacing error, mm.
    pub spacing_mm: f64,
    /// Flatness of the tilted plane: range of the residuals about the fitted plane, after leaving
    /// out residuals beyond 4 robust σ (the stripe where it runs along the plane's edge, with the
    /// board far behind: "flying" points), mm.
    pub flatness_mm: f64,
    /// Share of the plane's points left out as flying, %.
    pub flying_pct: f64,
}

/// The board file of the paper's layout with marker spacing `s` (mm).
pub fn paper_board(s: f64) -> BoardFile {
    let grid = Grid {
        cols: 3,
        rows: 2,
        u0: 0.6 * s,
        v0: -s,
        du: s,
        dv: 2.0 * s,
    };
    let sheet = SheetLayout {
        markers: None,
        grid: Some(grid),
        chessboard: None,
    };
    BoardFile {
        marker_diameter: 0.25 * s,
        sheet: SheetSize {
            width: 3.5 * s,
            height: 2.6 * s,
        },
        left: sheet.clone(),
        right: sheet,
        cross: Cross {
            arm: 200.0,
            dot: 12.0,
        },
    }
}

/// The scene at distance `d`: the paper's board (marker spacing `d/6.67`, 40 mm at 280), two
/// spheres and a tilted plane between the marker rows, a hand-held laser sweeping over them.
pub fn scene(width: u32, height: u32, d: f64, frames: usize) -> (Scene, BoardFile) {
    let s = if d <= 300.0 { d / 7.0 } else { d * 0.15 };
    let board = paper_board(s);
    let mut sc = Scene::demo(width, height);
    sc.board.distance = d;
    sc.board.markers = (&board).into();
    let sphere = |x: f64, y: f64, z: f64| Object {
        shape: Shape::Sphere {
            centre: Point3::new(x * d, y * d, z * d),
            radius: 0.055 * d,
        },
        albedo: [0.7, 0.65, 0.6],
        texture: None,
    };
    // Tilted back (facing up, towards the laser held above the camera).
    let tilt = Unit::new_normalize(Vector3::new(0.0, -(0.5f64.sin()), -0.5f64.cos()));
    let ex = Vector3::x();
    let ey = tilt.cross(&ex).normalize();
    sc.objects = vec![
        sphere(-0.14, 0.02, 0.62),
        sphere(0.0, 0.03, 0.6),
        Object {
            shape: Shape::Rectangle {
                centre: Point3::new(0.14 * d, 0.02 * d, 0.62 * d),
                axes: [ex, ey],
                half: [0.045 * d, 0.06 * d],
            },
            albedo: [0.75, 0.75, 0.75],
            texture: None,
        },
    ];
    sc.laser.source = Point3::new(0.025 * d, -0.19 * d, 0.04 * d);
    sc.laser.sweep = (-0.16 * d, 0.2 * d);
    sc.laser.frames = frames;
    sc.laser.jitter_mm = 0.0025 * d;
    sc.laser.sigma_mm = 0.00075 * d;
    (sc, board)
}

/// Intrinsics from 12 rendered dot-grid images of the demo camera at this size.
pub fn calibrate_camera(width: u32, height: u32) -> Camera<f64> {
    let rig = Rig::new(Scene::demo(width, height)).expect("demo rig");
    let grid = DotGrid::RIG;
    let images = rig.dot_grid_shots(&grid, 12);
    intrinsics(&images, &Target::Dots(grid), Free::ALL)
        .expect("intrinsics")
        .camera
}

/// Least-squares sphere (algebraic, then the radius from the centre): centre and radius.
pub fn fit_sphere(pts: &[Point3<f64>]) -> Option<(Point3<f64>, f64)> {
    // x² + y² + z² + D x + E y + F z + G = 0
    let mut ata = Matrix4::<f64>::zeros();
    let mut atb = Vector4::<f64>::zeros();
    for p in pts {
        let row = Vector4::new(p.x, p.y, p.z, 1.0);
        ata += row * row.transpose();
        atb += row * -(p.coords.norm_squared());
    }
    let sol = ata.cholesky()?.solve(&atb);
    let c = Point3::new(-sol[0] / 2.0, -sol[1] / 2.0, -sol[2] / 2.0);
    let r2 = c.coords.norm_squared() - sol[3];
    (r2 > 0.0).then(|| (c, r2.sqrt()))
}

/// Flatness (range of residuals about the best plane) after dropping points beyond 4 robust σ,
/// refitting once; and the share dropped, %.
fn robust_flatness(pts: &[Point3<f64>]) -> (f64, f64) {
    let Ok(f) = scanner_core::geometry::fit_plane(pts.iter().copied()) else {
        return (f64::NAN, f64::NAN);
    };
    let mut abs: Vec<f64> = pts
        .iter()
        .map(|p| f.plane.signed_distance(p).abs())
        .collect();
    abs.sort_by(f64::total_cmp);
    let sigma = 1.4826 * abs[abs.len() / 2];
    let kept: Vec<Point3<f64>> = pts
        .iter()
        .copied()
        .filter(|p| f.plane.signed_distance(p).abs() <= 4.0 * sigma)
        .collect();
    let Ok(g) = scanner_core::geometry::fit_plane(kept.iter().copied()) else {
        return (f64::NAN, f64::NAN);
    };
    let r: Vec<f64> = kept.iter().map(|p| g.plane.signed_distance(p)).collect();
    let range = r.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - r.iter().copied().fold(f64::INFINITY, f64::min);
    (
        range,
        100.0 * (pts.len() - kept.len()) as f64 / pts.len().max(1) as f64,
    )
}

/// Runs the report at distance `d` for both board constructions.
pub fn run_distance(
    camera: &Camera<f64>,
    width: u32,
    height: u32,
    d: f64,
    frames: usize,
) -> Vec<Row> {
    let (scene, board) = scene(width, height, d, frames);
    let rig = Rig::new(scene.clone()).expect("rig");
    let reference = rig.reference();
    let outcome = board_planes(&reference.to_gray_image(), &board, camera);
    let fit = outcome
        .result
        .expect("board calibration from the rendered board");
    let mut boards = vec![(
        "layout",
        Board::new(fit.sheets[0].plane, fit.sheets[1].plane).expect("board"),
    )];
    if let [Some(l), Some(r)] = fit.paper {
        boards.push(("paper", Board::new(l, r).expect("paper board")));
    }
    let refg = reference.to_format(PixelFormat::Gray8);
    let (w, h) = (width as usize, height as usize);
    let ref_frame =
        scanner_core::stripe::Frame::packed(&refg, w, h, PixelFormat::Gray8).expect("frame");
    let rendered: Vec<Vec<u8>> = (0..frames)
        .map(|k| rig.frame(k).expect("frame").to_format(PixelFormat::Gray8))
        .collect();
    let truth_objects: Vec<Shape> = scene.objects.iter().map(|o| o.shape.clone()).collect();
    let mut rows = Vec::new();
    for (name, b) in boards {
        let mut head = Box::new(Head::<4096>::new(
            camera.cast(),
            b.cast(),
            HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        ));
        let mut pts: Vec<Point3<f64>> = Vec::new();
        for data in &rendered {
            let f =
                scanner_core::stripe::Frame::packed(data, w, h, PixelFormat::Gray8).expect("frame");
            if let Ok(out) = head.process(&f, Some(&ref_frame)) {
                pts.extend(out.points.iter().map(|q| {
                    Point3::new(
                        f64::from(dequantise(q[0])),
                        f64::from(dequantise(q[1])),
                        f64::from(dequantise(q[2])),
                    )
                }));
            }
        }
        // Each point to its object (the nearest true surface).
        let mut errs = Vec::new();
        let mut per: Vec<Vec<Point3<f64>>> = vec![Vec::new(); truth_objects.len()];
        for p in &pts {
            let (k, dist) = truth_objects
                .iter()
                .enumerate()
                .map(|(k, s)| (k, s.distance(p).unwrap_or(f64::INFINITY)))
                .fold((0, f64::INFINITY), |a, x| if x.1 < a.1 { x } else { a });
            errs.push(rig.surface_distance(p));
            if dist < 0.01 * d {
                per[k].push(*p);
            }
        }
        errs.sort_by(f64::total_cmp);
        let mean = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
        let p99 = errs.get(errs.len() * 99 / 100).copied().unwrap_or(f64::NAN);
        let sphere_truth = |k: usize| match &truth_objects[k] {
            Shape::Sphere { centre, radius } => (*centre, *radius),
            _ => (Point3::origin(), f64::NAN),
        };
        let fits: Vec<Option<(Point3<f64>, f64)>> = (0..2).map(|k| fit_sphere(&per[k])).collect();
        let diameter =
            [0, 1].map(|k| fits[k].map_or(f64::NAN, |(_, r)| 2.0 * (r - sphere_truth(k).1)));
        let spacing = match (fits[0], fits[1]) {
            (Some((a, _)), Some((b, _))) => {
                (a - b).norm() - (sphere_truth(0).0 - sphere_truth(1).0).norm()
            }
            _ => f64::NAN,
        };
        let (flatness, flying) = robust_flatness(&per[2]);
        rows.push(Row {
            distance: d,
            board: name,
            points: pts.len(),
            mean_mm: mean,
            p99_mm: p99,
            diameter_mm: diameter,
            spacing_mm: spacing,
            flatness_mm: flatness,
            flying_pct: flying,
        });
    }
    rows
}

/// The report as a Markdown table.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| distance | board planes | points | mean error | p99 error | sphere diameter error | sphere spacing error | plane flatness (flying points left out) | paper's mean error |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let pct = |v: f64| 100.0 * v / r.distance;
        let paper = PAPER_MEAN_MM
            .iter()
            .find(|(d, _)| *d == r.distance)
            .map_or("—".to_string(), |(d, m)| {
                format!("{m} mm ({:.3} %)", 100.0 * m / d)
            });
        s += &format!(
            "| {} mm | {} | {} | {:.3} mm ({:.4} %) | {:.3} mm ({:.4} %) | {:+.3} / {:+.3} mm ({:.4} %) | {:+.3} mm ({:.4} %) | {:.3} mm ({:.1} %) | {paper} |\n",
            r.distance,
            r.board,
            r.points,
            r.mean_mm,
            pct(r.mean_mm),
            r.p99_mm,
            pct(r.p99_mm),
            r.diameter_mm[0],
            r.diameter_mm[1],
            pct(r.diameter_mm[0].abs().max(r.diameter_mm[1].abs())),
            r.spacing_mm,
            pct(r.spacing_mm.abs()),
            r.flatness_mm,
            r.flying_pct,
        );
    }
    s
}
