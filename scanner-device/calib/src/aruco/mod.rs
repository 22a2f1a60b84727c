//! ArUco markers in a gray image: OpenCV's predefined dictionaries ([`Dictionary`]) and the
//! markers of one of them found with their IDs and corners ([`find_aruco`]).
//!
//! 1. Dark candidates: pixels darker than the mean of a square window around them by a margin,
//!    at three window sizes (small markers, large markers, uneven light), as OpenCV does.
//! 2. Quads: each dark region's outer border is cut at the four points where it turns; each side
//!    is a line fitted to the border between its corners, and the corners are where the lines
//!    meet. Regions too small or too large for a marker, or not convex, are left.
//! 3. Cells: the quad's `(n + 2)²` cells (a border of dark cells around the `n × n` code) are
//!    sampled through the homography of the quad, each at its middle (the cell's margin left out:
//!    blur), and split into dark and light at the level that best separates them (Otsu).
//! 4. Code: a border with too many light cells is no marker; the code is read from each of the
//!    four corners and compared with the dictionary's, allowing as many wrong cells as OpenCV
//!    does (60 % of what the dictionary corrects).
//!
//! The same ID found at several window sizes is one marker (the mean of its corners); found at
//! places apart, it is reported ([`ArucoFound::repeated`]): two boards that share IDs.

mod codes;

use image::GrayImage;
use imageproc::contours::{BorderType, find_contours};
use imageproc::point::Point;
use scanner_core::nalgebra::{Matrix3, Point2, Vector2, Vector3};

/// The window sides of the local mean, pixels (OpenCV's 3, 13 and 23).
const WINDOWS: [u32; 3] = [3, 13, 23];
/// A pixel is dark when below its window's mean by this much, DN (OpenCV's 7).
const DARK_BELOW_MEAN: i32 = 7;
/// The smallest side of a dark quad worth reading as a marker, pixels (below, it is reported as
/// too small when nothing larger reads).
pub const MIN_QUAD_SIDE_PX: f64 = 6.0;
/// The smallest side of a marker's cell in the picture that is read, pixels: below, cells blur
/// into each other. A marker of `n` cells plus its border is at least `(n + 2)` times this.
pub const MIN_CELL_PX: f64 = 2.5;
/// The largest marker side, as a fraction of the picture's larger side.
const MAX_SIDE_FRAC: f64 = 0.9;
/// The share of a cell's side left out at each edge when it is sampled (OpenCV's 0.13).
const CELL_MARGIN: f64 = 0.13;
/// The largest share of light cells in the dark border (OpenCV's 0.35).
const MAX_LIGHT_BORDER: f64 = 0.35;
/// The smallest difference of the dark and light cells' means, DN: a flat square has none.
const MIN_CELL_CONTRAST: f64 = 20.0;

/// One of OpenCV's predefined dictionaries `DICT_NxN_C`: `n × n` code cells, the first `count`
/// codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dictionary {
    /// Code cells per side (4 to 7).
    pub n: usize,
    /// Codes (50, 100, 250 or 1000).
    pub count: usize,
}

/// The dictionaries OpenCV predefines, by name (`DICT_4X4_50` … `DICT_7X7_1000`).
pub const DICTIONARIES: [&str; 16] = [
    "DICT_4X4_50",
    "DICT_4X4_100",
    "DICT_4X4_250",
    "DICT_4X4_1000",
    "DICT_5X5_50",
    "DICT_5X5_100",
    "DICT_5X5_250",
    "DICT_5X5_1000",
    "DICT_6X6_50",
    "DICT_6X6_100",
    "DICT_6X6_250",
    "DICT_6X6_1000",
    "DICT_7X7_50",
    "DICT_7X7_100",
    "DICT_7X7_250",
    "DICT_7X7_1000",
];

impl Dictionary {
    /// The dictionary of an OpenCV name such as `DICT_4X4_50`; `None` for any other.
    pub fn named(name: &str) -> Option<Dictionary> {
        let rest = name.strip_prefix("DICT_")?;
        let (size, count) = rest.split_once('_')?;
        let (a, b) = size.split_once('X')?;
        let n: usize = a.parse().ok()?;
        let count: usize = count.parse().ok()?;
        (a == b && (4..=7).contains(&n) && [50, 100, 250, 1000].contains(&count))
            .then_some(Dictionary { n, count })
    }

    /// Its OpenCV name.
    pub fn name(&self) -> String {
        format!("DICT_{0}X{0}_{1}", self.n, self.count)
    }

    /// Every predefined dictionary.
    pub fn all() -> impl Iterator<Item = Dictionary> {
        DICTIONARIES.iter().filter_map(|s| Dictionary::named(s))
    }

    /// The codes, cells row by row from the marker's top left, the first the highest bit,
    /// light = 1.
    fn codes(&self) -> &'static [u64] {
        let all: &'static [u64; 1000] = match self.n {
            4 => &codes::CODES_4X4,
            5 => &codes::CODES_5X5,
            6 => &codes::CODES_6X6,
            _ => &codes::CODES_7X7,
        };
        &all[..self.count]
    }

    /// The code of marker `id` (`None` beyond the dictionary).
    pub fn code(&self, id: usize) -> Option<u64> {
        self.codes().get(id).copied()
    }

    /// The dark cells of marker `id` as printed, `(row, column)` from its top left among its
    /// `(n + 2)²` cells (the border all dark); `None` beyond the dictionary.
    pub fn dark_cells(&self, id: usize) -> Option<Vec<(usize, usize)>> {
        let code = self.code(id)?;
        let n = self.n;
        Some(
            (0..n + 2)
                .flat_map(|r| (0..n + 2).map(move |q| (r, q)))
                .filter(|&(r, q)| {
                    let border = r == 0 || q == 0 || r == n + 1 || q == n + 1;
                    border || (code >> (n * n - 1 - ((r - 1) * n + q - 1))) & 1 == 0
                })
                .collect(),
        )
    }

    /// How many wrong cells a read code may have and still be taken for a marker of this
    /// dictionary: OpenCV's rate (0.6) of the cells its codes are apart beyond detection.
    pub fn tolerance(&self) -> u32 {
        // OpenCV's `maxCorrectionBits` of each predefined dictionary (n, count).
        let corrects = match (self.n, self.count) {
            (4, 1000) => 0,
            (4, _) => 1,
            (5, 50 | 100) => 3,
            (5, _) => 2,
            (6, 50) => 6,
            (6, 100 | 250) => 5,
            (6, _) => 4,
            (7, 50) => 9,
            (7, 100 | 250) => 8,
            _ => 6,
        };
        corrects * 3 / 5
    }

    /// The ID whose code is within [`Self::tolerance`] cells of `read`, with the cells wrong.
    fn identify(&self, read: u64) -> Option<(usize, u32)> {
        let tol = self.tolerance();
        self.codes()
            .iter()
            .enumerate()
            .map(|(id, c)| (id, (c ^ read).count_ones()))
            .filter(|&(_, d)| d <= tol)
            .min_by_key(|&(_, d)| d)
    }
}

/// A marker found: its ID and corners, pixels, in the order printed (top left, top right,
/// bottom right, bottom left of the marker as drawn).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// Its ID in the dictionary.
    pub id: usize,
    /// Its corners, pixels (pixel centres at integer coordinates).
    pub corners: [Point2<f64>; 4],
    /// Code cells read wrong (corrected).
    pub wrong_cells: u32,
}

impl Marker {
    /// The mean side, pixels.
    pub fn side(&self) -> f64 {
        (0..4)
            .map(|k| (self.corners[(k + 1) % 4] - self.corners[k]).norm())
            .sum::<f64>()
            / 4.0
    }

    /// The centre (the mean of the corners).
    pub fn centre(&self) -> Point2<f64> {
        Point2::from(self.corners.iter().map(|c| c.coords).sum::<Vector2<f64>>() / 4.0)
    }
}

/// The markers of one dictionary in a picture.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ArucoFound {
    /// Markers, one per ID, by ID.
    pub markers: Vec<Marker>,
    /// IDs found at two places or more (left out of `markers`).
    pub repeated: Vec<usize>,
    /// Dark quads with a dark border that read as no code of the dictionary.
    pub unread: usize,
    /// Dark quads too small to read (cells under [`MIN_CELL_PX`]): the median side, pixels,
    /// and how many.
    pub too_small: Option<(f64, usize)>,
}

/// A quad with its corners in order (positive area with y down).
pub type Quad = [Point2<f64>; 4];

/// Dark quads in a picture, at every window size (a quad is listed once per window that finds
/// it), with sides of `min_side` pixels or more.
pub fn quads(img: &GrayImage, min_side: f64) -> Vec<Quad> {
    let (w, h) = img.dimensions();
    if w < 8 || h < 8 {
        return Vec::new();
    }
    let max_side = MAX_SIDE_FRAC * f64::from(w.max(h));
    let mut out = Vec::new();
    for win in WINDOWS {
        let mut dark = imageproc::contrast::adaptive_threshold(img, win / 2, -DARK_BELOW_MEAN);
        // Dark pixels are the foreground.
        for p in dark.iter_mut() {
            *p = 255 - *p;
        }
        for c in find_contours::<i32>(&dark) {
            if c.border_type != BorderType::Outer || (c.points.len() as f64) < 4.0 * min_side {
                continue;
            }
            if c.points.len() as f64 > 4.0 * max_side + 8.0 {
                continue;
            }
            if let Some(q) = quad_of(&c.points, min_side, (w, h)) {
                out.push(q);
            }
        }
    }
    out
}

/// The four corners of a closed border that is a convex quad, or `None`.
fn quad_of(border: &[Point<i32>], min_side: f64, (w, h): (u32, u32)) -> Option<Quad> {
    let n = border.len();
    let p = |i: usize| Point2::new(f64::from(border[i % n].x), f64::from(border[i % n].y));
    // A region touching the picture's edge is cut off.
    if border
        .iter()
        .any(|q| q.x <= 0 || q.y <= 0 || q.x as u32 >= w - 1 || q.y as u32 >= h - 1)
    {
        return None;
    }
    let centre = Point2::from((0..n).map(|i| p(i).coords).sum::<Vector2<f64>>() / n as f64);
    // The first corner: the farthest point from the centre; the third: the farthest from the
    // first; the second and fourth: the farthest from the line between them, on each side.
    let far = |from: Point2<f64>, range: &mut dyn Iterator<Item = usize>| {
        range.max_by(|&a, &b| (p(a) - from).norm().total_cmp(&(p(b) - from).norm()))
    };
    let a = far(centre, &mut (0..n))?;
    let c = far(p(a), &mut (0..n))?;
    let (lo, hi) = (a.min(c), a.max(c));
    let off = |i: usize| {
        let (u, v) = (p(lo), p(hi));
        let d = v - u;
        (d.x * (p(i).y - u.y) - d.y * (p(i).x - u.x)) / d.norm().max(1e-9)
    };
    let b = (lo + 1..hi).max_by(|&i, &j| off(i).abs().total_cmp(&off(j).abs()))?;
    let d = (hi + 1..lo + n).max_by(|&i, &j| off(i).abs().total_cmp(&off(j).abs()))? % n;
    let mut idx = [lo, b, hi, d];
    idx.sort_unstable();
    // Each side: the border between two corners must lie near the straight line (a quad, not
    // a blob), and a line is fitted to its middle part.
    let perimeter = n as f64;
    let mut lines = [(Point2::origin(), Vector2::<f64>::zeros()); 4];
    for k in 0..4 {
        let (i0, i1) = (idx[k], if k == 3 { idx[0] + n } else { idx[k + 1] });
        let len = i1 - i0;
        if (len as f64) < min_side * 0.8 {
            return None;
        }
        let (u, v) = (p(i0), p(i1));
        let dir = (v - u) / (v - u).norm().max(1e-9);
        let dev = (i0..i1)
            .map(|i| {
                let r = p(i) - u;
                (dir.x * r.y - dir.y * r.x).abs()
            })
            .fold(0.0f64, f64::max);
        if dev > 0.04 * perimeter + 1.5 {
            return None;
        }
        // The middle of the side, clear of the rounded corners.
        let cut = len / 6 + 1;
        let pts: Vec<Point2<f64>> = (i0 + cut..i1.saturating_sub(cut)).map(p).collect();
        lines[k] = if pts.len() >= 3 {
            fit_line(&pts)
        } else {
            (u, dir)
        };
    }
    let mut q = [Point2::origin(); 4];
    for k in 0..4 {
        q[k] = meet(lines[(k + 3) % 4], lines[k])?;
        if (q[k] - p(idx[k])).norm() > 0.1 * perimeter + 2.0 {
            return None;
        }
    }
    // The border runs around the dark region; its pixels lie half a pixel inside its edge.
    let mid = Point2::from(q.iter().map(|c| c.coords).sum::<Vector2<f64>>() / 4.0);
    for c in &mut q {
        let out = *c - mid;
        *c += out * (0.5 / out.norm().max(1.0)) * std::f64::consts::SQRT_2;
    }
    if signed_area(&q) < 0.0 {
        q.swap(1, 3);
    }
    convex(&q).then_some(q)
}

/// The line through points by least squares: a point and a unit direction.
fn fit_line(pts: &[Point2<f64>]) -> (Point2<f64>, Vector2<f64>) {
    let m = pts.len() as f64;
    let c = Point2::from(pts.iter().map(|p| p.coords).sum::<Vector2<f64>>() / m);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = p - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    (c, Vector2::new(angle.cos(), angle.sin()))
}

/// Where two lines meet (`None` when nearly parallel).
fn meet(a: (Point2<f64>, Vector2<f64>), b: (Point2<f64>, Vector2<f64>)) -> Option<Point2<f64>> {
    let cross = a.1.x * b.1.y - a.1.y * b.1.x;
    if cross.abs() < 0.05 {
        return None;
    }
    let d = b.0 - a.0;
    let t = (d.x * b.1.y - d.y * b.1.x) / cross;
    Some(a.0 + a.1 * t)
}

fn signed_area(q: &Quad) -> f64 {
    (0..4)
        .map(|k| {
            let (a, b) = (q[k], q[(k + 1) % 4]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0
}

fn convex(q: &Quad) -> bool {
    (0..4).all(|k| {
        let (a, b, c) = (q[k], q[(k + 1) % 4], q[(k + 2) % 4]);
        let (u, v) = (b - a, c - b);
        u.x * v.y - u.y * v.x > 0.0
    })
}

/// The homography taking the unit square's corners `(0,0), (1,0), (1,1), (0,1)` to `q`.
pub(crate) fn square_to(q: &Quad) -> Option<Matrix3<f64>> {
    // Heckbert's closed form for a square to a quad.
    let [p0, p1, p2, p3] = *q;
    let s = p0.coords - p1.coords + p2.coords - p3.coords;
    let d1 = p1 - p2;
    let d2 = p3 - p2;
    let den = d1.x * d2.y - d2.x * d1.y;
    if den.abs() < 1e-12 {
        return None;
    }
    let g = (s.x * d2.y - d2.x * s.y) / den;
    let hh = (d1.x * s.y - s.x * d1.y) / den;
    Some(Matrix3::new(
        p1.x - p0.x + g * p1.x,
        p3.x - p0.x + hh * p3.x,
        p0.x,
        p1.y - p0.y + g * p1.y,
        p3.y - p0.y + hh * p3.y,
        p0.y,
        g,
        hh,
        1.0,
    ))
}

/// Maps a point through a homography.
pub(crate) fn apply(hm: &Matrix3<f64>, x: f64, y: f64) -> Option<Point2<f64>> {
    let v = hm * Vector3::new(x, y, 1.0);
    (v.z.abs() > 1e-12).then(|| Point2::new(v.x / v.z, v.y / v.z))
}

/// Bilinear sample (`None` outside the picture).
fn sample(img: &GrayImage, p: Point2<f64>) -> Option<f64> {
    let (w, h) = img.dimensions();
    if !(p.x >= 0.0 && p.y >= 0.0 && p.x <= f64::from(w - 1) && p.y <= f64::from(h - 1)) {
        return None;
    }
    let (x0, y0) = (p.x.floor() as u32, p.y.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (p.x - f64::from(x0), p.y - f64::from(y0));
    let v = |x, y| f64::from(img.get_pixel(x, y)[0]);
    let a = v(x0, y0) * (1.0 - fx) + v(x1, y0) * fx;
    let b = v(x0, y1) * (1.0 - fx) + v(x1, y1) * fx;
    Some(a * (1.0 - fy) + b * fy)
}

/// The mean level of each of a quad's `m × m` cells, row by row from its first corner.
fn cell_levels(img: &GrayImage, q: &Quad, m: usize) -> Option<Vec<f64>> {
    let hm = square_to(q)?;
    let sub = 4;
    let mut out = Vec::with_capacity(m * m);
    for r in 0..m {
        for c in 0..m {
            let mut sum = 0.0;
            for i in 0..sub {
                for j in 0..sub {
                    let f = |k: usize, at: usize| {
                        let t =
                            CELL_MARGIN + (1.0 - 2.0 * CELL_MARGIN) * (k as f64 + 0.5) / sub as f64;
                        (at as f64 + t) / m as f64
                    };
                    sum += sample(img, apply(&hm, f(j, c), f(i, r))?)?;
                }
            }
            out.push(sum / (sub * sub) as f64);
        }
    }
    Some(out)
}

/// The level that best splits values into two groups (Otsu), and the groups' means.
fn split(values: &[f64]) -> (f64, f64, f64) {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let total: f64 = v.iter().sum();
    let n = v.len() as f64;
    let mut best = (f64::NEG_INFINITY, v[0], v[0], v[0]);
    let mut below = 0.0;
    for k in 1..v.len() {
        below += v[k - 1];
        let (n0, n1) = (k as f64, n - k as f64);
        let (m0, m1) = (below / n0, (total - below) / n1);
        let between = n0 * n1 * (m1 - m0) * (m1 - m0);
        if between > best.0 {
            best = (between, (v[k - 1] + v[k]) / 2.0, m0, m1);
        }
    }
    (best.1, best.2, best.3)
}

/// The reading of a quad as a marker of `dict`: its ID, its corners from the marker's top left
/// and the wrong cells; or why not.
fn read(img: &GrayImage, q: &Quad, dict: &Dictionary) -> Result<Marker, Unread> {
    let n = dict.n;
    let m = n + 2;
    let levels = cell_levels(img, q, m).ok_or(Unread::NoCode)?;
    let (level, dark, light) = split(&levels);
    if light - dark < MIN_CELL_CONTRAST {
        return Err(Unread::NoCode);
    }
    let bit = |r: usize, c: usize| levels[r * m + c] > level;
    let border_light = (0..m)
        .flat_map(|r| (0..m).map(move |c| (r, c)))
        .filter(|&(r, c)| r == 0 || c == 0 || r == m - 1 || c == m - 1)
        .filter(|&(r, c)| bit(r, c))
        .count();
    if border_light as f64 > MAX_LIGHT_BORDER * (4 * (m - 1)) as f64 {
        return Err(Unread::NoBorder);
    }
    // The code read from each corner as the first: from corner k, the rows run from corner k
    // towards corner k + 3 and the cells of a row towards corner k + 1.
    let mut best: Option<(usize, u32, usize)> = None;
    for k in 0..4 {
        let mut code = 0u64;
        for r in 0..n {
            for c in 0..n {
                // Cell (r, c) from corner k, in the cells from corner 0.
                let (rr, cc) = match k {
                    0 => (r, c),
                    1 => (c, n - 1 - r),
                    2 => (n - 1 - r, n - 1 - c),
                    _ => (n - 1 - c, r),
                };
                code = (code << 1) | u64::from(bit(rr + 1, cc + 1));
            }
        }
        if let Some((id, wrong)) = dict.identify(code)
            && best.is_none_or(|b| wrong < b.1)
        {
            best = Some((id, wrong, k));
        }
    }
    let (id, wrong_cells, k) = best.ok_or(Unread::NoCode)?;
    Ok(Marker {
        id,
        corners: [q[k], q[(k + 1) % 4], q[(k + 2) % 4], q[(k + 3) % 4]],
        wrong_cells,
    })
}

/// Why a quad is no marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Unread {
    /// Its border is not dark.
    NoBorder,
    /// Its code is none of the dictionary's.
    NoCode,
}

/// The markers of `dict` among the quads of a picture ([`quads`]).
pub fn find_aruco(img: &GrayImage, quads: &[Quad], dict: &Dictionary) -> ArucoFound {
    let m = (dict.n + 2) as f64;
    let mut seen: Vec<Marker> = Vec::new();
    let mut unread = 0;
    let mut small = Vec::new();
    for q in quads {
        let side = (0..4)
            .map(|k| (q[(k + 1) % 4] - q[k]).norm())
            .fold(f64::INFINITY, f64::min);
        match read(img, q, dict) {
            Ok(mk) => seen.push(mk),
            Err(_) if side < MIN_CELL_PX * m => small.push(side),
            Err(Unread::NoCode) => unread += 1,
            Err(Unread::NoBorder) => {}
        }
    }
    // One marker per ID: its readings at several windows merged; readings apart are repeats.
    seen.sort_by_key(|mk| mk.id);
    let mut found = ArucoFound::default();
    let mut i = 0;
    while i < seen.len() {
        let j = i + seen[i..]
            .iter()
            .take_while(|mk| mk.id == seen[i].id)
            .count();
        let group = &seen[i..j];
        let first = group[0];
        let apart = group
            .iter()
            .any(|mk| (mk.centre() - first.centre()).norm() > 0.25 * first.side());
        if apart {
            found.repeated.push(first.id);
        } else {
            let mut corners = [Point2::origin(); 4];
            for (k, c) in corners.iter_mut().enumerate() {
                *c = Point2::from(
                    group
                        .iter()
                        .map(|mk| mk.corners[k].coords)
                        .sum::<Vector2<f64>>()
                        / group.len() as f64,
                );
            }
            found.markers.push(Marker {
                id: first.id,
                corners,
                wrong_cells: group.iter().map(|mk| mk.wrong_cells).min().unwrap_or(0),
            });
        }
        i = j;
    }
    found.unread = unread;
    if !small.is_empty() {
        small.sort_by(f64::total_cmp);
        found.too_small = Some((small[small.len() / 2], small.len()));
    }
    found
}

/// A ChArUco board as OpenCV lays it out: `cols × rows` squares of side `square`, the first
/// (top left) dark, an ArUco marker of side `marker` centred in each light square, their IDs
/// from `first_id` row by row. Board coordinates: `x` along the first row, `y` down the first
/// column, from the board's top left corner, mm. Its inner corners are numbered row by row
/// from the top left, as OpenCV numbers them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CharucoBoard {
    /// Squares along `x`.
    pub cols: usize,
    /// Squares along `y`.
    pub rows: usize,
    /// Square side, mm.
    pub square: f64,
    /// Marker side, mm.
    pub marker: f64,
    /// The markers' dictionary.
    pub dictionary: Dictionary,
    /// The first marker's ID.
    pub first_id: usize,
}

impl CharucoBoard {
    /// Whether square `(x, y)` is light (and carries a marker).
    pub fn light(&self, x: usize, y: usize) -> bool {
        (x + y) % 2 == 1
    }

    /// How many markers the board carries.
    pub fn marker_count(&self) -> usize {
        self.cols * self.rows / 2
    }

    /// The light squares, row by row: the `k`-th carries marker `first_id + k`.
    fn light_squares(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.rows)
            .flat_map(move |y| (0..self.cols).map(move |x| (x, y)))
            .filter(|&(x, y)| self.light(x, y))
    }

    /// The ID of the marker in square `(x, y)`, if it is light.
    pub fn marker_in(&self, x: usize, y: usize) -> Option<usize> {
        if x >= self.cols || y >= self.rows || !self.light(x, y) {
            return None;
        }
        let before = self.light_squares().position(|s| s == (x, y))?;
        self.first_id.checked_add(before)
    }

    /// The square of marker `id`, if the board carries it.
    pub fn square_of(&self, id: usize) -> Option<(usize, usize)> {
        let k = id.checked_sub(self.first_id)?;
        self.light_squares().nth(k)
    }

    /// The corners of marker `id` on the board (top left, top right, bottom right, bottom left).
    pub fn marker_corners(&self, id: usize) -> Option<[Point2<f64>; 4]> {
        let (x, y) = self.square_of(id)?;
        let m = (self.square - self.marker) / 2.0;
        let (x0, y0) = (x as f64 * self.square + m, y as f64 * self.square + m);
        let s = self.marker;
        Some([
            Point2::new(x0, y0),
            Point2::new(x0 + s, y0),
            Point2::new(x0 + s, y0 + s),
            Point2::new(x0, y0 + s),
        ])
    }

    /// Inner corners per row.
    pub fn corners_per_row(&self) -> usize {
        self.cols.saturating_sub(1)
    }

    /// How many inner corners.
    pub fn corner_count(&self) -> usize {
        self.corners_per_row() * self.rows.saturating_sub(1)
    }

    /// Inner corner `k` on the board.
    pub fn corner(&self, k: usize) -> Point2<f64> {
        let per = self.corners_per_row().max(1);
        Point2::new(
            (k % per + 1) as f64 * self.square,
            (k / per + 1) as f64 * self.square,
        )
    }

    /// The IDs the board's markers take.
    pub fn ids(&self) -> std::ops::Range<usize> {
        self.first_id..self.first_id.saturating_add(self.marker_count())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The board's numbering, as OpenCV's: light squares row by row, corner `k` row by row.
    #[test]
    fn the_board_numbers_markers_and_corners_as_opencv_does() {
        for (cols, rows, first) in [
            (7, 5, [(1, 0), (3, 0), (5, 0), (0, 1)]),
            (8, 6, [(1, 0), (3, 0), (5, 0), (7, 0)]),
        ] {
            let b = CharucoBoard {
                cols,
                rows,
                square: 25.0,
                marker: 19.0,
                dictionary: Dictionary::named("DICT_4X4_50").unwrap(),
                first_id: 3,
            };
            for (k, sq) in first.iter().enumerate() {
                assert_eq!(b.square_of(3 + k), Some(*sq));
                assert_eq!(b.marker_in(sq.0, sq.1), Some(3 + k));
            }
            assert_eq!(b.marker_count(), cols * rows / 2);
            assert_eq!(b.corner(0), Point2::new(25.0, 25.0));
            assert_eq!(b.corner(cols - 1), Point2::new(25.0, 50.0));
            assert_eq!(b.marker_corners(3).unwrap()[0], Point2::new(28.0, 3.0));
        }
    }
}
