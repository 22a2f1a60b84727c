//! `merge`: several sweeps of one object, turned between them, registered into one frame (a
//! chain of pairwise registrations, then all views refined together, [`crate::refine`]) and
//! fused into one mesh ([`crate::fuse`]).
//! Each view is a receive output folder or a journal/recording; each is gridded and meshed as
//! `replay` does, and its mesh's vertices and normals are registered onto its neighbours.

use std::path::{Path, PathBuf};

use scanner_core::nalgebra::{Isometry3, Point3};
use scanner_core::wire::Header;

use crate::collect::{CollectOptions, Collector};
use crate::mesh::{self, MeshFrame, MeshOptions};
use crate::outputs::{OutputError, replay_into};
use crate::register::{Cloud, RegisterError, RegisterOptions, Registration, register_hinted};

/// Why views cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// Fewer than two views.
    #[error("merge needs at least two views (sweeps of the object turned between them), got {0}")]
    TooFewViews(usize),
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
    /// Views from different cameras or calibrations cannot share a frame.
    #[error(
        "view {view} ({}) was scanned with another camera or image size than view 0: merge views of one calibrated set-up",
        path.display()
    )]
    OtherCamera {
        /// Which view.
        view: usize,
        /// Its path.
        path: PathBuf,
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
    /// The loop of views does not close after the joint refinement: some view is registered
    /// wrongly (views of flat faces that share too little can fit one another turned the wrong
    /// way), and a model from them would be wrong however watertight.
    #[error(
        "the views do not close into one object: view {view} registered onto view 0 directly lands {rotation_deg:.2}° and {translation_mm:.1} mm from where the chain of views puts it (a merge accepts at most {LOOP_MAX_DEG}° and {max_mm:.1} mm): at least one view is registered wrongly, so no model was written; views.png and views.ply show each view in its colour, merge-report.txt each registration (a part of large flat faces registers wrongly so: docs/reports.md)"
    )]
    LoopOpen {
        /// The view that closes the loop.
        view: usize,
        /// Its rotation error, degrees.
        rotation_deg: f64,
        /// Its translation error, mm.
        translation_mm: f64,
        /// The translation allowed, mm.
        max_mm: f64,
    },
    /// A view registers onto none of the others.
    #[error("view {view} ({}) overlaps no other view; best try: {best}", path.display())]
    NoMatch {
        /// Which view.
        view: usize,
        /// Its path.
        path: PathBuf,
        /// The best attempt's reason.
        best: RegisterError,
    },
}

/// One view, read and meshed.
pub struct View {
    /// Where it came from.
    pub path: PathBuf,
    /// Its mesh's vertices and normals, camera frame.
    pub cloud: Cloud,
    /// Its session header.
    pub header: Header,
    /// The surface's colour at each point (empty: the scan carried no colour).
    pub colours: Vec<[u8; 3]>,
    /// How far each point is from the view's edges: the share of the grid cells averaged into
    /// it that lie away from an occluding edge, a shadow's border or the view's outline
    /// ([`mesh::edge_cells`]); 0 on an edge, 1 clear of it. The joint refinement pairs only
    /// points at least half clear ([`CLEAR`]); the fusion weighs them by it ([`EDGE_WEIGHT`]).
    pub clear: Vec<f64>,
}

/// Cells within this many steps of a view's edge count as on it ([`mesh::edge_cells`]): on the
/// 360° demo at 2-pixel cells, one step takes in 741 of the 756 points more than 0.5 mm off the
/// true surface (stripes cut at an edge) and a quarter of all (`merge_report`,
/// docs/reports.md).
pub const EDGE_REACH: usize = 1;

/// Points at least this clear of their view's edges ([`View::clear`]) register; the others
/// only fill in the fusion where nothing better saw the surface.
pub const CLEAR: f64 = 0.5;

/// The fusion's weight of a point on its view's edge, against 1 for one clear of it: where a
/// clear point of another view saw the same surface it decides, elsewhere the edge point does.
pub const EDGE_WEIGHT: f64 = 0.05;

/// Each view is thinned to one point per cube of this size, mm (finer than the fusion's cells,
/// so nothing the model could show is lost; denser views only slow the searches: eight views of
/// 49 000 points merge in 8 s instead of 21, `cargo bench -p scanner-host --bench merge`).
pub const THIN_MM: f64 = 0.75;

/// The merge's default voxel for the coarse match, mm.
pub const VOXEL_MM: f64 = 3.0;
/// The merge's default fusion cell, mm.
pub const FUSE_CELL_MM: f64 = 1.0;
/// The merge's default least overlap of a view with the one it is registered onto.
pub const MIN_OVERLAP: f64 = 0.4;

/// Most scans a journal is split into ([`split_scans`]).
pub const MAX_VIEWS: usize = 64;

/// Splits a journal that holds several scans (sweeps with the object turned between them) into
/// one journal per scan, in the order their first frames came: `dir/view-1/journal.stream`, …
/// Every frame goes to its scan's journal unchanged. Returns the view folders.
///
/// # Errors
/// The journal cannot be read, a view's journal cannot be written, or more than [`MAX_VIEWS`]
/// scans.
pub fn split_scans(journal: &Path, dir: &Path) -> Result<Vec<PathBuf>, MergeError> {
    use crate::journal::{Journal, JournalError};
    use std::io::Read;
    let split = |source| MergeError::Split {
        path: journal.to_path_buf(),
        source,
    };
    let mut file = crate::link::open_file(journal).map_err(|e| MergeError::Read {
        view: 0,
        path: journal.to_path_buf(),
        source: e.into(),
    })?;
    let mut decoder = Box::new(scanner_core::wire::Decoder::<
        { scanner_core::wire::MAX_ENCODED },
    >::new());
    let mut views: Vec<(u32, PathBuf, Journal)> = Vec::new();
    let mut failed: Option<MergeError> = None;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buf).map_err(|source| MergeError::Read {
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
            let id = msg.scan_id();
            let k = match views.iter().position(|(s, _, _)| *s == id) {
                Some(k) => k,
                None if views.len() >= MAX_VIEWS => {
                    failed = Some(MergeError::TooManyScans);
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

/// Reads view `k` from `path`: replays it into a grid (cells of `cell`) and takes its mesh.
///
/// # Errors
/// The file cannot be read, or holds no scan.
pub fn load_view(k: usize, path: &Path, cell: crate::grid::Cell) -> Result<View, MergeError> {
    let mut c = Collector::new(
        CollectOptions {
            cell,
            ..CollectOptions::default()
        },
        None,
    );
    replay_into(&mut c, &stream_of(path)).map_err(|source| MergeError::Read {
        view: k,
        path: path.to_path_buf(),
        source,
    })?;
    let (Some(grid), Some(header)) = (c.grid(), c.header()) else {
        return Err(MergeError::Empty {
            view: k,
            path: path.to_path_buf(),
        });
    };
    if c.counts().points == 0 {
        return Err(MergeError::NoPoints {
            view: k,
            path: path.to_path_buf(),
            frames: c.counts().decode.frames,
        });
    }
    let fx = f64::from(header.camera.fx);
    let m = mesh::build(grid, fx, &MeshOptions::default(), c.colour());
    let edges = mesh::edge_cells(grid, fx, &MeshOptions::default(), EDGE_REACH);
    let clear: Vec<f64> = m
        .cells
        .iter()
        .map(|&(c, r)| {
            if edges[r as usize * grid.cols + c as usize] {
                0.0
            } else {
                1.0
            }
        })
        .collect();
    let (cloud, colours, clear) = thin_view(
        &Cloud {
            points: m.vertices.iter().map(|p| p.cast()).collect(),
            normals: m.normals.iter().map(|n| n.cast()).collect(),
        },
        &m.colours,
        &clear,
        THIN_MM,
    );
    Ok(View {
        path: path.to_path_buf(),
        cloud,
        header: *header,
        colours,
        clear,
    })
}

/// The view's points at least [`CLEAR`] of its edges (all of them when fewer than half are:
/// a view that is all edge registers as it is).
pub fn clear_cloud(v: &View) -> Cloud {
    let keep: Vec<usize> = (0..v.cloud.points.len())
        .filter(|&i| v.clear.get(i).is_none_or(|&c| c >= CLEAR))
        .collect();
    if 2 * keep.len() < v.cloud.points.len() {
        return v.cloud.clone();
    }
    Cloud {
        points: keep.iter().map(|&i| v.cloud.points[i]).collect(),
        normals: keep.iter().map(|&i| v.cloud.normals[i]).collect(),
    }
}

/// Thins a view to one point per `voxel` mm cube: the mean of the points, normals, colours and
/// values (each when there is one per point: colours, e.g. [`View::clear`]) in it.
pub fn thin_view(
    c: &Cloud,
    colours: &[[u8; 3]],
    values: &[f64],
    voxel: f64,
) -> (Cloud, Vec<[u8; 3]>, Vec<f64>) {
    let coloured = colours.len() == c.points.len() && !colours.is_empty();
    let valued = values.len() == c.points.len() && !values.is_empty();
    let mut out = Cloud::default();
    let mut rgb = Vec::new();
    let mut mean = Vec::new();
    for group in crate::register::voxel_groups(&c.points, voxel) {
        let n: scanner_core::nalgebra::Vector3<f64> =
            group.iter().map(|&i| c.normals[i as usize]).sum();
        if n.norm() <= 1e-9 {
            continue;
        }
        let p: scanner_core::nalgebra::Vector3<f64> =
            group.iter().map(|&i| c.points[i as usize].coords).sum();
        out.points.push(Point3::from(p / group.len() as f64));
        out.normals.push(n.normalize());
        if valued {
            mean.push(group.iter().map(|&i| values[i as usize]).sum::<f64>() / group.len() as f64);
        }
        if coloured {
            let mut sum = [0u32; 3];
            for &i in &group {
                for (s, v) in sum.iter_mut().zip(colours[i as usize]) {
                    *s += u32::from(v);
                }
            }
            let k = group.len() as u32;
            rgb.push(sum.map(|s| ((s + k / 2) / k) as u8));
        }
    }
    (out, rgb, mean)
}

/// What the merge found for one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewResult {
    /// Its pose in view 0's frame.
    pub pose: Isometry3<f64>,
    /// The view it was registered onto (`None` for view 0).
    pub onto: Option<usize>,
    /// The registration (`None` for view 0).
    pub fit: Option<Registration>,
    /// Points.
    pub points: usize,
}

/// Registers every view into view 0's frame: each onto the nearest earlier view it overlaps
/// (the previous one first, then the others, newest first).
///
/// # Errors
/// Fewer than two views, views of another camera, a view that overlaps none of the earlier.
pub fn register_views(
    views: &[View],
    o: &RegisterOptions,
    turntable_deg: Option<f64>,
    mut progress: impl FnMut(usize),
) -> Result<Vec<ViewResult>, MergeError> {
    if views.len() < 2 {
        return Err(MergeError::TooFewViews(views.len()));
    }
    let first = &views[0].header;
    let mut out = vec![ViewResult {
        pose: Isometry3::identity(),
        onto: None,
        fit: None,
        points: views[0].cloud.points.len(),
    }];
    for (k, v) in views.iter().enumerate().skip(1) {
        let h = &v.header;
        if (h.width, h.height) != (first.width, first.height) || h.camera != first.camera {
            return Err(MergeError::OtherCamera {
                view: k,
                path: v.path.clone(),
            });
        }
        let mut best_err = None;
        let mut found = None;
        for j in (0..k).rev() {
            let hints =
                turntable_deg.map_or_else(Vec::new, |step| turntable_hints(views, k, j, step));
            match register_hinted(&v.cloud, &views[j].cloud, o, &hints) {
                Ok(fit) => {
                    found = Some((j, fit));
                    break;
                }
                Err(e) => {
                    best_err.get_or_insert(e);
                }
            }
        }
        let Some((j, fit)) = found else {
            return Err(MergeError::NoMatch {
                view: k,
                path: v.path.clone(),
                best: best_err.unwrap_or(RegisterError::TooFewPoints {
                    points: 0,
                    voxel_mm: o.voxel_mm,
                    min: 1,
                }),
            });
        };
        out.push(ViewResult {
            pose: out[j].pose * fit.pose,
            onto: Some(j),
            fit: Some(fit),
            points: v.cloud.points.len(),
        });
        progress(k);
    }
    Ok(out)
}

/// The motions a turntable suggests from view `k` onto view `j`, `step_deg` per view about the
/// board's vertical (its crease): see [`crate::register::turntable_motions`].
fn turntable_hints(views: &[View], k: usize, j: usize, step_deg: f64) -> Vec<Isometry3<f64>> {
    let Ok(board) = views[0].header.board() else {
        return Vec::new();
    };
    let MeshFrame::Board { rotation, .. } = MeshFrame::board(&board) else {
        return Vec::new();
    };
    let up = rotation.row(1).transpose().cast();
    let angle = step_deg * (k - j) as f64;
    crate::register::turntable_motions(&up, &views[k].cloud, &views[j].cloud, angle).to_vec()
}

/// The loop closure before and after [`refine_views`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closure {
    /// Before the joint refinement (`None`: no view closes a loop with view 0).
    pub before: Option<crate::refine::LoopError>,
    /// After it.
    pub after: Option<crate::refine::LoopError>,
}

/// Refines all views' poses together ([`crate::refine`]) from the chain [`register_views`]
/// found, pairs within `voxel_mm`; returns the loop closure before and after.
pub fn refine_views(
    views: &[View],
    results: &mut [ViewResult],
    o: &RegisterOptions,
    progress: impl FnMut(usize),
) -> Closure {
    use crate::refine::{loop_error, refine};
    const ROUNDS: usize = 8;
    // Points on a view's edges lie off the surface, all the same way: they would pull the views
    // apart.
    let clear: Vec<Cloud> = views.iter().map(clear_cloud).collect();
    let clouds: Vec<&Cloud> = clear.iter().collect();
    let poses: Vec<Isometry3<f64>> = results.iter().map(|r| r.pose).collect();
    // Views registered onto view 0 itself close no loop through it.
    let direct: Vec<usize> = (0..results.len())
        .filter(|&k| results[k].onto == Some(0))
        .collect();
    let closure = |p: &[Isometry3<f64>]| loop_error(&clouds, p, &direct, o.voxel_mm, o.min_overlap);
    let before = closure(&poses);
    let joint = refine(&clouds, &poses, o.voxel_mm, ROUNDS, progress);
    for (r, p) in results.iter_mut().zip(&joint) {
        r.pose = *p;
    }
    Closure {
        before,
        after: closure(&joint),
    }
}

/// Largest loop-closure rotation after the joint refinement that a merge accepts, degrees: the
/// 360° demo closes within 0.06°; a view registered the wrong way round leaves degrees.
pub const LOOP_MAX_DEG: f64 = 1.0;
/// Largest loop-closure translation after the joint refinement, in voxels (the registration's
/// `voxel_mm`): the demo closes within 0.22 mm at 3 mm voxels.
pub const LOOP_MAX_VOXELS: f64 = 1.0;

/// The plausibility check of a merge: the loop of views, where one closes, must close within
/// [`LOOP_MAX_DEG`] and [`LOOP_MAX_VOXELS`] after the joint refinement.
///
/// # Errors
/// [`MergeError::LoopOpen`] naming the view and its error.
pub fn check_closure(c: &Closure, voxel_mm: f64) -> Result<(), MergeError> {
    let max_mm = LOOP_MAX_VOXELS * voxel_mm;
    match c.after {
        Some(e) if !(e.rotation_deg <= LOOP_MAX_DEG && e.translation_mm <= max_mm) => {
            Err(MergeError::LoopOpen {
                view: e.view,
                rotation_deg: e.rotation_deg,
                translation_mm: e.translation_mm,
                max_mm,
            })
        }
        _ => Ok(()),
    }
}

/// The report's loop-closure line.
pub fn closure_line(c: &Closure) -> String {
    let show = |e: &Option<crate::refine::LoopError>| match e {
        Some(e) => format!("{:.3}° {:.3} mm", e.rotation_deg, e.translation_mm),
        None => "—".into(),
    };
    match (c.before, c.after) {
        (None, None) => "loop closure: no view besides those registered onto view 0 overlaps view 0 (no loop to close)\n".into(),
        (b, a) => format!(
            "loop closure (view {} onto view 0 directly against its pose): {} before the joint refinement, {} after\n",
            b.or(a).map_or(0, |e| e.view),
            show(&b),
            show(&a)
        ),
    }
}

/// Distinct colours for views, in order.
const COLOURS: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
    [210, 245, 60],
];

/// Each point's view colour, views in order (as [`registered_points`] lists the points).
pub fn view_colours(views: &[View]) -> Vec<[u8; 3]> {
    views
        .iter()
        .enumerate()
        .flat_map(|(k, v)| std::iter::repeat_n(COLOURS[k % COLOURS.len()], v.cloud.points.len()))
        .collect()
}

/// All views' points in one frame (`frame`: view 0's camera frame moved by it), each view in
/// its own colour, as a binary PLY with normals.
pub fn views_ply(views: &[View], results: &[ViewResult], frame: &MeshFrame) -> Vec<u8> {
    let m = mesh::Mesh {
        vertices: views
            .iter()
            .zip(results)
            .flat_map(|(v, r)| v.cloud.points.iter().map(move |p| (r.pose * p).cast()))
            .collect(),
        normals: views
            .iter()
            .zip(results)
            .flat_map(|(v, r)| v.cloud.normals.iter().map(move |n| (r.pose * n).cast()))
            .collect(),
        colours: views
            .iter()
            .enumerate()
            .flat_map(|(k, v)| {
                std::iter::repeat_n(COLOURS[k % COLOURS.len()], v.cloud.points.len())
            })
            .collect(),
        ..mesh::Mesh::default()
    };
    let mut m = m;
    m.into_frame(*frame);
    crate::export::ply(&m)
}

/// The report: per view its points (and how many of them lie clear of its edges, those the
/// joint refinement pairs), what it was registered onto, overlap and residual.
pub fn report(views: &[View], results: &[ViewResult]) -> String {
    let mut s = String::from(
        "view | points (clear of its edges) | registered onto | overlap | residual RMS | rotation from view 0\n",
    );
    for (k, (v, r)) in views.iter().zip(results).enumerate() {
        let (onto, overlap, rms) = match (&r.onto, &r.fit) {
            (Some(j), Some(f)) => (
                format!("view {j}"),
                format!("{:.0} %", 100.0 * f.overlap),
                format!("{:.3} mm", f.rms_mm),
            ),
            _ => ("(the reference)".into(), "—".into(), "—".into()),
        };
        let clear = v.clear.iter().filter(|&&c| c >= CLEAR).count();
        s += &format!(
            "{k} ({}) | {} ({clear}) | {onto} | {overlap} | {rms} | {:.3}°\n",
            v.path.display(),
            r.points,
            r.pose.rotation.angle().to_degrees()
        );
    }
    s
}

/// The centroid of all registered points (for pictures and checks).
pub fn centroid(views: &[View], results: &[ViewResult]) -> Point3<f64> {
    let (mut sum, mut n) = (Point3::origin().coords, 0usize);
    for (v, r) in views.iter().zip(results) {
        for p in &v.cloud.points {
            sum += (r.pose * p).coords;
            n += 1;
        }
    }
    Point3::from(sum / n.max(1) as f64)
}

/// All views' points and normals in view 0's frame.
pub fn registered_points(
    views: &[View],
    results: &[ViewResult],
) -> (Vec<Point3<f64>>, Vec<scanner_core::nalgebra::Vector3<f64>>) {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for (v, r) in views.iter().zip(results) {
        points.extend(v.cloud.points.iter().map(|p| r.pose * p));
        normals.extend(v.cloud.normals.iter().map(|n| r.pose * n));
    }
    (points, normals)
}

/// What the fusion and the pictures take: the registered points without isolated ones
/// ([`crate::fuse::inliers`]), their normals and each point's view colour.
pub struct FusionInput {
    /// Points, view 0's frame.
    pub points: Vec<Point3<f64>>,
    /// Their normals.
    pub normals: Vec<scanner_core::nalgebra::Vector3<f64>>,
    /// Their views' colours.
    pub colours: Vec<[u8; 3]>,
    /// The surface's colour at each point (empty unless every view carried colour).
    pub surface: Vec<[u8; 3]>,
    /// The fusion's weight of each point: 1 clear of its view's edges, down to [`EDGE_WEIGHT`]
    /// on one.
    pub weights: Vec<f64>,
}

/// [`registered_points`] without isolated points, with their view colours.
pub fn fusion_input(views: &[View], results: &[ViewResult]) -> FusionInput {
    let (points, normals) = registered_points(views, results);
    let colours = view_colours(views);
    let surface: Vec<[u8; 3]> = if views
        .iter()
        .all(|v| v.colours.len() == v.cloud.points.len())
    {
        views
            .iter()
            .flat_map(|v| v.colours.iter().copied())
            .collect()
    } else {
        Vec::new()
    };
    let weights: Vec<f64> = views
        .iter()
        .flat_map(|v| {
            (0..v.cloud.points.len())
                .map(|i| EDGE_WEIGHT + (1.0 - EDGE_WEIGHT) * v.clear.get(i).copied().unwrap_or(1.0))
        })
        .collect();
    let keep = crate::fuse::inliers(&points);
    FusionInput {
        weights: keep.iter().map(|&i| weights[i]).collect(),
        points: keep.iter().map(|&i| points[i]).collect(),
        normals: keep.iter().map(|&i| normals[i]).collect(),
        colours: keep.iter().map(|&i| colours[i]).collect(),
        surface: if surface.is_empty() {
            surface
        } else {
            keep.iter().map(|&i| surface[i]).collect()
        },
    }
}

/// The fused model of [`fuse_views`] and what the report says of it.
#[derive(Debug, Clone)]
pub struct Fused {
    /// The model, view 0's frame (camera coordinates).
    pub model: crate::mesh::Mesh,
    /// The share of its area no view saw (before any trimming).
    pub unseen_share: f64,
    /// The report's lines on the fusion.
    pub report: String,
}

/// How far from every point the model's surface counts as unseen, in fusion cells.
pub const UNSEEN_CELLS: f64 = 3.0;

/// Fuses the views' points ([`fusion_input`]) with cells of `cell` mm: closed (watertight) by
/// default, or with the surface no view saw removed (`trim_unseen`); coloured from the points
/// when they carry colour. `progress` sees the grid's slices done and in all.
///
/// # Errors
/// [`crate::fuse::FuseError`] from the fusion.
pub fn fuse_views(
    input: &FusionInput,
    cell: f64,
    trim_unseen: bool,
    progress: impl FnMut(usize, usize),
) -> Result<Fused, crate::fuse::FuseError> {
    let mut model = crate::fuse::fuse_with(
        &input.points,
        &input.normals,
        &input.weights,
        cell,
        progress,
    )?;
    let reach = UNSEEN_CELLS * cell;
    let unseen = crate::fuse::unseen_faces(&model, &input.points, reach);
    let unseen_share = crate::fuse::area_share(&model, &unseen);
    let mut report = if trim_unseen {
        let removed = crate::fuse::trim(&mut model, &unseen);
        format!(
            "trimmed {removed} faces ({:.1} % of the area) farther than {reach:.1} mm from every point: surface no view saw\n",
            100.0 * unseen_share
        )
    } else {
        format!(
            "surface no view saw (farther than {reach:.1} mm from every point): {:.1} % of the area, closed by the points' winding number (--trim-unseen removes it)\n",
            100.0 * unseen_share
        )
    };
    crate::fuse::colour_from(&mut model, &input.points, &input.surface);
    if !model.colours.is_empty() {
        report += "model coloured per vertex from the views (the nearest point's colour)\n";
    }
    let c = crate::fuse::check(&model);
    report += &format!(
        "model: {} vertices, {} faces, {}, {} component(s)\n",
        model.vertices.len(),
        model.faces.len(),
        if c.watertight {
            format!("watertight, volume {:.0} mm³", c.volume_mm3)
        } else {
            format!("{} open edges (no volume)", c.open_edges)
        },
        c.components,
    );
    Ok(Fused {
        model,
        unseen_share,
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::LoopError;

    fn closure(rotation_deg: f64, translation_mm: f64) -> Closure {
        let e = LoopError {
            view: 5,
            rotation_deg,
            translation_mm,
        };
        Closure {
            before: Some(e),
            after: Some(e),
        }
    }

    #[test]
    fn a_loop_left_open_refuses_the_merge_and_names_the_view() {
        // The 360° demo closes within 0.053° and 0.22 mm (docs/reports.md).
        assert!(check_closure(&closure(0.053, 0.219), 3.0).is_ok());
        // The part of flat faces at 60° steps (scanner-device/scenes/part-360.toml): 4.42° and
        // 22.2 mm; either limit alone refuses, and a loop error that is not a number refuses.
        for (deg, mm) in [(4.42, 22.2), (1.5, 0.5), (0.2, 3.5), (f64::NAN, 0.1)] {
            let e = check_closure(&closure(deg, mm), 3.0).unwrap_err();
            let text = e.to_string();
            assert!(
                matches!(e, MergeError::LoopOpen { view: 5, .. }) && text.contains("view 5"),
                "{text}"
            );
        }
        // No view closing a loop: nothing to check.
        let open = Closure {
            before: None,
            after: None,
        };
        assert!(check_closure(&open, 3.0).is_ok());
    }
}
