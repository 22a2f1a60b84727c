//! Grids of features (chessboard corners, dots) found by growing a lattice through neighbours.
//!
//! A grid target under a real lens is not one homography: a webcam's barrel distortion leaves
//! 1–2 px between a whole-board homography and the corners, more than any tolerance that still
//! tells a grid from its diagonals. Locally, though, a grid is affine. So:
//!
//! 1. **Seed**: a feature with four neighbours forming a plus (`p ± u`, `p ± v`), the nearest
//!    ones first. For chessboard corners every step must join corners of opposite colour
//!    orientation (the dark quadrants' bisector turns by 90° from a corner to its neighbour
//!    along a grid line, and stays along a diagonal), so a seed never runs along diagonals.
//! 2. **Grow**: each missing neighbour of a known node is predicted from the nodes around it
//!    (second-order extrapolation along a line, parallelograms across lines) and taken if a
//!    feature lies within 30 % of the local step and passes the same colour test. Lens
//!    distortion and perspective change the step slowly, so predictions stay close.
//! 3. **Normalise**: a lattice has no preferred basis; the one with the smallest bounding box
//!    (the target's rows and columns) is taken, oriented as the target is printed (seen from
//!    the printed side, so never mirrored).
//! 4. **Place** on the target: every rotation and offset where the lattice fits; for a
//!    chessboard the colour of the squares picks among them. The count given by the user is
//!    checked against what is seen.

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_4, PI};

use scanner_core::nalgebra::{Point2, Vector2};

use super::detect::Blob;

/// Most features a lattice search considers: beyond, an image is clutter, not a target.
pub const MAX_FEATURES: usize = 4096;
/// Neighbours kept per feature: a lattice step is among them even under 60° of perspective and
/// with clutter around.
const NEIGHBOURS: usize = 16;
/// A predicted node is accepted within this fraction of the local step.
const TOLERANCE: f64 = 0.3;
/// Seeds tried before giving up (most images need one).
const MAX_SEEDS: usize = 64;

/// Cell of a lattice: (column, row).
type Cell = (i32, i32);

/// A grid of features: `(column, row)` → feature index.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Lattice {
    nodes: HashMap<Cell, usize>,
}

/// Where a lattice lies on a target of `cols × rows` grid points.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// `(target index row by row, feature index)` of every node.
    pub found: Vec<(usize, usize)>,
    /// Columns × rows the lattice spans.
    pub extent: (usize, usize),
    /// Every grid point of the spanned rectangle has a feature.
    pub complete: bool,
    /// More than one placement on the target fits equally well (a partly seen grid without
    /// colours to tell them apart). For intrinsics this is harmless: on a uniform grid the
    /// placements differ by a rigid motion of the target, which the pose absorbs.
    pub ambiguous: bool,
}

/// The lattice is larger than the target the user described.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TooLarge {
    /// Columns × rows seen.
    pub seen: (usize, usize),
}

/// Whether two dark bisectors (mod π) are about 90° apart: neighbours along a grid line.
pub(super) fn turned(a: f64, b: f64) -> bool {
    let d = (a - b).rem_euclid(PI);
    d > FRAC_PI_4 && d < 3.0 * FRAC_PI_4
}

/// Whether feature `f` may be a grid neighbour of feature `n`: opposite colour orientation for
/// corners; for discs, similar size and darkness (perspective and light change both only
/// gradually across a printed sheet, while clutter has its own).
fn neighbours(feats: &[Blob], n: usize, f: usize) -> bool {
    let (a, b) = (&feats[n], &feats[f]);
    let colours = match (a.dark_axis, b.dark_axis) {
        (Some(x), Some(y)) => turned(x, y),
        _ => true,
    };
    let similar = |x: f64, y: f64, k: f64| x <= 0.0 || y <= 0.0 || (x < k * y && y < k * x);
    colours && similar(a.area, b.area, 2.0) && similar(a.contrast, b.contrast, 1.6)
}

fn cross(u: Vector2<f64>, v: Vector2<f64>) -> f64 {
    u.x * v.y - u.y * v.x
}

/// The `NEIGHBOURS` nearest features of every feature, nearest first.
fn nearest_lists(feats: &[Blob]) -> Vec<Vec<usize>> {
    (0..feats.len())
        .map(|i| {
            let mut d: Vec<(f64, usize)> = (0..feats.len())
                .filter(|&j| j != i)
                .map(|j| ((feats[j].centre - feats[i].centre).norm_squared(), j))
                .collect();
            let k = NEIGHBOURS.min(d.len());
            if k < d.len() {
                d.select_nth_unstable_by(k, |a, b| a.0.total_cmp(&b.0));
                d.truncate(k);
            }
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            d.into_iter().map(|(_, j)| j).collect()
        })
        .collect()
}

/// Among `cands`, the unused feature nearest to `at` within `tol` that may neighbour `n`.
fn pick(
    feats: &[Blob],
    cands: &[usize],
    used: &[bool],
    n: usize,
    at: Point2<f64>,
    tol: f64,
) -> Option<usize> {
    cands
        .iter()
        .copied()
        .filter(|&f| !used[f] && neighbours(feats, n, f))
        .map(|f| ((feats[f].centre - at).norm(), f))
        .filter(|(d, _)| *d <= tol)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, f)| f)
}

/// A plus of five features around `p`: `[p, p+u, p+v, p−u, p−v]`.
fn seed(feats: &[Blob], near: &[Vec<usize>], used: &[bool], p: usize) -> Option<[usize; 5]> {
    let nb = &near[p][..near[p].len().min(8)];
    let c = feats[p].centre;
    for (i, &a) in nb.iter().enumerate() {
        if used[a] || !neighbours(feats, p, a) {
            continue;
        }
        let u = feats[a].centre - c;
        let ua = pick(feats, &near[p], used, p, c - u, TOLERANCE * u.norm());
        let Some(ua) = ua.filter(|&f| f != a) else {
            continue;
        };
        for &b in &nb[i + 1..] {
            if used[b] || b == ua || !neighbours(feats, p, b) {
                continue;
            }
            let v = feats[b].centre - c;
            let ratio = u.norm() / v.norm();
            if cross(u, v).abs() < 0.5 * u.norm() * v.norm() || !(0.33..3.0).contains(&ratio) {
                continue;
            }
            let vb = pick(feats, &near[p], used, p, c - v, TOLERANCE * v.norm());
            if let Some(vb) = vb.filter(|&f| f != a && f != b && f != ua) {
                return Some([p, a, b, ua, vb]);
            }
        }
    }
    None
}

/// Predicted position of `t` from the known nodes around it and the local step length.
fn predict(nodes: &HashMap<Cell, usize>, feats: &[Blob], t: Cell) -> Option<(Point2<f64>, f64)> {
    let at = |c: Cell| nodes.get(&c).map(|&f| feats[f].centre.coords);
    let (mut sum, mut n, mut step) = (Vector2::zeros(), 0.0, f64::INFINITY);
    for d in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
        let back = |k: i32| (t.0 - k * d.0, t.1 - k * d.1);
        let (Some(a), Some(b)) = (at(back(1)), at(back(2))) else {
            continue;
        };
        step = step.min((a - b).norm());
        // Second order where three nodes run up to it: the step changes along a line under
        // perspective and distortion.
        sum += match at(back(3)) {
            Some(c) => 3.0 * a - 3.0 * b + c,
            None => 2.0 * a - b,
        };
        n += 1.0;
    }
    for (d, e) in [
        ((1, 0), (0, 1)),
        ((1, 0), (0, -1)),
        ((-1, 0), (0, 1)),
        ((-1, 0), (0, -1)),
    ] {
        let (Some(a), Some(b), Some(c)) = (
            at((t.0 - d.0, t.1 - d.1)),
            at((t.0 - e.0, t.1 - e.1)),
            at((t.0 - d.0 - e.0, t.1 - d.1 - e.1)),
        ) else {
            continue;
        };
        step = step.min((a - c).norm()).min((b - c).norm());
        sum += a + b - c;
        n += 1.0;
    }
    (n > 0.0).then(|| (Point2::from(sum / n), step))
}

/// Whether two lattices hold the same features.
fn same_features(a: &Lattice, b: &Lattice) -> bool {
    let mut x: Vec<usize> = a.nodes.values().copied().collect();
    let mut y: Vec<usize> = b.nodes.values().copied().collect();
    x.sort_unstable();
    y.sort_unstable();
    x == y
}

/// Grows a lattice from a seed until no neighbour can be added.
fn grow(feats: &[Blob], near: &[Vec<usize>], used: &mut [bool], s: [usize; 5]) -> Lattice {
    let mut nodes = HashMap::new();
    for (cell, f) in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)]
        .into_iter()
        .zip(s)
    {
        nodes.insert(cell, f);
        used[f] = true;
    }
    let mut frontier: Vec<Cell> = nodes.keys().copied().collect();
    while !frontier.is_empty() {
        let mut next = Vec::new();
        for cell in frontier {
            let n = nodes[&cell];
            for d in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let t = (cell.0 + d.0, cell.1 + d.1);
                if nodes.contains_key(&t) {
                    continue;
                }
                let Some((p, step)) = predict(&nodes, feats, t) else {
                    continue;
                };
                if let Some(f) = pick(feats, &near[n], used, n, p, TOLERANCE * step) {
                    nodes.insert(t, f);
                    used[f] = true;
                    next.push(t);
                }
            }
        }
        // Nodes that could not be predicted before may be now: retry around the new ones and
        // their neighbours.
        let mut around: Vec<Cell> = next
            .iter()
            .flat_map(|&(c, r)| [(c, r), (c + 1, r), (c - 1, r), (c, r + 1), (c, r - 1)])
            .filter(|c| nodes.contains_key(c))
            .collect();
        around.sort_unstable();
        around.dedup();
        frontier = around;
        if next.is_empty() {
            break;
        }
    }
    Lattice { nodes }
}

impl Lattice {
    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// No nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    fn bounds(&self) -> (Cell, Cell) {
        let mut lo = (i32::MAX, i32::MAX);
        let mut hi = (i32::MIN, i32::MIN);
        for &(c, r) in self.nodes.keys() {
            lo = (lo.0.min(c), lo.1.min(r));
            hi = (hi.0.max(c), hi.1.max(r));
        }
        (lo, hi)
    }

    /// Columns × rows spanned.
    pub fn extent(&self) -> (usize, usize) {
        let (lo, hi) = self.bounds();
        ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize)
    }

    fn map(&self, f: impl Fn(Cell) -> Cell) -> Lattice {
        let nodes: HashMap<Cell, usize> = self.nodes.iter().map(|(&c, &v)| (f(c), v)).collect();
        let lo = nodes
            .keys()
            .fold((i32::MAX, i32::MAX), |m, c| (m.0.min(c.0), m.1.min(c.1)));
        Lattice {
            nodes: nodes
                .into_iter()
                .map(|((c, r), v)| ((c - lo.0, r - lo.1), v))
                .collect(),
        }
    }

    /// The basis with the smallest bounding box (a grid's own rows and columns, not diagonals),
    /// oriented like the image (columns to rows turn as x to y: not mirrored), from (0, 0).
    fn normalised(&self, feats: &[Blob]) -> Lattice {
        let area = |l: &Lattice| {
            let (w, h) = l.extent();
            w * h
        };
        let mut best = self.map(|c| c);
        loop {
            let shears: [fn(Cell) -> Cell; 4] = [
                |(c, r)| (c + r, r),
                |(c, r)| (c - r, r),
                |(c, r)| (c, r + c),
                |(c, r)| (c, r - c),
            ];
            let improved = shears
                .iter()
                .map(|s| best.map(s))
                .filter(|l| area(l) < area(&best))
                .min_by_key(area);
            match improved {
                Some(l) => best = l,
                None => break,
            }
        }
        let handed: f64 = best
            .nodes
            .iter()
            .filter_map(|(&(c, r), &f)| {
                let (a, b) = (best.nodes.get(&(c + 1, r))?, best.nodes.get(&(c, r + 1))?);
                let p = feats[f].centre;
                Some(cross(feats[*a].centre - p, feats[*b].centre - p).signum())
            })
            .sum();
        if handed < 0.0 {
            best = best.map(|(c, r)| (c, -r));
        }
        best
    }

    /// Where the lattice is larger than `cols × rows` (either way round): the window of that
    /// size holding the most nodes, if what lies outside it is stray features that continued
    /// the grid by chance (each line outside holds at most half the nodes of the line next to
    /// it inside). A line as full as its neighbour is part of the grid: the lattice is then
    /// returned whole, and does not fit.
    fn trimmed_to(&self, cols: usize, rows: usize) -> Lattice {
        let (w, h) = self.extent();
        if (w <= cols && h <= rows) || (w <= rows && h <= cols) {
            return self.clone();
        }
        let (lo, _) = self.bounds();
        let count = |c0: i32, r0: i32, cw: i32, rh: i32| {
            self.nodes
                .keys()
                .filter(|(c, r)| *c >= c0 && *c < c0 + cw && *r >= r0 && *r < r0 + rh)
                .count()
        };
        let mut best: Option<(usize, (i32, i32, i32, i32))> = None;
        for (ww, hh) in [(cols, rows), (rows, cols)] {
            let (ww, hh) = (ww.min(w) as i32, hh.min(h) as i32);
            for r0 in lo.1..=lo.1 + h as i32 - hh {
                for c0 in lo.0..=lo.0 + w as i32 - ww {
                    let n = count(c0, r0, ww, hh);
                    if best.is_none_or(|(m, _)| n > m) {
                        best = Some((n, (c0, r0, ww, hh)));
                    }
                }
            }
        }
        let Some((_, (c0, r0, ww, hh))) = best else {
            return self.clone();
        };
        let (hi_c, hi_r) = (lo.0 + w as i32, lo.1 + h as i32);
        // Every line outside the window against the window's line next to it.
        let stray = (lo.0..c0)
            .map(|c| (count(c, r0, 1, hh), count(c0, r0, 1, hh)))
            .chain((c0 + ww..hi_c).map(|c| (count(c, r0, 1, hh), count(c0 + ww - 1, r0, 1, hh))))
            .chain((lo.1..r0).map(|r| (count(c0, r, ww, 1), count(c0, r0, ww, 1))))
            .chain((r0 + hh..hi_r).map(|r| (count(c0, r, ww, 1), count(c0, r0 + hh - 1, ww, 1))))
            .all(|(outside, inside)| 2 * outside <= inside);
        if !stray {
            return self.clone();
        }
        let mut l = self.clone();
        l.nodes
            .retain(|(c, r), _| *c >= c0 && *c < c0 + ww && *r >= r0 && *r < r0 + hh);
        l.map(|c| c)
    }

    /// Image directions of the lattice's +column and +row at a node (one-sided where needed).
    fn axes_at(&self, feats: &[Blob], c: Cell) -> Option<(Vector2<f64>, Vector2<f64>)> {
        let at = |c: Cell| self.nodes.get(&c).map(|&f| feats[f].centre);
        let diff = |a: Cell, b: Cell| Some(at(a)? - at(b)?);
        let along =
            |d: Cell| diff((c.0 + d.0, c.1 + d.1), c).or_else(|| diff(c, (c.0 - d.0, c.1 - d.1)));
        Some((along((1, 0))?, along((0, 1))?))
    }

    /// Nodes whose (+column, +row) quadrant is dark: `Some(true/false)` for corners,
    /// `None` where unknown.
    fn dark_quadrant(&self, feats: &[Blob], c: Cell) -> Option<bool> {
        let dark = feats[*self.nodes.get(&c)?].dark_axis?;
        let (gx, gy) = self.axes_at(feats, c)?;
        let diag = gx.normalize() + gy.normalize();
        Some(!turned(diag.y.atan2(diag.x), dark))
    }

    /// Places the lattice on a target of `cols × rows` grid points (row by row, `x` right and
    /// `y` down as printed); `dark_even` for a chessboard whose corner `(c, r)` has its
    /// (+x, +y) square dark when `c + r` is even (both our printed sheets and the intrinsics
    /// chessboard), `None` for dots.
    ///
    /// # Errors
    /// [`TooLarge`] if the lattice does not fit the target either way round.
    pub fn place(
        &self,
        feats: &[Blob],
        cols: usize,
        rows: usize,
        dark_even: Option<bool>,
    ) -> Result<Placement, TooLarge> {
        self.place_in(feats, (cols, rows), dark_even, false)
    }

    /// [`Lattice::place`], and with `window` a lattice one line longer than the target one way
    /// (a chessboard's only) placed too: something beside the target that continues its rows —
    /// a striped shirt, keys, a second pattern — made one more line of corners; the squares'
    /// colours tell which end is the target's, and the extra line is left out.
    ///
    /// # Errors
    /// As [`Lattice::place`].
    pub fn place_in(
        &self,
        feats: &[Blob],
        (cols, rows): (usize, usize),
        dark_even: Option<bool>,
        window: bool,
    ) -> Result<Placement, TooLarge> {
        let l = self.normalised(feats).trimmed_to(cols, rows);
        let rotations: [fn(Cell) -> Cell; 4] = [
            |(c, r)| (c, r),
            |(c, r)| (-r, c),
            |(c, r)| (-c, -r),
            |(c, r)| (r, -c),
        ];
        // Every fit: (colour agreement, alignment of +column with image +x, target indices).
        let mut fits: Vec<(i64, f64, Placement)> = Vec::new();
        for rot in rotations {
            let lr = l.map(rot);
            let (w, h) = lr.extent();
            // One line too many one way: something beside the target continues its rows; each
            // offset of the target on it shifts the squares' colours by one, so they tell which
            // end is the target's. Dots have no colours to tell; more than a line more is a
            // count that is wrong.
            let fits_in = w <= cols && h <= rows;
            let one_more = (w == cols + 1 && h <= rows) || (h == rows + 1 && w <= cols);
            if !(fits_in || (window && one_more && dark_even.is_some())) {
                continue;
            }
            let colours: Vec<(Cell, bool)> = match dark_even {
                Some(_) => lr
                    .nodes
                    .keys()
                    .filter_map(|&c| Some((c, lr.dark_quadrant(feats, c)?)))
                    .collect(),
                None => Vec::new(),
            };
            let align = lr
                .nodes
                .keys()
                .find_map(|&c| lr.axes_at(feats, c))
                .map_or(0.0, |(gx, _)| gx.normalize().x);
            // Offsets of the lattice on the target (negative: the target is a window of it).
            let span = |n: usize, of: usize| {
                let d = of as i32 - n as i32;
                d.min(0)..=d.max(0)
            };
            for oy in span(h, rows) {
                for ox in span(w, cols) {
                    let inside = |c: i32, r: i32| {
                        (0..cols as i32).contains(&(c + ox)) && (0..rows as i32).contains(&(r + oy))
                    };
                    let expect_dark = |c: i32, r: i32| {
                        (((c + ox + r + oy) % 2 + 2) % 2 == 0) == dark_even.unwrap_or(true)
                    };
                    let score: i64 = colours
                        .iter()
                        .filter(|((c, r), _)| inside(*c, *r))
                        .map(|&((c, r), dark)| if dark == expect_dark(c, r) { 1 } else { -1 })
                        .sum();
                    let mut found: Vec<(usize, usize)> = lr
                        .nodes
                        .iter()
                        .filter(|(cell, _)| inside(cell.0, cell.1))
                        .map(|(&(c, r), &f)| ((r + oy) as usize * cols + (c + ox) as usize, f))
                        .collect();
                    found.sort_unstable();
                    let (ew, eh) = (w.min(cols), h.min(rows));
                    let placement = Placement {
                        complete: found.len() == ew * eh,
                        found,
                        extent: (ew, eh),
                        ambiguous: false,
                    };
                    fits.push((score, align, placement));
                }
            }
        }
        let best = fits
            .iter()
            .max_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)))
            .ok_or(TooLarge { seen: l.extent() })?;
        // Placements that cover another part of the target with the same score.
        let cover = |f: &[(usize, usize)]| f.iter().map(|(k, _)| *k).collect::<Vec<_>>();
        let ambiguous = fits
            .iter()
            .any(|f| f.0 == best.0 && cover(&f.2.found) != cover(&best.2.found));
        Ok(Placement {
            ambiguous,
            ..best.2.clone()
        })
    }
}

/// The largest lattices among `feats`, largest first, each feature in at most one; a lattice
/// needs a seed plus (five features). The search stops once a lattice holds the whole target
/// of `cols × rows` nodes and fits it (a larger pattern beside the target, found first, does
/// not end it).
pub fn lattices(feats: &[Blob], (cols, rows): (usize, usize)) -> Vec<Lattice> {
    if feats.len() < 5 || feats.len() > MAX_FEATURES {
        return Vec::new();
    }
    let near = nearest_lists(feats);
    // Seeds from the middle of the features outward: the target is usually what most of them
    // belong to.
    let mid = feats
        .iter()
        .fold(Vector2::zeros(), |s, b| s + b.centre.coords)
        / feats.len() as f64;
    let mut order: Vec<usize> = (0..feats.len()).collect();
    order.sort_by(|&a, &b| {
        (feats[a].centre.coords - mid)
            .norm()
            .total_cmp(&(feats[b].centre.coords - mid).norm())
    });
    let mut used = vec![false; feats.len()];
    let mut out: Vec<Lattice> = Vec::new();
    let mut tried = 0;
    for p in order {
        if used[p] {
            continue;
        }
        if tried == MAX_SEEDS {
            break;
        }
        tried += 1;
        let Some(s) = seed(feats, &near, &used, p) else {
            continue;
        };
        // Each lattice grows through every feature, those of lattices found before too: a
        // lattice of clutter beside the target (a checked cloth of another step or angle) may
        // have taken the target's outer corners where the two meet, and the target's own
        // lattice must still reach them.
        let mut trial = vec![false; feats.len()];
        let l = grow(feats, &near, &mut trial, s);
        // A seed of clutter gives a lattice of a few nodes; never seed from it again.
        if l.len() >= 9 {
            let (w, h) = l.extent();
            let fits = (w <= cols && h <= rows) || (w <= rows && h <= cols);
            let done = l.len() >= cols * rows && fits;
            let again = out
                .iter()
                .any(|o| o.nodes.len() == l.nodes.len() && same_features(o, &l));
            // A lattice that fits the target, or one grown a second time (whichever of its
            // features seeds it, it is the same), claims its features: they seed no other. One
            // larger than the target, grown once, claims only its seed: it may be clutter joined
            // to the target where the two meet, and the target's own corners must still seed
            // the target's lattice.
            if fits || again {
                for (u, t) in used.iter_mut().zip(&trial) {
                    *u |= *t;
                }
            } else {
                for &f in &s {
                    used[f] = true;
                }
            }
            if !again {
                out.push(l);
            }
            if done {
                break;
            }
        } else {
            used[p] = true;
        }
    }
    out.sort_by_key(|l| std::cmp::Reverse(l.len()));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob(x: f64, y: f64, dark: Option<f64>) -> Blob {
        Blob {
            centre: Point2::new(x, y),
            area: 1.0,
            axes: (0.0, 0.0),
            angle: 0.0,
            contrast: 0.0,
            dark_axis: dark,
        }
    }

    /// Corners of a `cols × rows` grid under a strong barrel distortion and a shear, with
    /// colour orientations as a chessboard printed with (+x, +y) dark at even `c + r`.
    fn warped_chessboard(cols: usize, rows: usize) -> Vec<Blob> {
        let mut v = Vec::new();
        for r in 0..rows {
            for c in 0..cols {
                let (x, y) = (c as f64 * 30.0 - 120.0, r as f64 * 30.0 - 80.0);
                let (x, y) = (x + 0.3 * y, y);
                let k = 1.0 - 0.3 * (x * x + y * y) / 300.0f64.powi(2);
                let (x, y) = (320.0 + x * k, 240.0 + y * k);
                // (+x,+y) diagonal of the grid here is about 45° (+ the shear).
                let diag = 1.0f64.atan2(1.3);
                let dark = if (c + r) % 2 == 0 {
                    diag
                } else {
                    diag + PI / 2.0
                };
                v.push(blob(x, y, Some(dark.rem_euclid(PI))));
            }
        }
        v
    }

    #[test]
    fn a_distorted_sheared_chessboard_is_found_whole_and_numbered_as_printed() {
        let feats = warped_chessboard(9, 6);
        let ls = lattices(&feats, (9, 6));
        assert_eq!(ls[0].len(), 54);
        let p = ls[0].place(&feats, 9, 6, Some(true)).unwrap();
        assert!(p.complete && !p.ambiguous, "{p:?}");
        for (k, f) in &p.found {
            assert_eq!(k, f, "target index and feature index agree");
        }
    }

    #[test]
    fn colours_resolve_a_partly_seen_chessboard() {
        // Columns 1..9 of a 9-wide board: offset 1 (odd) is told apart by colour.
        let all = warped_chessboard(9, 6);
        let feats: Vec<Blob> = all
            .iter()
            .enumerate()
            .filter(|(i, _)| i % 9 != 0)
            .map(|(_, b)| *b)
            .collect();
        let ls = lattices(&feats, (8, 6));
        let p = ls[0].place(&feats, 9, 6, Some(true)).unwrap();
        assert_eq!(p.extent, (8, 6));
        assert!(!p.ambiguous);
        assert!(p.found.iter().all(|(k, _)| k % 9 != 0), "{:?}", p.found);
    }

    #[test]
    fn a_grid_larger_than_the_target_is_refused_with_what_was_seen() {
        let feats = warped_chessboard(9, 6);
        let ls = lattices(&feats, (9, 6));
        assert_eq!(
            ls[0].place(&feats, 8, 5, Some(true)),
            Err(TooLarge { seen: (9, 6) })
        );
        // Either way round is fine.
        assert!(ls[0].place(&feats, 6, 9, Some(true)).is_ok());
    }

    #[test]
    fn stray_features_continuing_a_row_are_trimmed_a_full_extra_line_is_not() {
        let mut feats = warped_chessboard(9, 6);
        // Two strays one step beyond the first column, in line with rows 0 and 1.
        for r in 0..2 {
            let (a, b) = (feats[r * 9].centre, feats[r * 9 + 1].centre);
            let p = a + (a - b);
            feats.push(blob(p.x, p.y, feats[r * 9 + 1].dark_axis));
        }
        let ls = lattices(&feats, (9, 6));
        assert_eq!(ls[0].len(), 56);
        let p = ls[0].place(&feats, 9, 6, Some(true)).unwrap();
        assert_eq!((p.found.len(), p.extent), (54, (9, 6)));
        assert!(p.found.iter().all(|(_, f)| *f < 54));
    }

    #[test]
    fn clutter_between_and_around_the_grid_is_not_taken() {
        let mut feats = warped_chessboard(9, 6);
        // Features at the centres of squares (a diagonal half-step) and one off the board.
        for k in 0..20 {
            let a = &feats[k];
            let b = &feats[k + 10];
            let m = Point2::from((a.centre.coords + b.centre.coords) / 2.0);
            feats.push(blob(m.x, m.y, a.dark_axis));
        }
        let ls = lattices(&feats, (9, 6));
        let p = ls[0].place(&feats, 9, 6, Some(true)).unwrap();
        assert_eq!(p.found.len(), 54);
        assert!(p.found.iter().all(|(_, f)| *f < 54));
    }

    #[test]
    fn dots_without_colours_are_found_under_sixty_degrees_about_a_diagonal() {
        // Foreshortened by cos 60° across the diagonal: the diagonal is shorter than a step.
        let mut feats = Vec::new();
        for r in 0..7 {
            for c in 0..9 {
                let (x, y) = (c as f64 * 20.0, r as f64 * 20.0);
                let (e, f) = ((x + y) / 2f64.sqrt(), (x - y) / 2f64.sqrt() * 0.5);
                feats.push(blob(
                    100.0 + (e + f) / 2f64.sqrt(),
                    100.0 + (e - f) / 2f64.sqrt(),
                    None,
                ));
            }
        }
        let ls = lattices(&feats, (9, 7));
        assert_eq!(ls[0].len(), 63);
        let p = ls[0].place(&feats, 9, 7, None).unwrap();
        assert_eq!(p.extent, (9, 7));
        assert!(p.complete);
    }
}
