//! Dark circular markers in a gray image, with sub-pixel centres.
//!
//! 1. Dark pixels: darker than `dark_ratio` × the local mean over a square window (`imageproc`'s
//!    integral image), so uneven lighting does not matter.
//! 2. Connected regions (8-neighbour, `imageproc`'s labelling) of dark pixels, not touching the image border.
//! 3. Shape: the ellipse with the region's second moments must cover it — a disc seen at an angle
//!    is an ellipse; squares, texture, stripes, the object's shadow and half-hidden markers are
//!    not, and are rejected.
//! 4. Centre: the gray-weighted centroid of the darkness `background − I` over the ellipse grown
//!    by a margin that covers the lens blur, the background being a plane fitted (with one
//!    outlier-rejecting pass) to a ring of pixels around it. The weights are not clipped, so noise
//!    averages out instead of biasing the centre; this finds the centroid of the imaged disc,
//!    which [`scanner_core::calib::model`] predicts.

use image::{GrayImage, Luma};
use imageproc::definitions::Image;
use imageproc::integral_image::{integral_image, sum_image_pixels};
use imageproc::region_labelling::{Connectivity, connected_components};
use scanner_core::nalgebra::{Matrix3, Point2, Vector3};

/// Detection settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectConfig {
    /// A pixel is dark below this fraction of its local mean.
    pub dark_ratio: f64,
    /// Side of the local-mean window as a fraction of the image's larger side.
    pub window_frac: f64,
    /// Smallest marker area, pixels.
    pub min_area: usize,
    /// Largest marker area as a fraction of the image.
    pub max_area_frac: f64,
    /// Smallest ratio of the ellipse's minor to major axis.
    pub min_axis_ratio: f64,
    /// Largest mismatch between the region and its moment ellipse (symmetric difference over
    /// area), beyond what pixelation of the rim explains.
    pub max_shape_error: f64,
    /// Margin around the ellipse for the centroid (covers the lens blur), pixels.
    pub margin_px: f64,
}

impl Default for DetectConfig {
    fn default() -> Self {
        DetectConfig {
            dark_ratio: 0.6,
            window_frac: 1.0 / 8.0,
            min_area: 12,
            max_area_frac: 0.02,
            min_axis_ratio: 0.2,
            max_shape_error: 0.12,
            margin_px: 3.0,
        }
    }
}

/// A detected marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    /// Sub-pixel centre (pixel centres at integer coordinates).
    pub centre: Point2<f64>,
    /// Area of the dark region, pixels.
    pub area: f64,
    /// Semi-axes of the moment ellipse (major, minor), pixels.
    pub axes: (f64, f64),
    /// Direction of the major axis, radians from +x.
    pub angle: f64,
    /// Darkness: background minus the marker's mean level, DN.
    pub contrast: f64,
    /// For a chessboard corner: the direction of the bisector of its two dark quadrants,
    /// radians modulo π, x right, y down (`None` for a disc).
    pub dark_axis: Option<f64>,
}

impl Blob {
    /// A feature that is only a point (a corner named by other means, such as a ChArUco
    /// board's): no area, axes or contrast.
    pub fn point(centre: Point2<f64>) -> Blob {
        Blob {
            centre,
            area: 1.0,
            axes: (0.0, 0.0),
            angle: 0.0,
            contrast: 0.0,
            dark_axis: None,
        }
    }
}

/// A rejected dark region (for the overlay and error messages).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rejected {
    /// Centre of the region.
    pub centre: Point2<f64>,
    /// Area, pixels.
    pub area: usize,
    /// Why.
    pub reason: &'static str,
}

/// All detections in one image.
#[derive(Debug, Clone, Default)]
pub struct Detections {
    /// Accepted markers.
    pub blobs: Vec<Blob>,
    /// Dark regions that were not markers (not counting specks below the smallest area).
    pub rejected: Vec<Rejected>,
}

struct Region {
    pixels: Vec<(u32, u32)>,
    border: bool,
}

/// Finds dark elliptical markers in `img`.
pub fn find_markers(img: &GrayImage, cfg: &DetectConfig) -> Detections {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let mut out = Detections::default();
    if w < 8 || h < 8 {
        return out;
    }
    let max_area = (cfg.max_area_frac * (w * h) as f64) as usize;
    for region in dark_regions(&dark_mask(img, cfg)) {
        if region.pixels.len() < cfg.min_area {
            continue;
        }
        match examine(img, &region, cfg, max_area) {
            Ok(b) => out.blobs.push(b),
            Err((centre, reason)) => out.rejected.push(Rejected {
                centre,
                area: region.pixels.len(),
                reason,
            }),
        }
    }
    out
}

/// Step 1: 255 where a pixel is darker than `dark_ratio` × the mean of the square window
/// around it (clipped at the image border), 0 elsewhere.
fn dark_mask(img: &GrayImage, cfg: &DetectConfig) -> GrayImage {
    let (w, h) = img.dimensions();
    let integral: Image<Luma<u64>> = integral_image(img);
    let half = ((w.max(h) as f64 * cfg.window_frac) / 2.0).max(7.0) as u32;
    GrayImage::from_fn(w, h, |x, y| {
        let (x0, y0) = (x.saturating_sub(half), y.saturating_sub(half));
        let (x1, y1) = ((x + half).min(w - 1), (y + half).min(h - 1));
        let sum = sum_image_pixels(&integral, x0, y0, x1, y1)[0];
        let mean = sum as f64 / (f64::from(x1 - x0 + 1) * f64::from(y1 - y0 + 1));
        let dark = f64::from(img.get_pixel(x, y)[0]) < cfg.dark_ratio * mean;
        Luma([if dark { 255 } else { 0 }])
    })
}

/// Step 2: the 8-connected regions of a mask, in raster order of their first pixel.
fn dark_regions(mask: &GrayImage) -> Vec<Region> {
    let (w, h) = mask.dimensions();
    let labels = connected_components(mask, Connectivity::Eight, Luma([0u8]));
    let mut regions: Vec<Region> = Vec::new();
    for (x, y, l) in labels.enumerate_pixels() {
        let Some(k) = (l[0] as usize).checked_sub(1) else {
            continue;
        };
        // Labels number the regions from 1 in raster order of their first pixel.
        if k >= regions.len() {
            regions.resize_with(k + 1, || Region {
                pixels: Vec::new(),
                border: false,
            });
        }
        let region = &mut regions[k];
        region.pixels.push((x, y));
        region.border |= x == 0 || y == 0 || x + 1 == w || y + 1 == h;
    }
    regions
}

type Verdict = Result<Blob, (Point2<f64>, &'static str)>;

fn examine(img: &GrayImage, region: &Region, cfg: &DetectConfig, max_area: usize) -> Verdict {
    let n = region.pixels.len() as f64;
    let (mut sx, mut sy) = (0.0, 0.0);
    for &(x, y) in &region.pixels {
        sx += f64::from(x);
        sy += f64::from(y);
    }
    let (mx, my) = (sx / n, sy / n);
    let centre = Point2::new(mx, my);
    if region.border {
        return Err((centre, "touches the image border"));
    }
    if region.pixels.len() > max_area {
        return Err((centre, "too large for a marker"));
    }
    let (mut cxx, mut cyy, mut cxy) = (0.0, 0.0, 0.0);
    for &(x, y) in &region.pixels {
        let (dx, dy) = (f64::from(x) - mx, f64::from(y) - my);
        cxx += dx * dx;
        cyy += dy * dy;
        cxy += dx * dy;
    }
    // Pixel areas add 1/12 to each variance.
    let (cxx, cyy, cxy) = (cxx / n + 1.0 / 12.0, cyy / n + 1.0 / 12.0, cxy / n);
    let tr = cxx + cyy;
    let disc = ((cxx - cyy).powi(2) / 4.0 + cxy * cxy).sqrt();
    let (l1, l2) = (tr / 2.0 + disc, tr / 2.0 - disc);
    if !(l2 > 0.0) {
        return Err((centre, "a line, not a disc"));
    }
    // A uniform ellipse with semi-axes a, b has variances a²/4, b²/4.
    let (a, b) = (2.0 * l1.sqrt(), 2.0 * l2.sqrt());
    if b / a < cfg.min_axis_ratio {
        return Err((centre, "too elongated"));
    }
    let angle = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
    // Inverse covariance for the ellipse test: inside when d·Σ⁻¹·d ≤ 4.
    let det = cxx * cyy - cxy * cxy;
    let (ixx, iyy, ixy) = (cyy / det, cxx / det, -cxy / det);
    let inside = |x: f64, y: f64, grow: f64| {
        let (dx, dy) = (x - mx, y - my);
        let q = dx * dx * ixx + 2.0 * dx * dy * ixy + dy * dy * iyy;
        q <= 4.0 * grow * grow
    };
    // Shape: region pixels outside the ellipse plus ellipse pixels outside the region.
    let (w, h) = (img.width() as i64, img.height() as i64);
    let r = a.ceil() as i64 + 2;
    let (x0, x1) = ((mx as i64 - r).max(0), (mx as i64 + r).min(w - 1));
    let (y0, y1) = ((my as i64 - r).max(0), (my as i64 + r).min(h - 1));
    let mut member = vec![false; ((x1 - x0 + 1) * (y1 - y0 + 1)) as usize];
    let bw = x1 - x0 + 1;
    let mut outside = 0usize;
    for &(x, y) in &region.pixels {
        let (x, y) = (i64::from(x), i64::from(y));
        if x >= x0 && x <= x1 && y >= y0 && y <= y1 {
            member[((y - y0) * bw + x - x0) as usize] = true;
        }
        if !inside(x as f64, y as f64, 1.0) {
            outside += 1;
        }
    }
    let mut missing = 0usize;
    for y in y0..=y1 {
        for x in x0..=x1 {
            if inside(x as f64, y as f64, 1.0) && !member[((y - y0) * bw + x - x0) as usize] {
                missing += 1;
            }
        }
    }
    // Rim pixelation: about one pixel in four along the perimeter is misjudged.
    let perimeter = std::f64::consts::PI * (1.5 * (a + b) - (a * b).sqrt());
    let allowance = cfg.max_shape_error * n + 0.35 * perimeter;
    if (outside + missing) as f64 > allowance {
        return Err((centre, "not elliptical (clutter or partly hidden)"));
    }
    refine_centre(img, (mx, my), (ixx, iyy, ixy), a, cfg.margin_px)
        .map(|(centre, contrast)| Blob {
            centre,
            area: n,
            axes: (a, b),
            angle,
            contrast,
            dark_axis: None,
        })
        .ok_or((centre, "no clear background around it"))
}

/// Gray-weighted centroid of the darkness over the grown ellipse, against a planar background
/// fitted on a ring around it.
fn refine_centre(
    img: &GrayImage,
    (mx, my): (f64, f64),
    (ixx, iyy, ixy): (f64, f64, f64),
    a: f64,
    margin: f64,
) -> Option<(Point2<f64>, f64)> {
    let (w, h) = (img.width() as i64, img.height() as i64);
    // Mahalanobis radius 2 is the ellipse rim; grow it by `margin` pixels along the major axis
    // (the minor axis grows a little more, which is harmless).
    let g_in = (a + margin) / a;
    let g_out = (a + margin + 3.0) / a;
    let r = (a * g_out).ceil() as i64 + 1;
    let (x0, x1) = (mx as i64 - r, mx as i64 + r);
    let (y0, y1) = (my as i64 - r, my as i64 + r);
    if x0 < 0 || y0 < 0 || x1 >= w || y1 >= h {
        return None;
    }
    let q = |x: f64, y: f64| {
        let (dx, dy) = (x - mx, y - my);
        (dx * dx * ixx + 2.0 * dx * dy * ixy + dy * dy * iyy).sqrt() / 2.0
    };
    let px = |x: i64, y: i64| f64::from(img.get_pixel(x as u32, y as u32)[0]);
    // Background plane b0 + b1·dx + b2·dy on the ring, least squares, then once more without
    // pixels far from the first fit (a neighbouring marker, an edge).
    let mut ring = Vec::new();
    for y in y0..=y1 {
        for x in x0..=x1 {
            let m = q(x as f64, y as f64);
            if m > g_in && m <= g_out {
                ring.push((x as f64 - mx, y as f64 - my, px(x, y)));
            }
        }
    }
    let fit = |pts: &[(f64, f64, f64)]| -> Option<Vector3<f64>> {
        let mut ata = Matrix3::zeros();
        let mut atb = Vector3::zeros();
        for &(dx, dy, v) in pts {
            let row = Vector3::new(1.0, dx, dy);
            ata += row * row.transpose();
            atb += row * v;
        }
        ata.cholesky().map(|c| c.solve(&atb))
    };
    let plane = fit(&ring)?;
    let mut dev: Vec<f64> = ring
        .iter()
        .map(|&(dx, dy, v)| (v - plane.dot(&Vector3::new(1.0, dx, dy))).abs())
        .collect();
    let mut sorted = dev.clone();
    sorted.sort_by(f64::total_cmp);
    let mad = sorted[sorted.len() / 2].max(0.5);
    let kept: Vec<(f64, f64, f64)> = ring
        .iter()
        .zip(dev.iter_mut())
        .filter(|(_, d)| **d <= 4.0 * 1.4826 * mad)
        .map(|(p, _)| *p)
        .collect();
    if kept.len() < ring.len() / 2 {
        return None;
    }
    let plane = fit(&kept)?;
    let (mut sw, mut swx, mut swy, mut inner, mut dark_sum, mut dark_n) =
        (0.0, 0.0, 0.0, 0usize, 0.0, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (fx, fy) = (x as f64, y as f64);
            let m = q(fx, fy);
            if m > g_in {
                continue;
            }
            let (dx, dy) = (fx - mx, fy - my);
            let wgt = plane.dot(&Vector3::new(1.0, dx, dy)) - px(x, y);
            sw += wgt;
            swx += wgt * dx;
            swy += wgt * dy;
            inner += 1;
            if m <= 0.7 {
                dark_sum += wgt;
                dark_n += 1.0;
            }
        }
    }
    if !(sw > 0.0) || inner == 0 || dark_n == 0.0 {
        return None;
    }
    let c = Point2::new(mx + swx / sw, my + swy / sw);
    // The centroid cannot leave the marker.
    if q(c.x, c.y) > 1.0 {
        return None;
    }
    Some((c, dark_sum / dark_n))
}
