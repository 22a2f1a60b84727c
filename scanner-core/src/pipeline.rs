//! The head's per-frame pipeline in fixed memory: stripe extraction → rays → board stripe points
//! → laser plane (least squares or the paper's construction) with its quality check →
//! triangulation of the object pixels → quantised points (and colour) ready for the wire.
//!
//! [`Head`] owns every buffer (sized by the const `W`, the most lines per frame); a frame
//! allocates nothing. A frame whose laser plane cannot be trusted is skipped with a
//! [`Skip`] reason.

use nalgebra::{Point2, Point3, Vector3};

use crate::geometry::{Board, LaserFitConfig, Limits, Surface, laser};
use crate::stripe::{Axis, Extractor, Frame, PixelFormat, StripeConfig, StripeError};
use crate::wire::{Skip, points::quantise};
use crate::{Camera, GeomError};

/// How the laser plane is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaneMethod {
    /// Least squares over all board-stripe points with outlier rejection (default).
    LeastSquares,
    /// The paper's construction (lines MN and QR, corrected through the mean of S and T).
    Paper,
}

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

/// The per-frame pipeline with its buffers for up to `W` lines.
pub struct Head<const W: usize> {
    extractor: Extractor<W>,
    camera: Camera<f32>,
    board: Board<f32>,
    cfg: HeadConfig,
    pixels: [Point2<f32>; W],
    rays: [Vector3<f32>; W],
    left: [Point3<f32>; W],
    right: [Point3<f32>; W],
    out: [[i32; 3]; W],
    rgb: [[u8; 3]; W],
    tri: [Option<Point3<f32>>; W],
}

impl<const W: usize> Head<W> {
    /// A head for a calibrated camera and board.
    pub fn new(camera: Camera<f32>, board: Board<f32>, cfg: HeadConfig) -> Self {
        Head {
            extractor: Extractor::new(),
            camera,
            board,
            cfg,
            pixels: [Point2::origin(); W],
            rays: [Vector3::zeros(); W],
            left: [Point3::origin(); W],
            right: [Point3::origin(); W],
            out: [[0; 3]; W],
            rgb: [[0; 3]; W],
            tri: [None; W],
        }
    }

    /// The settings.
    pub fn config(&self) -> &HeadConfig {
        &self.cfg
    }

    /// Runs one frame. `reference` is the laser-off frame (required for the difference method,
    /// and for colour).
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
        // Rays of the valid lines, and the board points among them.
        let (mut n, mut nl, mut nr) = (0, 0, 0);
        for (line, p) in ex.valid() {
            let px = match self.cfg.stripe.axis {
                Axis::Columns => Point2::new(line as f32, p.centre),
                Axis::Rows => Point2::new(p.centre, line as f32),
            };
            let Ok(ray) = self.camera.pixel_to_ray(&px) else {
                continue;
            };
            self.pixels[n] = px;
            self.rays[n] = ray;
            n += 1;
            if let Ok((q, s)) = self.board.intersect_ray(&ray, self.cfg.limits.min_sin) {
                if q.coords.norm() > self.cfg.limits.max_range {
                    continue;
                }
                match s {
                    Surface::Left => {
                        self.left[nl] = q;
                        nl += 1;
                    }
                    Surface::Right => {
                        self.right[nr] = q;
                        nr += 1;
                    }
                    Surface::Object => {}
                }
            }
        }
        let (left, right) = (&self.left[..nl], &self.right[..nr]);
        let fit = match self.cfg.method {
            PlaneMethod::LeastSquares => laser::least_squares(left, right, &self.cfg.laser),
            PlaneMethod::Paper => laser::paper(&self.board, left, right, &self.cfg.laser),
        }
        .map_err(|e| match e {
            GeomError::OnePlaneOnly => Skip::OnePlaneOnly,
            GeomError::TooFewPoints { .. } => {
                if nl == 0 || nr == 0 {
                    if nl + nr >= self.cfg.laser.min_points_per_side {
                        Skip::OnePlaneOnly
                    } else {
                        Skip::NoStripe
                    }
                } else {
                    Skip::NoStripe
                }
            }
            GeomError::PlaneThroughCamera => Skip::PlaneThroughCamera,
            _ => Skip::PoorPlane,
        })?;
        if !(fit.quality.rms <= self.cfg.max_plane_rms) {
            return Err(Skip::PoorPlane);
        }
        let plane = fit.plane;
        let limits = self.cfg.limits;
        for i in 0..n {
            self.tri[i] = plane
                .intersect_ray(&self.rays[i], limits.min_sin)
                .ok()
                .filter(|p| p.coords.norm() <= limits.max_range);
        }
        let line_of = |px: &Point2<f32>| match self.cfg.stripe.axis {
            Axis::Columns => px.x,
            Axis::Rows => px.y,
        };
        let fx = self.camera.fx();
        let mut m = 0;
        for i in 0..n {
            let Some(p) = self.tri[i] else {
                continue;
            };
            if self.cfg.continuity > 0.0 {
                let footprint = p.coords.norm() / fx;
                let near = |j: usize| -> bool {
                    let dl = libm::fabsf(line_of(&self.pixels[j]) - line_of(&self.pixels[i]));
                    self.tri[j].is_some_and(|q| {
                        dl <= 2.0 && (q - p).norm() <= self.cfg.continuity * footprint * dl + 1.0
                    })
                };
                if !((i > 0 && near(i - 1)) || (i + 1 < n && near(i + 1))) {
                    continue;
                }
            }
            match self.board.locate(&p, limits.board_tol) {
                Ok(Surface::Object) => {}
                Ok(_) if self.cfg.keep_board => {}
                _ => continue,
            }
            let (Some(x), Some(y), Some(z)) = (quantise(p.x), quantise(p.y), quantise(p.z)) else {
                continue;
            };
            self.out[m] = [x, y, z];
            if self.cfg.colour {
                self.rgb[m] = reference.map_or([0; 3], |r| colour_at(r, &self.pixels[i]));
            }
            m += 1;
        }
        let nv = plane.normal();
        Ok(FrameOutput {
            points: &self.out[..m],
            rgb: if self.cfg.colour { &self.rgb[..m] } else { &[] },
            plane: [nv.x, nv.y, nv.z, plane.offset()],
            plane_rms: fit.quality.rms,
            stripe_lines: n,
        })
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
