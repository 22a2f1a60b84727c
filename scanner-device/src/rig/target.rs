//! Calibration shots: the paper's image-distance cross pattern (Fig. 5) and planar targets (dot
//! grid, chessboard) in front of the rig's camera, with ground truth. Rendered with the scene's
//! camera, ambient light, lens blur and sensor; every pixel is supersampled 3×3, and 12×12 where
//! the pattern has an edge in it (calibration shots are few, and their edges are what
//! calibration measures).

use scanner_core::nalgebra::{Point2, Point3, Rotation3, Vector3};

use super::{Rgb8, Rig};

/// Albedo of the white target sheet and of its ink.
const PAPER: f64 = 0.85;
const INK: f64 = 0.06;
/// Sub-samples per pixel side.
const SUB: usize = 3;
/// Sub-samples per pixel side on an edge of the pattern.
const EDGE_SUB: usize = 12;

/// What is printed on the target sheet. Sheet coordinates in mm, origin at the pattern's centre,
/// `x` right and `y` down when the sheet faces the camera upright.
#[derive(Debug, Clone, PartialEq)]
pub enum Pattern {
    /// The paper's cross (Fig. 5): dots A (top), E (bottom), B (left), D (right) at `arm / 2` from
    /// the centre dot C, so `|AE| = |BD| = arm`.
    Cross {
        /// Distance A–E (and B–D), mm.
        arm: f64,
        /// Dot diameter, mm.
        dot: f64,
    },
    /// A grid of dots, centred.
    DotGrid {
        /// Dots per row.
        cols: usize,
        /// Rows.
        rows: usize,
        /// Centre-to-centre distance, mm.
        pitch: f64,
        /// Dot diameter, mm.
        dot: f64,
    },
    /// A chessboard of `cols × rows` squares, centred; its inner corners are the features.
    Chessboard {
        /// Squares per row.
        cols: usize,
        /// Rows of squares.
        rows: usize,
        /// Square side, mm.
        square: f64,
    },
}

impl Pattern {
    /// Dot centres on the sheet (none for a chessboard).
    pub fn dots(&self) -> Vec<[f64; 2]> {
        match *self {
            Pattern::Cross { arm, .. } => {
                let a = arm / 2.0;
                // A, B, C, D, E
                vec![[0.0, -a], [-a, 0.0], [0.0, 0.0], [a, 0.0], [0.0, a]]
            }
            Pattern::DotGrid {
                cols, rows, pitch, ..
            } => (0..rows)
                .flat_map(|r| {
                    (0..cols).map(move |c| {
                        [
                            (c as f64 - (cols - 1) as f64 / 2.0) * pitch,
                            (r as f64 - (rows - 1) as f64 / 2.0) * pitch,
                        ]
                    })
                })
                .collect(),
            Pattern::Chessboard { .. } => Vec::new(),
        }
    }

    /// Inner corners of a chessboard on the sheet (none for dots).
    pub fn corners(&self) -> Vec<[f64; 2]> {
        match *self {
            Pattern::Chessboard { cols, rows, square } => (1..rows)
                .flat_map(|r| {
                    (1..cols).map(move |c| {
                        [
                            (c as f64 - cols as f64 / 2.0) * square,
                            (r as f64 - rows as f64 / 2.0) * square,
                        ]
                    })
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    fn albedo(&self, x: f64, y: f64) -> f64 {
        let ink = |inside: bool| if inside { INK } else { PAPER };
        match *self {
            Pattern::Cross { dot, .. } => {
                let r2 = (dot / 2.0).powi(2);
                ink(self
                    .dots()
                    .iter()
                    .any(|c| (x - c[0]).powi(2) + (y - c[1]).powi(2) <= r2))
            }
            Pattern::DotGrid {
                cols,
                rows,
                pitch,
                dot,
            } => {
                // The nearest grid dot only (dots are less than a pitch wide).
                let (fc, fr) = (
                    x / pitch + (cols - 1) as f64 / 2.0,
                    y / pitch + (rows - 1) as f64 / 2.0,
                );
                let (c, r) = (fc.round(), fr.round());
                if c < 0.0 || r < 0.0 || c > (cols - 1) as f64 || r > (rows - 1) as f64 {
                    return PAPER;
                }
                let (dx, dy) = ((fc - c) * pitch, (fr - r) * pitch);
                ink(dx * dx + dy * dy <= (dot / 2.0).powi(2))
            }
            Pattern::Chessboard { cols, rows, square } => {
                let (u, v) = (
                    x / square + cols as f64 / 2.0,
                    y / square + rows as f64 / 2.0,
                );
                if u < 0.0 || v < 0.0 || u >= cols as f64 || v >= rows as f64 {
                    PAPER
                } else if (u.floor() as i64 + v.floor() as i64) % 2 == 0 {
                    INK
                } else {
                    PAPER
                }
            }
        }
    }

    fn dot_diameter(&self) -> f64 {
        match *self {
            Pattern::Cross { dot, .. } | Pattern::DotGrid { dot, .. } => dot,
            Pattern::Chessboard { .. } => 0.0,
        }
    }
}

/// Where the target sheet is: the pattern's centre in camera coordinates and the sheet's turn
/// (degrees about the camera's x, y, z axes, applied in that order) from facing the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetPose {
    /// Pattern centre, mm.
    pub centre: Point3<f64>,
    /// Turns about x, y, z, degrees.
    pub turn_deg: [f64; 3],
}

impl TargetPose {
    /// Pose `i` of `n` for an intrinsics calibration: the target 550–850 mm away, spread over the
    /// image and turned up to ±35° in every direction (what a user waving a printed target in
    /// front of the camera does, evenly).
    pub fn sweep(i: usize, n: usize) -> TargetPose {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        let z = 550.0 + 300.0 * ((i * 7) % n) as f64 / n as f64;
        TargetPose {
            centre: Point3::new(0.22 * z * a.cos(), 0.15 * z * a.sin(), z),
            turn_deg: [
                35.0 * a.sin(),
                -35.0 * a.cos(),
                10.0 * (i as f64 - n as f64 / 2.0) / n as f64,
            ],
        }
    }
}

/// Ground truth of one feature (a dot or a chessboard corner).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureTruth {
    /// Position on the sheet, mm.
    pub sheet: [f64; 2],
    /// Position in camera coordinates, mm.
    pub point: Point3<f64>,
    /// Projection of the point, pixels.
    pub projected: Point2<f64>,
    /// For a dot: the centroid of its projected disc (where an unbiased detector finds it);
    /// for a corner: the same as `projected`.
    pub centroid: Point2<f64>,
}

/// A rendered calibration shot with its truth.
#[derive(Debug, Clone)]
pub struct Shot {
    /// The frame.
    pub image: Rgb8,
    /// Its features in the pattern's order (cross: A, B, C, D, E).
    pub features: Vec<FeatureTruth>,
}

impl Rig {
    /// Renders a calibration shot: `pattern` at `pose`, nothing else in view (a wall of the
    /// same white behind), with `noise_seed` choosing the sensor noise.
    pub fn shot(&self, pattern: &Pattern, pose: &TargetPose, noise_seed: u64) -> Shot {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let turn = Rotation3::from_euler_angles(
            pose.turn_deg[0].to_radians(),
            pose.turn_deg[1].to_radians(),
            pose.turn_deg[2].to_radians(),
        );
        let (ex, ey, n) = (
            turn * Vector3::x(),
            turn * Vector3::y(),
            turn * Vector3::z(),
        );
        let sheet = |p: &Point3<f64>| ((p - pose.centre).dot(&ex), (p - pose.centre).dot(&ey));
        let amb = self.scene.ambient;
        let coverage = |u: usize, v: usize, sub: usize| {
            let (mut sum, mut lo, mut hi) = (0.0, f64::INFINITY, 0.0f64);
            for (su, sv) in super::subpixels(u, v, sub) {
                let mut a = 0.0;
                if let Some(d) = self.ray_fast(su, sv) {
                    let den = d.dot(&n);
                    let t = if den.abs() < 1e-9 {
                        -1.0
                    } else {
                        pose.centre.coords.dot(&n) / den
                    };
                    if t > 0.0 {
                        let (x, y) = sheet(&Point3::from(d * t));
                        a = pattern.albedo(x, y);
                    }
                }
                sum += a;
                lo = lo.min(a);
                hi = hi.max(a);
            }
            (sum / (sub * sub) as f64, lo < hi)
        };
        let coarse: Vec<(f64, bool)> = (0..w * h).map(|i| coverage(i % w, i / w, SUB)).collect();
        // Pixels on an edge of the pattern, and their neighbours (a thin sliver can pass between
        // the coarse samples), get a finer grid: the edges are what calibration measures.
        let mut flat = vec![[0.0; 3]; w * h];
        for v in 0..h {
            for u in 0..w {
                let near_edge = (v.saturating_sub(1)..=(v + 1).min(h - 1)).any(|y| {
                    (u.saturating_sub(1)..=(u + 1).min(w - 1)).any(|x| coarse[y * w + x].1)
                });
                let a = if near_edge {
                    coverage(u, v, EDGE_SUB).0
                } else {
                    coarse[v * w + u].0
                };
                flat[v * w + u] = [amb * a; 3];
            }
        }
        let blurred: Vec<[f32; 3]> = super::blur(&flat, w, h, &self.kernel)
            .into_iter()
            .map(|p| p.map(|v| v as f32))
            .collect();
        let image = self.expose(&blurred, noise_seed ^ 0xCA1B);
        let cam = &self.scene.camera;
        let place = |s: [f64; 2]| pose.centre + ex * s[0] + ey * s[1];
        let mut features = Vec::new();
        let r = pattern.dot_diameter() / 2.0;
        for s in pattern.dots() {
            let point = place(s);
            let Ok(projected) = cam.project(&point) else {
                continue;
            };
            let rim: Vec<Point2<f64>> = (0..720)
                .filter_map(|i| {
                    let a = i as f64 / 720.0 * std::f64::consts::TAU;
                    cam.project(&place([s[0] + r * a.cos(), s[1] + r * a.sin()]))
                        .ok()
                })
                .collect();
            let centroid = super::polygon_centroid(&rim).unwrap_or(projected);
            features.push(FeatureTruth {
                sheet: s,
                point,
                projected,
                centroid,
            });
        }
        for s in pattern.corners() {
            let point = place(s);
            if let Ok(projected) = cam.project(&point) {
                features.push(FeatureTruth {
                    sheet: s,
                    point,
                    projected,
                    centroid: projected,
                });
            }
        }
        Shot { image, features }
    }
}
