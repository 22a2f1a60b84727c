//! The head's per-frame pipeline in fixed memory: stripe extraction → rays → board stripe points
//! → laser plane (least squares or the paper's construction) with its quality check →
//! triangulation of the object pixels → quantised points (and colour) ready for the wire.
//!
//! [`Head`] owns every buffer (sized by the const `W`, the most lines per frame); a frame
//! allocates nothing. A frame whose laser plane cannot be trusted is skipped with a
//! [`Skip`] reason.

use heapless::Vec;
use nalgebra::{Point2, Point3, Vector3};

use crate::calib::spread::CalibrationSpread;
use crate::geometry::{Board, LaserFitConfig, LaserPlane, Limits, Plane, Surface, laser};
use crate::stripe::{
    Axis, Extraction, Extractor, Frame, Locate, PixelFormat, StripeConfig, StripeError,
};
use crate::{Camera, GeomError};
use scanner_wire::PlaneMethod;
use scanner_wire::Skip;
use scanner_wire::points::{quantise, uncertainty_code};

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
    /// A plane whose normal's standard uncertainty ([`FrameOutput::plane_tilt`]) exceeds this
    /// (radians) fails the check: the stripe's board points are too few or too bunched (a
    /// stripe barely past the crease on one side) to fix the plane, however well they fit.
    pub max_plane_tilt: f32,
    /// Keep the stripe's board points too (normally only the object's are sent).
    pub keep_board: bool,
    /// Colour each point from the reference frame.
    pub colour: bool,
    /// A point counts as on the board within this many of its sensitivities (mm per pixel of
    /// stripe error) of a board plane, when that exceeds `limits.board_tol`.
    pub board_tol_px: f32,
    /// The last point of a continuous run is dropped when its stripe is weaker than this
    /// fraction of its neighbour's: a pixel across the object's silhouette (0 keeps them).
    /// Applies with `continuity` only.
    pub silhouette: f32,
    /// A point is dropped when it lies nearer than this many times its profile's width (the
    /// stripe's FWHM, a shadow edge's ramp), in lines, to where the surface breaks: the end of
    /// its run of continuous points (an object's silhouette, the edge of its shadow, which cut
    /// the profiles of the lines within about a width of them), or the board's crease (where
    /// the stripe bends: a board point there is neither sheet's, nor used for the plane). Their
    /// centres are pulled off the surface. 0 keeps them (the default: the price is points at
    /// every run's end, which the merge's registration and a fixed laser's fragmented real
    /// stripes feel); run ends apply with `continuity` only.
    pub edge_reach: f32,
    /// Board fringes: a run of at most this many continuous object points within twice the board
    /// tolerance of the board, continuing into board points, counts as board (the light sheet's
    /// tail where a shadow or a border clips it on the board). 0 turns it off.
    pub board_fringe: usize,
    /// Continuity: a point is kept only when a neighbouring line's point lies within this many
    /// pixel footprints of it (plus 1 mm) in 3-D. Points between an object's edge and the board
    /// behind it (the stripe blurred across the occlusion: "flying pixels") have none. 0 keeps
    /// every point.
    pub continuity: f32,
    /// A fixed laser's plane, calibrated once (a turntable scanner's): every frame's stripe is
    /// triangulated with it, and the board's planes only say what is not the object. `None`: the
    /// plane is fitted to each frame's stripe on the board (the hand-held laser).
    pub fixed_plane: Option<FixedPlane>,
    /// What of each line's profile is triangulated: the stripe's centre (a laser), or one edge
    /// of a shadow's band ([`Head::again`] gives the other edge of the same frame).
    pub locate: Locate,
}

/// A fixed laser's plane and how sure it is ([`HeadConfig::fixed_plane`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedPlane {
    /// The plane, camera coordinates.
    pub plane: Plane<f32>,
    /// The standard uncertainty of a point on it along its normal, mm (its calibration's
    /// scatter).
    pub sigma: f32,
}

impl HeadConfig {
    /// Defaults for a stripe configuration: least squares, plane RMS ≤ 1 mm and tilt uncertainty
    /// ≤ 0.05° (at a lever of 0.4 × the distance, 0.035 % of it), object points only,
    /// no colour; points within 3 mm of a board plane count as board (the stripe where it
    /// crosses a dark printed marker is off by a couple of millimetres: without this margin those
    /// board points would be sent as object points), or within two pixels' worth of depth where
    /// that is more (beyond about 900 mm at 1600×1200, where a pixel of stripe error is several
    /// millimetres: the marker's shift of the stripe, or three noise σ of a weak one, would
    /// otherwise send board points as object points; measured in the accuracy report).
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
            max_plane_tilt: 0.05 * core::f32::consts::PI / 180.0,
            keep_board: false,
            colour: false,
            board_tol_px: 2.0,
            silhouette: 0.85,
            edge_reach: 0.0,
            board_fringe: 4,
            continuity: 6.0,
            fixed_plane: None,
            locate: Locate::Centre,
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
    /// Their standard uncertainties, coded ([`uncertainty_code`]): the stripe centre's (from its
    /// height over the noise and its width) through the point's sensitivity, and the laser
    /// plane's (offset and tilt) along the ray, in quadrature.
    pub uncertainty: &'a [u8],
    /// The laser plane `[nx, ny, nz, d]`.
    pub plane: [f32; 4],
    /// RMS of the board points about the plane, mm.
    pub plane_rms: f32,
    /// Standard uncertainty of the plane's normal, radians ([`LaserQuality::tilt`]).
    ///
    /// [`LaserQuality::tilt`]: crate::geometry::LaserQuality::tilt
    pub plane_tilt: f32,
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
    /// The stripe's points on the known surfaces: the left sheet, the right sheet, the
    /// turntable disc.
    known: [Vec<Point3<f32>, W>; 3],
    out: Vec<[i32; 3], W>,
    rgb: Vec<[u8; 3], W>,
    uncertainty: Vec<u8, W>,
    verdicts: Vec<Verdict, W>,
    /// The calibration's modes, when its covariance is known.
    spread: Option<CalibrationSpread>,
    /// Each stripe pixel's calibration share, mm.
    moves: Vec<f32, W>,
    /// The turntable disc lying in front of the board, when its pose is known.
    turntable: Option<Turntable>,
}

/// The printed turntable disc where the head found it (its pose from the reference frame): a
/// third known surface in front of the board. A stripe ray that meets it before the board is
/// never a board point; and where the board alone cannot fix a frame's laser plane (a stand or a
/// table hides the board's lower part), the stripe's line on the disc, with one on a sheet, can.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Turntable {
    /// The disc's plane, camera coordinates (mm).
    pub plane: Plane<f32>,
    /// Its centre, camera coordinates (mm).
    pub centre: Point3<f32>,
    /// The radius within which the disc's print is trusted to lie flat on its plane, mm.
    pub radius: f32,
}

impl Turntable {
    /// Where `ray` meets the disc, if it does within the radius.
    fn hit(&self, ray: &Vector3<f32>, min_sin: f32) -> Option<Point3<f32>> {
        let p = self.plane.intersect_ray(ray, min_sin).ok()?;
        ((p - self.centre).norm() <= self.radius && p.z > 0.0).then_some(p)
    }
}

/// A valid stripe pixel, its ray, and (once the plane is known) its 3-D point, how far that
/// point moves per pixel of stripe error along the line (mm), and its standard uncertainty (mm).
#[derive(Debug, Clone, Copy)]
struct StripePixel {
    px: Point2<f32>,
    ray: Vector3<f32>,
    point: Option<Point3<f32>>,
    sensitivity: f32,
    /// The centre's standard uncertainty, pixels.
    sigma_px: f32,
    uncertainty: f32,
    peak: u16,
    /// How wide what was located is, lines: the stripe's FWHM, or the edge's ramp.
    width: f32,
    /// The ray's point on a board sheet (0 left, 1 right), when it meets one within range.
    on_board: Option<(Point3<f32>, usize)>,
    /// That point lies nearer the crease, in the image, than `edge_reach` times the profile's
    /// width: the stripe bends there, and a profile across the bend is centred off both sheets.
    at_crease: bool,
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
            known: [Vec::new(), Vec::new(), Vec::new()],
            out: Vec::new(),
            rgb: Vec::new(),
            uncertainty: Vec::new(),
            verdicts: Vec::new(),
            spread: None,
            moves: Vec::new(),
            turntable: None,
        }
    }

    /// The turntable disc in front of the board (see [`Turntable`]); `None` without one.
    pub fn set_turntable(&mut self, turntable: Option<Turntable>) {
        self.turntable = turntable;
    }

    /// Adds the calibration's share to every point's uncertainty (see [`CalibrationSpread`]);
    /// `None` leaves it out.
    pub fn set_spread(&mut self, spread: Option<CalibrationSpread>) {
        self.spread = spread;
    }

    /// The last frame's extraction (every line's stripe, edges and status).
    pub fn extraction(&self) -> Extraction<'_> {
        self.extractor.last()
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
        self.extractor
            .extract(frame, reference, &self.cfg.stripe)
            // A frame of the wrong shape, or a configuration the head was built with wrongly:
            // either way this frame cannot be used.
            .map_err(|_: StripeError| Skip::BadFrame)?;
        self.triangulate_last(self.cfg.locate, reference)
    }

    /// The last frame processed again, its lines located by `locate` instead (the other edge
    /// of a shadow's band: a second plane of light in the same frame); `reference` as given to
    /// [`Self::process`]. Nothing is extracted again.
    ///
    /// # Errors
    /// The [`Skip`] reason when the frame gives no points.
    pub fn again(
        &mut self,
        locate: Locate,
        reference: Option<&Frame<'_>>,
    ) -> Result<FrameOutput<'_>, Skip> {
        self.triangulate_last(locate, reference)
    }

    /// The last extraction's lines located by `locate`: board points, the plane, the object
    /// points.
    fn triangulate_last(
        &mut self,
        locate: Locate,
        reference: Option<&Frame<'_>>,
    ) -> Result<FrameOutput<'_>, Skip> {
        board_points(
            &self.extractor.last(),
            locate,
            &self.camera,
            (&self.board, self.turntable.as_ref()),
            &self.cfg,
            (&mut self.stripe, &mut self.known),
        );
        let [left, right, on_disc] = &self.known;
        let fit = match &self.cfg.fixed_plane {
            Some(fixed) => fixed_fit(fixed),
            None => laser_plane(&self.board, &self.cfg, [left, right, on_disc])?,
        };
        let plane = fit.plane;
        let step = match self.cfg.stripe.axis {
            Axis::Columns => Vector3::new(0.0, 1.0 / self.camera.fy(), 0.0),
            Axis::Rows => Vector3::new(1.0 / self.camera.fx(), 0.0, 0.0),
        };
        triangulate(&fit, &self.cfg.limits, step, &mut self.stripe);
        if let Some(spread) = &self.spread {
            add_calibration_share(spread, &self.board, &fit, &mut self.stripe, &mut self.moves);
        }
        self.keep(reference);
        let nv = plane.normal();
        Ok(FrameOutput {
            points: &self.out,
            rgb: if self.cfg.colour { &self.rgb } else { &[] },
            uncertainty: &self.uncertainty,
            plane: [nv.x, nv.y, nv.z, plane.offset()],
            plane_rms: fit.quality.rms,
            plane_tilt: fit.quality.tilt,
            stripe_lines: self.stripe.len(),
        })
    }

    /// The object points worth sending: continuous with a neighbouring line's (no flying
    /// pixels), off the board (unless board points are kept), not a board fringe, quantised;
    /// with their colour and uncertainty.
    ///
    /// A point is on the board within `board_tol` mm or `board_tol_px` of its own sensitivity
    /// (how far it moves per pixel of stripe error), whichever is larger: at long range a
    /// pixel is several millimetres of depth, and a fixed margin would send the stripe's noise
    /// on the board as object points.
    fn keep(&mut self, reference: Option<&Frame<'_>>) {
        self.out.clear();
        self.rgb.clear();
        self.uncertainty.clear();
        self.verdicts.clear();
        let (cfg, stripe) = (&self.cfg, &self.stripe);
        let fx = self.camera.fx();
        let n = stripe.len();
        for i in 0..n {
            let v = self.verdict(i, fx);
            // one per stripe pixel, at most W: the push cannot fail
            let _ = self.verdicts.push(v);
        }
        if cfg.board_fringe > 0 {
            drop_fringes(stripe, &mut self.verdicts, cfg, fx);
        }
        for (s, v) in self.stripe.iter().zip(&self.verdicts) {
            let send = match v {
                Verdict::Object { .. } => true,
                Verdict::Board => self.cfg.keep_board,
                Verdict::Drop => false,
            };
            let Some(p) = s.point.filter(|_| send) else {
                continue;
            };
            let (Some(x), Some(y), Some(z)) = (quantise(p.x), quantise(p.y), quantise(p.z)) else {
                continue;
            };
            // At most one point per line: W is enough.
            if self.out.push([x, y, z]).is_err() {
                break;
            }
            let _ = self.uncertainty.push(uncertainty_code(s.uncertainty));
            if self.cfg.colour {
                let c = reference.map_or([0; 3], |r| colour_at(r, &s.px));
                let _ = self.rgb.push(c);
            }
        }
    }

    /// What becomes of stripe pixel `i`: dropped (no point, no continuous neighbour, a
    /// silhouette pixel, behind the board), on the board, or an object point.
    fn verdict(&self, i: usize, fx: f32) -> Verdict {
        let (cfg, stripe) = (&self.cfg, &self.stripe);
        let s = &stripe[i];
        let Some(p) = s.point else {
            return Verdict::Drop;
        };
        if cfg.continuity > 0.0 {
            let near = |j: usize| continuous(stripe, i, j, cfg, fx);
            let (before, after) = (i > 0 && near(i - 1), i + 1 < stripe.len() && near(i + 1));
            if !(before || after) {
                return Verdict::Drop;
            }
            // The last line of a run (one side continues, the other jumps or ends) may
            // straddle the silhouette: partly the object, partly what lies behind. Its
            // light is then weaker than its neighbour's, and its ray, through the pixel's
            // centre, misses the lit part by up to half a footprint.
            let j = if before { i - 1 } else { i + 1 };
            if before != after && f32::from(s.peak) < cfg.silhouette * f32::from(stripe[j].peak) {
                return Verdict::Drop;
            }
            // Nearer a run's end than the profile is wide, the profile may be cut by the
            // occluding edge that ends the run: its centre is pulled off the surface.
            let reach = (cfg.edge_reach * s.width) as usize;
            let run = |up: bool| {
                let (mut a, mut k) = (i, 0);
                while k < reach {
                    let b = if up { a + 1 } else { a.wrapping_sub(1) };
                    if b >= stripe.len() || !continuous(stripe, a, b, cfg, fx) {
                        break;
                    }
                    a = b;
                    k += 1;
                }
                k
            };
            if run(false).min(run(true)) < reach {
                return Verdict::Drop;
            }
        }
        let tol = cfg.limits.board_tol.max(cfg.board_tol_px * s.sensitivity);
        match self.board.locate(&p, tol) {
            Ok(Surface::Object) => Verdict::Object {
                near_board: !matches!(self.board.locate(&p, 2.0 * tol), Ok(Surface::Object)),
            },
            Ok(_) if s.at_crease => Verdict::Drop,
            Ok(_) => Verdict::Board,
            Err(_) => Verdict::Drop,
        }
    }
}

/// What becomes of a stripe pixel ([`Head::keep`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// Not sent.
    Drop,
    /// On the board (sent only when board points are kept).
    Board,
    /// An object point; `near_board`: within twice the board tolerance of the board.
    Object { near_board: bool },
}

/// Whether the points of stripe pixels `i` and `j` (at most two lines apart) are continuous:
/// within `continuity` pixel footprints per line (plus 1 mm) of each other in 3-D.
fn continuous(stripe: &[StripePixel], i: usize, j: usize, cfg: &HeadConfig, fx: f32) -> bool {
    let line_of = |px: &Point2<f32>| match cfg.stripe.axis {
        Axis::Columns => px.x,
        Axis::Rows => px.y,
    };
    let (Some(p), Some(q)) = (stripe[i].point, stripe[j].point) else {
        return false;
    };
    let dl = libm::fabsf(line_of(&stripe[j].px) - line_of(&stripe[i].px));
    let footprint = p.coords.norm() / fx;
    dl <= 2.0 && (q - p).norm() <= cfg.continuity * footprint * dl + 1.0
}

/// Board fringes dropped: a run of at most `board_fringe` continuous object points, all within
/// twice the board tolerance of the board, that continues into board points on a side. Where an
/// object's shadow or border clips the light sheet on the board, the board keeps only the sheet's
/// tail for a few lines: its centre is pulled a few pixels, and those lines land just beyond
/// the board tolerance (measured on the accuracy report's scene at 800 mm: runs of 1–4 lines
/// 3.8–4.9 mm in front of the board, the sheet's centre in an object's shadow). An object that
/// stands out of the board that little over so few lines is not told from them.
fn drop_fringes(stripe: &[StripePixel], verdicts: &mut [Verdict], cfg: &HeadConfig, fx: f32) {
    let n = verdicts.len();
    let object = |v: Verdict| matches!(v, Verdict::Object { .. });
    let mut a = 0;
    while a < n {
        if !object(verdicts[a]) {
            a += 1;
            continue;
        }
        // the run a..=b of continuous object points
        let mut b = a;
        while b + 1 < n && object(verdicts[b + 1]) && continuous(stripe, b, b + 1, cfg, fx) {
            b += 1;
        }
        let touches =
            |k: usize, j: usize| verdicts[j] == Verdict::Board && continuous(stripe, k, j, cfg, fx);
        let short = b - a < cfg.board_fringe;
        let near = verdicts[a..=b]
            .iter()
            .all(|v| *v == Verdict::Object { near_board: true });
        let joins = (a > 0 && touches(a, a - 1)) || (b + 1 < n && touches(b, b + 1));
        if short && near && joins {
            verdicts[a..=b].fill(Verdict::Board);
        }
        a = b + 1;
    }
}

/// The valid lines' pixels and rays into `stripe`, and the rays' points on the known surfaces
/// into `known`: the two board planes (within range), and the turntable disc for a ray that
/// meets it first (it lies in front of the board).
fn board_points<const W: usize>(
    ex: &Extraction<'_>,
    locate: Locate,
    camera: &Camera<f32>,
    (board, turntable): (&Board<f32>, Option<&Turntable>),
    cfg: &HeadConfig,
    (stripe, known): (&mut Vec<StripePixel, W>, &mut [Vec<Point3<f32>, W>; 3]),
) {
    stripe.clear();
    for k in known.iter_mut() {
        k.clear();
    }
    let [left, right, on_disc] = known;
    for (line, p) in ex.valid() {
        let Some((at, sigma_px)) = p.located(locate) else {
            continue;
        };
        let px = match cfg.stripe.axis {
            Axis::Columns => Point2::new(line as f32, at),
            Axis::Rows => Point2::new(at, line as f32),
        };
        let Ok(ray) = camera.pixel_to_ray(&px) else {
            continue;
        };
        let width = p.extent(locate);
        // One entry per line of at most W: the pushes cannot fail.
        if stripe
            .push(StripePixel {
                px,
                ray,
                point: None,
                sensitivity: 0.0,
                sigma_px,
                uncertainty: f32::INFINITY,
                peak: p.peak,
                width,
                on_board: None,
                at_crease: false,
            })
            .is_err()
        {
            break;
        }
        let on_board = board
            .intersect_ray(&ray, cfg.limits.min_sin)
            .ok()
            .filter(|(q, _)| q.coords.norm() <= cfg.limits.max_range);
        let disc = turntable.and_then(|t| t.hit(&ray, cfg.limits.min_sin));
        if let Some(d) = disc
            && on_board.is_none_or(|(q, _)| d.z < q.z)
        {
            let _ = on_disc.push(d);
            continue;
        }
        if let Some((q, s)) = on_board {
            if cfg.edge_reach > 0.0 && crease_px(board, &q, camera.fx()) < cfg.edge_reach * width {
                if let Some(last) = stripe.last_mut() {
                    last.at_crease = true;
                }
                continue;
            }
            let side = match s {
                Surface::Left => left.push(q).map(|()| 0),
                Surface::Right => right.push(q).map(|()| 1),
                Surface::Object => continue,
            };
            if let (Ok(side), Some(last)) = (side, stripe.last_mut()) {
                last.on_board = Some((q, side));
            }
        }
    }
}

/// How far board point `q` is from the crease in the image, pixels (`fx`: the focal length).
fn crease_px(board: &Board<f32>, q: &Point3<f32>, fx: f32) -> f32 {
    let c = board.crease();
    let foot = c.point() + c.direction() * (q - c.point()).dot(c.direction());
    let image = |p: &Point3<f32>| nalgebra::Vector2::new(p.x / p.z, p.y / p.z);
    fx * (image(q) - image(&foot)).norm()
}

/// The share of [`HeadConfig::max_plane_tilt`] a plane that rests on the turntable disc may use:
/// the disc's plane comes from its pose in the reference frame, whose own error (a few
/// hundredths of a degree and a few tenths of a millimetre) the fit's residuals do not show.
const DISC_TILT_SHARE: f32 = 0.5;

/// The laser plane from the board points, checked; the reason to skip the frame otherwise. When
/// the board's sheets alone give no plane that passes (a stand or a table hides their lower
/// part, or the stripe on one sheet is too short to fix the plane's tilt), and the stripe
/// crosses the turntable disc, the least-squares plane over the sheets and the disc together;
/// the board-only reason stands when that fails too.
/// A fixed plane as a fit: its scatter as the offset's uncertainty, no tilt.
fn fixed_fit(fixed: &FixedPlane) -> LaserPlane<f32> {
    LaserPlane {
        plane: fixed.plane,
        quality: crate::geometry::LaserQuality {
            rms: 0.0,
            max: 0.0,
            used: 1,
            rejected: 0,
            st_gap: None,
            tilt: 0.0,
            sigma: fixed.sigma,
            centroid: Point3::origin(),
        },
    }
}

fn laser_plane(
    board: &Board<f32>,
    cfg: &HeadConfig,
    [left, right, on_disc]: [&[Point3<f32>]; 3],
) -> Result<LaserPlane<f32>, Skip> {
    let (nl, nr) = (left.len(), right.len());
    let checked = |fit: Result<LaserPlane<f32>, GeomError>, max_tilt: f32| {
        let fit = fit.map_err(|e| match e {
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
        if !(fit.quality.rms <= cfg.max_plane_rms && fit.quality.tilt <= max_tilt) {
            return Err(Skip::PoorPlane);
        }
        Ok(fit)
    };
    let on_board = checked(
        match cfg.method {
            PlaneMethod::LeastSquares => laser::least_squares(left, right, &cfg.laser),
            PlaneMethod::Paper => laser::paper(board, left, right, &cfg.laser),
        },
        cfg.max_plane_tilt,
    );
    match on_board {
        Err(why) if on_disc.len() >= cfg.laser.min_points_per_side => checked(
            laser::least_squares_on(&[left, right, on_disc], &cfg.laser),
            cfg.max_plane_tilt * DISC_TILT_SHARE,
        )
        .map_err(|_| why),
        done => done,
    }
}

/// Each stripe ray's point on the laser plane (within range), its sensitivity and its
/// uncertainty. With the ray `r` (z = 1) meeting the plane `n·x = c` at `t r`, a pixel along the
/// line moves the ray by `step` (the inverse focal length along that image axis, lens distortion
/// neglected) and the point by `t (step − r (n·step)/(n·r))`: the sensitivity, times the centre's
/// uncertainty in pixels, is the stripe's share. The plane's share: a shift `δ` of the plane
/// along its normal moves the point along the ray by `δ / |n·r̂|`.
fn triangulate<const W: usize>(
    fit: &LaserPlane<f32>,
    limits: &Limits<f32>,
    step: Vector3<f32>,
    stripe: &mut Vec<StripePixel, W>,
) {
    let plane: &Plane<f32> = &fit.plane;
    let n = plane.normal();
    for s in stripe.iter_mut() {
        s.point = plane
            .intersect_ray(&s.ray, limits.min_sin)
            .ok()
            .filter(|p| p.coords.norm() <= limits.max_range);
        if let Some(p) = s.point {
            let t = p.z / s.ray.z;
            let along = libm::fabsf(n.dot(&s.ray)) / s.ray.norm();
            s.sensitivity = (step - s.ray * (n.dot(&step) / n.dot(&s.ray))).norm() * t;
            let stripe_part = s.sensitivity * s.sigma_px;
            let plane_part = fit.quality.at(&p) / along;
            s.uncertainty = libm::sqrtf(stripe_part * stripe_part + plane_part * plane_part);
        }
    }
}

/// The calibration's share ([`CalibrationSpread::point_moves`]) added in quadrature to each
/// stripe point's uncertainty. The board points the laser plane rests on are those within three
/// of its residual σ (never less than the inlier tolerance) of it.
fn add_calibration_share<const W: usize>(
    spread: &CalibrationSpread,
    board: &Board<f32>,
    fit: &LaserPlane<f32>,
    stripe: &mut Vec<StripePixel, W>,
    moves: &mut Vec<f32, W>,
) {
    let plane = &fit.plane;
    let near = 3.0 * fit.quality.sigma;
    let on_plane = stripe.iter().filter_map(|s| {
        let (b, side) = s.on_board?;
        (libm::fabsf(plane.signed_distance(&b)) <= near).then_some((s.px, s.ray, b, side))
    });
    let sheets = [board.left(), board.right()].map(|p| (*p.normal(), p.offset()));
    let objects = stripe
        .iter()
        .filter_map(|s| s.point.map(|p| (s.px, s.ray, p)));
    moves.clear();
    let with_point = stripe.iter().filter(|s| s.point.is_some()).count();
    // one per stripe pixel, at most W: the pushes cannot fail
    for _ in 0..with_point {
        let _ = moves.push(0.0);
    }
    spread.point_moves(
        on_plane,
        &sheets,
        (*plane.normal(), plane.offset()),
        objects,
        moves,
    );
    for (s, m) in stripe
        .iter_mut()
        .filter(|s| s.point.is_some())
        .zip(moves.iter())
    {
        s.uncertainty = libm::sqrtf(s.uncertainty * s.uncertainty + m * m);
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
