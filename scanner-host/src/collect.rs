//! From bytes to the grid: the streaming decoder (any chunks, resynchronising, counting every
//! rejection), the journal ([`crate::journal`]: every accepted frame appended and flushed as it
//! arrives), and the grid.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use scanner_core::nalgebra::{
    Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3,
};
use scanner_core::{Camera, GeomError};
use scanner_wire::{
    Controls, DecodeStats, Decoder, DiscFound, DiscPose, FixedLaser, Header, MAX_ENCODED, Message,
    Notice, Planes, PreviewState, SKIP_REASONS, Status, points,
};

use crate::grid::{Cell, Grid, GridError};
pub use crate::journal::{Journal, JournalError};

/// Why the collection cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum CollectError {
    /// The journal could not be written (nothing received is dropped from memory).
    #[error(transparent)]
    Journal(#[from] JournalError),
    /// The header's camera is not a camera.
    #[error("the header's camera is unusable")]
    Camera(#[source] GeomError),
    /// The grid cannot be built for the header.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The first header describes no usable scan (a corrupt or crafted header).
    #[error("the header of scan {scan_id:08x}: {why}")]
    Header {
        /// Its scan.
        scan_id: u32,
        /// What is wrong.
        why: String,
    },
}

type Result<T, E = CollectError> = std::result::Result<T, E>;

/// Settings of the collection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollectOptions {
    /// Grid cell.
    pub cell: Cell,
    /// Outlier threshold of a cell, mm (at least; 3σ of the cell's samples otherwise).
    pub outlier_mm: f32,
    /// Point packets kept while no header has arrived yet (a host that joins mid-stream).
    pub pending_max: usize,
}

impl Default for CollectOptions {
    fn default() -> Self {
        CollectOptions {
            cell: Cell::Pixels(2.0),
            outlier_mm: 2.0,
            pending_max: 256,
        }
    }
}

/// What arrived.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Counts {
    /// The decoder's counts (frames, bytes, rejections by kind).
    pub decode: DecodeStats,
    /// Headers received.
    pub headers: u64,
    /// Point packets received.
    pub packets: u64,
    /// Points received.
    pub points: u64,
    /// Points in the grid (not outside, not outliers).
    pub gridded: u64,
    /// Packets whose point data did not decode.
    pub bad_points: u64,
    /// Packets dropped because no header came within `pending_max` packets.
    pub no_header: u64,
    /// Point packets received again (same scan and frame: a duplicated frame on the link), not
    /// counted twice.
    pub duplicates: u64,
    /// Scans seen.
    pub scans: BTreeSet<u32>,
    /// Scans left out of the grid because their header's image size or camera differs from the
    /// first scan's (their points would be ghosts in its grid); their frames are in the journal.
    pub other_camera: BTreeSet<u32>,
    /// Points of those scans.
    pub other_camera_points: u64,
    /// The latest status of each scan.
    pub status: BTreeMap<u32, Status>,
    /// The camera controls of each scan, as its head reported them.
    pub controls: BTreeMap<u32, Controls>,
    /// The latest laser-plane fit of each scan, as its head reported it.
    pub planes: BTreeMap<u32, Planes>,
    /// What the head found of the turntable disc in each scan, as it reported it.
    pub discs: BTreeMap<u32, DiscPose>,
    /// Each fixed-laser scan's platform, by scan id.
    pub fixed: BTreeMap<u32, FixedLaser>,
    /// Frames' measured turns (a platform's markers), radians, by scan id and frame (at most
    /// [`MAX_TURNS`]; more are counted in `turns_not_kept`).
    pub turns: BTreeMap<(u32, u32), f64>,
    /// Measured turns beyond [`MAX_TURNS`], not kept.
    pub turns_not_kept: u64,
    /// Frames' points not kept for a fixed-laser model: beyond [`MAX_KEPT_POINTS`].
    pub not_kept: u64,
    /// Capture time span of the points, µs (first, last).
    pub time_us: Option<(u64, u64)>,
    /// The head's prompts and events, in order (the latest [`MAX_NOTICES`]).
    pub notices: VecDeque<Notice>,
    /// Preview pictures received (`scanner-device preview`).
    pub previews: u64,
}

/// Notices kept in [`Counts::notices`] (a head repeats none; this bounds a hostile stream).
pub const MAX_NOTICES: usize = 64;

/// Most frames' measured turns kept ([`Counts::turns`]): a turn of a million frames.
pub const MAX_TURNS: usize = 1 << 20;

/// A preview picture as received ([`scanner_wire::Preview`], owned).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PreviewImage {
    /// Its session.
    pub scan_id: u32,
    /// The frame's number.
    pub frame: u32,
    /// Thumbnail width and height, pixels.
    pub size: (u16, u16),
    /// Camera pixels per thumbnail pixel.
    pub scale: u16,
    /// Luma, row by row.
    pub pixels: Vec<u8>,
    /// The dark dots found, thumbnail pixels.
    pub markers: Vec<[u8; 2]>,
    /// `true`: [`PreviewImage::stripe`] has one entry per row (a vertical line).
    pub rows: bool,
    /// The laser line's position along each thumbnail column (or row), 255 where none.
    pub stripe: Vec<u8>,
    /// Clipped pixels, per mille.
    pub clipped_permille: u16,
    /// The laser's light over the reference, DN.
    pub laser_dn: u16,
    /// What a scan would make of the frame.
    pub state: PreviewState,
    /// With [`PreviewState::Skipped`], why.
    pub skip: Option<scanner_wire::Skip>,
    /// With [`PreviewState::Points`], how many.
    pub points: u16,
}

impl Counts {
    /// Frames the head skipped, by reason, summed over the scans.
    pub fn skipped(&self) -> [u64; SKIP_REASONS] {
        let mut s = [0u64; SKIP_REASONS];
        for st in self.status.values() {
            for (k, v) in st.skipped.iter().enumerate() {
                s[k] += u64::from(*v);
            }
        }
        s
    }
}

/// A decoded point packet held until a header arrives.
struct Pending {
    points: Vec<Point3<f32>>,
    rgb: Vec<[u8; 3]>,
    uncertainty: Vec<f32>,
}

/// Bytes in, grid out: the decoder, and what it feeds.
pub struct Collector {
    decoder: Box<Decoder<MAX_ENCODED>>,
    state: State,
}

/// Everything but the decoder (so the decoder's callback can borrow it while it decodes).
struct State {
    opts: CollectOptions,
    journal: Option<Journal>,
    header: Option<Header>,
    grid: Option<Grid>,
    colour: bool,
    uncertainty: bool,
    pending: VecDeque<Pending>,
    counts: Counts,
    error: Option<CollectError>,
    points: Vec<Point3<f32>>,
    seen: BTreeSet<(u32, u32)>,
    /// Each accepted frame's points and colours since the last [`Collector::take_watched`]
    /// (only while watched).
    watched: Option<Vec<Watched>>,
    /// The frames' laser planes, summed: where the light comes from.
    pencil: crate::thickness::LaserOrigin,
    /// Moves each frame's points to where the sheet's middle crosses the surface (a second pass
    /// over a scan, see [`crate::thickness`]), and how many it moved.
    sheet: Option<(crate::thickness::Correction, u64)>,
    /// The latest preview picture not yet taken.
    preview: Option<PreviewImage>,
    /// Every accepted frame's points, camera frame, up to [`MAX_KEPT_POINTS`]: a fixed-laser
    /// scan's model is made from them (its frames overlap in the camera's view, so no image
    /// grid holds them).
    kept: Vec<KeptFrame>,
    kept_points: usize,
    /// Notices not yet taken.
    fresh_notices: Vec<Notice>,
}

/// Most frames' points a collector keeps for a fixed-laser model (12 bytes each: 240 MB).
pub const MAX_KEPT_POINTS: usize = 20_000_000;

/// One accepted frame's points, camera frame, mm.
#[derive(Debug, Clone, PartialEq)]
pub struct KeptFrame {
    /// Its scan.
    pub scan_id: u32,
    /// Its number in the scan.
    pub frame: u32,
    /// Its points.
    pub points: Vec<Point3<f32>>,
}

/// One accepted frame's points (camera frame, mm) and colours (empty: none), for a live view.
pub type Watched = (Vec<Point3<f32>>, Vec<[u8; 3]>);

impl Collector {
    /// A collector, journaling to `journal` if given.
    pub fn new(opts: CollectOptions, journal: Option<Journal>) -> Collector {
        Collector {
            decoder: Box::new(Decoder::new()),
            state: State::new(opts, journal),
        }
    }

    /// The counts so far.
    pub fn counts(&self) -> Counts {
        let mut c = self.state.counts.clone();
        c.decode = self.decoder.stats();
        c
    }

    /// The first header.
    pub fn header(&self) -> Option<&Header> {
        self.state.header.as_ref()
    }

    /// The turntable disc's pose (disc → camera) in the first scan's reference frame, when its
    /// head found the disc.
    pub fn disc_pose(&self) -> Option<Isometry3<f64>> {
        let d = self.state.counts.discs.get(&self.state.header?.scan_id)?;
        if d.found != DiscFound::Found {
            return None;
        }
        let [i, j, k, w] = d.rotation.map(f64::from);
        let q = Quaternion::new(w, i, j, k);
        if !(q.norm() > 0.5) || !d.translation.iter().all(|v| v.is_finite()) {
            return None;
        }
        Some(Isometry3::from_parts(
            Translation3::from(Vector3::from(d.translation.map(f64::from))),
            UnitQuaternion::from_quaternion(q),
        ))
    }

    /// The first scan's fixed laser and platform, when it is a fixed-laser scan.
    pub fn fixed(&self) -> Option<&FixedLaser> {
        self.state.counts.fixed.get(&self.state.header?.scan_id)
    }

    /// The frames' measured turns (a platform's markers), radians, by scan id and frame.
    pub fn turns(&self) -> &BTreeMap<(u32, u32), f64> {
        &self.state.counts.turns
    }

    /// Every accepted frame's points, in arrival order (up to [`MAX_KEPT_POINTS`]).
    pub fn kept(&self) -> &[KeptFrame] {
        &self.state.kept
    }

    /// The grid (once a header has arrived).
    pub fn grid(&self) -> Option<&Grid> {
        self.state.grid.as_ref()
    }

    /// Keeps each accepted frame's points for [`Collector::take_watched`] from now on.
    pub fn watch(&mut self) {
        self.state.watched.get_or_insert_with(Vec::new);
    }

    /// The latest preview picture since the last call.
    pub fn take_preview(&mut self) -> Option<PreviewImage> {
        self.state.preview.take()
    }

    /// The head's notices since the last call, in order.
    pub fn take_notices(&mut self) -> Vec<Notice> {
        std::mem::take(&mut self.state.fresh_notices)
    }

    /// The frames accepted since the last call (empty unless [`Collector::watch`]ed).
    pub fn take_watched(&mut self) -> Vec<Watched> {
        self.state
            .watched
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// Corrects every frame's points for the light sheet's thickness from now on (see
    /// [`crate::thickness`]); the journal keeps them as they came.
    pub fn correct_sheet(&mut self, c: crate::thickness::Correction) {
        self.state.sheet = Some((c, 0));
    }

    /// Points moved by the sheet's correction so far (`None`: no correction).
    pub fn sheet_corrected(&self) -> Option<u64> {
        self.state.sheet.as_ref().map(|s| s.1)
    }

    /// Takes the grid of `again`, the same frames collected a second time with the sheet's
    /// correction ([`Collector::correct_sheet`]); what arrived (the counts) stays this
    /// collection's, so that the link's rejections are still reported.
    pub fn regrid(&mut self, again: Collector) {
        let a = again.state;
        self.state.grid = a.grid;
        self.state.sheet = a.sheet;
        self.state.counts.gridded = a.counts.gridded;
    }

    /// Where the laser's light comes from, as the frames' planes so far say (see
    /// [`crate::thickness::LaserOrigin`]).
    pub fn light_source(&self) -> Option<scanner_core::nalgebra::Point3<f64>> {
        self.state.pencil.source()
    }

    /// Whether points carried colour.
    pub fn colour(&self) -> bool {
        self.state.colour
    }

    /// Whether points carried their standard uncertainty (heads since wire version 2).
    pub fn uncertainty(&self) -> bool {
        self.state.uncertainty
    }

    /// Feeds bytes in any chunks.
    ///
    /// # Errors
    /// The journal could not be written (nothing received is dropped from memory), or the first
    /// header is unusable.
    pub fn feed(&mut self, bytes: &[u8]) -> Result<()> {
        let state = &mut self.state;
        self.decoder.feed(bytes, |m| {
            if let Ok(msg) = m
                && let Err(e) = state.handle(&msg)
            {
                state.error.get_or_insert(e);
            }
        });
        match self.state.error.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Ends the input: a frame cut off at the end counts as truncated (see [`Decoder::finish`]).
    pub fn finish(&mut self) {
        self.decoder.finish();
    }

    /// Flushes the journal to disk.
    ///
    /// # Errors
    /// The sync failed.
    pub fn sync(&mut self) -> Result<()> {
        if let Some(j) = &mut self.state.journal {
            j.sync()?;
        }
        Ok(())
    }
}

impl State {
    fn new(opts: CollectOptions, journal: Option<Journal>) -> State {
        State {
            opts,
            journal,
            header: None,
            grid: None,
            colour: false,
            uncertainty: false,
            pending: VecDeque::new(),
            counts: Counts::default(),
            error: None,
            points: Vec::with_capacity(4096),
            seen: BTreeSet::new(),
            watched: None,
            pencil: crate::thickness::LaserOrigin::default(),
            sheet: None,
            preview: None,
            fresh_notices: Vec::new(),
            kept: Vec::new(),
            kept_points: 0,
        }
    }

    fn handle(&mut self, msg: &Message) -> Result<()> {
        if let Some(j) = &mut self.journal {
            j.append(msg)?;
        }
        match msg {
            Message::Header(h) => {
                self.counts.headers += 1;
                self.counts.scans.insert(h.scan_id);
                match &self.header {
                    None => self.start(h)?,
                    Some(first) if !same_view(first, h) => {
                        self.counts.other_camera.insert(h.scan_id);
                    }
                    Some(_) => {}
                }
            }
            Message::Status(s) => {
                self.counts.scans.insert(s.scan_id);
                self.counts.status.insert(s.scan_id, *s);
            }
            Message::Controls(k) => {
                self.counts.scans.insert(k.scan_id);
                self.counts.controls.insert(k.scan_id, *k);
            }
            Message::Planes(p) => {
                self.counts.scans.insert(p.scan_id);
                self.counts.planes.insert(p.scan_id, *p);
            }
            Message::Disc(d) => {
                self.counts.scans.insert(d.scan_id);
                self.counts.discs.insert(d.scan_id, *d);
            }
            Message::FixedLaser(f) => {
                self.counts.scans.insert(f.scan_id);
                self.counts.fixed.insert(f.scan_id, *f);
            }
            Message::Turn(t) => {
                self.counts.scans.insert(t.scan_id);
                if self.counts.turns.len() < MAX_TURNS
                    || self.counts.turns.contains_key(&(t.scan_id, t.frame))
                {
                    self.counts.turns.insert((t.scan_id, t.frame), t.angle);
                } else {
                    self.counts.turns_not_kept += 1;
                }
            }
            Message::Notice(n) => {
                if self.counts.notices.len() == MAX_NOTICES {
                    self.counts.notices.pop_front();
                }
                self.counts.notices.push_back(*n);
                if self.fresh_notices.len() < MAX_NOTICES {
                    self.fresh_notices.push(*n);
                }
            }
            // the answers to commands: the studio reads them; a scan's grid has no use for them
            Message::Reply(_) | Message::Shot(_) | Message::Calibrated(_) | Message::Picture(_) => {
            }
            Message::Preview(p) => {
                self.counts.previews += 1;
                self.preview = Some(PreviewImage {
                    scan_id: p.scan_id,
                    frame: p.frame,
                    size: (p.width, p.height),
                    scale: p.scale,
                    pixels: p.pixels.to_vec(),
                    markers: p.markers.chunks_exact(2).map(|m| [m[0], m[1]]).collect(),
                    rows: p.axis == 1,
                    stripe: p.stripe.to_vec(),
                    clipped_permille: p.clipped_permille,
                    laser_dn: p.laser_dn,
                    state: p.state,
                    skip: (p.state == PreviewState::Skipped)
                        .then(|| scanner_wire::Skip::ALL.get(usize::from(p.skip)).copied())
                        .flatten(),
                    points: p.points,
                });
            }
            Message::Points(p) => {
                if !self.seen.insert((p.scan_id, p.frame)) {
                    self.counts.duplicates += 1;
                    return Ok(());
                }
                self.counts.packets += 1;
                self.counts.scans.insert(p.scan_id);
                if self.counts.other_camera.contains(&p.scan_id) {
                    self.counts.other_camera_points += u64::from(p.count);
                    return Ok(());
                }
                self.counts.time_us = Some(match self.counts.time_us {
                    Some((a, b)) => (a.min(p.time_us), b.max(p.time_us)),
                    None => (p.time_us, p.time_us),
                });
                self.points.clear();
                let unit = f32::from(self.header.map_or(10, |h| h.unit_um)) / 1000.0;
                let pts = &mut self.points;
                if points::decode(p.xyz, p.count as usize, |q| {
                    pts.push(Point3::new(
                        q[0] as f32 * unit,
                        q[1] as f32 * unit,
                        q[2] as f32 * unit,
                    ));
                })
                .is_err()
                {
                    self.counts.bad_points += 1;
                    return Ok(());
                }
                self.pencil.add(p.plane);
                if let Some((c, moved)) = &mut self.sheet {
                    *moved += c.apply(p.plane, &mut self.points) as u64;
                }
                self.counts.points += u64::from(p.count);
                let rgb: Vec<[u8; 3]> = p.rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
                if !rgb.is_empty() {
                    self.colour = true;
                }
                let uncertainty: Vec<f32> = p
                    .uncertainty
                    .iter()
                    .map(|&c| points::uncertainty_mm(c))
                    .collect();
                if !uncertainty.is_empty() {
                    self.uncertainty = true;
                }
                if let Some(w) = &mut self.watched {
                    w.push((self.points.clone(), rgb.clone()));
                }
                if self.kept_points + self.points.len() <= MAX_KEPT_POINTS {
                    self.kept_points += self.points.len();
                    self.kept.push(KeptFrame {
                        scan_id: p.scan_id,
                        frame: p.frame,
                        points: self.points.clone(),
                    });
                } else {
                    self.counts.not_kept += self.points.len() as u64;
                }
                if self.grid.is_some() {
                    let points = std::mem::take(&mut self.points);
                    self.insert(&points, &rgb, &uncertainty);
                    self.points = points;
                } else {
                    if self.pending.len() >= self.opts.pending_max {
                        self.pending.pop_front();
                        self.counts.no_header += 1;
                    }
                    self.pending.push_back(Pending {
                        points: self.points.clone(),
                        rgb,
                        uncertainty,
                    });
                }
            }
        }
        Ok(())
    }

    fn start(&mut self, h: &Header) -> Result<()> {
        check_header(h)?;
        let camera: Camera<f64> = scanner_core::Camera::<f32>::try_from(h.camera)
            .map_err(CollectError::Camera)?
            .cast();
        // Millimetre grids span the view out to the board's crease distance (or 2 m).
        let depth = h
            .board
            .iter()
            .map(|b| f64::from(b.offset).abs())
            .fold(0.0, f64::max)
            .max(200.0)
            * 1.5;
        let grid = Grid::new(
            camera,
            u32::from(h.width),
            u32::from(h.height),
            self.opts.cell,
            depth,
            self.opts.outlier_mm,
        )?;
        self.header = Some(*h);
        self.grid = Some(grid);
        while let Some(p) = self.pending.pop_front() {
            self.insert(&p.points, &p.rgb, &p.uncertainty);
        }
        Ok(())
    }

    fn insert(&mut self, pts: &[Point3<f32>], rgb: &[[u8; 3]], uncertainty: &[f32]) {
        let Some(grid) = &mut self.grid else { return };
        for (i, p) in pts.iter().enumerate() {
            if grid.insert(p, rgb.get(i).copied(), uncertainty.get(i).copied()) {
                self.counts.gridded += 1;
            }
        }
    }
}

/// Whether two headers describe the same view: image size and camera (sweeps of one scan, or
/// several scans from one camera that stayed put, share a grid).
fn same_view(a: &Header, b: &Header) -> bool {
    (a.width, a.height, a.unit_um) == (b.width, b.height, b.unit_um) && a.camera == b.camera
}

/// Refuses a header that no real head sends: an image size beyond the head's
/// [`MAX_LINES`](scanner_core::config::MAX_LINES), a zero unit, an implausible camera or
/// board (see [`Camera::check_plausible`]). Nothing is allocated for it.
fn check_header(h: &Header) -> Result<()> {
    let bad = |why: String| {
        Err(CollectError::Header {
            scan_id: h.scan_id,
            why,
        })
    };
    if h.unit_um == 0 {
        return bad("its unit is 0 µm: no point can be placed".into());
    }
    let camera =
        scanner_core::Camera::<f32>::try_from(h.camera).map_err(|e| CollectError::Header {
            scan_id: h.scan_id,
            why: format!("its camera is unusable ({e})"),
        })?;
    if let Err(e) = camera.check_plausible(u32::from(h.width), u32::from(h.height)) {
        return bad(format!(
            "{e} (image {}×{}, fx {:.4e}, fy {:.4e})",
            h.width,
            h.height,
            camera.fx(),
            camera.fy()
        ));
    }
    for (name, b) in ["left", "right"].iter().zip(&h.board) {
        if !(f64::from(b.offset).abs() <= scanner_core::config::MAX_PLANE_OFFSET_MM) {
            return bad(format!(
                "its {name} board plane is {:.4e} mm away",
                b.offset
            ));
        }
    }
    Ok(())
}
