//! A fixed-laser turntable scan's model: every frame's points carried into the turning
//! platform's frame (where the object stands still), the platform itself and what lies off it
//! left out, normals towards the camera that saw each point, and one closed mesh with a flat
//! base — the whole 360° from one pass, with no registration.

use scanner_core::geometry::Platform;
use scanner_core::nalgebra::{Matrix3, Point3, Vector3};
use scanner_merge::fuse::{self, HalfSpace};
use scanner_merge::{Model, spatial};
use scanner_wire::FixedLaser;

use crate::collect::KeptFrame;

/// Points within this height of the platform's top are the platform's, mm: its surface is
/// never the object (the head's own margin is its `board_tol`; this is the host's, for the
/// points it receives).
pub const TOP_MARGIN_MM: f64 = 1.0;

/// Cloud points farther than this many cells from the model are not the object's: they were
/// lit on something that did not stand on the platform (its piece of the model went).
pub const OFF_MODEL_CELLS: f64 = 2.0;

/// Neighbours of a point its normal is fitted to.
const NORMAL_NEIGHBOURS: usize = 48;

/// Why a fixed-laser model cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum PlatformError {
    /// The platform in the scan's message is not a pose.
    #[error("the scan's platform is unusable: {0}")]
    Platform(scanner_core::GeomError),
    /// The turn per frame is not a number, or 0.
    #[error("the scan's turn per frame is {0} rad: the platform would not turn")]
    Turn(f32),
    /// The fusion failed.
    #[error(transparent)]
    Fuse(#[from] scanner_merge::error::FuseError),
}

/// A fixed-laser scan's points in the platform's frame (`z` up the axis, origin on the axis at
/// its top).
#[derive(Debug, Clone)]
pub struct PlatformCloud {
    /// The object's points.
    pub points: Vec<Point3<f64>>,
    /// Where the camera was, seen from the platform, when each point was taken.
    pub seen_from: Vec<Point3<f64>>,
    /// Whether each point was lit where something looked the same at every turn (a cell of the
    /// camera's view lit in a quarter of the frames or more).
    pub still: Vec<bool>,
    /// Points on (or below) the platform's top, left out.
    pub on_top: usize,
    /// Points farther from the axis than the platform's radius, left out.
    pub off_platform: usize,
    /// The platform's surface as the points showed it (the plane of the low points that
    /// stood still while the platform turned), [`TOP_MARGIN_MM`] above it: what the model keeps.
    pub floor: HalfSpace,
    /// Frames in the cloud.
    pub frames: usize,
    /// The turns the frames cover, degrees (from the first to the last frame).
    pub turned_deg: f64,
    /// The median distance between neighbouring points along one frame's stripe, mm (0: none).
    pub stripe_spacing: f64,
    /// The platform's turn per frame, radians: the scan's, or with measured turns the mean
    /// from the first frame to the last.
    pub step: f64,
    /// Whether the frames' turns were measured (markers on the platform): then frames without
    /// one are left out.
    pub measured: bool,
    /// Frames left out because their turn was not measured.
    pub unmeasured: usize,
}

/// The platform of a scan's message.
///
/// # Errors
/// [`PlatformError::Platform`] for numbers that are not a pose.
pub fn platform_of(f: &FixedLaser) -> Result<Platform<f64>, PlatformError> {
    let r = f.rotation.map(f64::from);
    Platform::new(
        Matrix3::new(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]),
        Point3::from(f.origin.map(f64::from)),
    )
    .map_err(PlatformError::Platform)
}

/// The points of scan `f.scan_id`'s frames in the platform's frame, frame `k` turned back by
/// its measured turn in `turns` (by scan id and frame) where the scan has any — frames without
/// one left out — and by `k · turn` where it has none; the platform's surface as the points
/// show it and what lies beyond its radius left out.
///
/// # Errors
/// An unusable platform, or a turn per frame that is no turn where none was measured.
pub fn platform_cloud(
    f: &FixedLaser,
    frames: &[KeptFrame],
    turns: &std::collections::BTreeMap<(u32, u32), f64>,
) -> Result<PlatformCloud, PlatformError> {
    let platform = platform_of(f)?;
    let measured = turns
        .range((f.scan_id, 0)..=(f.scan_id, u32::MAX))
        .next()
        .is_some();
    let steady = f.turn.is_finite() && f.turn != 0.0;
    if !(measured || steady) {
        return Err(PlatformError::Turn(f.turn));
    }
    let radius = f64::from(f.radius);
    let still = still_cells(f.scan_id, frames);
    let mut all = Vec::new();
    let mut low_still = Vec::new();
    let mut cloud = PlatformCloud {
        points: Vec::new(),
        seen_from: Vec::new(),
        still: Vec::new(),
        on_top: 0,
        off_platform: 0,
        floor: HalfSpace {
            up: Vector3::z(),
            at: TOP_MARGIN_MM,
        },
        frames: 0,
        turned_deg: 0.0,
        stripe_spacing: 0.0,
        step: f64::from(f.turn),
        measured,
        unmeasured: 0,
    };
    let mut steps = Vec::new();
    // the first and the last frame, with their turns
    let (mut first, mut last) = ((u32::MAX, 0.0), (0, 0.0));
    for k in frames.iter().filter(|k| k.scan_id == f.scan_id) {
        let angle = if measured {
            let Some(&a) = turns.get(&(f.scan_id, k.frame)) else {
                cloud.unmeasured += 1;
                continue;
            };
            a
        } else {
            f64::from(k.frame) * f64::from(f.turn)
        };
        let eye = platform.camera_centre(angle);
        cloud.frames += 1;
        if k.frame < first.0 {
            first = (k.frame, angle);
        }
        if k.frame >= last.0 {
            last = (k.frame, angle);
        }
        steps.extend(k.points.windows(2).map(|w| (w[1] - w[0]).norm()));
        for p in &k.points {
            let q = platform.to_platform(&p.cast(), angle);
            let is_still = still.contains(&cell_of(p));
            if is_still && q.z < FLOOR_SEARCH_MM {
                low_still.push(q);
            }
            all.push((q, eye, is_still));
        }
    }
    if !steps.is_empty() {
        let mid = steps.len() / 2;
        cloud.stripe_spacing = f64::from(*steps.select_nth_unstable_by(mid, f32::total_cmp).1);
    }
    cloud.floor = floor(&low_still);
    let top = cloud.floor;
    for (q, eye, is_still) in all {
        if top.up.dot(&q.coords) < top.at {
            cloud.on_top += 1;
        } else if radius > 0.0 && q.x.hypot(q.y) > radius {
            cloud.off_platform += 1;
        } else {
            cloud.points.push(q);
            cloud.seen_from.push(eye);
            cloud.still.push(is_still);
        }
    }
    if cloud.frames > 0 {
        cloud.turned_deg = (last.1 - first.1).to_degrees().abs();
        if measured && last.0 > first.0 {
            cloud.step = (last.1 - first.1) / f64::from(last.0 - first.0);
        }
    }
    Ok(cloud)
}

/// Still points this low (mm above the calibrated top) may be the platform's surface.
const FLOOR_SEARCH_MM: f64 = 10.0;

/// Fewest still points that show the platform's surface.
const FLOOR_POINTS: usize = 50;

/// The platform's surface as the points show it, and [`TOP_MARGIN_MM`] above it: the plane
/// fitted to the low points that stood still in the camera's view while the platform turned
/// (a turning disc looks the same at every turn, so the laser lights it at the same pixels),
/// their farthest fifth from it dropped and the plane fitted again. A calibration's top is a
/// millimetre or two off the surface (the pattern's height above it is measured by hand, the
/// disc may wobble): without this, a ring of the platform's surface stays on the model's
/// foot. The calibrated top when too few such points are seen, or their plane tilts more than
/// [`FLOOR_TILT_DEG`] from it.
fn floor(low: &[Point3<f64>]) -> HalfSpace {
    let calibrated = HalfSpace {
        up: Vector3::z(),
        at: TOP_MARGIN_MM,
    };
    if low.len() < FLOOR_POINTS {
        return calibrated;
    }
    let Ok(first) = scanner_core::geometry::fit_plane(low.iter().copied()) else {
        return calibrated;
    };
    let mut d: Vec<f64> = low
        .iter()
        .map(|p| first.plane.signed_distance(p).abs())
        .collect();
    d.sort_by(f64::total_cmp);
    let cut = d[d.len() * 4 / 5];
    let kept = low
        .iter()
        .copied()
        .filter(|p| first.plane.signed_distance(p).abs() <= cut);
    let Ok(fit) = scanner_core::geometry::fit_plane(kept) else {
        return calibrated;
    };
    let n = *fit.plane.normal();
    let up = if n.z < 0.0 { -n } else { n };
    if up.z < FLOOR_TILT_DEG.to_radians().cos() {
        return calibrated;
    }
    // the plane n·x + d = 0 with n up: up·x ≥ −d (+ margin) is above it
    let offset = if n.z < 0.0 {
        -fit.plane.offset()
    } else {
        fit.plane.offset()
    };
    HalfSpace {
        up,
        at: (-offset + TOP_MARGIN_MM).max(TOP_MARGIN_MM),
    }
}

/// Largest tilt of the platform's surface seen in the points against the calibrated top,
/// degrees.
const FLOOR_TILT_DEG: f64 = 3.0;

/// The camera-frame cells of [`STILL_CELL_MM`] that [`still_cells`] counts in.
fn cell_of(p: &Point3<f32>) -> (i32, i32, i32) {
    let c = |v: f32| (v / STILL_CELL_MM).floor() as i32;
    (c(p.x), c(p.y), c(p.z))
}

/// A cell of the camera's view lit in at least this share of a scan's frames holds something
/// that looks the same at every turn.
const STILL_SHARE: f64 = 0.25;

/// The side of the camera-frame cells [`still_cells`] counts in, mm.
const STILL_CELL_MM: f32 = 1.0;

/// The camera-frame cells lit in at least [`STILL_SHARE`] of scan `scan_id`'s frames (and in
/// five at least): the laser on something that looks the same at every turn — the platform's
/// surface, the scanner's case, but also an object's part that is round about the axis (a
/// vase's foot), so that stillness alone never takes a point from the object.
fn still_cells(scan_id: u32, frames: &[KeptFrame]) -> std::collections::HashSet<(i32, i32, i32)> {
    let mut lit: std::collections::HashMap<(i32, i32, i32), (u32, u32)> =
        std::collections::HashMap::new();
    let mut n = 0usize;
    for k in frames.iter().filter(|k| k.scan_id == scan_id) {
        n += 1;
        for p in &k.points {
            let e = lit.entry(cell_of(p)).or_insert((u32::MAX, 0));
            if e.0 != k.frame {
                *e = (k.frame, e.1 + 1);
            }
        }
    }
    let need = ((n as f64 * STILL_SHARE).ceil() as u32).max(5);
    lit.into_iter()
        .filter(|(_, (_, count))| *count >= need)
        .map(|(c, _)| c)
        .collect()
}

/// Points of a cloud are joined into pieces through cubes of this side, mm, at least (and
/// twice the arc between neighbouring stripes at the cloud's outermost points): the gap a
/// piece of one object never shows.
const JOIN_MM: f64 = 3.0;

/// A piece that does not reach down to the platform's top is the object's (a part seen apart
/// from the rest) only when it holds at least this share of the cloud's points and is not made
/// mostly of still points.
const FLOATER_SHARE: f64 = 0.02;

/// Which of `cloud`'s points are the object's, its platform turning `turn` radians a frame:
/// the points joined into pieces (through touching cubes of 3 mm or more), the pieces
/// that reach down to the platform's top kept, and those apart from it kept only when they
/// hold 2 % of the points and most of them moved with the platform. What is left
/// out is something lit that did not stand on the platform (the scanner's case above it, a
/// wall behind: still things that the turn back spreads into rings) or scattered noise — which
/// would otherwise set the model's size and cell and cost the fusion most of its time. When no
/// piece reaches the top, every point is kept.
pub fn object(cloud: &PlatformCloud, turn: f64) -> Vec<bool> {
    let n = cloud.points.len();
    let mut radii: Vec<f64> = cloud.points.iter().map(|p| p.x.hypot(p.y)).collect();
    radii.sort_by(f64::total_cmp);
    let outer = radii.get(n * 99 / 100).copied().unwrap_or(0.0);
    let side = JOIN_MM.max(2.0 * outer * turn.abs());
    let key = |p: &Point3<f64>| {
        let c = |v: f64| (v / side).floor() as i64;
        (c(p.x), c(p.y), c(p.z))
    };
    let mut cubes: std::collections::HashMap<(i64, i64, i64), usize> =
        std::collections::HashMap::new();
    let of_point: Vec<usize> = cloud
        .points
        .iter()
        .map(|p| {
            let next = cubes.len();
            *cubes.entry(key(p)).or_insert(next)
        })
        .collect();
    let mut parent: Vec<usize> = (0..cubes.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (&(x, y, z), &i) in &cubes {
        for (dx, dy, dz) in (-1..=1)
            .flat_map(|dx| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dz| (dx, dy, dz))))
        {
            if let Some(&j) = cubes.get(&(x + dx, y + dy, z + dz)) {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a] = b;
            }
        }
    }
    // per piece: points, still points, whether it reaches down to the top
    let mut pieces = vec![(0usize, 0usize, false); parent.len()];
    let top = cloud.floor;
    for ((p, &still), &c) in cloud.points.iter().zip(&cloud.still).zip(&of_point) {
        let r = root(&mut parent, c);
        let e = &mut pieces[r];
        e.0 += 1;
        e.1 += usize::from(still);
        e.2 |= top.up.dot(&p.coords) - top.at <= side;
    }
    if !pieces.iter().any(|e| e.2) {
        return vec![true; n];
    }
    let least = FLOATER_SHARE * n as f64;
    let keep: Vec<bool> = pieces
        .iter()
        .map(|&(all, still, low)| low || (all as f64 >= least && 2 * still <= all))
        .collect();
    of_point
        .iter()
        .map(|&c| keep[root(&mut parent, c)])
        .collect()
}

impl PlatformCloud {
    /// The cloud of the points where `keep` is true (the counts of points left out before
    /// stay).
    pub fn only(&self, keep: &[bool]) -> PlatformCloud {
        fn kept<T: Copy>(v: &[T], keep: &[bool]) -> Vec<T> {
            v.iter()
                .zip(keep)
                .filter(|(_, k)| **k)
                .map(|(x, _)| *x)
                .collect()
        }
        PlatformCloud {
            points: kept(&self.points, keep),
            seen_from: kept(&self.seen_from, keep),
            still: kept(&self.still, keep),
            ..*self
        }
    }
}

/// Each point's normal, fitted to its neighbours and turned towards the camera that saw it.
pub fn normals(cloud: &PlatformCloud) -> Vec<Vector3<f64>> {
    let mut n = spatial::normals(&cloud.points, NORMAL_NEIGHBOURS);
    for ((n, p), eye) in n.iter_mut().zip(&cloud.points).zip(&cloud.seen_from) {
        if n.dot(&(eye - p)) < 0.0 {
            *n = -*n;
        }
    }
    n
}

/// The closed model of a cloud (its points' `normals` from [`normals`]) with cells of `cell` mm: cut flat at the platform's top (a base
/// to stand and print on).
///
/// # Errors
/// [`PlatformError::Fuse`]: too few points, or a grid too large for the cell.
pub fn model(
    cloud: &PlatformCloud,
    normals: &[Vector3<f64>],
    cell: f64,
    progress: impl FnMut(usize, usize),
) -> Result<Model, PlatformError> {
    let keep = cloud.floor;
    let mut m = fuse::fuse_cut(&cloud.points, normals, &[], cell, Some(keep), progress)?;
    standing(&mut m, cloud, keep, 2.0 * cell);
    Ok(m)
}

/// Drops the pieces of `m` that float (reach nowhere down to within `reach` mm of `floor`) and
/// were made mostly of still points ([`still_cells`]): the laser on the scanner's case, which
/// looks the same at every turn. A floating piece of the object (a ball resting on its unseen
/// underside) has points lit once a turn, and stays; so does a piece standing on the platform,
/// still or not (a vase, round about the axis).
fn standing(m: &mut Model, cloud: &PlatformCloud, floor: HalfSpace, reach: f64) {
    let n = m.vertices.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for f in &m.faces {
        let a = root(&mut parent, f[0] as usize);
        for &v in &f[1..] {
            let b = root(&mut parent, v as usize);
            parent[b] = a;
        }
    }
    let mut low = vec![false; n];
    for i in 0..n {
        if floor.up.dot(&m.vertices[i].coords.cast()) <= floor.at + reach {
            let r = root(&mut parent, i);
            low[r] = true;
        }
    }
    // Every piece reaches down to the platform's top: all stay, no cloud point need be placed.
    if (0..n).all(|i| {
        let r = root(&mut parent, i);
        low[r]
    }) {
        return;
    }
    // each piece's cloud points, still and in all (by the nearest vertex)
    let mut counts = vec![(0usize, 0usize); n];
    let vertices: Vec<Point3<f64>> = m.vertices.iter().map(|v| v.cast()).collect();
    if let Some(t) = spatial::balanced(&vertices) {
        for (p, &still) in cloud.points.iter().zip(&cloud.still) {
            let i = t
                .nearest_one::<kiddo::SquaredEuclidean>(&[p.x, p.y, p.z])
                .item as usize;
            let r = root(&mut parent, i);
            counts[r].0 += usize::from(still);
            counts[r].1 += 1;
        }
    }
    let keep: Vec<bool> = (0..n)
        .map(|r| low[r] || 2 * counts[r].0 <= counts[r].1)
        .collect();
    m.faces.retain(|f| {
        let r = root(&mut parent, f[0] as usize);
        keep[r]
    });
    // the vertices of the pieces left out go too
    let mut new = vec![u32::MAX; n];
    let mut next = 0u32;
    for f in &mut m.faces {
        for v in f.iter_mut() {
            let i = *v as usize;
            if new[i] == u32::MAX {
                new[i] = next;
                next += 1;
            }
            *v = new[i];
        }
    }
    keep_all(&mut m.vertices, &new, next);
    keep_all(&mut m.normals, &new, next);
    keep_all(&mut m.colours, &new, next);
}

/// `values` (one per old vertex, or none) reordered to the new numbering `new` of `count`
/// vertices (`u32::MAX`: gone).
fn keep_all<T: Copy + Default>(values: &mut Vec<T>, new: &[u32], count: u32) {
    if values.len() != new.len() {
        return;
    }
    let mut out = vec![T::default(); count as usize];
    for (v, &k) in values.iter().zip(new) {
        if k != u32::MAX {
            out[k as usize] = *v;
        }
    }
    *values = out;
}

/// Which of `cloud`'s points lie within [`OFF_MODEL_CELLS`] cells of the model `m` (both in the
/// platform's frame): the object's, once the pieces that did not stand on the platform went.
pub fn near_model(cloud: &PlatformCloud, m: &Model, cell: f64) -> Vec<bool> {
    let vertices: Vec<Point3<f64>> = m.vertices.iter().map(|v| v.cast()).collect();
    let Some(t) = spatial::balanced(&vertices) else {
        return vec![false; cloud.points.len()];
    };
    let reach = (OFF_MODEL_CELLS * cell).powi(2);
    cloud
        .points
        .iter()
        .map(|p| {
            // searched within the reach only: the points off the model lie far from it
            !t.nearest_n_within::<kiddo::SquaredEuclidean>(
                &[p.x, p.y, p.z],
                reach,
                std::num::NonZero::<usize>::MIN,
                false,
            )
            .is_empty()
        })
        .collect()
}

/// The platform's frame turned for y-up viewers (MeshLab, Blender, CloudCompare): `(x, y, z)`
/// becomes `(x, z, −y)`, up the axis is +y.
pub fn y_up(m: &mut Model) {
    for v in &mut m.vertices {
        *v = Point3::new(v.x, v.z, -v.y);
    }
    for n in &mut m.normals {
        *n = Vector3::new(n.x, n.z, -n.y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cloud of `points` (each with whether it stood still), the top at 1 mm.
    fn cloud(points: Vec<(Point3<f64>, bool)>) -> PlatformCloud {
        PlatformCloud {
            seen_from: vec![Point3::new(0.0, -300.0, 100.0); points.len()],
            still: points.iter().map(|p| p.1).collect(),
            points: points.into_iter().map(|p| p.0).collect(),
            on_top: 0,
            off_platform: 0,
            floor: HalfSpace {
                up: Vector3::z(),
                at: TOP_MARGIN_MM,
            },
            frames: 200,
            turned_deg: 360.0,
            stripe_spacing: 0.1,
            step: std::f64::consts::TAU / 200.0,
            measured: false,
            unmeasured: 0,
        }
    }

    #[test]
    fn the_object_is_what_stands_on_the_platform_and_what_moved_with_it() {
        let mut points = Vec::new();
        // an upright cylinder 20 mm across standing on the top, 30 mm tall: moving points
        for k in 0..200 {
            for h in 0..60 {
                let a = f64::from(k) * std::f64::consts::TAU / 200.0;
                let z = TOP_MARGIN_MM + 0.5 * f64::from(h);
                points.push((Point3::new(10.0 * a.cos(), 10.0 * a.sin(), z), false));
            }
        }
        // its top, where it meets the axis, looks the same at every turn: still, but part of it
        for r in 0..20 {
            points.push((Point3::new(0.5 * f64::from(r), 0.0, 30.5), true));
        }
        // a ring of still points 40 mm above (the scanner's case, turned back frame by frame)
        for k in 0..2000 {
            let a = f64::from(k) * std::f64::consts::TAU / 2000.0;
            points.push((Point3::new(60.0 * a.cos(), 60.0 * a.sin(), 70.0), true));
        }
        // a loose part of the object, apart from it and moving (big enough to stay) ...
        for k in 0..400 {
            let a = f64::from(k) * 0.01;
            points.push((Point3::new(30.0 + a, 0.0, 20.0 + a), false));
        }
        // ... and a few scattered moving points (noise)
        for k in 0..30 {
            points.push((Point3::new(-40.0, 3.0 * f64::from(k), 50.0), false));
        }
        let c = cloud(points);
        let keep = object(&c, std::f64::consts::TAU / 200.0);
        assert_eq!(keep.len(), c.points.len());
        let kept = |range: std::ops::Range<usize>| keep[range].iter().filter(|&&k| k).count();
        assert_eq!(kept(0..12_000), 12_000, "the cylinder");
        assert_eq!(kept(12_000..12_020), 20, "the still top");
        assert_eq!(kept(12_020..14_020), 0, "the still ring");
        assert_eq!(kept(14_020..14_420), 400, "the moving part apart");
        assert_eq!(kept(14_420..14_450), 0, "the scattered points");
        let only = c.only(&keep);
        assert_eq!(only.points.len(), 12_420);
        assert_eq!(only.still.len(), 12_420);
        assert_eq!(only.stripe_spacing, 0.1);
        // no piece reaches the top: nothing is taken
        let mut high = c.clone();
        high.floor.at = -100.0;
        high.floor.up = -Vector3::z();
        assert!(object(&high, 0.03).iter().all(|&k| k));
    }
}
