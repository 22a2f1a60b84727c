//! Views for the 360° merge, read from the host's files: each view a receive output folder or
//! a journal/recording, gridded and meshed as `replay` does ([`load_view`]); a session's journal
//! of several sweeps split into one view each ([`split_scans`]); and the merge of view folders
//! ([`merge_folders`]), which reads the views as the merge's options ask and hands them to
//! [`scanner_merge::run`].

use std::path::{Path, PathBuf};

use scanner_merge::spatial::Cloud;
use scanner_merge::{MergeError, MergeOptions, Merged, Progress, ScanPoints, View};

use crate::collect::CollectOptions;
use crate::grid::Cell;
use crate::mesh::{self, MeshOptions};
use crate::outputs::{OutputError, OutputOptions};

/// Why views could not be read or merged.
#[derive(Debug, thiserror::Error)]
pub enum ViewsError {
    /// A view could not be read.
    #[error("view {view} ({})", path.display())]
    Read {
        /// Which view (from 0).
        view: usize,
        /// Its path.
        path: PathBuf,
        /// Why.
        #[source]
        source: OutputError,
    },
    /// A view has no scan in it.
    #[error("view {view} ({}): no scan in it (no session header): is this a receive output folder or a journal?", path.display())]
    Empty {
        /// Which view.
        view: usize,
        /// Its path.
        path: PathBuf,
    },
    /// A view's scan sent no point (the laser never seen on the board, or every frame skipped).
    #[error("view {view} ({}): the scan holds no point ({frames} frames received): nothing to register", path.display())]
    NoPoints {
        /// Which view.
        view: usize,
        /// Its path.
        path: PathBuf,
        /// Frames in its stream.
        frames: u64,
    },
    /// A journal holds more scans than [`MAX_VIEWS`].
    #[error("the journal holds more than {MAX_VIEWS} scans: split into views only up to that many")]
    TooManyScans,
    /// A journal could not be split into its scans.
    #[error("splitting {} into its scans", path.display())]
    Split {
        /// The journal.
        path: PathBuf,
        /// Why.
        #[source]
        source: crate::journal::JournalError,
    },
    /// The sheet's thickness is out of range.
    #[error(transparent)]
    Thickness(#[from] crate::thickness::ThicknessError),
    /// The merge refused the views or failed.
    #[error(transparent)]
    Merge(#[from] MergeError),
}

/// Cells within this many steps of a view's edge count as on it ([`mesh::edge_cells`]): on the
/// 360° demo at 2-pixel cells, one step takes in 741 of the 756 points more than 0.5 mm off the
/// true surface (stripes cut at an edge) and a quarter of all (`merge_report`,
/// docs/reports.md).
const EDGE_REACH: usize = 1;

/// Most scans a journal is split into ([`split_scans`]).
pub const MAX_VIEWS: usize = 64;

/// Splits a journal that holds several scans (sweeps with the object turned between them) into
/// one journal per scan, in the order their first frames came: `dir/view-1/journal.stream`, …
/// Every frame goes to its scan's journal unchanged. Returns the view folders.
///
/// # Errors
/// The journal cannot be read, a view's journal cannot be written, or more than [`MAX_VIEWS`]
/// scans.
pub fn split_scans(journal: &Path, dir: &Path) -> Result<Vec<PathBuf>, ViewsError> {
    use crate::journal::{Journal, JournalError};
    use std::io::Read;
    let split = |source| ViewsError::Split {
        path: journal.to_path_buf(),
        source,
    };
    let mut file = crate::link::open_file(journal).map_err(|e| ViewsError::Read {
        view: 0,
        path: journal.to_path_buf(),
        source: e.into(),
    })?;
    let mut decoder = Box::new(scanner_wire::Decoder::<{ scanner_wire::MAX_ENCODED }>::new());
    let mut views: Vec<(u32, PathBuf, Journal)> = Vec::new();
    let mut failed: Option<ViewsError> = None;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buf).map_err(|source| ViewsError::Read {
            view: 0,
            path: journal.to_path_buf(),
            source: OutputError::Input {
                path: journal.to_path_buf(),
                source,
            },
        })?;
        if n == 0 {
            break;
        }
        decoder.feed(&buf[..n], |m| {
            let Ok(msg) = m else { return };
            if failed.is_some() {
                return;
            }
            // the answers to commands belong to no view
            let Some(id) = msg.scan_id() else { return };
            let k = match views.iter().position(|(s, _, _)| *s == id) {
                Some(k) => k,
                None if views.len() >= MAX_VIEWS => {
                    failed = Some(ViewsError::TooManyScans);
                    return;
                }
                None => {
                    let folder = dir.join(format!("view-{}", views.len() + 1));
                    let opened = std::fs::create_dir_all(&folder)
                        .map_err(|source| JournalError::Open {
                            path: folder.clone(),
                            source,
                        })
                        .and_then(|()| Journal::open(&folder.join("journal.stream")));
                    match opened {
                        Ok(j) => views.push((id, folder, j)),
                        Err(e) => {
                            failed = Some(split(e));
                            return;
                        }
                    }
                    views.len() - 1
                }
            };
            if let Err(e) = views[k].2.append(&msg) {
                failed = Some(split(e));
            }
        });
        if let Some(e) = failed.take() {
            return Err(e);
        }
    }
    let mut folders = Vec::new();
    for (_, folder, mut j) in views {
        j.sync().map_err(split)?;
        folders.push(folder);
    }
    Ok(folders)
}

/// The journal inside a receive output folder, or the file itself.
fn stream_of(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("journal.stream")
    } else {
        path.to_path_buf()
    }
}

/// Reads view `k` from `path`: replays it into a grid (cells of `cell`) and takes its mesh: the
/// vertices, normals, colours and uncertainties, and how clear of the view's edges each lies.
/// With `sheet_mm` (the laser sheet's Gaussian thickness, mm) above zero the scan is replayed a
/// second time, each frame's points moved to where the sheet's middle crosses the surface the
/// first pass found (see [`crate::thickness`]).
///
/// # Errors
/// The file cannot be read, holds no scan, or its scan holds no point.
pub fn load_view(k: usize, path: &Path, cell: Cell, sheet_mm: f64) -> Result<View, ViewsError> {
    let opts = CollectOptions {
        cell,
        ..CollectOptions::default()
    };
    let c = crate::outputs::replay(opts, &stream_of(path), sheet_mm).map_err(|source| {
        ViewsError::Read {
            view: k,
            path: path.to_path_buf(),
            source,
        }
    })?;
    let (Some(grid), Some(m), Some(header)) = (
        c.grid(),
        // a merge fuses the views' measured points: its own surface spans their gaps
        crate::outputs::mesh_of(
            &c,
            &OutputOptions {
                bridge_gaps: false,
                ..OutputOptions::default()
            },
        ),
        c.header(),
    ) else {
        return Err(ViewsError::Empty {
            view: k,
            path: path.to_path_buf(),
        });
    };
    if c.counts().points == 0 {
        return Err(ViewsError::NoPoints {
            view: k,
            path: path.to_path_buf(),
            frames: c.counts().decode.frames,
        });
    }
    let fx = f64::from(header.camera.fx);
    let edges = mesh::edge_cells(grid, fx, &MeshOptions::default(), EDGE_REACH);
    let surface = ScanPoints {
        cloud: Cloud {
            points: m.vertices.iter().map(|p| p.cast()).collect(),
            normals: m.normals.iter().map(|n| n.cast()).collect(),
        },
        clearance: m
            .cells
            .iter()
            .map(|&(c, r)| f64::from(u8::from(!edges[r as usize * grid.cols + c as usize])))
            .collect(),
        sigma: m.quality.iter().map(|&q| f64::from(q)).collect(),
        colours: m.colours,
    };
    let disc = c.disc_pose();
    let disc_scale = disc
        .as_ref()
        .and_then(|d| disc_scale(&surface.cloud.points, d));
    let (surface, backdrop) = match &disc {
        Some(d) => above_disc(&surface, d),
        None => (surface, Vec::new()),
    };
    let mut view = View::new(
        path.display().to_string(),
        *header,
        &surface,
        c.sheet_corrected().map(|moved| (moved, c.counts().points)),
    );
    view.disc = disc;
    view.disc_scale = disc_scale;
    view.backdrop = backdrop;
    Ok(view)
}

/// Widest share of its pose's size a disc is looked for at (A4's disc posed as A3's is 0.69,
/// A3's as A4's 1.46).
const DISC_SCALES: (f64, f64) = (0.5, 1.6);
/// Width of the histogram's bins the disc's plane is found in, as a share.
const DISC_SCALE_BIN: f64 = 0.002;
/// Fewest points on the disc's plane for a measure.
const MIN_DISC_POINTS: usize = 200;

/// The disc's size as the laser measures it, as a share of the size its pose `disc` (disc →
/// camera) was computed for: a pose from a disc of the wrong size is the true one with its
/// translation scaled, so the laser's points on the disc's plane lie at the share `s` of the
/// pose's distance along the plane's normal. `s` is the densest share among the view's points
/// (the disc and the table it lies on are the largest flat thing in view), refined by the
/// median of the points within two bins of it. `None`: too few points on any plane.
pub fn disc_scale(
    points: &[scanner_core::nalgebra::Point3<f64>],
    disc: &scanner_core::nalgebra::Isometry3<f64>,
) -> Option<f64> {
    let n = disc.rotation * scanner_core::nalgebra::Vector3::z();
    let d = n.dot(&disc.translation.vector);
    if !(d.abs() > 1.0) {
        return None;
    }
    let (lo, hi) = DISC_SCALES;
    let shares: Vec<f64> = points
        .iter()
        .map(|p| n.dot(&p.coords) / d)
        .filter(|s| (lo..hi).contains(s))
        .collect();
    let bins = ((hi - lo) / DISC_SCALE_BIN).ceil() as usize;
    let mut count = vec![0usize; bins];
    for s in &shares {
        count[(((s - lo) / DISC_SCALE_BIN) as usize).min(bins - 1)] += 1;
    }
    let (best, _) = count
        .windows(3)
        .enumerate()
        .map(|(i, w)| (i + 1, w.iter().sum::<usize>()))
        .max_by_key(|&(_, c)| c)?;
    let centre = lo + (best as f64 + 0.5) * DISC_SCALE_BIN;
    let mut near: Vec<f64> = shares
        .into_iter()
        .filter(|s| (s - centre).abs() <= 2.0 * DISC_SCALE_BIN)
        .collect();
    if near.len() < MIN_DISC_POINTS {
        return None;
    }
    near.sort_by(f64::total_cmp);
    Some(near[near.len() / 2])
}

/// Points nearer the turntable disc's plane than this, or below it, are the disc's or the
/// table's, never the object's, mm.
const ON_DISC_MM: f64 = 1.5;

/// The surface without the points on or under the turntable disc's plane (`disc`: disc →
/// camera, its third axis pointing into the table), and those points (the view's backdrop).
fn above_disc(
    s: &ScanPoints,
    disc: &scanner_core::nalgebra::Isometry3<f64>,
) -> (ScanPoints, Vec<scanner_core::nalgebra::Point3<f64>>) {
    let above = |i: usize| disc.inverse_transform_point(&s.cloud.points[i]).z < -ON_DISC_MM;
    let keep: Vec<usize> = (0..s.cloud.points.len()).filter(|&i| above(i)).collect();
    let backdrop = (0..s.cloud.points.len())
        .filter(|&i| !above(i))
        .map(|i| s.cloud.points[i])
        .collect();
    let surface = s.subset(&keep);
    (surface, backdrop)
}

/// The grid cell a merge reads the view at `path` with unless told: [`VIEW_CELL_PX`] pixels for
/// every 640 of its image's width (from its first header), so that the cell on the object does
/// not shrink with a sharper camera: cells of 2 px at 1280×960 hold half the points and made the
/// round stand's model 0.042 % of the camera–board distance off on average, cells of 4 px
/// 0.017 % (`tests/tests/turntable.rs`). 2 px where the journal's header cannot be read (the
/// read then says why). Views that cannot be registered so are read again at 2 px
/// ([`merge_folders`]).
pub fn cell_for(path: &Path) -> Cell {
    let head = std::fs::File::open(stream_of(path)).ok().map(|f| {
        let mut bytes = Vec::new();
        let _ = std::io::Read::read_to_end(&mut std::io::Read::take(f, HEAD_BYTES), &mut bytes);
        bytes
    });
    let width = head.and_then(|bytes| {
        let mut found = None;
        let mut d = Box::new(scanner_wire::Decoder::<{ scanner_wire::MAX_ENCODED }>::new());
        d.feed(&bytes, |m| {
            if let Ok(scanner_wire::Message::Header(h)) = m {
                found.get_or_insert(h.width);
            }
        });
        found
    });
    let per = width.map_or(1, |w| u32::from(w).div_ceil(640).max(1));
    Cell::Pixels(VIEW_CELL_PX * f64::from(per))
}

/// See [`cell_for`].
pub const VIEW_CELL_PX: f64 = 2.0;

/// How much of a journal [`cell_for`] reads for its header (the first message).
const HEAD_BYTES: u64 = 64 * 1024;

/// Reads every view of `paths` ([`load_view`]), `reading(k)` told as view `k`'s turn comes,
/// each with the grid cell `cell` (`None`: [`cell_for`] it).
///
/// # Errors
/// As [`load_view`].
pub fn load_views(
    paths: &[PathBuf],
    cell: Option<Cell>,
    sheet_mm: f64,
    mut reading: impl FnMut(usize),
) -> Result<Vec<View>, ViewsError> {
    paths
        .iter()
        .enumerate()
        .map(|(k, p)| {
            reading(k);
            load_view(k, p, cell.unwrap_or_else(|| cell_for(p)), sheet_mm)
        })
        .collect()
}

/// The laser sheet's thickness for a merge: given (mm; 0 leaves the points as the head sent
/// them), or found where the views agree best ([`scanner_merge::find_thickness`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Thickness {
    /// Given, mm.
    Mm(f64),
    /// Found by the merge.
    Auto,
}

impl std::str::FromStr for Thickness {
    type Err = String;
    /// A thickness in mm, or `auto`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "auto" {
            return Ok(Thickness::Auto);
        }
        s.parse::<f64>().map(Thickness::Mm).map_err(|_| {
            format!(
                "expected the sheet's thickness in mm (0 to {}) or \"auto\"",
                crate::thickness::MAX_SIGMA_MM
            )
        })
    }
}

/// What the merge of view folders tells as it goes: the merge's own stages, and which view
/// is being read (for a given sheet thickness, mm).
pub trait MergeProgress: Progress {
    /// View `view` is being read with the sheet's thickness `sheet_mm`.
    fn reading(&mut self, view: usize, sheet_mm: f64);

    /// The views could not be registered (`why`) at the cells chosen for their images and are
    /// read again with cells of `cell_px` image pixels.
    fn finer(&mut self, cell_px: f64, why: &MergeError);
}

/// Merges the views in `paths` (cells of `cell`): reads them with the sheet's thickness
/// (`Thickness::Auto`: each thickness [`scanner_merge::thickness_tries`] names, to find the one where
/// they agree best; then again with it) and runs [`scanner_merge::run`] on them.
///
/// # Errors
/// A view that cannot be read, or the merge's own [`MergeError`].
pub fn merge_folders(
    paths: &[PathBuf],
    cell: Option<Cell>,
    sheet: Thickness,
    options: &MergeOptions,
    progress: &mut impl MergeProgress,
) -> Result<Merged, ViewsError> {
    options.check()?;
    if let Thickness::Mm(mm) = sheet {
        crate::thickness::check_thickness(mm)?;
    }
    if paths.len() < 2 {
        return Err(MergeError::TooFewViews(paths.len()).into());
    }
    let mut options = options.clone();
    let sheet_mm = match sheet {
        Thickness::Mm(mm) => mm,
        Thickness::Auto => {
            let mut tries = Vec::new();
            for &sigma in scanner_merge::thickness_tries() {
                tries.push(load_views(paths, cell, sigma, |k| {
                    progress.reading(k, sigma)
                })?);
            }
            let found = scanner_merge::find_thickness(&tries, &options, progress)?;
            let sigma = found.sigma_mm;
            options.sheet = Some(found);
            sigma
        }
    };
    let views = load_views(paths, cell, sheet_mm, |k| progress.reading(k, sheet_mm))?;
    match scanner_merge::run(&views, &options, progress) {
        // Cells chosen for the image (4 px at 1280×960) hold a quarter of the points of 2 px
        // ones: a sparse sweep's views can then share too few to be registered by shape.
        Err(e @ (MergeError::NoMatch { .. } | MergeError::Apart { .. }))
            if cell.is_none() && paths.iter().any(|p| cell_for(p) != FINEST) =>
        {
            progress.finer(VIEW_CELL_PX, &e);
            let views = load_views(paths, Some(FINEST), sheet_mm, |k| {
                progress.reading(k, sheet_mm)
            })?;
            let mut merged = scanner_merge::run(&views, &options, progress)?;
            merged.report.finer_cell_px = Some(VIEW_CELL_PX);
            Ok(merged)
        }
        merged => Ok(merged?),
    }
}

/// The cell a merge reads the views with again when, at the cells [`cell_for`] chose, they
/// could not be registered.
const FINEST: Cell = Cell::Pixels(VIEW_CELL_PX);
