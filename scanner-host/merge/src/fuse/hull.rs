//! The space no view saw through, under the object: where it may be. The object stands on the
//! turntable disc, so what lies under a surface a view saw — down to the disc's plane — may be
//! the object's, unless a view saw through it: a view that saw a surface (the object's, or the
//! disc's beyond it) saw the space between its camera and that surface empty. The fusion fills the surface no view saw with it
//! ([`Hull::solid`]), so that undersides and the insides of overhangs close as solid rather than
//! as thin caps; the volume of that model bounds the object's from above.
//!
//! Under the object means: over the disc's plane, within the object's footprint on it (the
//! points' shadow straight down, its gaps between sweeps closed), and below the highest point
//! seen over that spot. Nothing above what a view saw, nor beside the object, is ever filled.

use scanner_core::nalgebra::{Isometry3, Point3, Unit, Vector3};

use crate::view::View;

/// How far in front of what a view saw in a bin a point must lie to count as seen empty, in
/// fusion cells: the seen surface's own noise and the fusion's rounding stay solid.
const IN_FRONT_CELLS: f64 = 1.0;

/// Gaps in the footprint up to twice this many cells across (between one sweep's lines) are
/// closed.
const FOOTPRINT_CLOSE: usize = 3;

/// Pixels a hull's depth map looks around each of its bins for the nearest depth seen: the
/// gap between one sweep's lines on the object (a few pixels), so that a bin between two lines
/// carves no deeper than the nearer of them.
const REACH_PX: f64 = 4.0;

/// One view as the hull carves with it: the nearest depth it saw (the object, or the disc
/// beyond it) within [`REACH_PX`] of each bin of its image, bins of a pixel (two or more on
/// images over 1280 wide).
struct Seen {
    /// View 0's frame → this view's camera frame.
    from_model: Isometry3<f64>,
    /// Focal lengths and principal point, in bins.
    camera: [f64; 4],
    cols: usize,
    rows: usize,
    /// Per bin, the nearest depth seen around it, mm (infinite: nothing).
    depth: Vec<f32>,
}

impl Seen {
    fn new(view: &View, from_model: Isometry3<f64>) -> Seen {
        let h = &view.header;
        let bin = (f64::from(h.width) / 1280.0).ceil().max(1.0);
        let side = |s: u16| {
            (usize::from(s).min(scanner_core::config::MAX_LINES) as f64 / bin).ceil() as usize
        };
        let (cols, rows) = (side(h.width), side(h.height));
        let c = &h.camera;
        let camera = [c.fx, c.fy, c.cx, c.cy].map(|v| f64::from(v) / bin);
        let mut s = Seen {
            from_model,
            camera,
            cols,
            rows,
            depth: vec![f32::INFINITY; cols * rows],
        };
        for p in view.cloud.points.iter().chain(&view.backdrop) {
            if let Some(b) = s.bin(p) {
                s.depth[b] = s.depth[b].min(p.z as f32);
            }
        }
        let reach = (REACH_PX / bin).ceil() as usize;
        s.depth = nearest_around(&s.depth, cols, rows, reach);
        s
    }

    /// The bin `p` (this view's camera frame) projects into.
    fn bin(&self, p: &Point3<f64>) -> Option<usize> {
        let [fx, fy, cx, cy] = self.camera;
        if !(p.z > 0.0) {
            return None;
        }
        let (u, v) = (fx * p.x / p.z + cx + 0.5, fy * p.y / p.z + cy + 0.5);
        (u >= 0.0 && v >= 0.0 && (u as usize) < self.cols && (v as usize) < self.rows)
            .then(|| v as usize * self.cols + u as usize)
    }

    /// Whether the view saw `q` (view 0's frame) empty: something more than `tol` mm beyond it.
    fn saw_through(&self, q: &Point3<f64>, tol: f64) -> bool {
        let p = self.from_model * q;
        self.bin(&p)
            .is_some_and(|b| p.z < f64::from(self.depth[b]) - tol)
    }
}

/// The least of `depth` (a `cols × rows` grid) within `r` bins of each bin, across and down.
fn nearest_around(depth: &[f32], cols: usize, rows: usize, r: usize) -> Vec<f32> {
    let mut across = vec![f32::INFINITY; depth.len()];
    for row in 0..rows {
        for c in 0..cols {
            let (a, b) = (c.saturating_sub(r), (c + r + 1).min(cols));
            across[row * cols + c] = depth[row * cols + a..row * cols + b]
                .iter()
                .fold(f32::INFINITY, |m, &d| m.min(d));
        }
    }
    let mut out = vec![f32::INFINITY; depth.len()];
    for row in 0..rows {
        let (a, b) = (row.saturating_sub(r), (row + r + 1).min(rows));
        for c in 0..cols {
            out[row * cols + c] = (a..b)
                .map(|rr| across[rr * cols + c])
                .fold(f32::INFINITY, f32::min);
        }
    }
    out
}

/// Where the object may be ([`crate::fuse::hull`]).
pub(crate) struct Hull {
    seen: Vec<Seen>,
    /// Up, unit, view 0's frame: away from the disc, into the space the object stands in.
    up: Vector3<f64>,
    /// Two unit directions along the disc's plane.
    across: (Vector3<f64>, Vector3<f64>),
    /// The disc's plane: `up · x = floor`.
    floor: f64,
    /// The footprint's grid: its corner (along `across`), cell and size.
    origin: (f64, f64),
    cell: f64,
    cols: usize,
    rows: usize,
    /// Per footprint cell, the height over the floor of the highest point seen over it
    /// (negative: outside the footprint).
    top: Vec<f64>,
    /// In front of a seen surface by more than this, mm: seen empty.
    tol: f64,
}

impl Hull {
    /// The hull under `points` (every view's, view 0's frame), the views at `poses`, standing on
    /// the disc (`disc`: disc → view 0's camera, its third axis into the table), for a fusion
    /// of `cell` mm.
    pub(crate) fn new(
        views: &[View],
        poses: &[Isometry3<f64>],
        points: &[Point3<f64>],
        disc: &Isometry3<f64>,
        cell: f64,
    ) -> Hull {
        let seen = views
            .iter()
            .zip(poses)
            .map(|(v, pose)| Seen::new(v, pose.inverse()))
            .collect();
        let up = -(disc.rotation * Vector3::z());
        let floor = up.dot(&disc.translation.vector);
        let across = crate::spatial::across(&Unit::new_normalize(up));
        let flat = |p: &Point3<f64>| (p.coords.dot(&across.0), p.coords.dot(&across.1));
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for p in points {
            let (x, y) = flat(p);
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
        let margin = (FOOTPRINT_CLOSE + 1) as f64 * cell;
        let origin = (lo.0 - margin, lo.1 - margin);
        let side = |a: f64, b: f64| (((b - a) + 2.0 * margin) / cell).ceil().max(1.0) as usize + 1;
        let (cols, rows) = if points.is_empty() {
            (0, 0)
        } else {
            (side(lo.0, hi.0), side(lo.1, hi.1))
        };
        let mut top = vec![f64::NEG_INFINITY; cols * rows];
        for p in points {
            let (x, y) = flat(p);
            let (c, r) = (
                ((x - origin.0) / cell) as usize,
                ((y - origin.1) / cell) as usize,
            );
            if c < cols && r < rows {
                let h = up.dot(&p.coords) - floor;
                top[r * cols + c] = top[r * cols + c].max(h);
            }
        }
        let top = closed(&top, cols, rows, FOOTPRINT_CLOSE);
        Hull {
            seen,
            up,
            across,
            floor,
            origin,
            cell,
            cols,
            rows,
            top,
            tol: IN_FRONT_CELLS * cell,
        }
    }

    /// The disc's plane: up (unit, view 0's frame) and its offset along it.
    pub(crate) fn floor(&self) -> (Vector3<f64>, f64) {
        (self.up, self.floor)
    }

    /// Whether `q` (view 0's frame) may be the object's: over the disc's plane, under the
    /// highest point seen over it within the footprint, and in front of nothing a view saw.
    pub(crate) fn solid(&self, q: &Point3<f64>) -> bool {
        let h = self.up.dot(&q.coords) - self.floor;
        if h < 0.0 {
            return false;
        }
        let (x, y) = (q.coords.dot(&self.across.0), q.coords.dot(&self.across.1));
        let (c, r) = (
            (x - self.origin.0) / self.cell,
            (y - self.origin.1) / self.cell,
        );
        if !(c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows) {
            return false;
        }
        if !(h <= self.top[r as usize * self.cols + c as usize]) {
            return false;
        }
        !self.seen.iter().any(|s| s.saw_through(q, self.tol))
    }
}

/// The heights `top` (a `cols × rows` grid, `-∞` where nothing was seen) with gaps of up to
/// `2 r` cells closed: a cell takes the highest of its neighbours within `r` where cells within
/// `r` on both sides of it, along a row or a column, hold a height.
fn closed(top: &[f64], cols: usize, rows: usize, r: usize) -> Vec<f64> {
    let at = |c: usize, row: usize| top[row * cols + c];
    let mut out = top.to_vec();
    for row in 0..rows {
        for c in 0..cols {
            if at(c, row).is_finite() {
                continue;
            }
            let along = |dc: isize, dr: isize| -> f64 {
                (1..=r as isize)
                    .filter_map(|k| {
                        let (cc, rr) = (c as isize + dc * k, row as isize + dr * k);
                        (cc >= 0 && rr >= 0 && (cc as usize) < cols && (rr as usize) < rows)
                            .then(|| at(cc as usize, rr as usize))
                    })
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let pairs = [((1, 0), (-1, 0)), ((0, 1), (0, -1))];
            let h = pairs
                .iter()
                .map(|&((a, b), (c2, d))| along(a, b).min(along(c2, d)))
                .fold(f64::NEG_INFINITY, f64::max);
            out[row * cols + c] = h;
        }
    }
    out
}
