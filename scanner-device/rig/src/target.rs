//! Calibration shots: the paper's image-distance cross pattern (Fig. 5) and planar targets (dot
//! grid, chessboard) in front of the rig's camera, with ground truth. Rendered with the scene's
//! camera, ambient light, lens blur and sensor; every pixel is supersampled 3×3, and 12×12 where
//! the pattern has an edge in it (calibration shots are few, and their edges are what
//! calibration measures).

use scanner_core::nalgebra::{Point2, Point3, Rotation3, Vector3};

use scanner_calib::aruco::CharucoBoard;

pub use crate::scene::TargetPose;

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
    /// A ChArUco board (OpenCV's layout), centred; its inner corners are the features, in
    /// OpenCV's order.
    Charuco(CharucoBoard),
}

impl From<&scanner_calib::DotGrid> for Pattern {
    fn from(g: &scanner_calib::DotGrid) -> Self {
        Pattern::DotGrid {
            cols: g.cols,
            rows: g.rows,
            pitch: g.pitch,
            dot: g.dot,
        }
    }
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
            Pattern::Chessboard { .. } | Pattern::Charuco(_) => Vec::new(),
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
            Pattern::Charuco(b) => {
                let (hx, hy) = self.half_extent();
                (0..b.corner_count())
                    .map(|k| {
                        let c = b.corner(k);
                        [c.x - hx, c.y - hy]
                    })
                    .collect()
            }
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
            Pattern::Charuco(b) => {
                let (hx, hy) = self.half_extent();
                ink(charuco_ink(&b, x + hx, y + hy))
            }
        }
    }

    /// Half the printed pattern's width and height, mm (to its outermost ink).
    pub fn half_extent(&self) -> (f64, f64) {
        match *self {
            Pattern::Cross { arm, dot } => ((arm + dot) / 2.0, (arm + dot) / 2.0),
            Pattern::DotGrid {
                cols,
                rows,
                pitch,
                dot,
            } => (
                ((cols - 1) as f64 * pitch + dot) / 2.0,
                ((rows - 1) as f64 * pitch + dot) / 2.0,
            ),
            Pattern::Chessboard { cols, rows, square } => {
                (cols as f64 * square / 2.0, rows as f64 * square / 2.0)
            }
            Pattern::Charuco(b) => (
                b.cols as f64 * b.square / 2.0,
                b.rows as f64 * b.square / 2.0,
            ),
        }
    }

    fn dot_diameter(&self) -> f64 {
        match *self {
            Pattern::Cross { dot, .. } | Pattern::DotGrid { dot, .. } => dot,
            Pattern::Chessboard { .. } | Pattern::Charuco(_) => 0.0,
        }
    }
}

/// Whether a ChArUco board has ink at board point `(x, y)` (mm from its top left): a dark
/// square, or a dark cell of a marker (its border, or a dark cell of its code).
fn charuco_ink(b: &CharucoBoard, x: f64, y: f64) -> bool {
    let (u, v) = (x / b.square, y / b.square);
    if u < 0.0 || v < 0.0 || u >= b.cols as f64 || v >= b.rows as f64 {
        return false;
    }
    let (sx, sy) = (u.floor() as usize, v.floor() as usize);
    let Some(id) = b.marker_in(sx, sy) else {
        return true;
    };
    let m = (b.square - b.marker) / 2.0;
    let (mx, my) = (x - sx as f64 * b.square - m, y - sy as f64 * b.square - m);
    if mx < 0.0 || my < 0.0 || mx >= b.marker || my >= b.marker {
        return false;
    }
    let n = b.dictionary.n;
    let cell = b.marker / (n + 2) as f64;
    let (c, r) = ((mx / cell) as usize, (my / cell) as usize);
    if r == 0 || c == 0 || r > n || c > n {
        return true;
    }
    let code = b.dictionary.code(id).unwrap_or(0);
    (code >> (n * n - 1 - ((r - 1) * n + c - 1))) & 1 == 0
}

/// What surrounds the target in a shot: what a real photograph has (the paper's edge, a room
/// behind, the hand holding the sheet). The default is nothing: the sheet fills the view.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Surroundings {
    /// White paper around the pattern, mm; beyond it, the room. `None`: the sheet has no edge.
    pub margin: Option<f64>,
    /// A wall with dark clutter behind the target.
    pub clutter: Option<Clutter>,
    /// A hand holding the sheet, its fingers reaching over the pattern from this point (pattern
    /// coordinates, mm) towards the pattern's centre, 25 mm in front of the sheet.
    pub hand: Option<[f64; 2]>,
    /// Something regular beside the sheet, in its plane and aligned with its rows.
    pub beside: Option<Beside>,
}

/// Regular clutter right beside the target (to its right, `gap` of a row's pitch from the
/// pattern's edge, over the sheet's margin there), in the sheet's plane and lined up with the
/// pattern's rows — a striped shirt, a keyboard, a second printed pattern laid next to the
/// first: what a lattice of the pattern's features could take for more of itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beside {
    /// What it is.
    pub kind: BesideKind,
    /// Its distance from the pattern's edge, in rows' pitches.
    pub gap: f64,
}

/// The kinds of [`Beside`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BesideKind {
    /// Dark bands as wide as the pattern's rows, one row apart, their edges on the rows' lines.
    Stripes,
    /// Dark keys of 70 % of a row's pitch on a grid of that pitch, lined up with the rows.
    Keys,
    /// A second chessboard of the same squares, its rows continuing the pattern's (six squares
    /// wide, as high as the pattern).
    Checker,
    /// A chessboard of squares 0.7 of the pattern's, turned by 30° (a checked cloth, another
    /// board lying askew): corners of the right kind on a lattice of another step and angle.
    Turned,
    /// A chessboard of half the pattern's squares, lined up with its rows: every other corner
    /// on the pattern's own lattice.
    Fine,
}

/// A mid-gray wall behind the target with dark things on it: discs the size of markers, bars,
/// rectangles and a keyboard-like block of dark keys.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clutter {
    /// Distance of the wall behind the target's centre, mm.
    pub behind: f64,
    /// Chooses the clutter.
    pub seed: u64,
}

/// Albedo of the wall, of the dark things on it, and of skin.
const WALL: f64 = 0.45;
const DARK: f64 = 0.05;
const SKIN: f64 = 0.4;
/// Distance of the hand in front of the sheet, mm.
const HAND_LIFT: f64 = 25.0;

/// A dark thing on the clutter wall (wall coordinates, mm).
#[derive(Debug, Clone, Copy)]
enum Thing {
    Disc {
        x: f64,
        y: f64,
        r: f64,
    },
    Rect {
        x: f64,
        y: f64,
        hw: f64,
        hh: f64,
        cos: f64,
        sin: f64,
    },
}

impl Thing {
    fn covers(&self, px: f64, py: f64) -> bool {
        match *self {
            Thing::Disc { x, y, r } => (px - x).powi(2) + (py - y).powi(2) <= r * r,
            Thing::Rect {
                x,
                y,
                hw,
                hh,
                cos,
                sin,
            } => {
                let (dx, dy) = (px - x, py - y);
                (dx * cos + dy * sin).abs() <= hw && (-dx * sin + dy * cos).abs() <= hh
            }
        }
    }
}

/// The clutter of a wall spanning `±span` mm.
fn clutter_things(seed: u64, span: (f64, f64)) -> Vec<Thing> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(seed ^ 0x00C1_077E);
    let mut things = Vec::new();
    let at = |rng: &mut rand::rngs::SmallRng| {
        (
            rng.random_range(-span.0..span.0),
            rng.random_range(-span.1..span.1),
        )
    };
    for _ in 0..30 {
        let (x, y) = at(&mut rng);
        things.push(Thing::Disc {
            x,
            y,
            r: rng.random_range(4.0..25.0),
        });
    }
    for _ in 0..20 {
        let (x, y) = at(&mut rng);
        let a: f64 = rng.random_range(0.0..std::f64::consts::PI);
        let long = rng.random_bool(0.5);
        things.push(Thing::Rect {
            x,
            y,
            hw: if long {
                rng.random_range(40.0..150.0)
            } else {
                rng.random_range(5.0..40.0)
            },
            hh: rng.random_range(3.0..30.0),
            cos: a.cos(),
            sin: a.sin(),
        });
    }
    // A keyboard: rows of dark keys with gaps.
    let (kx, ky) = at(&mut rng);
    for r in 0..5 {
        for c in 0..14 {
            things.push(Thing::Rect {
                x: kx + c as f64 * 19.0,
                y: ky + r as f64 * 19.0,
                hw: 7.5,
                hh: 7.5,
                cos: 1.0,
                sin: 0.0,
            });
        }
    }
    things
}

/// A hand in its own plane coordinates: x along the fingers (towards their tips), palm behind.
fn hand_covers(x: f64, y: f64) -> bool {
    let palm = ((x + 50.0) / 55.0).powi(2) + (y / 45.0).powi(2) <= 1.0;
    let finger = |cy: f64, len: f64| {
        let dy = y - cy;
        if x < -10.0 {
            return false;
        }
        let tip = (x - len).max(0.0);
        tip * tip + dy * dy <= 8.0 * 8.0
    };
    palm || finger(-27.0, 45.0) || finger(-9.0, 60.0) || finger(9.0, 63.0) || finger(27.0, 52.0)
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
    /// Fully in view: inside the image and not hidden by the hand (nor is anything within a
    /// dot's radius or half a square of it).
    pub visible: bool,
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
        self.shot_in(pattern, pose, &Surroundings::default(), noise_seed)
    }

    /// Renders a calibration shot with [`Surroundings`]: the sheet's edge, a cluttered wall
    /// behind it, a hand over it.
    pub fn shot_in(
        &self,
        pattern: &Pattern,
        pose: &TargetPose,
        around: &Surroundings,
        noise_seed: u64,
    ) -> Shot {
        let view = ShotView::new(self, pattern, pose, around);
        let image = self.render_albedo(|d| view.albedo_along(d), noise_seed ^ 0xCA1B);
        let features = view.features(self);
        Shot { image, features }
    }

    /// A frame of the scene's camera where a ray `d` (unit, camera frame) sees `albedo(d)` in
    /// the ambient light: supersampled, finer on edges, blurred by the lens, exposed.
    fn render_albedo(&self, albedo: impl Fn(&Vector3<f64>) -> f64, noise_seed: u64) -> Rgb8 {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let coverage = |u: usize, v: usize, sub: usize| {
            let (mut sum, mut lo, mut hi) = (0.0, f64::INFINITY, 0.0f64);
            for (su, sv) in super::subpixels(u, v, sub) {
                let a = self.ray_fast(su, sv).map_or(0.0, |d| albedo(&d));
                sum += a;
                lo = lo.min(a);
                hi = hi.max(a);
            }
            (sum / (sub * sub) as f64, lo < hi)
        };
        let coarse: Vec<(f64, bool)> = (0..w * h).map(|i| coverage(i % w, i / w, SUB)).collect();
        // Pixels on an edge of the pattern, and their neighbours (a thin sliver can pass between
        // the coarse samples), get a finer grid: the edges are what calibration measures.
        let amb = self.scene.ambient;
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
        let blurred: Vec<[f32; 3]> = scanner_calib::blur::blur(&flat, w, h, &self.kernel)
            .into_iter()
            .map(|p| p.map(|v| v as f32))
            .collect();
        self.expose(&blurred, noise_seed)
    }
}

/// Where a ray meets a plane through `c` with normal `n` (distance along the unit ray `d`).
fn meet(d: &Vector3<f64>, c: &Point3<f64>, n: &Vector3<f64>) -> Option<f64> {
    let den = d.dot(n);
    if den.abs() < 1e-9 {
        return None;
    }
    let t = c.coords.dot(n) / den;
    (t > 0.0).then_some(t)
}

/// A hand held over the sheet: fingers from `at` (sheet mm) towards the pattern's centre
/// (`dir`), in a plane parallel to the sheet through `plane`.
#[derive(Clone, Copy)]
struct Hand {
    at: [f64; 2],
    dir: (f64, f64),
    plane: Point3<f64>,
}

/// What a calibration shot's camera looks at: the sheet with its pattern, a hand, a wall.
struct ShotView<'a> {
    pattern: &'a Pattern,
    centre: Point3<f64>,
    /// The sheet's x and y axes and its normal, camera frame.
    ex: Vector3<f64>,
    ey: Vector3<f64>,
    n: Vector3<f64>,
    /// Half the sheet's size, mm (`None`: it fills the view).
    half_sheet: Option<(f64, f64)>,
    hand: Option<Hand>,
    /// The clutter wall: its depth, mm, and the dark things on it.
    wall: Option<(f64, Vec<Thing>)>,
    /// Regular clutter beside the sheet: what, where it starts (sheet x, mm), the pattern's row
    /// pitch and where a row line lies (sheet y, mm).
    beside: Option<(BesideKind, f64, f64, f64)>,
}

impl<'a> ShotView<'a> {
    fn new(rig: &Rig, pattern: &'a Pattern, pose: &TargetPose, around: &Surroundings) -> Self {
        let turn = Rotation3::from_euler_angles(
            pose.turn_deg[0].to_radians(),
            pose.turn_deg[1].to_radians(),
            pose.turn_deg[2].to_radians(),
        );
        let n = turn * Vector3::z();
        let (hx, hy) = pattern.half_extent();
        let hand = around.hand.map(|at| {
            let len = (at[0] * at[0] + at[1] * at[1]).sqrt().max(1e-9);
            Hand {
                at,
                dir: (-at[0] / len, -at[1] / len),
                plane: pose.centre - n * HAND_LIFT,
            }
        });
        let wall = around.clutter.map(|c| {
            let z = pose.centre.z + c.behind;
            let (scene, cam) = (&rig.scene, &rig.scene.camera);
            let span = (
                0.6 * z * f64::from(scene.width) / cam.fx(),
                0.6 * z * f64::from(scene.height) / cam.fy(),
            );
            (z, clutter_things(c.seed, span))
        });
        let pitch = match *pattern {
            Pattern::Chessboard { square, .. } => square,
            Pattern::Charuco(b) => b.square,
            Pattern::DotGrid { pitch, .. } => pitch,
            Pattern::Cross { arm, .. } => arm / 2.0,
        };
        ShotView {
            pattern,
            centre: pose.centre,
            ex: turn * Vector3::x(),
            ey: turn * Vector3::y(),
            n,
            half_sheet: around.margin.map(|m| (hx + m, hy + m)),
            hand,
            wall,
            beside: around
                .beside
                .map(|b| (b.kind, hx + b.gap * pitch, pitch, -hy)),
        }
    }

    /// The point of the sheet at sheet coordinates `s`, camera frame.
    fn place(&self, s: [f64; 2]) -> Point3<f64> {
        self.centre + self.ex * s[0] + self.ey * s[1]
    }

    /// The distance along the unit ray `d` to the hand, if it meets the hand.
    fn on_hand(&self, d: &Vector3<f64>) -> Option<f64> {
        let hand = self.hand?;
        let t = meet(d, &hand.plane, &self.n)?;
        let q = Point3::from(d * t) - hand.plane;
        let (x, y) = (q.dot(&self.ex) - hand.at[0], q.dot(&self.ey) - hand.at[1]);
        let (fx, fy) = (
            x * hand.dir.0 + y * hand.dir.1,
            -x * hand.dir.1 + y * hand.dir.0,
        );
        hand_covers(fx, fy).then_some(t)
    }

    /// What the unit ray `d` sees: the hand, the sheet, the wall or the dark room.
    fn albedo_along(&self, d: &Vector3<f64>) -> f64 {
        if self.on_hand(d).is_some() {
            return SKIN;
        }
        if let Some(t) = meet(d, &self.centre, &self.n) {
            let q = Point3::from(d * t) - self.centre;
            let (x, y) = (q.dot(&self.ex), q.dot(&self.ey));
            if let Some((kind, from, pitch, row)) = self.beside
                && x >= from
                && x <= from + 6.0 * pitch
                && y.abs() <= row.abs()
            {
                let (u, v) = ((x - from) / pitch, (y - row) / pitch);
                let dark = match kind {
                    BesideKind::Stripes => v.floor().rem_euclid(2.0) == 0.0,
                    BesideKind::Keys => {
                        (u.rem_euclid(1.0) - 0.5).abs() < 0.35
                            && (v.rem_euclid(1.0) - 0.5).abs() < 0.35
                    }
                    BesideKind::Checker => (u.floor() + v.floor()).rem_euclid(2.0) == 0.0,
                    BesideKind::Turned => {
                        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
                        let (a, b) = ((u * c - v * s) / 0.7, (u * s + v * c) / 0.7);
                        (a.floor() + b.floor()).rem_euclid(2.0) == 0.0
                    }
                    BesideKind::Fine => {
                        ((2.0 * u).floor() + (2.0 * v).floor()).rem_euclid(2.0) == 0.0
                    }
                };
                return if dark { DARK } else { PAPER };
            }
            if self
                .half_sheet
                .is_none_or(|(hx, hy)| x.abs() <= hx && y.abs() <= hy)
            {
                return self.pattern.albedo(x, y);
            }
        }
        match &self.wall {
            Some((z, things)) if d.z > 0.0 => {
                let (x, y) = (d.x / d.z * z, d.y / d.z * z);
                if things.iter().any(|t| t.covers(x, y)) {
                    DARK
                } else {
                    WALL
                }
            }
            // Without a wall, the sheet has no edge unless a margin is given: then the room is
            // dark.
            _ => 0.0,
        }
    }

    /// In the image and not under the hand, nor anything within `clear` (sheet mm) of it.
    fn visible(
        &self,
        cam: &scanner_core::Camera<f64>,
        size: (f64, f64),
        s: [f64; 2],
        clear: f64,
    ) -> bool {
        let ring = (0..8).map(|i| {
            let a = f64::from(i) / 8.0 * std::f64::consts::TAU;
            [s[0] + clear * a.cos(), s[1] + clear * a.sin()]
        });
        std::iter::once(s).chain(ring).all(|q| {
            let p = self.place(q);
            let Ok(px) = cam.project(&p) else {
                return false;
            };
            let inside = px.x >= 0.5 && px.y >= 0.5 && px.x <= size.0 - 1.5 && px.y <= size.1 - 1.5;
            inside && self.on_hand(&p.coords.normalize()).is_none()
        })
    }

    /// The truth of every feature that projects: dots with the centroid of their imaged disc,
    /// then corners.
    fn features(&self, rig: &Rig) -> Vec<FeatureTruth> {
        let cam = &rig.scene.camera;
        let size = (f64::from(rig.scene.width), f64::from(rig.scene.height));
        let r = self.pattern.dot_diameter() / 2.0;
        let clear = match *self.pattern {
            // The corner refinement's window reaches about 0.35 of a square.
            Pattern::Chessboard { square, .. } => square / 2.0,
            Pattern::Charuco(b) => b.square / 2.0,
            _ => r,
        };
        let mut features = Vec::new();
        for s in self.pattern.dots() {
            let point = self.place(s);
            let Ok(projected) = cam.project(&point) else {
                continue;
            };
            let rim: Vec<Point2<f64>> = (0..720)
                .filter_map(|i| {
                    let a = i as f64 / 720.0 * std::f64::consts::TAU;
                    cam.project(&self.place([s[0] + r * a.cos(), s[1] + r * a.sin()]))
                        .ok()
                })
                .collect();
            features.push(FeatureTruth {
                sheet: s,
                point,
                projected,
                centroid: crate::render::polygon_centroid(&rim).unwrap_or(projected),
                visible: self.visible(cam, size, s, clear),
            });
        }
        for s in self.pattern.corners() {
            let point = self.place(s);
            if let Ok(projected) = cam.project(&point) {
                features.push(FeatureTruth {
                    sheet: s,
                    point,
                    projected,
                    centroid: projected,
                    visible: self.visible(cam, size, s, clear),
                });
            }
        }
        features
    }
}

impl crate::Rig {
    /// `n` rendered shots of a dot grid in front of the rig's camera
    /// ([`TargetPose::sweep`] poses), gray.
    pub fn dot_grid_shots(&self, grid: &scanner_calib::DotGrid, n: usize) -> Vec<image::GrayImage> {
        let pattern = Pattern::from(grid);
        (0..n)
            .map(|i| {
                self.shot(&pattern, &TargetPose::sweep(i, n), i as u64)
                    .image
                    .to_gray_image()
            })
            .collect()
    }
}
