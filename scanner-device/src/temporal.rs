//! A shadow sweep read through time (Bouguet and Perona's method): each pixel gets the moments
//! the shadow's edges cross it, and each moment its plane of light.
//!
//! Against each pixel's value lit and in the shadow's core (read from the sweep beforehand),
//! the threshold is halfway between them. Going into the shadow and coming out of it, a pixel
//! crosses that threshold once each (a crossing counts once the pixel was clearly on the other
//! side: noise about the threshold is not a crossing). Where it crossed between frames `k` and
//! `k + 1`, an edge lay on one side of it along its image line in frame `k` and on the other in
//! frame `k + 1` (each frame's edges: where it crosses the threshold along each line, to a
//! subpixel, of two polarities — the band's two sides); the moment is where between those two
//! places the pixel lies. Each frame's edges of one polarity on the two board planes, away from
//! the object, are two straight lines of one plane through the lamp: fitted per frame (a frame
//! without one gets the blend of the nearest frames' planes across a short gap, which is why
//! a crossing in such a frame waits for the sweep's end), the plane at the pixel's moment is
//! the blend of the two frames' planes, and the pixel's ray meets it in a point. Each pixel is
//! crossed by two edges — the shadow's way in (leading) and its way out (trailing) — whose
//! points must agree; the pixel's point is their middle (see [`EDGES_AGREE_TIMES`]). A pixel
//! crossed again (the rod went back, or its edge shook) keeps its first crossing where the later
//! ones agree with it.
//!
//! Memory is fixed by the image: about 42 bytes a pixel (its threshold, margin, last value and
//! state, and per edge the frame, depth, spread and place between frames of its crossings),
//! two frames' edge lists and a frame's board points (buffers refilled frame after frame: no
//! allocation once they have grown), and a record a frame for the report. Pixels whose contrast is too
//! low, that were never crossed, or whose crossings disagree get no point and are counted.

use scanner_core::Camera;
use scanner_core::geometry::{Board, Plane, Surface};
use scanner_core::nalgebra::{Matrix3, Point2, Point3, Vector3};
use scanner_core::stripe::Axis;

/// Least difference between a pixel's lit and shadowed values (luma) for it to be read: below
/// it the shadow does not show there (the object's own shadows, black print, a dim flank).
pub const MIN_CONTRAST: u8 = 20;

/// A pixel is clearly lit (or shadowed) when it is above (below) its threshold by more than
/// its contrast over this: as a slow edge passes, noise carries it back and forth across the
/// threshold, which is not the rod coming back.
pub const MARGIN_SHARE: u8 = 6;

/// …and by at least this many DN.
pub const MIN_MARGIN: u8 = 3;

/// Farthest an edge moves between two frames along an image line, pixels: a pixel crossed by
/// an edge that moved farther is given no point (too fast a sweep to place the edge in between).
pub const MAX_STEP_PX: f32 = 40.0;

/// A board point lies on an edge's line (and plane) within this, mm.
pub const PLANE_TOL_MM: f64 = 3.0;

/// A frame's edge plane whose board points scatter more than this (RMS, mm, on either plane)
/// is not used: its lines do not lie in one plane (a line matched on something else).
pub const MAX_PLANE_RMS_MM: f64 = 1.0;

/// A frame without an edge's plane (its lines short beside the object, not in one plane) gets
/// one blended from the nearest frames before and after that have it, when they are at most
/// this many frames apart: the lamp and the rod move smoothly over so few frames.
pub const MAX_PLANE_GAP: u32 = 12;

/// Least share of the frames whose edges lay on a straight line on each board plane that must
/// give that edge's plane: fewer, the edges do not lie in one plane on the board's planes, and
/// the planes are not where the calibration says (the board or the camera moved since, or the
/// calibration is another setup's). Measured on the real frog sweep: 72–77 % with its own
/// planes, 66–75 % with the desk 5 mm off, 27–52 % 10 mm off, under 8 % 20 mm off.
pub const MIN_PLANE_SHARE: f64 = 0.5;

/// Fewest board points on each plane for an edge's plane.
pub const MIN_LINE_POINTS: usize = 20;

/// A point at least this far in front of the board (mm, along its ray) is the object's.
pub const OBJECT_MM: f32 = 5.0;

/// Most frames in one sweep (the report keeps a record of each): 100 000, an hour at 30 frames/s.
pub const MAX_SWEEP_FRAMES: usize = 100_000;

/// The band's shadowed pixels must have moved this far (pixels, summed over frames) before the
/// way it moves decides the lines its edges are placed along.
pub const AXIS_AFTER_PX: f64 = 8.0;

/// A pixel's later crossings by one edge must place it within this many times the two edges'
/// median distance on the board (and at least [`AGREE_MIN_MM`]) from its first: farther, the
/// rod came back at another place (or an edge of something else passed), and the pixel gets
/// no point from that edge.
pub const AGREE_TIMES: f64 = 6.0;

/// The two edges' points of a pixel must lie within this many times their median distance on
/// the board (and at least [`AGREE_MIN_MM`]): farther, one of them was placed by something
/// else than the shadow's edge (the rod's end, an outline), and both are left out. Nearer,
/// they still differ by more than on the board: each edge's plane is fitted where the board
/// lies, and a lamp wider than the rod casts edges whose halfway level lies elsewhere at
/// other distances from the rod (on the real frog sweep 2–4 mm, the 90th percentile 12 mm,
/// against 1 mm on the board); their middle does not move, which is why a pixel's point is
/// the middle of its two edges' points.
pub const EDGES_AGREE_TIMES: f64 = 20.0;

/// See [`AGREE_TIMES`], mm.
pub const AGREE_MIN_MM: f64 = 3.0;

/// A point's kind of edge: the shadow's way in, or its way out.
pub const EDGES: [&str; 2] = ["leading", "trailing"];

/// Why a sweep cannot be read through time.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TemporalError {
    /// The lit or the shadow's frame differs in size from the sweep's frames.
    #[error("frame of {got:?} pixels in a sweep of {expected:?}")]
    FrameSize {
        /// The sweep's width and height.
        expected: (usize, usize),
        /// The frame's.
        got: (usize, usize),
    },
    /// More frames than [`MAX_SWEEP_FRAMES`].
    #[error("more than {MAX_SWEEP_FRAMES} frames in one sweep")]
    TooManyFrames,
}

/// A pixel's crossings, per edge kind (into the shadow, out of it).
#[derive(Debug, Clone, Copy, Default)]
struct Crossing {
    /// Times crossed.
    count: [u8; 2],
    /// The frame the crossing ended in.
    frame: [u32; 2],
    /// The point's depth along the pixel's ray (its `z`, mm), NaN when it got none.
    depth: [f32; 2],
    /// The polarity of the edge that placed it (see [`LineEdges`]).
    polarity: [u8; 2],
    /// How far (in depth, mm) the later crossings would place it from the first.
    spread: [f32; 2],
    /// Where between the frames before and at `frame` the edge passed, when a frame's plane
    /// was missing then: the pixel is placed at the sweep's end on the planes blended across
    /// the gap (NaN: placed already, or not at all).
    fraction: [f32; 2],
}

/// Where a crossing's point comes from.
enum Placed {
    /// Its depth along the ray (mm) and the polarity of the edge that placed it.
    Now(f32, u8),
    /// A frame's plane was missing: the edge's polarity and where between the two frames it
    /// passed, for the sweep's end.
    Later(u8, f32),
}

/// One frame's edges along each image line, per polarity (0: dark to lit going along the
/// line, 1: lit to dark), as subpixel positions.
#[derive(Debug, Clone, Default)]
struct LineEdges {
    /// Start of each line's positions in `at` (one more than lines).
    start: Vec<u32>,
    at: Vec<f32>,
}

impl LineEdges {
    fn line(&self, i: usize) -> &[f32] {
        &self.at[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

/// How one frame's edge plane was fitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct EdgePlaneFit {
    /// The edges' board points made a straight line on each plane (of [`MIN_LINE_POINTS`]
    /// or more): the band was there, and its plane was looked for.
    pub tried: bool,
    /// The plane was found and used.
    pub used: bool,
    /// Board points on its line on the left and the right plane.
    pub points: [u32; 2],
    /// Their RMS distance from the fitted plane, mm.
    pub rms_mm: [f64; 2],
    /// The plane, `[nx, ny, nz, d]`.
    pub plane: [f32; 4],
}

/// What a sweep read through time gave.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TemporalReport {
    /// Frames read.
    pub frames: u32,
    /// The image lines the edges were placed along (`rows` or `columns`), found from the
    /// frames.
    pub along: Option<&'static str>,
    /// Frames whose plane was found, per polarity of edge along the line.
    pub planes: [u32; 2],
    /// Frames whose edges lay on a straight line on each board plane: the band was there,
    /// and its plane was looked for.
    pub planes_tried: [u32; 2],
    /// Frames without one whose plane was blended from frames at most [`MAX_PLANE_GAP`] apart.
    pub planes_blended: [u32; 2],
    /// RMS of the used planes' board points over the sweep, mm: `[polarity][left, right]`.
    pub plane_rms_mm: [[f64; 2]; 2],
    /// Pixels in the picture.
    pub pixels: u64,
    /// Pixels whose lit and shadowed values differ less than [`MIN_CONTRAST`].
    pub low_contrast: u64,
    /// Readable pixels the edge never crossed, per edge kind.
    pub never_crossed: [u64; 2],
    /// Pixels crossed more than once (the rod moved back over them, or its edge shook) whose
    /// crossings would place them farther apart than `crossings_agree_within_mm`: left out, per
    /// edge kind.
    pub crossed_again: [u64; 2],
    /// Pixels crossed more than once whose crossings agree: kept (the first crossing's point).
    pub crossed_agreeing: [u64; 2],
    /// Pixels crossed once with no plane to place them (a frame without one, an edge that
    /// jumped farther than [`MAX_STEP_PX`]), per edge kind.
    pub no_plane: [u64; 2],
    /// Pixels whose two edges' points lie farther apart than `edges_agree_within_mm`: both
    /// left out.
    pub edges_disagree: u64,
    /// Pixels with a point: the middle of their two edges' points.
    pub points_both: u64,
    /// Pixels with a point from one edge only (the other not crossed, without a plane, or
    /// refused), per edge kind.
    pub points_one_edge: [u64; 2],
    /// Pixels of the object: those with a point [`OBJECT_MM`] in front of the board among as
    /// many around them (see [`DENSE_RADIUS_PX`]), and the pixels without one enclosed by them
    /// within [`HOLE_REACH_PX`].
    pub object_pixels: u64,
    /// The object's pixels with a point (either edge).
    pub object_covered: u64,
    /// `object_covered / object_pixels`.
    pub coverage: f64,
    /// On the object's pixels with both edges' points: their distance, mm (median, 90th
    /// percentile), and how many pixels.
    pub edges_apart_mm: [f64; 2],
    /// Pixels the edges' distance was measured on.
    pub edges_compared: u64,
    /// The same on the board's pixels (within [`OBJECT_MM`] of it): the method's own noise.
    pub edges_apart_board_mm: [f64; 2],
    /// The points on the board (within [`OBJECT_MM`] of it): their distance from its planes,
    /// mm (median, 90th percentile) — how flat the desk and the wall come out, a check on
    /// real frames where no other truth is known.
    pub board_off_mm: [f64; 2],
    /// A pixel's two edges' points are used when they lie within this, mm:
    /// [`EDGES_AGREE_TIMES`] the board's median, at least [`AGREE_MIN_MM`].
    pub edges_agree_within_mm: f64,
    /// A pixel's later crossings by one edge must agree with its first within this, mm:
    /// [`AGREE_TIMES`] the board's median, at least [`AGREE_MIN_MM`].
    pub crossings_agree_within_mm: f64,
    /// Each frame's fits, per polarity.
    #[serde(skip)]
    pub fits: Vec<[EdgePlaneFit; 2]>,
}

impl TemporalReport {
    /// The polarity of edge (see [`EdgePlaneFit`]) whose plane was found in fewer than
    /// [`MIN_PLANE_SHARE`] of the frames it was looked for in: the sweep contradicts the
    /// board's planes.
    pub fn contradicted(&self) -> Option<usize> {
        (0..2).find(|&p| {
            f64::from(self.planes[p]) < MIN_PLANE_SHARE * f64::from(self.planes_tried[p])
        })
    }
}

/// A pixel without a point is counted as the object's (a hole) when object pixels lie within
/// this many pixels of it on both sides, along its row or its column.
pub const HOLE_REACH_PX: usize = 8;

/// A pixel whose point lies in front of the board is the object's when at least half the
/// pixels within this many of it (a square) are, or it lies this near to such a pixel: stray
/// points in front of the board (noise in an object's cast shadow, which the lamp never
/// lights) are not an object, nor are the holes between them.
pub const DENSE_RADIUS_PX: usize = 3;

/// Points of one frame interval and edge polarity, ready to send.
#[derive(Debug, Clone)]
pub struct SweepPoints {
    /// The frame the crossings ended in.
    pub frame: u32,
    /// The polarity of the edge that placed them along the image line (0: dark to lit, 1: lit
    /// to dark).
    pub polarity: u8,
    /// That frame's plane of that edge (`[nx, ny, nz, d]`, camera coordinates).
    pub plane: [f32; 4],
    /// Camera coordinates, mm.
    pub points: Vec<[f32; 3]>,
}

/// The sweep being read: see the module's documentation.
pub struct TemporalSweep {
    camera: Camera<f64>,
    board: Board<f64>,
    size: (usize, usize),
    axis: Option<Axis>,
    threshold: Vec<u8>,
    readable: Vec<bool>,
    last: Vec<u8>,
    /// How far past the threshold a pixel must go to count as clearly lit or shadowed.
    margin: Vec<u8>,
    /// Per pixel: bit 0 set once clearly lit since its last crossing into the shadow (the next
    /// one counts), bit 1 once clearly shadowed since its last crossing out.
    armed: Vec<u8>,
    crossing: Vec<Crossing>,
    /// The previous frame's and this frame's edges per polarity.
    edges: [[LineEdges; 2]; 2],
    /// An edge's board points on the left and the right plane (a buffer kept between frames).
    sides: [Vec<Point3<f64>>; 2],
    /// Their planes.
    planes: [[Option<Plane<f64>>; 2]; 2],
    fits: Vec<[EdgePlaneFit; 2]>,
    frames: u32,
    rng: u64,
    luma: Vec<u8>,
    /// The shadowed pixels' centre in the last frame, and how far it has moved each way.
    centre: Option<(f64, f64)>,
    moved: (f64, f64),
}

impl TemporalSweep {
    /// A sweep of frames the size of `lit` (each pixel's value without the shadow) and `dark`
    /// (in the shadow's core), both luma, row by row.
    ///
    /// # Errors
    /// [`TemporalError::FrameSize`] when the two differ in size.
    pub fn new(
        camera: Camera<f64>,
        board: Board<f64>,
        (width, height): (usize, usize),
        lit: &[u8],
        dark: &[u8],
    ) -> Result<Self, TemporalError> {
        let n = width * height;
        for f in [lit, dark] {
            if f.len() != n {
                return Err(TemporalError::FrameSize {
                    expected: (width, height),
                    got: (f.len() / height.max(1), height),
                });
            }
        }
        let threshold = lit
            .iter()
            .zip(dark)
            .map(|(&l, &d)| ((u16::from(l) + u16::from(d)) / 2) as u8)
            .collect();
        let readable = lit
            .iter()
            .zip(dark)
            .map(|(&l, &d)| l.saturating_sub(d) >= MIN_CONTRAST)
            .collect();
        Ok(Self {
            camera,
            board,
            size: (width, height),
            axis: None,
            threshold,
            readable,
            last: Vec::new(),
            margin: lit
                .iter()
                .zip(dark)
                .map(|(&l, &d)| (l.saturating_sub(d) / MARGIN_SHARE).max(MIN_MARGIN))
                .collect(),
            armed: vec![0; n],
            crossing: vec![
                Crossing {
                    depth: [f32::NAN; 2],
                    fraction: [f32::NAN; 2],
                    ..Crossing::default()
                };
                n
            ],
            edges: Default::default(),
            sides: Default::default(),
            planes: [[None; 2]; 2],
            fits: Vec::new(),
            frames: 0,
            rng: 0x9E37_79B9_7F4A_7C15,
            luma: Vec::with_capacity(n),
            centre: None,
            moved: (0.0, 0.0),
        })
    }

    /// Reads the next frame (luma, row by row).
    ///
    /// # Errors
    /// [`TemporalError::FrameSize`] for a frame of another size;
    /// [`TemporalError::TooManyFrames`] beyond [`MAX_SWEEP_FRAMES`].
    pub fn frame(&mut self, luma: &[u8]) -> Result<(), TemporalError> {
        let (w, h) = self.size;
        if luma.len() != w * h {
            return Err(TemporalError::FrameSize {
                expected: self.size,
                got: (luma.len() / h.max(1), h),
            });
        }
        if self.fits.len() >= MAX_SWEEP_FRAMES {
            return Err(TemporalError::TooManyFrames);
        }
        self.luma.clear();
        self.luma.extend_from_slice(luma);
        if self.axis.is_none() {
            self.axis = self.band_axis();
        }
        let mut fit = [EdgePlaneFit::default(); 2];
        self.edges.swap(0, 1);
        self.planes.swap(0, 1);
        if let Some(axis) = self.axis {
            // the frame before last's buffers, refilled: no allocation once they are grown
            let mut edges = std::mem::take(&mut self.edges[1]);
            self.line_edges(axis, &mut edges);
            self.edges[1] = edges;
            for (p, f) in fit.iter_mut().enumerate() {
                let (plane, got) = self.edge_plane(axis, p);
                self.planes[1][p] = plane;
                *f = got;
            }
            if !self.last.is_empty() {
                self.cross(axis);
            }
        }
        self.fits.push(fit);
        std::mem::swap(&mut self.last, &mut self.luma);
        self.frames += 1;
        Ok(())
    }

    /// The lines the band moves along: the way its shadowed pixels' centre moved since the
    /// last frame, summed until it has moved [`AXIS_AFTER_PX`].
    fn band_axis(&mut self) -> Option<Axis> {
        let (w, _) = self.size;
        let (mut n, mut sx, mut sy) = (0u64, 0u64, 0u64);
        for (i, (&v, &t)) in self.luma.iter().zip(&self.threshold).enumerate() {
            if self.readable[i] && v < t {
                n += 1;
                sx += (i % w) as u64;
                sy += (i / w) as u64;
            }
        }
        let centre = (n > 0).then(|| (sx as f64 / n as f64, sy as f64 / n as f64));
        if let (Some(now), Some(before)) = (centre, self.centre) {
            self.moved.0 += (now.0 - before.0).abs();
            self.moved.1 += (now.1 - before.1).abs();
        }
        self.centre = centre;
        let (mx, my) = self.moved;
        if mx.max(my) < AXIS_AFTER_PX {
            return None;
        }
        Some(if mx >= my { Axis::Rows } else { Axis::Columns })
    }

    /// Lines and positions along them: rows (x along y) or columns (y along x).
    fn line_shape(&self, axis: Axis) -> (usize, usize, usize, usize) {
        let (w, h) = self.size;
        match axis {
            // (lines, length, stride between lines, stride along a line)
            Axis::Rows => (h, w, w, 1),
            Axis::Columns => (w, h, 1, w),
        }
    }

    fn pixel(&self, axis: Axis, line: usize, at: f64) -> Point2<f64> {
        match axis {
            Axis::Rows => Point2::new(at, line as f64),
            Axis::Columns => Point2::new(line as f64, at),
        }
    }

    /// This frame's threshold crossings along every line, per polarity.
    fn line_edges(&self, axis: Axis, out: &mut [LineEdges; 2]) {
        let (lines, len, step_line, step) = self.line_shape(axis);
        for e in out.iter_mut() {
            e.start.clear();
            e.at.clear();
            e.start.push(0);
        }
        for l in 0..lines {
            let base = l * step_line;
            for a in 0..len.saturating_sub(1) {
                let (i, j) = (base + a * step, base + (a + 1) * step);
                if !(self.readable[i] && self.readable[j]) {
                    continue;
                }
                let da = i32::from(self.luma[i]) - i32::from(self.threshold[i]);
                let db = i32::from(self.luma[j]) - i32::from(self.threshold[j]);
                let polarity = match (da < 0, db < 0) {
                    (true, false) => 0,
                    (false, true) => 1,
                    _ => continue,
                };
                let t = da as f32 / (da - db) as f32;
                out[polarity].at.push(a as f32 + t);
            }
            for e in out.iter_mut() {
                e.start.push(e.at.len() as u32);
            }
        }
    }

    fn next_random(&mut self, n: usize) -> usize {
        // xorshift64*: a fixed sequence, so that a sweep gives the same planes every time
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        ((self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 33) as usize) % n.max(1)
    }

    /// The plane of this frame's edges of `polarity`: their board points fall on two lines
    /// (one per board plane) of one plane, which must be neither board plane.
    fn edge_plane(&mut self, axis: Axis, polarity: usize) -> (Option<Plane<f64>>, EdgePlaneFit) {
        let (lines, ..) = self.line_shape(axis);
        let mut sides = std::mem::take(&mut self.sides);
        for s in &mut sides {
            s.clear();
        }
        for l in 0..lines {
            for &at in self.edges[1][polarity].line(l) {
                let px = self.pixel(axis, l, f64::from(at));
                let Ok(ray) = self.camera.pixel_to_ray(&px) else {
                    continue;
                };
                if let Ok((p, s)) = self.board.intersect_ray(&ray, 0.05) {
                    sides[usize::from(s == Surface::Right)].push(p);
                }
            }
        }
        let lines = [0, 1].map(|s| {
            (sides[s].len() >= MIN_LINE_POINTS)
                .then(|| self.line(&sides[s]))
                .flatten()
        });
        let mut fit = EdgePlaneFit {
            tried: lines.iter().all(Option::is_some),
            ..EdgePlaneFit::default()
        };
        let plane = self.two_lines(&sides, &lines);
        if let Some(plane) = plane {
            for (s, pts) in sides.iter().enumerate() {
                let (n, sq) = pts
                    .iter()
                    .map(|p| plane.signed_distance(p))
                    .filter(|r| r.abs() < PLANE_TOL_MM)
                    .fold((0u32, 0.0), |(n, sq), r| (n + 1, sq + r * r));
                fit.points[s] = n;
                fit.rms_mm[s] = (sq / f64::from(n.max(1))).sqrt();
            }
        }
        self.sides = sides;
        let Some(plane) = plane else {
            return (None, fit);
        };
        let (n, d) = (plane.normal(), plane.offset());
        fit.plane = [n.x as f32, n.y as f32, n.z as f32, d as f32];
        fit.used = fit.points.iter().all(|&n| n as usize >= MIN_LINE_POINTS)
            && fit.rms_mm.iter().all(|&r| r <= MAX_PLANE_RMS_MM);
        (fit.used.then_some(plane), fit)
    }

    /// A plane through a line of one side's points and as many of the other's as it can take:
    /// the line found first on either side (consensus of pairs), the plane's last degree of
    /// freedom from the other side's points (consensus of single points), then refitted by
    /// least squares to both sides' points near it.
    fn two_lines(
        &mut self,
        sides: &[Vec<Point3<f64>>; 2],
        lines: &[Option<(Point3<f64>, Point3<f64>)>; 2],
    ) -> Option<Plane<f64>> {
        if sides.iter().any(|s| s.len() < MIN_LINE_POINTS) {
            return None;
        }
        let boards = [*self.board.left().normal(), *self.board.right().normal()];
        let near = |p: &Plane<f64>, q: &Point3<f64>| p.signed_distance(q).abs() < PLANE_TOL_MM;
        let mut best: Option<(usize, Plane<f64>)> = None;
        for first in 0..2 {
            let Some((a, b)) = lines[first] else {
                continue;
            };
            let other = &sides[1 - first];
            for _ in 0..200 {
                let c = other[self.next_random(other.len())];
                let Ok(p) = Plane::new((b - a).cross(&(c - a)), 0.0) else {
                    continue;
                };
                // a board plane holds all of its own side's points: not an edge's
                if boards.iter().any(|m| m.dot(p.normal()).abs() > 0.985) {
                    continue;
                }
                let Ok(p) = Plane::from_point_normal(&a, p.normal()) else {
                    continue;
                };
                let n = sides.iter().flatten().filter(|q| near(&p, q)).count();
                if best.as_ref().is_none_or(|(m, _)| n > *m) {
                    best = Some((n, p));
                }
            }
        }
        let (_, mut plane) = best?;
        for _ in 0..3 {
            let inliers = || sides.iter().flatten().filter(|q| near(&plane, q));
            if inliers().count() < 2 * MIN_LINE_POINTS {
                return None;
            }
            plane = least_squares_plane(inliers())?;
            if boards.iter().any(|m| m.dot(plane.normal()).abs() > 0.985) {
                return None;
            }
        }
        Some(plane)
    }

    /// Two points of the straight line most of `pts` lie on (within [`PLANE_TOL_MM`]).
    fn line(&mut self, pts: &[Point3<f64>]) -> Option<(Point3<f64>, Point3<f64>)> {
        let off = |a: &Point3<f64>, d: &Vector3<f64>, p: &Point3<f64>| {
            let v = p - a;
            (v - d * v.dot(d)).norm()
        };
        let mut best: Option<(usize, Point3<f64>, Vector3<f64>)> = None;
        for _ in 0..200 {
            let (a, b) = (
                pts[self.next_random(pts.len())],
                pts[self.next_random(pts.len())],
            );
            let d = b - a;
            if d.norm() < 5.0 {
                continue;
            }
            let d = d.normalize();
            let n = pts.iter().filter(|p| off(&a, &d, p) < PLANE_TOL_MM).count();
            if best.as_ref().is_none_or(|(m, ..)| n > *m) {
                best = Some((n, a, d));
            }
        }
        let (n, a, d) = best?;
        if n < MIN_LINE_POINTS {
            return None;
        }
        // its ends among the points on it
        let (lo, hi) = pts
            .iter()
            .filter(|p| off(&a, &d, p) < PLANE_TOL_MM)
            .map(|p| (p - a).dot(&d))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), t| {
                (l.min(t), h.max(t))
            });
        Some((a + d * lo, a + d * hi))
    }

    /// The pixels that crossed the threshold between the last frame and this one.
    fn cross(&mut self, axis: Axis) {
        let (w, _) = self.size;
        let frame = self.frames;
        for i in 0..self.luma.len() {
            if !self.readable[i] {
                continue;
            }
            let t = i32::from(self.threshold[i]);
            let (da, db) = (i32::from(self.last[i]) - t, i32::from(self.luma[i]) - t);
            let (v, m) = (i32::from(self.luma[i]), i32::from(self.margin[i]));
            let armed = self.armed[i];
            self.armed[i] |= u8::from(v > t + m) | (u8::from(v < t - m) << 1);
            let kind = match (da < 0, db < 0) {
                (false, true) => 0,
                (true, false) => 1,
                _ => continue,
            };
            // a crossing counts once the pixel has been clearly on the side it leaves since
            // its last crossing that way: noise about the threshold as a slow edge passes is
            // not the rod coming back
            if armed & (1 << kind) == 0 {
                continue;
            }
            self.armed[i] &= !(1 << kind);
            let c = &mut self.crossing[i];
            c.count[kind] = c.count[kind].saturating_add(1);
            let (x, y) = (i % w, i / w);
            let (line, at) = match axis {
                Axis::Rows => (y, x as f32),
                Axis::Columns => (x, y as f32),
            };
            let Some(placed) = self.place(line, at, Point2::new(x as f64, y as f64)) else {
                continue;
            };
            // every crossing places the pixel by its edge's plane at that moment: the first
            // is kept, the later ones say how far from it they would put it (not known when
            // either waits for the sweep's end: those are left out)
            let c = &mut self.crossing[i];
            let first = c.depth[kind].is_nan() && c.fraction[kind].is_nan();
            match placed {
                Placed::Now(depth, polarity) if first => {
                    c.depth[kind] = depth;
                    c.polarity[kind] = polarity;
                    c.frame[kind] = frame;
                }
                Placed::Later(polarity, f) if first => {
                    c.fraction[kind] = f;
                    c.polarity[kind] = polarity;
                    c.frame[kind] = frame;
                }
                Placed::Now(depth, _) if c.depth[kind].is_finite() => {
                    c.spread[kind] = c.spread[kind].max((depth - c.depth[kind]).abs());
                }
                _ => c.spread[kind] = f32::INFINITY,
            }
        }
    }

    /// The point of the pixel at `at` on `line` crossed between the last frame and this one:
    /// of the edges of either polarity that passed it (on one side of it before, on the other
    /// now), the one that moved least whose point lies in front of the board, its plane
    /// blended at where between its two places the pixel lies (the edge that passed is that
    /// one; an edge that seems to have passed but puts the point behind the board is another
    /// of the line's crossings, the object's or the band's other side). Where that edge's
    /// plane is missing in either frame, the pixel waits for the sweep's end.
    fn place(&self, line: usize, at: f32, px: Point2<f64>) -> Option<Placed> {
        let mut passed: [(f32, usize, f32); 4] = [(f32::INFINITY, 0, 0.0); 4];
        for p in 0..2 {
            let nearest = |e: &[f32], side: f32| {
                e.iter()
                    .map(|&x| x - at)
                    .filter(|d| d * side > 0.0 || *d == 0.0)
                    .map(f32::abs)
                    .fold(f32::INFINITY, f32::min)
            };
            let (before, now) = (self.edges[0][p].line(line), self.edges[1][p].line(line));
            for (k, side) in [-1.0f32, 1.0].into_iter().enumerate() {
                let (db, dn) = (nearest(before, side), nearest(now, -side));
                let span = db + dn;
                if span.is_finite() && span > 0.0 && span <= MAX_STEP_PX {
                    passed[2 * p + k] = (span, p, db / span);
                }
            }
        }
        passed.sort_by(|a, b| a.0.total_cmp(&b.0));
        let ray = self.camera.pixel_to_ray(&px).ok()?;
        let board = self.board_depth(&ray);
        passed
            .iter()
            .take_while(|(span, ..)| span.is_finite())
            .find_map(|&(_, p, f)| match (self.planes[0][p], self.planes[1][p]) {
                (Some(a), Some(b)) => {
                    let z = depth_on(&blend(&a, &b, f64::from(f))?, &ray, board)?;
                    Some(Placed::Now(z, p as u8))
                }
                _ => Some(Placed::Later(p as u8, f)),
            })
    }

    /// The board's depth behind `ray` and how far in front of it a point may still be taken
    /// as on it (mm, along z): infinite where the ray misses the board.
    fn board_depth(&self, ray: &Vector3<f64>) -> (f64, f64) {
        let board = self
            .board
            .intersect_ray(ray, 0.05)
            .map_or(f64::INFINITY, |(q, _)| q.z);
        (board, PLANE_TOL_MM * ray.z / ray.norm())
    }

    /// Each frame's plane per polarity: the frame's own, or blended across a gap of at most
    /// [`MAX_PLANE_GAP`] frames between two that have one.
    fn timeline(&self) -> (Vec<FramePlanes>, [u32; 2]) {
        let mut out: Vec<FramePlanes> = self
            .fits
            .iter()
            .map(|f| f.map(|fit| fit.used.then(|| fit_plane(&fit)).flatten()))
            .collect();
        let mut blended = [0; 2];
        for p in 0..2 {
            let mut last: Option<usize> = None;
            for k in 0..out.len() {
                if out[k][p].is_none() {
                    continue;
                }
                if let Some(j) = last
                    && k - j > 1
                    && (k - j) as u32 <= MAX_PLANE_GAP + 1
                    && let (Some(a), Some(b)) = (out[j][p], out[k][p])
                {
                    for (m, planes) in out[j + 1..k].iter_mut().enumerate() {
                        let f = (m + 1) as f64 / (k - j) as f64;
                        planes[p] = blend(&a, &b, f);
                        blended[p] += u32::from(planes[p].is_some());
                    }
                }
                last = Some(k);
            }
        }
        (out, blended)
    }

    /// The points of pixels crossed once, grouped by frame and polarity, and the report.
    pub fn finish(self) -> (Vec<SweepPoints>, TemporalReport) {
        let (w, h) = self.size;
        let mut report = TemporalReport {
            frames: self.frames,
            along: self.axis.map(|a| match a {
                Axis::Rows => "rows",
                Axis::Columns => "columns",
            }),
            planes: [0; 2],
            planes_tried: [0; 2],
            planes_blended: [0; 2],
            plane_rms_mm: [[0.0; 2]; 2],
            pixels: (w * h) as u64,
            low_contrast: 0,
            never_crossed: [0; 2],
            crossed_again: [0; 2],
            crossed_agreeing: [0; 2],
            no_plane: [0; 2],
            edges_disagree: 0,
            points_both: 0,
            points_one_edge: [0; 2],
            object_pixels: 0,
            object_covered: 0,
            coverage: 0.0,
            edges_apart_mm: [f64::NAN; 2],
            edges_compared: 0,
            edges_apart_board_mm: [f64::NAN; 2],
            board_off_mm: [f64::NAN; 2],
            edges_agree_within_mm: f64::NAN,
            crossings_agree_within_mm: f64::NAN,
            fits: Vec::new(),
        };
        let (timeline, blended) = self.timeline();
        report.planes_blended = blended;
        for f in &self.fits {
            for (p, fit) in f.iter().enumerate() {
                report.planes_tried[p] += u32::from(fit.tried);
                if fit.used {
                    report.planes[p] += 1;
                    for s in 0..2 {
                        report.plane_rms_mm[p][s] += fit.rms_mm[s] * fit.rms_mm[s];
                    }
                }
            }
        }
        for p in 0..2 {
            for s in 0..2 {
                report.plane_rms_mm[p][s] =
                    (report.plane_rms_mm[p][s] / f64::from(report.planes[p].max(1))).sqrt();
            }
        }
        // each readable pixel's ray (scaled to z = 1), the board's depth behind it, its points
        let mut placed: Vec<(usize, Vector3<f64>, f32, [f32; 2])> = Vec::new();
        for (i, c) in self.crossing.iter().enumerate() {
            if !self.readable[i] {
                report.low_contrast += 1;
                continue;
            }
            let Ok(ray) = self
                .camera
                .pixel_to_ray(&Point2::new((i % w) as f64, (i / w) as f64))
            else {
                continue;
            };
            let board = self.board_depth(&ray);
            let mut depths = [f32::NAN; 2];
            for (k, d) in depths.iter_mut().enumerate() {
                if c.count[k] == 0 {
                    report.never_crossed[k] += 1;
                    continue;
                }
                *d = if c.depth[k].is_finite() {
                    c.depth[k]
                } else {
                    self.later(c, k, &timeline, &ray, board).unwrap_or(f32::NAN)
                };
                if d.is_nan() {
                    report.no_plane[k] += 1;
                }
            }
            if depths.iter().all(|d| d.is_nan()) {
                continue;
            }
            placed.push((i, ray / ray.z, board.0 as f32, depths));
        }
        // how far apart the two edges' points lie on the board (the method's noise there), and
        // the agreement asked of them everywhere
        let along = |ray: &Vector3<f64>| ray.norm() as f32;
        let mut board_apart: Vec<f64> = placed
            .iter()
            .filter(|(_, r, behind, d)| d.iter().all(|z| (behind - z).abs() * along(r) < OBJECT_MM))
            .map(|(_, r, _, d)| f64::from((d[0] - d[1]).abs() * along(r)))
            .collect();
        if !board_apart.is_empty() {
            board_apart.sort_by(f64::total_cmp);
            report.edges_apart_board_mm = [
                board_apart[board_apart.len() / 2],
                board_apart[board_apart.len() * 9 / 10],
            ];
        }
        let within = |times: f64| {
            let mm = (times * report.edges_apart_board_mm[0]).max(AGREE_MIN_MM);
            if mm.is_finite() { mm } else { AGREE_MIN_MM }
        };
        let (agree, recross) = (within(EDGES_AGREE_TIMES), within(AGREE_TIMES));
        report.edges_agree_within_mm = agree;
        report.crossings_agree_within_mm = recross;
        let mut buckets: std::collections::BTreeMap<(u32, u8), Vec<[f32; 3]>> =
            std::collections::BTreeMap::new();
        let mut object = vec![false; w * h];
        let mut has_point = vec![false; w * h];
        let mut apart = Vec::new();
        let mut board_off = Vec::new();
        for (i, ray, behind, mut depths) in placed {
            let c = &self.crossing[i];
            for (k, d) in depths.iter_mut().enumerate() {
                if c.count[k] > 1 && d.is_finite() {
                    if f64::from(c.spread[k] * along(&ray)) > recross {
                        report.crossed_again[k] += 1;
                        *d = f32::NAN;
                    } else {
                        report.crossed_agreeing[k] += 1;
                    }
                }
            }
            if depths.iter().all(|d| d.is_nan()) {
                continue;
            }
            let gap = f64::from((depths[0] - depths[1]).abs() * along(&ray));
            let z = if depths[0].is_finite() {
                depths[0]
            } else {
                depths[1]
            };
            object[i] = (behind - z) * along(&ray) > OBJECT_MM;
            if gap > agree {
                report.edges_disagree += 1;
                continue;
            }
            has_point[i] = true;
            if object[i] && gap.is_finite() {
                apart.push(gap);
            }
            // the middle of the two edges' points, sent with the first edge that gave one
            let k = usize::from(depths[0].is_nan());
            let z = if gap.is_finite() {
                report.points_both += 1;
                0.5 * (depths[0] + depths[1])
            } else {
                report.points_one_edge[k] += 1;
                depths[k]
            };
            if !object[i] {
                board_off.push(f64::from((behind - z).abs() * along(&ray)));
            }
            let p = ray * f64::from(z);
            buckets
                .entry((c.frame[k], c.polarity[k]))
                .or_default()
                .push([p.x as f32, p.y as f32, p.z as f32]);
        }
        let region = fill_holes(
            &dense(&object, (w, h), DENSE_RADIUS_PX),
            (w, h),
            HOLE_REACH_PX,
        );
        report.object_pixels = region.iter().filter(|&&r| r).count() as u64;
        report.object_covered = region
            .iter()
            .zip(&has_point)
            .filter(|(r, p)| **r && **p)
            .count() as u64;
        report.coverage = report.object_covered as f64 / report.object_pixels.max(1) as f64;
        if !board_off.is_empty() {
            board_off.sort_by(f64::total_cmp);
            let n = board_off.len();
            report.board_off_mm = [board_off[n / 2], board_off[n * 9 / 10]];
        }
        report.edges_compared = apart.len() as u64;
        if !apart.is_empty() {
            apart.sort_by(f64::total_cmp);
            report.edges_apart_mm = [apart[apart.len() / 2], apart[apart.len() * 9 / 10]];
        }
        let sweep = buckets
            .into_iter()
            .map(|((frame, polarity), points)| SweepPoints {
                frame,
                polarity,
                plane: timeline
                    .get(frame as usize)
                    .and_then(|f| f[usize::from(polarity)])
                    .map_or([0.0; 4], |p| {
                        let n = p.normal();
                        [n.x as f32, n.y as f32, n.z as f32, p.offset() as f32]
                    }),
                points,
            })
            .collect();
        report.fits = self.fits;
        (sweep, report)
    }
}

impl TemporalSweep {
    /// The depth of a crossing that waited for the sweep's end, on the planes of its two
    /// frames from `timeline`.
    fn later(
        &self,
        c: &Crossing,
        k: usize,
        timeline: &[FramePlanes],
        ray: &Vector3<f64>,
        board: (f64, f64),
    ) -> Option<f32> {
        let (frame, p) = (c.frame[k] as usize, usize::from(c.polarity[k]));
        if c.fraction[k].is_nan() || frame == 0 {
            return None;
        }
        let a = timeline.get(frame - 1)?[p]?;
        let b = timeline.get(frame)?[p]?;
        depth_on(&blend(&a, &b, f64::from(c.fraction[k]))?, ray, board)
    }
}

/// A frame's plane per edge polarity, where it has one.
type FramePlanes = [Option<Plane<f64>>; 2];

/// The plane `f` of the way from `a` to `b` (their normals turned to one side first).
fn blend(a: &Plane<f64>, b: &Plane<f64>, f: f64) -> Option<Plane<f64>> {
    let sign = if a.normal().dot(b.normal()) < 0.0 {
        -1.0
    } else {
        1.0
    };
    Plane::new(
        a.normal() * (1.0 - f) + b.normal() * (sign * f),
        a.offset() * (1.0 - f) + b.offset() * (sign * f),
    )
    .ok()
}

/// Where `ray` meets `plane` (its depth, mm), if in front of the camera and not behind the
/// board (`board`: its depth there and the tolerance, see [`TemporalSweep::board_depth`]).
fn depth_on(plane: &Plane<f64>, ray: &Vector3<f64>, (board, tolerance): (f64, f64)) -> Option<f32> {
    let point = plane.intersect_ray(ray, 0.01).ok()?;
    (point.z > 0.0 && point.z <= board + tolerance).then_some(point.z as f32)
}

/// A fit's plane, as fitted.
fn fit_plane(fit: &EdgePlaneFit) -> Option<Plane<f64>> {
    let [x, y, z, d] = fit.plane.map(f64::from);
    Plane::new(Vector3::new(x, y, z), d).ok()
}

/// The pixels of `mask` that are, or lie within the square of `radius` of, pixels with at least
/// half of that square (clipped to the picture) in `mask`: a solid region whole, corners and
/// thin parts beside it included, without the stray pixels away from it.
fn dense(mask: &[bool], (w, h): (usize, usize), radius: usize) -> Vec<bool> {
    let core: Vec<bool> = window_counts(mask, (w, h), radius)
        .into_iter()
        .zip(mask)
        .map(|((n, area), &m)| m && 2 * n >= area)
        .collect();
    window_counts(&core, (w, h), radius)
        .into_iter()
        .zip(mask)
        .map(|((n, _), &m)| m && n > 0)
        .collect()
}

/// For each pixel, how many of the square of `radius` around it (clipped to the picture) are
/// in `mask`, and how many pixels that square has.
fn window_counts(mask: &[bool], (w, h): (usize, usize), radius: usize) -> Vec<(u32, u32)> {
    // summed-area table, one row and one column of zeros first
    let mut sum = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0;
        for x in 0..w {
            row += u32::from(mask[y * w + x]);
            sum[(y + 1) * (w + 1) + x + 1] = sum[y * (w + 1) + x + 1] + row;
        }
    }
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (x0, y0) = (x.saturating_sub(radius), y.saturating_sub(radius));
            let (x1, y1) = ((x + radius + 1).min(w), (y + radius + 1).min(h));
            let at = |x: usize, y: usize| sum[y * (w + 1) + x];
            let n = at(x1, y1) + at(x0, y0) - at(x0, y1) - at(x1, y0);
            (n, ((x1 - x0) * (y1 - y0)) as u32)
        })
        .collect()
}

/// `mask` with the gaps it encloses filled: a pixel outside it is the object's when the mask
/// lies within `reach` pixels of it on both sides, along its row or along its column.
fn fill_holes(mask: &[bool], (w, h): (usize, usize), reach: usize) -> Vec<bool> {
    let mut out = mask.to_vec();
    let within = |i: usize, step: isize, n: usize, pos: usize, len: usize| {
        (1..=reach).any(|k| {
            let p = pos as isize + step.signum() * k as isize;
            p >= 0 && (p as usize) < len && mask[(i as isize + step * k as isize) as usize]
        }) && n > 0
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if mask[i] {
                continue;
            }
            let row = within(i, -1, 1, x, w) && within(i, 1, 1, x, w);
            let col = within(i, -(w as isize), 1, y, h) && within(i, w as isize, 1, y, h);
            out[i] = row || col;
        }
    }
    out
}

/// The plane nearest `pts` (least squares).
fn least_squares_plane<'a>(
    pts: impl Iterator<Item = &'a Point3<f64>> + Clone,
) -> Option<Plane<f64>> {
    let (n, sum) = pts.clone().fold((0usize, Vector3::zeros()), |(n, s), p| {
        (n + 1, s + p.coords)
    });
    let c = sum / n.max(1) as f64;
    let mut m = Matrix3::zeros();
    for p in pts {
        let v = p.coords - c;
        m += v * v.transpose();
    }
    let e = m.symmetric_eigen();
    let n: Vector3<f64> = e.eigenvectors.column(e.eigenvalues.imin()).into();
    Plane::from_point_normal(&Point3::from(c), &n).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaps narrower than the reach between the object's pixels are its own; wider ones are
    /// not, nor is what lies beyond its outline.
    #[test]
    fn holes_within_reach_are_the_objects() {
        let (w, h) = (40, 5);
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in (2..8).chain(12..14).chain(32..35) {
                mask[y * w + x] = true;
            }
        }
        let filled = fill_holes(&mask, (w, h), HOLE_REACH_PX);
        // 8..12 (4 px) filled; 14..32 (18 px, more than the reach each way) not; 0..2 and
        // 35.. lie outside
        assert!((8..12).all(|x| filled[2 * w + x]));
        assert!((14..32).all(|x| !filled[2 * w + x]));
        assert!(!filled[2 * w] && !filled[2 * w + 36]);
    }

    /// Frames of another size than the sweep's lit and shadowed values are refused by size.
    #[test]
    fn stray_pixels_are_not_dense() {
        let (w, h) = (20, 20);
        let mut mask = vec![false; w * h];
        // a solid block with a thin arm, and apart from it a scatter of single pixels
        for y in 2..10 {
            for x in 2..10 {
                mask[y * w + x] = true;
            }
        }
        mask[5 * w + 10] = true;
        mask[5 * w + 11] = true;
        for (x, y) in [(15, 3), (17, 5), (14, 15), (18, 18), (5, 16)] {
            mask[y * w + x] = true;
        }
        let d = dense(&mask, (w, h), 2);
        assert!(
            d[5 * w + 5] && d[2 * w + 2] && d[9 * w + 9],
            "the block's corners stay"
        );
        assert!(d[5 * w + 10] && d[5 * w + 11], "and its arm");
        for (x, y) in [(15, 3), (17, 5), (14, 15), (18, 18), (5, 16)] {
            assert!(!d[y * w + x], "({x}, {y})");
        }
        assert_eq!(d.iter().filter(|&&b| b).count(), 66);
    }

    #[test]
    fn frames_of_another_size_are_refused() {
        let camera = Camera::paper(600.0, 8, 4).unwrap();
        let board = Board::new(
            Plane::new(Vector3::new(0.0, 0.6, -0.8), 500.0).unwrap(),
            Plane::new(Vector3::new(0.0, -0.6, -0.8), 500.0).unwrap(),
        )
        .unwrap();
        let (lit, dark) = ([200u8; 32], [20u8; 32]);
        assert!(matches!(
            TemporalSweep::new(camera, board, (8, 4), &lit, &dark[..31]),
            Err(TemporalError::FrameSize { .. })
        ));
        let mut sweep = TemporalSweep::new(camera, board, (8, 4), &lit, &dark).unwrap();
        assert_eq!(
            sweep.frame(&[0u8; 24]),
            Err(TemporalError::FrameSize {
                expected: (8, 4),
                got: (6, 4)
            })
        );
        sweep.frame(&lit).unwrap();
        let (points, report) = sweep.finish();
        assert!(points.is_empty());
        assert_eq!((report.frames, report.pixels), (1, 32));
        assert_eq!(report.never_crossed, [32, 32]);
    }
}
