//! Two lasers of one turntable scanner held against each other: the model one laser made of an
//! object (a receive's output folder) against the model the other laser made of it, aligned
//! first (two recordings: the object may have stood otherwise), their distance, their volumes,
//! and which way they differ. Calibrated right, both see one surface; a platform axis off
//! sideways or a laser plane's offset makes one model larger about the axis than the other,
//! a tilted plane bends one.

use std::path::Path;

use scanner_core::nalgebra::{Isometry3, Point3};
use scanner_merge::spatial::{Cloud, normals, tree};

/// The largest models compared, vertices (each is thinned to 60 000 first).
pub const MAX_VERTICES: usize = 5_000_000;

/// The largest model file read, bytes (a model of [`MAX_VERTICES`] vertices is under it).
pub const MAX_OBJ_BYTES: u64 = 1 << 30;

/// Vertices of each model used in the comparison.
const SAMPLES: usize = 60_000;

/// Why two lasers' models cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum LasersError {
    /// A folder's model cannot be read.
    #[error("cannot read the model {}", path.display())]
    Model {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: tobj::LoadError,
    },
    /// A folder's summary cannot be read, or is not a turntable scan's.
    #[error("{}: not the summary of a turntable scan (summary.json with its `fixed` block)", path.display())]
    Summary {
        /// The file.
        path: std::path::PathBuf,
    },
    /// A model file larger than [`MAX_OBJ_BYTES`].
    #[error("{}: {bytes} bytes, more than the {MAX_OBJ_BYTES} of a model to compare", path.display())]
    TooLarge {
        /// The file.
        path: std::path::PathBuf,
        /// Its size.
        bytes: u64,
    },
    /// Not a turntable scan: nothing to hold another laser's model against.
    #[error(
        "--other-laser compares two lasers of a turntable scanner: this is not a turntable scan"
    )]
    NotTurntable,
    /// A distance to agree within that is none.
    #[error("--agree-within {0} mm: give a distance above 0 and at most 100 mm")]
    Within(f64),
    /// The two lasers' models disagree.
    #[error(
        "the two lasers' models disagree: {median_mm:.2} mm apart (median, more than {within_mm} mm) and volumes {volume_pct:+.1} % apart; {}. The model is written but not done: check the calibration (docs/turntable-scanners.md), or give --accept-disagreement",
        if *cause == "size" { "one is larger about the axis: the platform's axis off sideways, or a laser plane's offset" } else { "their shapes differ: a laser plane tilted, or the object moved" }
    )]
    Disagree {
        /// Their distance, median, mm.
        median_mm: f64,
        /// Their volumes' difference, %.
        volume_pct: f64,
        /// The distance allowed, mm.
        within_mm: f64,
        /// The likely cause ([`Agreement::likely_cause`]).
        cause: &'static str,
    },
    /// A model with too few vertices, or too many, to compare.
    #[error("{}: {vertices} vertices, not a model to compare (100 to {MAX_VERTICES})", path.display())]
    Size {
        /// The file.
        path: std::path::PathBuf,
        /// Its vertices.
        vertices: usize,
    },
}

/// How two lasers' models of one object agree (`summary.json` → `lasers`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Agreement {
    /// The other laser's output folder.
    pub other: String,
    /// This scan's laser and the other's.
    pub lasers: [u8; 2],
    /// This model's vertices' distance from the other's surface after aligning: median, mm.
    pub median_mm: f64,
    /// …and 90th percentile, mm.
    pub p90_mm: f64,
    /// This model's volume over the other's.
    pub volume_ratio: f64,
    /// How much farther from the axis this model's surface lies than the other's (mean over
    /// matched points, aligned), mm: a difference in size.
    pub radial_mm: f64,
    /// The median distance allowed, mm (and volumes within 2 %).
    pub within_mm: f64,
    /// Whether the two agree within it.
    pub agree: bool,
    /// When they do not: the likely cause, `size` (the axis off sideways or a laser plane's
    /// offset: one model larger about the axis) or `shape` (a laser plane tilted, or the object
    /// moved between the recordings).
    pub likely_cause: Option<&'static str>,
    /// Whether a disagreement was accepted (`--accept-disagreement`).
    pub accepted: bool,
}

/// Volumes within this share of each other agree.
const VOLUME_SHARE: f64 = 0.02;

/// The model of the receive folder `this` against the model of the folder `other`: aligned
/// by ICP (10, 5, then 2 mm), the distances of this model's vertices from the other's surface.
///
/// # Errors
/// [`LasersError`]: a model or a summary that cannot be read.
pub fn agreement(this: &Path, other: &Path, within_mm: f64) -> Result<Agreement, LasersError> {
    let (a, b) = (model(this)?, model(other)?);
    let (va, la) = figures(this)?;
    let (vb, lb) = figures(other)?;
    let mut pose = Isometry3::identity();
    for max in [10.0, 5.0, 2.0] {
        pose = scanner_merge::pose::icp(&a, &b, pose, max, 40).pose;
    }
    let t = tree(&b.points);
    let mut d = Vec::with_capacity(a.points.len());
    let mut radial = 0.0;
    for p in &a.points {
        let q = pose * p;
        let n = t.nearest_one::<kiddo::SquaredEuclidean>(&[q.x, q.y, q.z]);
        let i = n.item as usize;
        d.push((q - b.points[i]).dot(&b.normals[i]).abs());
        // y up the axis: the distance from it in x and z
        radial += q.x.hypot(q.z) - b.points[i].x.hypot(b.points[i].z);
    }
    d.sort_by(f64::total_cmp);
    let median_mm = d[d.len() / 2];
    let p90_mm = d[d.len() * 9 / 10];
    let radial_mm = radial / a.points.len() as f64;
    let volume_ratio = va / vb;
    let agree = median_mm <= within_mm && (volume_ratio - 1.0).abs() <= VOLUME_SHARE;
    let likely_cause = (!agree).then_some(if radial_mm.abs() >= 0.5 * median_mm {
        "size"
    } else {
        "shape"
    });
    Ok(Agreement {
        other: other.display().to_string(),
        lasers: [la, lb],
        median_mm,
        p90_mm,
        volume_ratio,
        radial_mm,
        within_mm,
        agree,
        likely_cause,
        accepted: false,
    })
}

/// A folder's model (`scan.obj`, y up the platform's axis), thinned, with its normals.
fn model(dir: &Path) -> Result<Cloud, LasersError> {
    let path = dir.join("scan.obj");
    if let Ok(m) = std::fs::metadata(&path)
        && m.len() > MAX_OBJ_BYTES
    {
        return Err(LasersError::TooLarge {
            path,
            bytes: m.len(),
        });
    }
    let (models, _) = tobj::load_obj(&path, &tobj::LoadOptions::default()).map_err(|source| {
        LasersError::Model {
            path: path.clone(),
            source,
        }
    })?;
    let all: usize = models.iter().map(|m| m.mesh.positions.len() / 3).sum();
    if !(100..=MAX_VERTICES).contains(&all) {
        return Err(LasersError::Size {
            path,
            vertices: all,
        });
    }
    let step = all.div_ceil(SAMPLES).max(1);
    let points: Vec<Point3<f64>> = models
        .iter()
        .flat_map(|m| m.mesh.positions.chunks_exact(3))
        .step_by(step)
        .map(|v| Point3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
        .collect();
    let normals = normals(&points, 12);
    Ok(Cloud { points, normals })
}

/// A turntable scan's summary: its model's volume, mm³, and its laser.
fn figures(dir: &Path) -> Result<(f64, u8), LasersError> {
    #[derive(serde::Deserialize)]
    struct Fixed {
        volume_mm3: f64,
        laser: u8,
    }
    #[derive(serde::Deserialize)]
    struct Summary {
        fixed: Fixed,
    }
    let path = dir.join("summary.json");
    let bad = || LasersError::Summary { path: path.clone() };
    let text = scanner_io::text_file::read(&path).map_err(|_| bad())?;
    let s: Summary = serde_json::from_str(&text).map_err(|_| bad())?;
    if !(s.fixed.volume_mm3.is_finite() && s.fixed.volume_mm3 > 0.0) {
        return Err(bad());
    }
    Ok((s.fixed.volume_mm3, s.fixed.laser))
}
