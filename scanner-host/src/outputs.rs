//! What a collection becomes: the mesh, the files and pictures, the summary; and a replay of a
//! journal or recording into a collector.

use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

use scanner_wire::{Control, Header, Skip};

use crate::collect::{CollectError, CollectOptions, Collector, Counts};
use crate::export::{self, ExportError};
use crate::grid::Grid;
use crate::mesh::{self, Mesh, MeshFrame, MeshOptions};
use scanner_core::nalgebra::{Point3, Vector3};

/// Why the outputs could not be made.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output folder cannot be created.
    #[error("cannot create the output folder {}", path.display())]
    Folder {
        /// The folder.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Nothing to build: no session header arrived.
    #[error(
        "no session header received ({bytes} bytes, {frames} frames, {rejected} rejected): nothing to build; is this a scanner stream?"
    )]
    NoHeader {
        /// Bytes read.
        bytes: u64,
        /// Frames decoded.
        frames: u64,
        /// Frames rejected.
        rejected: u64,
    },
    /// A file could not be written.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// The input of a replay cannot be opened.
    #[error(transparent)]
    Open(#[from] crate::link::InputError),
    /// The input of a replay cannot be read.
    #[error("cannot read {}", path.display())]
    Input {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The collection failed while replaying.
    #[error(transparent)]
    Collect(#[from] CollectError),
    /// A fixed-laser scan's model could not be made.
    #[error(transparent)]
    Platform(#[from] crate::platform::PlatformError),
}

/// What a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The counts.
    pub counts: Counts,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh faces.
    pub faces: usize,
    /// Vertices across short gaps between stripes, interpolated (see
    /// [`OutputOptions::bridge_gaps`]).
    pub bridged: usize,
    /// Cells without a vertex inside the surface (see [`interior_holes`]).
    pub interior_holes: usize,
    /// Filled cells over all cells of the grid.
    pub coverage: f64,
    /// Points per second of capture time.
    pub point_rate: f64,
    /// Outlier samples rejected by the grid.
    pub outliers: u64,
    /// The meshes' frame, described.
    pub frame: String,
    /// The vertices' standard uncertainty (the PLY's `quality`), mm: median and 95th
    /// percentile; `None` when the points carried none (a head before wire version 2).
    pub uncertainty: Option<(f32, f32)>,
    /// Points moved by the laser sheet's correction (`--sheet`), of all; `None`: not asked.
    pub sheet_moved: Option<u64>,
    /// A fixed-laser turntable scan's figures.
    pub fixed: Option<FixedFigures>,
    /// How its model agrees with another laser's of the same object, when compared.
    pub lasers: Option<crate::lasers::Agreement>,
}

/// What a fixed-laser turntable scan's model was made of (`summary.json` → `fixed`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FixedFigures {
    /// Which laser.
    pub laser: u8,
    /// Frames with points.
    pub frames: usize,
    /// The turn they cover, degrees.
    pub turned_deg: f64,
    /// Whether each frame's turn came measured (the platform's markers), not from the steps.
    pub turns_measured: bool,
    /// Frames left out because their turn was not measured (with `turns_measured`).
    pub frames_without_turn: usize,
    /// The object's points (in `cloud.ply`).
    pub object_points: usize,
    /// Points on the platform's top, left out.
    pub on_top: usize,
    /// Points beyond the platform's radius, left out.
    pub off_platform: usize,
    /// Points lit on what did not stand on the platform (the scanner's case): off the model,
    /// left out of `cloud.ply`.
    pub off_model: usize,
    /// The platform's surface as the points showed it: its height on the axis above the
    /// calibrated top, mm, and its tilt against it, degrees.
    pub floor_mm: f64,
    /// See `floor_mm`.
    pub floor_tilt_deg: f64,
    /// The fusion's cell, mm.
    pub cell_mm: f64,
    /// Whether the model is closed (every edge shared by two faces) and manifold.
    pub watertight: bool,
    /// The model's volume, mm³.
    pub volume_mm3: f64,
}

impl Summary {
    /// The summary as text lines.
    pub fn text(&self) -> String {
        let c = &self.counts;
        let d = &c.decode;
        // a fixed laser's points go to the platform's cloud, not the image grid
        let grid = if self.fixed.is_some() {
            String::new()
        } else {
            format!(" ({} in the grid, {} outliers)", c.gridded, self.outliers)
        };
        let coverage = if self.fixed.is_some() {
            String::new()
        } else {
            let bridged = if self.bridged > 0 {
                format!(
                    " ({} vertices across gaps between stripes, interpolated)",
                    self.bridged
                )
            } else {
                String::new()
            };
            format!(
                "{bridged}; {} holes inside the surface; coverage {:.1} % of the grid",
                self.interior_holes,
                100.0 * self.coverage
            )
        };
        let mut s = format!(
            "frames {} ({} point packets, {} headers) from {} scan(s); points {}{grid}; vertices {}, faces {}{coverage}; {:.0} points/s\n",
            d.frames,
            c.packets,
            c.headers,
            c.scans.len(),
            c.points,
            self.vertices,
            self.faces,
            self.point_rate
        );
        s += &format!(
            "link: {} bytes; rejected frames: {} bad CRC, {} bad COBS, {} unknown version, {} bad payload, {} oversize, {} truncated; {} packets with bad points, {} without a header, {} duplicates\n",
            d.bytes,
            d.bad_crc,
            d.bad_cobs,
            d.bad_version,
            d.bad_payload,
            d.oversize,
            d.truncated,
            c.bad_points,
            c.no_header,
            c.duplicates
        );
        if !c.other_camera.is_empty() {
            s += &format!(
                "warning: {} left out of the grid ({} points): their image size or camera differs from the first scan's; they are in the journal\n",
                c.other_camera
                    .iter()
                    .map(|id| format!("scan {id:08x}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                c.other_camera_points
            );
        }
        for (id, k) in &c.controls {
            s += &format!(
                "scan {id:08x} camera controls: {}\n",
                scanner_io::words::controls_line(k)
            );
            if k.named().iter().any(|(_, c)| *c == Control::Refused) {
                s += "warning: a control the difference image needs fixed was refused: the picture may drift between the reference and the laser frames\n";
            }
        }
        if c.previews > 0 && self.vertices == 0 {
            s += &format!(
                "a preview session: {} pictures, no points, no meshes\n",
                c.previews
            );
            for n in &c.notices {
                s += &format!("head: {}\n", scanner_io::words::notice_line(n));
            }
            return s;
        }
        s += &format!("meshes in the {}\n", self.frame);
        s += &match (self.uncertainty, &self.fixed) {
            (Some((median, p95)), _) => format!(
                "vertex uncertainty (scan.ply quality): median {median:.3} mm, 95 % below {p95:.3} mm\n"
            ),
            // the fused model of a turntable keeps no per-vertex uncertainty
            (None, Some(_)) => String::new(),
            (None, None) => "the points carried no uncertainty (a head before wire version 2): scan.ply has no quality\n".into(),
        };
        if let Some(f) = &self.fixed {
            s += &format!(
                "turntable, laser {}: {} frames over {:.1}°{}; {} object points in cloud.ply ({} on the platform's top, {} beyond its radius, {} off the object, left out); cell {:.2} mm; model {}, volume {:.0} mm³\n",
                f.laser,
                f.frames,
                f.turned_deg,
                if f.turns_measured {
                    format!(
                        ", each frame's turn from the platform's markers ({} frames without one left out)",
                        f.frames_without_turn
                    )
                } else {
                    String::new()
                },
                f.object_points,
                f.on_top,
                f.off_platform,
                f.off_model,
                f.cell_mm,
                if f.watertight {
                    "watertight"
                } else {
                    "NOT watertight"
                },
                f.volume_mm3
            );
        }
        if let Some(a) = &self.lasers {
            s += &format!(
                "laser {} against laser {} ({}): {:.2} mm apart (median, aligned; p90 {:.2} mm), volumes {:+.1} %, {:+.2} mm farther from the axis: {}\n",
                a.lasers[0],
                a.lasers[1],
                a.other,
                a.median_mm,
                a.p90_mm,
                100.0 * (a.volume_ratio - 1.0),
                a.radial_mm,
                match (a.agree, a.likely_cause, a.accepted) {
                    (true, _, _) => "they agree".to_string(),
                    (false, cause, accepted) => format!(
                        "they DISAGREE beyond {:.2} mm or 2 % in volume{}{}",
                        a.within_mm,
                        match cause {
                            Some("size") =>
                                ": one model is larger about the axis, as the platform's axis off sideways or a laser plane's offset makes it",
                            _ =>
                                ": their shapes differ, as a tilted laser plane (or the object moved) makes them",
                        },
                        if accepted { " (accepted)" } else { "" }
                    ),
                }
            );
        }
        if let Some(moved) = self.sheet_moved {
            s += &format!(
                "laser sheet (--sheet): {moved} of {} points moved to where its middle crosses the surface\n",
                c.points
            );
        }
        for n in &c.notices {
            s += &format!("head: {}\n", scanner_io::words::notice_line(n));
        }
        if c.previews > 0 {
            s += &format!("{} preview pictures received\n", c.previews);
        }
        let skipped = c.skipped();
        for r in Skip::ALL {
            if skipped[r as usize] > 0 {
                s += &format!(
                    "head skipped {} frames: {}\n",
                    skipped[r as usize],
                    scanner_io::words::skip_reason(r)
                );
            }
        }
        s
    }
}

/// A summary as data (`summary.json`): the figures [`Summary::text`] tells, field for field.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SummaryData {
    /// Frames decoded.
    pub frames: u64,
    /// Point packets received.
    pub point_packets: u64,
    /// Headers received.
    pub headers: u64,
    /// Scan ids seen.
    pub scans: Vec<u32>,
    /// Points received.
    pub points: u64,
    /// Points in the grid.
    pub gridded: u64,
    /// Samples the grid rejected as outliers.
    pub outliers: u64,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh faces.
    pub faces: usize,
    /// Vertices across short gaps between stripes: interpolated, not measured.
    pub bridged: usize,
    /// Grid cells without a vertex that have vertices within [`HOLE_REACH_CELLS`] on both
    /// sides along their row or their column: slits and holes inside the surface.
    pub interior_holes: usize,
    /// Filled cells over all cells of the grid (0–1).
    pub coverage: f64,
    /// Points per second of capture time.
    pub points_per_second: f64,
    /// What the link lost.
    pub link: LinkData,
    /// Scans left out of the grid (another image size or camera than the first).
    pub other_camera_scans: Vec<u32>,
    /// Their points.
    pub other_camera_points: u64,
    /// Each scan's camera controls, one entry per scan and control.
    pub controls: Vec<ControlData>,
    /// The meshes' frame, described.
    pub frame: String,
    /// The vertices' standard uncertainty, mm: median (`None`: the points carried none).
    pub uncertainty_median_mm: Option<f32>,
    /// …and 95th percentile.
    pub uncertainty_p95_mm: Option<f32>,
    /// Points moved by the laser sheet's correction (`--sheet`).
    pub sheet_moved: Option<u64>,
    /// Frames the head skipped, by reason (reasons with none left out).
    pub skipped: Vec<SkippedData>,
    /// Preview pictures received (`scanner-device preview`).
    pub previews: u64,
    /// The head's prompts and events, in order.
    pub notices: Vec<NoticeData>,
    /// A fixed-laser turntable scan's figures (absent for any other scan).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixed: Option<FixedFigures>,
    /// How its model agrees with another laser's (absent unless compared).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lasers: Option<crate::lasers::Agreement>,
}

/// One prompt or event of the head.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NoticeData {
    /// The scan.
    pub scan: u32,
    /// `taking_reference`, `switch_laser_on`, `laser_seen` or `no_laser`.
    pub kind: &'static str,
    /// What the head said.
    pub text: String,
}

/// The notices of `c` as data.
fn notice_data(c: &Counts) -> Vec<NoticeData> {
    c.notices
        .iter()
        .map(|n| NoticeData {
            scan: n.scan_id,
            kind: n.kind.name(),
            text: scanner_io::words::notice_line(n),
        })
        .collect()
}

/// One camera control of one scan, as its head reported it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ControlData {
    /// The scan.
    pub scan: u32,
    /// The control (`exposure`, `white balance`, `gain`, `focus`, `power line`).
    pub control: &'static str,
    /// `no_camera`, `not_offered`, `set` or `refused`.
    pub state: &'static str,
    /// With `set`: the value (V4L2's).
    pub value: Option<i32>,
}

/// Frames the head skipped for one reason.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SkippedData {
    /// The reason, as the head names it.
    pub reason: &'static str,
    /// Frames.
    pub frames: u64,
}

/// What the link lost, counted.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LinkData {
    /// Bytes read.
    pub bytes: u64,
    /// Frames rejected for a bad CRC.
    pub bad_crc: u64,
    /// …bad COBS framing.
    pub bad_cobs: u64,
    /// …an unknown wire version.
    pub bad_version: u64,
    /// …a payload that is no message.
    pub bad_payload: u64,
    /// …longer than the largest frame.
    pub oversize: u64,
    /// …too short.
    pub truncated: u64,
    /// Point packets whose points did not decode.
    pub bad_points: u64,
    /// Packets dropped without a header.
    pub no_header: u64,
    /// Packets received twice.
    pub duplicates: u64,
}

impl Summary {
    /// The summary as data.
    pub fn data(&self) -> SummaryData {
        let c = &self.counts;
        let d = &c.decode;
        let skipped = c.skipped();
        SummaryData {
            frames: d.frames,
            point_packets: c.packets,
            headers: c.headers,
            scans: c.scans.iter().copied().collect(),
            points: c.points,
            gridded: c.gridded,
            outliers: self.outliers,
            vertices: self.vertices,
            faces: self.faces,
            bridged: self.bridged,
            interior_holes: self.interior_holes,
            coverage: self.coverage,
            points_per_second: self.point_rate,
            link: LinkData {
                bytes: d.bytes,
                bad_crc: d.bad_crc,
                bad_cobs: d.bad_cobs,
                bad_version: d.bad_version,
                bad_payload: d.bad_payload,
                oversize: d.oversize,
                truncated: d.truncated,
                bad_points: c.bad_points,
                no_header: c.no_header,
                duplicates: c.duplicates,
            },
            other_camera_scans: c.other_camera.iter().copied().collect(),
            other_camera_points: c.other_camera_points,
            controls: c
                .controls
                .iter()
                .flat_map(|(&scan, k)| {
                    k.named().map(|(control, c)| {
                        let (state, value) = match c {
                            Control::NoCamera => ("no_camera", None),
                            Control::NotOffered => ("not_offered", None),
                            Control::Set(v) => ("set", Some(v)),
                            Control::Refused => ("refused", None),
                        };
                        ControlData {
                            scan,
                            control,
                            state,
                            value,
                        }
                    })
                })
                .collect(),
            frame: self.frame.clone(),
            uncertainty_median_mm: self.uncertainty.map(|u| u.0),
            uncertainty_p95_mm: self.uncertainty.map(|u| u.1),
            sheet_moved: self.sheet_moved,
            skipped: Skip::ALL
                .iter()
                .filter(|&&r| skipped[r as usize] > 0)
                .map(|&r| SkippedData {
                    reason: scanner_io::words::skip_reason(r),
                    frames: skipped[r as usize],
                })
                .collect(),
            previews: c.previews,
            notices: notice_data(c),
            fixed: self.fixed,
            lasers: self.lasers.clone(),
        }
    }
}

/// The files [`write_outputs`] makes, `summary.txt` last (also what the live view offers for
/// download when a receive ends).
pub const OUTPUT_FILES: [&str; 7] = [
    "scan.obj",
    "scan.ply",
    "scan.stl",
    "depth.png",
    "preview.png",
    "summary.json",
    "summary.txt",
];

/// Which frame the meshes are written in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameChoice {
    /// The board's, y up: the right way up in MeshLab, Blender, CloudCompare (default).
    #[default]
    Board,
    /// The camera's: +y down, +z forward, as the head sends the points.
    Camera,
}

/// How the outputs are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputOptions {
    /// Cells with fewer samples are left out of the mesh.
    pub min_count: u32,
    /// The meshes' frame.
    pub frame: FrameChoice,
    /// Short gaps between stripes bridged in the mesh ([`MeshOptions::bridge_cells`], up to
    /// [`mesh::EDGE_GAP_CELLS`] cells): the vertices there interpolated, not measured.
    pub bridge_gaps: bool,
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            min_count: 1,
            frame: FrameChoice::Board,
            bridge_gaps: true,
        }
    }
}

/// Writes every output of a collection into `dir`.
///
/// # Errors
/// No header ever arrived (nothing to grid), or a file cannot be written.
pub fn write_outputs(
    c: &Collector,
    dir: &Path,
    out: &OutputOptions,
) -> Result<Summary, OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Folder {
        path: dir.to_path_buf(),
        source,
    })?;
    let counts = c.counts();
    if c.header().is_none() && counts.previews > 0 {
        return preview_summary(counts, dir);
    }
    let (Some(grid), Some(header)) = (c.grid(), c.header()) else {
        let e = OutputError::NoHeader {
            bytes: counts.decode.bytes,
            frames: counts.decode.frames,
            rejected: counts.decode.rejected(),
        };
        // Meshes and pictures of an earlier run beside this run's error would be taken for its
        // result: they go (the journal they came from, if any, stays).
        for f in OUTPUT_FILES {
            let _ = std::fs::remove_file(dir.join(f));
        }
        let failed = serde_json::json!({
            "error": e.to_string(),
            "bytes": counts.decode.bytes,
            "frames": counts.decode.frames,
            "rejected": counts.decode.rejected(),
            "notices": notice_data(&counts),
        });
        export::write_atomic(&dir.join("summary.json"), failed.to_string().as_bytes())?;
        export::write_atomic(&dir.join("summary.txt"), e.to_string().as_bytes())?;
        return Err(e);
    };
    if let Some(f) = c.fixed() {
        return fixed_outputs(c, f, dir);
    }
    let m = camera_mesh(grid, header, (c.colour(), c.uncertainty()), out);
    // The pictures are the camera's view; then the meshes, in their frame, streamed to their
    // files (the mesh is never held twice in memory).
    export::write_atomic_with(&dir.join("depth.png"), |w| {
        export::write_png(&export::depth_png(grid, &m), w)
    })?;
    export::write_atomic_with(&dir.join("preview.png"), |w| {
        export::write_png(&export::shaded_png(grid, &m), w)
    })?;
    let mut m = m;
    if out.frame == FrameChoice::Board {
        let board = scanner_core::geometry::Board::<f32>::try_from(header.board).map_err(|e| {
            CollectError::Header {
                scan_id: header.scan_id,
                why: format!("its board gives no frame for the meshes ({e})"),
            }
        })?;
        m.into_frame(MeshFrame::board(&board));
    }
    export::write_files(mesh_files(dir, &m))?;
    let summary = Summary {
        point_rate: point_rate(&counts),
        counts,
        vertices: m.vertices.len(),
        faces: m.faces.len(),
        bridged: m.bridged.len(),
        interior_holes: interior_holes(&m.cells, (grid.cols, grid.rows)),
        coverage: grid.filled() as f64 / (grid.cols * grid.rows) as f64,
        outliers: grid.rejected(),
        frame: m.frame.describe(),
        uncertainty: quantiles(&m.quality),
        sheet_moved: c.sheet_corrected(),
        fixed: None,
        lasers: None,
    };
    write_summary(&summary, dir)?;
    Ok(summary)
}

/// A model's meshes in `dir`: `scan.obj`, `scan.ply` and `scan.stl`, for [`export::write_files`].
fn mesh_files<'a>(dir: &Path, m: &'a Mesh) -> Vec<(PathBuf, export::FileWriter<'a>)> {
    vec![
        (dir.join("scan.obj"), Box::new(|w| export::write_obj(m, w))),
        (dir.join("scan.ply"), Box::new(|w| export::write_ply(m, w))),
        (dir.join("scan.stl"), Box::new(|w| export::write_stl(m, w))),
    ]
}

/// The fusion's cell for a fixed-laser model: the object's size over this many, mm.
const FIXED_CELLS_ACROSS: f64 = 400.0;

/// A fixed-laser model's cell against the arc between neighbouring frames' stripes, at least:
/// the fusion's band (two cells) bridges the gap between stripes.
const FIXED_ARC_SHARE: f64 = 0.75;

/// At finer turns a fixed-laser model's cell is the geometric mean of the arc between
/// stripes and this share of the object's size: it shrinks as the square root of the frames,
/// so that the grid's cells along the surface grow as the points do (the model's cost grows
/// with the frames, not with their square), and it meets [`FIXED_ARC_SHARE`] of the arc at
/// about 100 frames a turn on a bust and on the rig's scene.
const FIXED_SIZE_SHARE: f64 = 0.01;

/// The finest fusion cell of a fixed-laser model, mm.
const FIXED_MIN_CELL_MM: f64 = 0.2;

/// The outputs of a fixed-laser turntable scan: `cloud.ply` (the points in the platform's
/// frame), the closed model with a flat base as `scan.obj`, `scan.ply`, `scan.stl` and
/// `scan.3mf` (y up the platform's axis), `preview.png` (the model from four sides) and the
/// summary. The camera's depth picture means nothing for frames of a turning object: none.
fn fixed_outputs(
    c: &Collector,
    f: &scanner_wire::FixedLaser,
    dir: &Path,
) -> Result<Summary, OutputError> {
    let _ = std::fs::remove_file(dir.join("depth.png"));
    let whole = crate::platform::platform_cloud(f, c.kept(), c.turns())?;
    // The model's size, cell and grid come from the object's points alone.
    let object = crate::platform::object(&whole, whole.step);
    let apart = object.iter().filter(|&&o| !o).count();
    let cloud = whole.only(&object);
    drop(whole);
    let (lo, hi) = cloud.points.iter().fold(
        (
            Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let size = (hi - lo).max();
    // Neighbouring frames' stripes lie a turn apart: the arc at the points' median distance
    // from the axis. The fusion's band must bridge it.
    let mut radii: Vec<f64> = cloud.points.iter().map(|p| p.x.hypot(p.y)).collect();
    radii.sort_by(f64::total_cmp);
    let arc = radii
        .get(radii.len() / 2)
        .map_or(0.0, |r| r * cloud.step.abs());
    let cell = if size.is_finite() {
        (size / FIXED_CELLS_ACROSS)
            .max(FIXED_MIN_CELL_MM)
            .max(FIXED_ARC_SHARE * arc)
            .max((arc * FIXED_SIZE_SHARE * size).sqrt())
    } else {
        1.0
    };
    let normals = crate::platform::normals(&cloud);
    let mut model = crate::platform::model(&cloud, &normals, cell, |_, _| {})?;
    let near = crate::platform::near_model(&cloud, &model, cell);
    let off_model = near.iter().filter(|&&n| !n).count();
    let y_up = |v: &Vector3<f64>| Vector3::new(v.x as f32, v.z as f32, -v.y as f32);
    let cloud_mesh = Mesh {
        vertices: cloud
            .points
            .iter()
            .zip(&near)
            .filter(|(_, n)| **n)
            .map(|(p, _)| Point3::from(y_up(&p.coords)))
            .collect(),
        normals: normals
            .iter()
            .zip(&near)
            .filter(|(_, n)| **n)
            .map(|(v, _)| y_up(v))
            .collect(),
        frame: MeshFrame::Platform,
        ..Mesh::default()
    };
    let check = scanner_merge::fuse::check(&model);
    crate::platform::y_up(&mut model);
    let m = Mesh {
        frame: MeshFrame::Platform,
        ..Mesh::from(model)
    };
    let (m, cloud_mesh) = (&m, &cloud_mesh);
    let mut files = mesh_files(dir, m);
    files.extend::<[(PathBuf, export::FileWriter); 3]>([
        (dir.join("scan.3mf"), Box::new(|w| export::write_3mf(m, w))),
        (
            dir.join("preview.png"),
            Box::new(|w| export::write_png(&export::orbit_png(m), w)),
        ),
        (
            dir.join("cloud.ply"),
            Box::new(|w| export::write_ply(cloud_mesh, w)),
        ),
    ]);
    export::write_files(files)?;
    let counts = c.counts();
    let summary = Summary {
        point_rate: point_rate(&counts),
        counts,
        vertices: m.vertices.len(),
        faces: m.faces.len(),
        bridged: m.bridged.len(),
        interior_holes: 0,
        coverage: 0.0,
        outliers: 0,
        frame: m.frame.describe(),
        uncertainty: None,
        sheet_moved: None,
        fixed: Some(FixedFigures {
            laser: f.laser,
            frames: cloud.frames,
            turned_deg: cloud.turned_deg,
            turns_measured: cloud.measured,
            frames_without_turn: cloud.unmeasured,
            object_points: cloud.points.len() - off_model,
            on_top: cloud.on_top,
            off_platform: cloud.off_platform,
            off_model: off_model + apart,
            floor_mm: cloud.floor.at - crate::platform::TOP_MARGIN_MM,
            floor_tilt_deg: cloud.floor.up.z.clamp(-1.0, 1.0).acos().to_degrees(),
            cell_mm: cell,
            watertight: check.watertight && check.nonmanifold_vertices == 0,
            volume_mm3: check.volume_mm3,
        }),
        lasers: None,
    };
    write_summary(&summary, dir)?;
    Ok(summary)
}

/// A cell without a vertex counts as a hole inside the surface when vertices lie within this
/// many cells of it on both sides, along its row or its column.
pub const HOLE_REACH_CELLS: usize = 3;

/// The cells of a `cols`×`rows` grid without a vertex (`cells`: those with one) that have
/// vertices within [`HOLE_REACH_CELLS`] on both sides along their row or their column.
pub fn interior_holes(cells: &[(u32, u32)], (cols, rows): (usize, usize)) -> usize {
    let mut has = vec![false; cols * rows];
    for &(c, r) in cells {
        if let Some(h) = has.get_mut(r as usize * cols + c as usize) {
            *h = true;
        }
    }
    let at = |c: isize, r: isize| {
        c >= 0
            && r >= 0
            && (c as usize) < cols
            && (r as usize) < rows
            && has[r as usize * cols + c as usize]
    };
    let near = |c: usize, r: usize, step: (isize, isize)| {
        (1..=HOLE_REACH_CELLS as isize)
            .any(|k| at(c as isize + step.0 * k, r as isize + step.1 * k))
    };
    (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (c, r)))
        .filter(|&(c, r)| {
            !has[r * cols + c]
                && ((near(c, r, (0, -1)) && near(c, r, (0, 1)))
                    || (near(c, r, (-1, 0)) && near(c, r, (1, 0))))
        })
        .count()
}

/// Points per second of the frames' capture time (0 without a span).
fn point_rate(counts: &Counts) -> f64 {
    let span = counts.time_us.map_or(0.0, |(a, b)| (b - a) as f64 / 1e6);
    if span > 0.0 {
        counts.points as f64 / span
    } else {
        0.0
    }
}

/// The summary of a preview session (`scanner-device preview`: pictures, no points, so no
/// mesh): the counts, with every mesh figure zero; meshes of an earlier run in `dir` go.
fn preview_summary(counts: Counts, dir: &Path) -> Result<Summary, OutputError> {
    for f in OUTPUT_FILES {
        let _ = std::fs::remove_file(dir.join(f));
    }
    let summary = Summary {
        counts,
        vertices: 0,
        faces: 0,
        bridged: 0,
        interior_holes: 0,
        coverage: 0.0,
        point_rate: 0.0,
        outliers: 0,
        frame: "none: a preview session sends pictures, no points".into(),
        uncertainty: None,
        sheet_moved: None,
        fixed: None,
        lasers: None,
    };
    write_summary(&summary, dir)?;
    Ok(summary)
}

/// Writes `summary.json` and `summary.txt` into `dir`.
///
/// # Errors
/// A file cannot be written.
pub fn write_summary(summary: &Summary, dir: &Path) -> Result<(), OutputError> {
    let json = serde_json::to_vec_pretty(&summary.data()).map_err(|e| ExportError::Write {
        path: dir.join("summary.json"),
        source: std::io::Error::other(e),
    })?;
    export::write_atomic(&dir.join("summary.json"), &json)?;
    export::write_atomic(&dir.join("summary.txt"), summary.text().as_bytes())?;
    Ok(())
}

/// The median and 95th percentile of `v` (`None` when empty).
fn quantiles(v: &[f32]) -> Option<(f32, f32)> {
    let mut s: Vec<f32> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return None;
    }
    s.sort_by(f32::total_cmp);
    Some((s[s.len() / 2], s[(s.len() * 95 / 100).min(s.len() - 1)]))
}

/// The mesh of a collection's grid, in camera coordinates (the one [`write_outputs`] writes;
/// `None` before a header arrived).
pub fn mesh_of(c: &Collector, out: &OutputOptions) -> Option<Mesh> {
    Some(camera_mesh(
        c.grid()?,
        c.header()?,
        (c.colour(), c.uncertainty()),
        out,
    ))
}

/// The mesh with the cells' colours and uncertainties where the points carried them.
fn camera_mesh(
    grid: &Grid,
    header: &Header,
    (colour, uncertainty): (bool, bool),
    out: &OutputOptions,
) -> Mesh {
    let opts = MeshOptions {
        min_count: out.min_count,
        bridge_cells: if out.bridge_gaps {
            mesh::EDGE_GAP_CELLS
        } else {
            0
        },
        ..MeshOptions::default()
    };
    let mut m = mesh::build(grid, f64::from(header.camera.fx), &opts, colour);
    if uncertainty {
        let measured = m.vertices.len() - m.bridged.len();
        m.quality = m.cells[..measured]
            .iter()
            .map(|&(c, r)| grid.at(c as usize, r as usize).uncertainty())
            .collect();
        // a vertex across a gap: as uncertain as the less certain of its two ends
        for &[a, b] in &m.bridged {
            let q = m.quality[a as usize].max(m.quality[b as usize]);
            m.quality.push(q);
        }
    }
    m
}

/// Feeds a whole file (a journal or a recording) into a collector.
///
/// # Errors
/// The file cannot be read.
pub fn replay_into(c: &mut Collector, input: &Path) -> Result<(), OutputError> {
    replay_from(c, input, 0)
}

/// Feeds a file into a collector from byte `from` on (a journal's later session: it starts
/// where the journal ended before it).
///
/// # Errors
/// The file cannot be read.
pub fn replay_from(c: &mut Collector, input: &Path, from: u64) -> Result<(), OutputError> {
    let io = |source| OutputError::Input {
        path: input.to_path_buf(),
        source,
    };
    let mut f = crate::link::open_file(input)?;
    f.seek(std::io::SeekFrom::Start(from)).map_err(io)?;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf).map_err(io)?;
        if n == 0 {
            c.finish();
            return Ok(());
        }
        c.feed(&buf[..n])?;
    }
}

/// The laser sheet's correction for a collection (see [`crate::thickness`]): the surface its grid's
/// mesh gives, each frame's points moved for a sheet of Gaussian thickness `sigma_mm`, the
/// light's source from its planes. `None` before a header arrived.
pub fn sheet_correction(c: &Collector, sigma_mm: f64) -> Option<crate::thickness::Correction> {
    let (grid, header) = (c.grid()?, c.header()?);
    let m = mesh::build(
        grid,
        f64::from(header.camera.fx),
        &MeshOptions::default(),
        false,
    );
    Some(crate::thickness::Correction::new(
        &m.vertices.iter().map(|p| p.cast()).collect::<Vec<_>>(),
        &m.normals.iter().map(|n| n.cast()).collect::<Vec<_>>(),
        f64::from(header.camera.fy),
        sigma_mm,
        c.light_source(),
    ))
}

/// A file (a journal or a recording) collected with `opts`; with `sheet_mm` (the laser sheet's
/// Gaussian thickness) above 0 it is read twice, the second time with each frame's points moved
/// to where the sheet's middle crosses the surface the first reading found.
///
/// # Errors
/// The file cannot be read.
pub fn replay(opts: CollectOptions, input: &Path, sheet_mm: f64) -> Result<Collector, OutputError> {
    let mut c = Collector::new(opts, None);
    replay_into(&mut c, input)?;
    let correction = (sheet_mm > 0.0)
        .then(|| sheet_correction(&c, sheet_mm))
        .flatten();
    match correction {
        Some(correction) => replay_corrected(opts, input, 0, correction),
        None => Ok(c),
    }
}

/// A file collected with `opts` from byte `from` on, each frame's points moved by the sheet's
/// `correction`.
///
/// # Errors
/// The file cannot be read.
pub fn replay_corrected(
    opts: CollectOptions,
    input: &Path,
    from: u64,
    correction: crate::thickness::Correction,
) -> Result<Collector, OutputError> {
    let mut c = Collector::new(opts, None);
    c.correct_sheet(correction);
    replay_from(&mut c, input, from)?;
    Ok(c)
}
