//! Chessboard inner corners (X-junctions) in a gray image, with sub-pixel positions.
//!
//! 1. Smooth with a Gaussian (σ = 1.5 px) and take the Hessian: at an X-junction its eigenvalues
//!    have opposite signs and are both large, so `−det H` peaks there while edges (one eigenvalue
//!    near zero) and flat areas do not respond.
//! 2. Local maxima of `−det H` above a fraction of the strongest.
//! 3. Check: on a circle around a true corner the intensity alternates bright–dark–bright–dark
//!    (exactly four crossings of the local mean, with clear contrast). Texture, blob edges and the
//!    object's outline fail this.
//! 4. Refine like OpenCV's `cornerSubPix`: the corner `q` is where every nearby gradient `g(p)` is
//!    orthogonal to `p − q`; solve `Σ g gᵀ q = Σ g gᵀ p` over a Gaussian-weighted window, and
//!    repeat from the new position until it moves less than 0.001 px.

use image::GrayImage;
use scanner_core::nalgebra::{Matrix2, Point2, Vector2};

use super::detect::Blob;

/// Corner detection settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerConfig {
    /// Gaussian smoothing before the Hessian, pixels.
    pub sigma: f64,
    /// Candidates must reach this fraction of the strongest response.
    pub min_response: f64,
    /// Largest half size of the refinement window, pixels (it is also kept within 0.35 of the
    /// distance to the nearest other corner).
    pub window: i64,
    /// Radius of the alternation check, pixels.
    pub check_radius: f64,
    /// Smallest brightness difference between the sectors, DN.
    pub min_contrast: f64,
}

impl Default for CornerConfig {
    fn default() -> Self {
        CornerConfig {
            sigma: 1.5,
            min_response: 0.05,
            window: 15,
            check_radius: 5.0,
            min_contrast: 20.0,
        }
    }
}

fn gaussian_blur(img: &GrayImage, sigma: f64) -> Vec<f64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let src: Vec<[f64; 1]> = img.as_raw().iter().map(|&v| [f64::from(v)]).collect();
    crate::blur::blur(&src, w, h, &crate::blur::gaussian_kernel(sigma))
        .into_iter()
        .map(|[v]| v)
        .collect()
}

/// Bilinear sample of a float image.
fn sample(img: &[f64], w: usize, h: usize, x: f64, y: f64) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let a = img[y0 * w + x0] * (1.0 - fx) + img[y0 * w + x1] * fx;
    let b = img[y1 * w + x0] * (1.0 - fx) + img[y1 * w + x1] * fx;
    Some(a * (1.0 - fy) + b * fy)
}

/// Exactly four alternating sectors with clear contrast on a circle around `(x, y)`; if so, the
/// direction of the bisector of the two dark sectors (radians, modulo π).
fn x_junction(
    s: &[f64],
    w: usize,
    h: usize,
    x: f64,
    y: f64,
    r: f64,
    min_contrast: f64,
) -> Option<f64> {
    let n = 48;
    let mut vals = Vec::with_capacity(n);
    for i in 0..n {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        match sample(s, w, h, x + r * a.cos(), y + r * a.sin()) {
            Some(v) => vals.push(v),
            None => return None,
        }
    }
    let mut sorted = vals.clone();
    sorted.sort_by(f64::total_cmp);
    let (lo, hi) = (sorted[n / 8], sorted[n - 1 - n / 8]);
    if hi - lo < min_contrast {
        return None;
    }
    let mid = (lo + hi) / 2.0;
    let crossings = (0..n)
        .filter(|&i| (vals[i] > mid) != (vals[(i + 1) % n] > mid))
        .count();
    // Opposite points of an X-junction have the same colour.
    let opposite = (0..n / 2)
        .filter(|&i| (vals[i] > mid) == (vals[i + n / 2] > mid))
        .count();
    if crossings != 4 || opposite < n / 2 - 4 {
        return None;
    }
    // The dark sectors are opposite each other: on doubled angles they point the same way, and
    // their mean is the dark bisector (the two bisectors of any two lines are perpendicular, so
    // a corner's neighbour along a grid line has its dark bisector turned by 90°).
    let (mut sx, mut sy) = (0.0, 0.0);
    for (i, v) in vals.iter().enumerate() {
        if *v < mid {
            let a = 2.0 * i as f64 / n as f64 * std::f64::consts::TAU;
            sx += a.cos();
            sy += a.sin();
        }
    }
    Some(sy.atan2(sx).rem_euclid(std::f64::consts::TAU) / 2.0)
}

/// The refinement's Gaussian σ as a share of its window's half side, for chessboard corners.
const CHESSBOARD_SPREAD: f64 = 0.5;

/// Finds chessboard inner corners. Returned as [`Blob`]s (area 1, no axes) so that the same
/// identification serves dots and corners.
pub fn find_corners(img: &GrayImage, cfg: &CornerConfig) -> Vec<Blob> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w < 16 || h < 16 {
        return Vec::new();
    }
    let s = gaussian_blur(img, cfg.sigma);
    let at = |x: usize, y: usize| s[y * w + x];
    let mut resp = vec![0.0; w * h];
    let mut max_r = 0.0f64;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let ixx = at(x + 1, y) - 2.0 * at(x, y) + at(x - 1, y);
            let iyy = at(x, y + 1) - 2.0 * at(x, y) + at(x, y - 1);
            let ixy =
                (at(x + 1, y + 1) - at(x + 1, y - 1) - at(x - 1, y + 1) + at(x - 1, y - 1)) / 4.0;
            let r = (ixy * ixy - ixx * iyy).max(0.0);
            resp[y * w + x] = r;
            max_r = max_r.max(r);
        }
    }
    if max_r == 0.0 {
        return Vec::new();
    }
    let thr = cfg.min_response * max_r;
    let nms = 4i64;
    let mut found = Vec::new();
    let margin = (cfg.check_radius.ceil() as usize + 3).max(nms as usize);
    for y in margin..h.saturating_sub(margin) {
        for x in margin..w.saturating_sub(margin) {
            let r = resp[y * w + x];
            if r < thr {
                continue;
            }
            let mut is_max = true;
            'n: for dy in -nms..=nms {
                for dx in -nms..=nms {
                    if (dx, dy) == (0, 0) {
                        continue;
                    }
                    let q = resp[(y as i64 + dy) as usize * w + (x as i64 + dx) as usize];
                    if q > r || q == r && (dy, dx) < (0, 0) {
                        is_max = false;
                        break 'n;
                    }
                }
            }
            if !is_max {
                continue;
            }
            let (xf, yf) = (x as f64, y as f64);
            if let Some(dark) = x_junction(&s, w, h, xf, yf, cfg.check_radius, cfg.min_contrast) {
                found.push((Point2::new(xf, yf), dark));
            }
        }
    }
    // The window grows with the corner spacing (noise averages out) but stays inside the
    // squares next to the corner.
    let mut out = Vec::new();
    for (i, (p, dark)) in found.iter().enumerate() {
        let nn = found
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, (q, _))| (q - p).norm())
            .fold(f64::INFINITY, f64::min);
        let win = ((0.35 * nn).floor() as i64).clamp(3, cfg.window.max(3));
        if let Some(c) = refine(img, *p, (win, CHESSBOARD_SPREAD), |_| true) {
            out.push(Blob {
                centre: c,
                area: 1.0,
                axes: (0.0, 0.0),
                angle: 0.0,
                contrast: 0.0,
                dark_axis: Some(*dark),
            });
        }
    }
    out
}

/// Gradient-orthogonality refinement (as OpenCV's `cornerSubPix`), on the raw image's central
/// differences with Gaussian weights of σ = `spread` × the half side `win`, over the pixels of
/// the window that `keep` keeps (the edges of something else beside the corner, such as a
/// ChArUco marker, would pull it).
pub(crate) fn refine(
    img: &GrayImage,
    start: Point2<f64>,
    (win, spread): (i64, f64),
    keep: impl Fn(Point2<f64>) -> bool,
) -> Option<Point2<f64>> {
    let (w, h) = (i64::from(img.width()), i64::from(img.height()));
    let px = |x: i64, y: i64| f64::from(img.get_pixel(x as u32, y as u32)[0]);
    let mut q = start;
    for _ in 0..20 {
        let (cx, cy) = (q.x.round() as i64, q.y.round() as i64);
        if cx - win - 1 < 0 || cy - win - 1 < 0 || cx + win + 1 >= w || cy + win + 1 >= h {
            return None;
        }
        let mut a = Matrix2::zeros();
        let mut b = Vector2::zeros();
        let sw = win as f64 * spread;
        for y in cy - win..=cy + win {
            for x in cx - win..=cx + win {
                if !keep(Point2::new(x as f64, y as f64)) {
                    continue;
                }
                let g = Vector2::new(
                    (px(x + 1, y) - px(x - 1, y)) / 2.0,
                    (px(x, y + 1) - px(x, y - 1)) / 2.0,
                );
                let (dx, dy) = (x as f64 - q.x, y as f64 - q.y);
                let wt = (-(dx * dx + dy * dy) / (2.0 * sw * sw)).exp();
                let ggt = g * g.transpose() * wt;
                a += ggt;
                b += ggt * Vector2::new(x as f64, y as f64);
            }
        }
        let next = a.try_inverse().map(|inv| inv * b)?;
        let moved = (next - q.coords).norm();
        q = Point2::from(next);
        if moved > 2.0 * win as f64 {
            return None;
        }
        if moved < 1e-3 {
            break;
        }
    }
    (q - start).norm().le(&(win as f64)).then_some(q)
}
