//! The head's per-frame pipeline in fixed memory: stripe extraction → rays → board stripe points
//! → laser plane (least squares or the paper's construction) with its quality check →
//! triangulation of the object pixels → quantised points (and colour) ready for the wire.
//!
//! [`Head`] owns every buffer (sized by the const `W`, the most lines per frame); a frame
//! allocates nothing. A frame whose laser plane cannot be trusted is skipped with a
//! [`Skip`] reason.

use heapless::Vec;
use nalgebra::{Point2, Point3, Vector3};

use crate::geometry::{Board, LaserFitConfig, LaserPlane, Limits, Plane, Surface, laser};
use crate::stripe::{Axis, Extraction, Extractor, Frame, PixelFormat, StripeConfig, StripeError};
pub use crate::wire::PlaneMethod;
use crate::wire::{Skip, points::quantise};
use crate::{Camera, GeomError};

/// Settings of the head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadConfig {
    /// Stripe extraction.
    pub stripe: StripeConfig,
    /// Laser-plane fit.
    pub laser: LaserFitConfig<f32>,
    /// Validity of triangulated points.
    pub limits: Limits<f32>,
    /// Laser-plane method.
    pub method: PlaneMethod,
    /// A plane whose board points scatter more than this (RMS, mm) fails the check.
    pub max_plane_rms: f32,
    /// Keep the stripe's board points too (normally only the object's are sent).
    pub keep_board: bool,
    /// Colour each point from the reference frame.
    pub colour: bool,
    /// Continuity: a point is kept only when a neighbouring line's point lies within this many
    /// pixel footprints of it (plus 1 mm) in 3-D. Points between an object's edge and the board
    /// behind it (the stripe blurred across the occlusion: "flying pixels") have none. 0 keeps
    /// every point.
    pub continuity: f32,
}

impl HeadConfig {
    /// Defaults for a stripe configuration: least squares, plane RMS ≤ 1 mm, object points only,
    /// no colour; points within 3 mm of a board plane count as board (the stripe where it
    /// crosses a dark printed marker is off by a couple of millimetres: without this margin those
    /// board points would be sent as object points).
    pub fn new(stripe: StripeConfig) -> Self {
        HeadConfig {
            stripe,
            laser: LaserFitConfig::default(),
            limits: Limits {
                board_tol: 3.0,
                ..Limits::default()
            },
            method: PlaneMethod::LeastSquares,
            max_plane_rms: 1.0,
            keep_board: false,
            colour: false,
            continuity: 6.0,
        }
    }
}

/// One frame's result.
#[derive(Debug, Clone, Copy)]
pub struct FrameOutput<'a> {
    /// Quantised points (wire units), in line order.
    pub points: &'a [[i32; 3]],
    /// Their colours (empty without colour).
    pub rgb: &'a [[u8; 3]],
    /// The laser plane `[nx, ny, nz, d]`.
    pub plane: [f32; 4],
    /// RMS of the board points about the plane, mm.
    pub plane_rms: f32,
    /// Valid stripe lines.
    pub stripe_lines: usize,
}

/// The per-frame pipeline with its buffers for up to `W` lines (fixed-capacity `heapless`
/// vectors, filled afresh each frame: at most one entry per line, so a push cannot fail).
pub struct Head<const W: usize> {
    extractor: Extractor<W>,
    camera: Camera<f32>,
    board: Board<f32>,
    cfg: HeadConfig,
    /// The valid lines' stripe pixels, their rays, and each ray's point on the laser plane.
    stripe: Vec<StripePixel, W>,
    left: Vec<Point3<f32>, W>,
    right: Vec<Point3<f32>, W>,
    out: Vec<[i32; 3], W>,
    rgb: Vec<[u8; 3], W>,
}

/// A valid stripe pixel, its ray, and (once the plane is known) its 3-D point.
#[derive(Debug, Clone, Copy)]
struct StripePixel {
    px: Point2<f32>,
    ray: Vector3<f32>,
    point: Option<Point3<f32>>,
}

impl<const W: usize> Head<W> {
    /// A head for a calibrated camera and board.
    pub fn new(camera: Camera<f32>, board: Board<f32>, cfg: HeadConfig) -> Self {
        Head {
            extractor: Extractor::new(),
            camera,
            board,
            cfg,
            stripe: Vec::new(),
            left: Vec::new(),
            right: Vec::new(),
            out: Vec::new(),
            rgb: Vec::new(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &HeadConfig {
        &self.cfg
    }

    /// Runs one frame: the stripe, its board points, the laser plane, the object points.
    /// `reference` is the laser-off frame (required for the difference method, and for colour).
    ///
    /// # Errors
    /// The [`Skip`] reason when the frame gives no points.
    pub fn process(
        &mut self,
        frame: &Frame<'_>,
        reference: Option<&Frame<'_>>,
    ) -> Result<FrameOutput<'_>, Skip> {
        let ex = self
            .extractor
            .extract(frame, reference, &self.cfg.stripe)
            // A frame of the wrong shape, or a configuration the head was built with wrongly:
            // either way this frame cannot be used.
            .map_err(|_: StripeError| Skip::BadFrame)?;
        board_points(
            &ex,
            &self.camera,
            &self.board,
            &self.cfg,
            (&mut self.stripe, &mut self.left, &mut self.right),
        );
        let fit = laser_plane(&self.board, &self.cfg, &self.left, &self.right)?;
        let plane = fit.plane;
        triangulate(&plane, &self.cfg.limits, &mut self.stripe);
        self.keep(reference);
        let nv = plane.normal();
        Ok(FrameOutput {
            points: &self.out,
            rgb: if self.cfg.colour { &self.rgb } else { &[] },
            plane: [nv.x, nv.y, nv.z, plane.offset()],
            plane_rms: fit.quality.rms,
            stripe_lines: self.stripe.len(),
        })
    }

    /// The object points worth sending: continuous with a neighbouring line's (no flying
    /// pixels), off the board (unless board points are kept), quantised; with their colour.
    fn keep(&mut self, reference: Option<&Frame<'_>>) {
        self.out.clear();
        self.rgb.clear();
        let (cfg, stripe) = (&self.cfg, &self.stripe);
        let line_of = |px: &Point2<f32>| match cfg.stripe.axis {
            Axis::Columns => px.x,
            Axis::Rows => px.y,
        };
        let fx = self.camera.fx();
        let n = stripe.len();
        for (i, s) in stripe.iter().enumerate() {
            let Some(p) = s.point else {
                continue;
            };
            if cfg.continuity > 0.0 {
                let footprint = p.coords.norm() / fx;
                let near = |j: usize| -> bool {
                    let dl = libm::fabsf(line_of(&stripe[j].px) - line_of(&s.px));
                    stripe[j].point.is_some_and(|q| {
                        dl <= 2.0 && (q - p).norm() <= cfg.continuity * footprint * dl + 1.0
                    })
                };
                if !((i > 0 && near(i - 1)) || (i + 1 < n && near(i + 1))) {
                    continue;
                }
            }
            match self.board.locate(&p, cfg.limits.board_tol) {
                Ok(Surface::Object) => {}
                Ok(_) if cfg.keep_board => {}
                _ => continue,
            }
            let (Some(x), Some(y), Some(z)) = (quantise(p.x), quantise(p.y), quantise(p.z)) else {
                continue;
            };
            // At most one point per line: W is enough.
            if self.out.push([x, y, z]).is_err() {
                break;
            }
            if cfg.colour {
                let c = reference.map_or([0; 3], |r| colour_at(r, &s.px));
                let _ = self.rgb.push(c);
            }
        }
    }
}

/// The valid lines' pixels and rays into `stripe`, and the rays' points on the two board planes
/// into `left` and `right` (within range).
fn board_points<const W: usize>(
    ex: &Extraction<'_>,
    camera: &Camera<f32>,
    board: &Board<f32>,
    cfg: &HeadConfig,
    (stripe, left, right): (
        &mut Vec<StripePixel, W>,
        &mut Vec<Point3<f32>, W>,
        &mut Vec<Point3<f32>, W>,
    ),
) {
    stripe.clear();
    left.clear();
    right.clear();
    for (line, p) in ex.valid() {
        let px = match cfg.stripe.axis {
            Axis::Columns => Point2::new(line as f32, p.centre),
            Axis::Rows => Point2::new(p.centre, line as f32),
        };
        let Ok(ray) = camera.pixel_to_ray(&px) else {
            continue;
        };
        // One entry per line of at most W: the pushes cannot fail.
        if stripe
            .push(StripePixel {
                px,
                ray,
                point: None,
            })
            .is_err()
        {
            break;
        }
        if let Ok((q, s)) = board.intersect_ray(&ray, cfg.limits.min_sin) {
            if q.coords.norm() > cfg.limits.max_range {
                continue;
            }
            let _ = match s {
                Surface::Left => left.push(q),
                Surface::Right => right.push(q),
                Surface::Object => Ok(()),
            };
        }
    }
}

/// The laser plane from the board points, checked; the reason to skip the frame otherwise.
fn laser_plane(
    board: &Board<f32>,
    cfg: &HeadConfig,
    left: &[Point3<f32>],
    right: &[Point3<f32>],
) -> Result<LaserPlane<f32>, Skip> {
    let (nl, nr) = (left.len(), right.len());
    let fit = match cfg.method {
        PlaneMethod::LeastSquares => laser::least_squares(left, right, &cfg.laser),
        PlaneMethod::Paper => laser::paper(board, left, right, &cfg.laser),
    }
    .map_err(|e| match e {
        GeomError::OnePlaneOnly => Skip::OnePlaneOnly,
        GeomError::TooFewPoints { .. }
            if (nl == 0 || nr == 0) && nl + nr >= cfg.laser.min_points_per_side =>
        {
            Skip::OnePlaneOnly
        }
        GeomError::TooFewPoints { .. } => Skip::NoStripe,
        GeomError::PlaneThroughCamera => Skip::PlaneThroughCamera,
        _ => Skip::PoorPlane,
    })?;
    if !(fit.quality.rms <= cfg.max_plane_rms) {
        return Err(Skip::PoorPlane);
    }
    Ok(fit)
}

/// Each stripe ray's point on the laser plane (within range).
fn triangulate<const W: usize>(
    plane: &Plane<f32>,
    limits: &Limits<f32>,
    stripe: &mut Vec<StripePixel, W>,
) {
    for s in stripe.iter_mut() {
        s.point = plane
            .intersect_ray(&s.ray, limits.min_sin)
            .ok()
            .filter(|p| p.coords.norm() <= limits.max_range);
    }
}

/// The colour of the nearest pixel of `frame` to `at`.
pub fn colour_at(frame: &Frame<'_>, at: &Point2<f32>) -> [u8; 3] {
    let x = (libm::roundf(at.x).max(0.0) as usize).min(frame.width().saturating_sub(1));
    let y = (libm::roundf(at.y).max(0.0) as usize).min(frame.height().saturating_sub(1));
    let row = frame.row(y);
    match frame.format() {
        PixelFormat::Gray8 => [row[x]; 3],
        PixelFormat::Rgb24 => [row[3 * x], row[3 * x + 1], row[3 * x + 2]],
        PixelFormat::Yuyv => {
            // Y of this pixel, U and V of its pair.
            let pair = (x / 2) * 4;
            crate::colour::yuv_to_rgb(row[2 * x], row[pair + 1], row[pair + 3])
        }
    }
}
