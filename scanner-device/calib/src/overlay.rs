//! Pictures of what calibration found: the board image with every marker numbered, missing and
//! dropped ones marked, residuals drawn 100× enlarged, the marker lines, the crease `L_c`, and a
//! legend; the same for dot-grid images. Drawn with the [`Canvas`].

use image::{GrayImage, Rgb, RgbImage};
use scanner_core::Camera;
use scanner_core::calib::model::predict;
use scanner_core::nalgebra::{Point2, Point3};

use super::board::BoardFile;
use super::detect::Rejected;
use super::{BoardOutcome, MarkerFit};
use crate::canvas::Canvas;
use scanner_core::geometry::{Board, Pose};

/// Colours of the overlay.
pub mod colour {
    use image::Rgb;
    /// A marker used in the fit.
    pub const USED: Rgb<u8> = Rgb([40, 220, 60]);
    /// A marker found but dropped as an outlier.
    pub const DROPPED: Rgb<u8> = Rgb([255, 150, 0]);
    /// A layout point not found.
    pub const MISSING: Rgb<u8> = Rgb([255, 40, 40]);
    /// Residual vectors.
    pub const RESIDUAL: Rgb<u8> = Rgb([255, 255, 0]);
    /// Marker lines.
    pub const LINE: Rgb<u8> = Rgb([0, 200, 255]);
    /// The crease.
    pub const CREASE: Rgb<u8> = Rgb([255, 0, 255]);
    /// Dark regions rejected as clutter.
    pub const CLUTTER: Rgb<u8> = Rgb([150, 150, 150]);
    /// Text.
    pub const TEXT: Rgb<u8> = Rgb([255, 255, 255]);
}

fn font_scale(img: &GrayImage) -> u32 {
    (img.width() / 640).max(1)
}

/// The annotated board image: markers found (numbered L0…, R0…), missing (red ×) and dropped
/// (orange) ones, residuals ×100, the fitted marker lines, the crease `L_c`, clutter and a
/// legend. Drawn whether calibration succeeded or not.
pub fn board_overlay(
    img: &GrayImage,
    outcome: &BoardOutcome,
    board: &BoardFile,
    camera: &Camera<f64>,
) -> RgbImage {
    let mut pen = Pen {
        cv: Canvas::from_gray(img),
        scale: font_scale(img),
        th: f64::from(font_scale(img)),
    };
    pen.clutter(&outcome.detections.rejected);
    let mut legend: Vec<(String, Rgb<u8>)> = Vec::new();
    match &outcome.result {
        Ok(fit) => {
            for (k, s) in fit.sheets.iter().enumerate() {
                let layout = [&board.left, &board.right][k];
                let place = SheetPlace {
                    name: SHEET_NAMES[k],
                    camera,
                    pose: &s.pose,
                    radius: layout.marker_radius(board.marker_diameter),
                };
                pen.marker_lines(&layout.points(), &place);
                let r_px = 0.6 * place.radius.max(5.0) * (img.width() as f64 / 1000.0).max(0.6);
                for (i, m) in s.markers.iter().enumerate() {
                    pen.marker(i, m, r_px, &place);
                }
                legend.push((s.summary(["left", "right"][k]), colour::USED));
            }
            pen.crease(&fit.board, board.sheet.height / 2.0, camera);
            legend.push((
                format!(
                    "angle between the planes {:.3} deg; crease L_c in magenta",
                    fit.board.angle().to_degrees()
                ),
                colour::CREASE,
            ));
            legend.push(("residuals drawn x100 (yellow)".into(), colour::RESIDUAL));
        }
        Err(e) => {
            pen.unfitted(outcome, board);
            legend.push((format!("FAILED: {e}"), colour::MISSING));
        }
    }
    legend.push((
        format!(
            "{} markers detected, {} dark regions rejected (grey +)",
            outcome.detections.blobs.len(),
            outcome.detections.rejected.len()
        ),
        colour::TEXT,
    ));
    pen.cv.legend(&legend, pen.scale);
    pen.cv.image
}

/// Label prefixes of the left and right sheets' markers.
const SHEET_NAMES: [&str; 2] = ["L", "R"];

/// Where a fitted sheet's layout points land in the image.
struct SheetPlace<'a> {
    name: &'static str,
    camera: &'a Camera<f64>,
    pose: &'a Pose,
    radius: f64,
}

impl SheetPlace<'_> {
    /// The image of the marker centred at layout point `p`, if it projects.
    fn pixel(&self, p: &Point2<f64>) -> Option<(f64, f64)> {
        predict(self.camera, self.pose, p, self.radius)
            .ok()
            .map(|q| (q.x, q.y))
    }
}

/// A canvas with the line width and font scale of one overlay.
struct Pen {
    cv: Canvas,
    scale: u32,
    th: f64,
}

impl Pen {
    /// A grey + on every dark region rejected as clutter.
    fn clutter(&mut self, rejected: &[Rejected]) {
        for r in rejected {
            let s = (r.area as f64).sqrt() / 2.0 + 2.0;
            let (x, y) = (r.centre.x, r.centre.y);
            self.cv.line((x - s, y), (x + s, y), 1.0, colour::CLUTTER);
            self.cv.line((x, y - s), (x, y + s), 1.0, colour::CLUTTER);
        }
    }

    /// The fitted marker lines: layout points sharing a `v`, drawn as projected curves.
    fn marker_lines(&mut self, layout: &[Point2<f64>], place: &SheetPlace) {
        let mut vs: Vec<f64> = layout.iter().map(|p| p.y).collect();
        vs.sort_by(f64::total_cmp);
        vs.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
        for v in vs {
            let (u0, u1, n) = layout
                .iter()
                .filter(|p| (p.y - v).abs() < 1e-6)
                .fold((f64::INFINITY, f64::NEG_INFINITY, 0), |(a, b, n), p| {
                    (a.min(p.x), b.max(p.x), n + 1)
                });
            if n < 2 {
                continue;
            }
            let steps = 24;
            let pts: Vec<_> = (0..=steps)
                .filter_map(|i| {
                    let u = u0 + (u1 - u0) * f64::from(i) / f64::from(steps);
                    place.pixel(&Point2::new(u, v))
                })
                .collect();
            for w in pts.windows(2) {
                self.cv.line(w[0], w[1], self.th, colour::LINE);
            }
        }
    }

    /// One layout point: used (green circle, residual ×100), dropped (orange) or missing (red ×
    /// where it should be).
    fn marker(&mut self, i: usize, m: &MarkerFit, r_px: f64, place: &SheetPlace) {
        let label = format!("{}{i}", place.name);
        let th = self.th;
        match (m.pixel, m.residual) {
            (Some(p), Some(res)) => {
                self.cv.circle((p.x, p.y), r_px + 4.0, th, colour::USED);
                let tip = (p.x + 100.0 * res.x, p.y + 100.0 * res.y);
                self.cv.line((p.x, p.y), tip, th + 1.0, colour::RESIDUAL);
                let at = (p.x + r_px + 6.0, p.y - 4.0 * th);
                self.label(at, &label, colour::USED);
            }
            (Some(p), None) => {
                self.cv.circle((p.x, p.y), r_px + 4.0, th, colour::DROPPED);
                let at = (p.x + r_px + 6.0, p.y - 4.0 * th);
                self.label(at, &format!("{label} dropped"), colour::DROPPED);
            }
            (None, _) => {
                if let Some(q) = place.pixel(&m.sheet) {
                    self.cv.cross(q, 10.0 * th, th + 1.0, colour::MISSING);
                    let at = (q.0 + 12.0 * th, q.1 - 4.0 * th);
                    self.label(at, &format!("{label} missing"), colour::MISSING);
                }
            }
        }
    }

    /// The crease `L_c` between the sheets' top and bottom edges (`half_height` from its middle).
    fn crease(&mut self, board: &Board<f64>, half_height: f64, camera: &Camera<f64>) {
        let c = board.crease();
        let pts: Vec<(f64, f64)> = (0..=32)
            .filter_map(|i| {
                let t = -half_height + 2.0 * half_height * f64::from(i) / 32.0;
                let p: Point3<f64> = c.point() + c.direction() * t;
                camera.project(&p).ok().map(|q| (q.x, q.y))
            })
            .collect();
        for w in pts.windows(2) {
            self.cv.line(w[0], w[1], self.th + 1.0, colour::CREASE);
        }
    }

    /// After a failed fit: the identifications found (`L3?`) and every marker detected.
    fn unfitted(&mut self, outcome: &BoardOutcome, board: &BoardFile) {
        for (k, a) in outcome.assignments.iter().enumerate() {
            let features = outcome.features(board, k);
            let Some(a) = a else { continue };
            for (i, b) in a.blob_of.iter().enumerate() {
                if let Some(p) = b.and_then(|b| features.get(b)).map(|f| f.centre) {
                    let name = format!("{}{i}?", SHEET_NAMES[k]);
                    self.label((p.x + 10.0, p.y), &name, colour::DROPPED);
                }
            }
        }
        for b in &outcome.detections.blobs {
            let at = (b.centre.x, b.centre.y);
            self.cv.circle(at, b.axes.0 + 3.0, self.th, colour::DROPPED);
        }
    }

    fn label(&mut self, at: (f64, f64), text: &str, c: Rgb<u8>) {
        self.cv.text(at.0, at.1, text, self.scale, c);
    }
}

/// An intrinsics image: every feature detected (grey +), the ones used (green, numbered by
/// their place on the target), the ones dropped from the fit (orange, with their error), the
/// residuals ×20 (yellow), and a legend saying whether the image was used and why not.
pub fn grid_overlay(img: &GrayImage, report: &super::ImageReport) -> RgbImage {
    let mut cv = Canvas::from_gray(img);
    let scale = font_scale(img);
    if let Some(g) = &report.grid {
        for f in &g.features {
            cv.cross((f.centre.x, f.centre.y), 3.0, 1.0, colour::CLUTTER);
        }
    }
    let mut lines = Vec::new();
    match &report.status {
        Ok(v) => {
            for ((i, p), r) in v.found.iter().zip(&v.residuals) {
                cv.circle((p.x, p.y), 5.0, 1.0, colour::USED);
                cv.text(p.x + 6.0, p.y - 9.0, &i.to_string(), scale, colour::USED);
                cv.line(
                    (p.x, p.y),
                    (p.x + 20.0 * r.x, p.y + 20.0 * r.y),
                    1.5,
                    colour::RESIDUAL,
                );
            }
            for (i, p, e) in &v.dropped {
                cv.circle((p.x, p.y), 7.0, 2.0, colour::DROPPED);
                cv.text(
                    p.x + 8.0,
                    p.y + 2.0,
                    &format!("{i}: {e:.1} px"),
                    scale,
                    colour::DROPPED,
                );
            }
            if !v.dropped.is_empty() {
                lines.push((
                    format!(
                        "{} dropped from the fit (error far above the rest)",
                        v.dropped.len()
                    ),
                    colour::DROPPED,
                ));
            }
            lines.insert(
                0,
                (
                    format!(
                        "used: {} features, rms {:.3} px, max {:.3} px",
                        v.found.len(),
                        v.rms_px,
                        v.max_px
                    ),
                    colour::USED,
                ),
            );
        }
        Err(e) => {
            if let Some(g) = &report.grid {
                for (i, p) in &g.found {
                    cv.circle((p.x, p.y), 5.0, 1.0, colour::DROPPED);
                    cv.text(p.x + 6.0, p.y - 9.0, &i.to_string(), scale, colour::DROPPED);
                }
            }
            lines.push((format!("not used: {e}"), colour::MISSING));
        }
    }
    if report.status.is_ok() {
        lines.push(("yellow: residual x20".into(), colour::RESIDUAL));
    }
    lines.push(("grey +: every feature detected".into(), colour::CLUTTER));
    cv.legend(&lines, scale);
    cv.image
}

/// Colour of a projection uncertainty `sigma` (pixels) on a log scale: blue at 0.01 px and
/// below, through green (0.1 px) and yellow, to red at 1 px and above.
pub fn uncertainty_colour(sigma: f64) -> Rgb<u8> {
    const STOPS: [(f64, [f64; 3]); 5] = [
        (-2.0, [40.0, 60.0, 220.0]),
        (-1.5, [0.0, 170.0, 220.0]),
        (-1.0, [40.0, 200.0, 60.0]),
        (-0.5, [240.0, 220.0, 0.0]),
        (0.0, [230.0, 30.0, 30.0]),
    ];
    if !sigma.is_finite() {
        return Rgb([90, 90, 90]);
    }
    let l = sigma.max(1e-6).log10().clamp(STOPS[0].0, STOPS[4].0);
    let k = STOPS
        .windows(2)
        .position(|w| l <= w[1].0)
        .unwrap_or(STOPS.len() - 2);
    let ((l0, c0), (l1, c1)) = (STOPS[k], STOPS[k + 1]);
    let t = (l - l0) / (l1 - l0);
    Rgb(core::array::from_fn(|i| {
        (c0[i] + t * (c1[i] - c0[i])).round() as u8
    }))
}

/// The projection-uncertainty map over an image of the target: each pixel tinted by the
/// uncertainty there ([`uncertainty_colour`]), the features used as white dots, a legend with
/// the scale, the halves' difference and where more shots would help.
pub fn uncertainty_overlay(
    img: &GrayImage,
    check: &super::selfcheck::SelfCheck,
    features: impl Iterator<Item = Point2<f64>>,
) -> RgbImage {
    let map = &check.map;
    let mut cv = Canvas::from_gray(img);
    for (x, y, p) in cv.image.enumerate_pixels_mut() {
        let c = uncertainty_colour(map.at(f64::from(x) + 0.5, f64::from(y) + 0.5));
        *p = Rgb(core::array::from_fn(|i| {
            (0.4 * f64::from(p[i]) + 0.6 * f64::from(c[i])).round() as u8
        }));
    }
    for f in features {
        cv.disc((f.x, f.y), 1.5, colour::TEXT);
    }
    let scale = font_scale(img);
    let mut lines = vec![(
        format!(
            "projection uncertainty (1 sigma, worst direction): {:.3} px median where the features were, {:.3} px at most",
            map.covered_median(),
            map.max()
        ),
        colour::TEXT,
    )];
    for s in [0.01, 0.03, 0.1, 0.3, 1.0] {
        lines.push((format!("  {s} px"), uncertainty_colour(s)));
    }
    match &check.halves {
        Ok(h) => lines.push((
            format!(
                "halves of {} and {} images differ by {:.3} px rms where the features were ({:.3} px expected), {:.3} px over the image",
                h.images.0,
                h.images.1,
                h.features_rms_px,
                h.expected_features_rms_px,
                h.image_rms_px
            ),
            if h.too_far() {
                colour::DROPPED
            } else {
                colour::USED
            },
        )),
        Err(e) => lines.push((format!("no cross-validation: {e}"), colour::DROPPED)),
    }
    let more = map.more_shots();
    if !more.is_empty() {
        lines.push((
            format!(
                "more shots with the target in the {} would help",
                more.iter().map(|r| r.name).collect::<Vec<_>>().join(", ")
            ),
            colour::DROPPED,
        ));
    }
    cv.legend(&lines, scale);
    cv.image
}
