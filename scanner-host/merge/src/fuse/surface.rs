//! Fusion of registered views into one closed mesh (issue 17): a field on a regular grid whose
//! zero surface is the model, cut by marching tetrahedra (a closed manifold by construction); the
//! largest piece is kept with any others of some size (`MIN_PIECE`). Near the points (within
//! `BAND` cells, over a point) the field is the signed distance along the nearest points'
//! normals (positive outside): precise where the views saw the surface. Elsewhere its sign is the
//! points' generalized winding number's ([`crate::fuse::winding`]): inside where it exceeds ½, which
//! closes the gaps the views left with a smooth patch instead of letting tangent planes run on
//! as sheets. Points that are less sure (`SURE`: on a view's edge) do not set the side against
//! a clear verdict of the winding number ([`off_surface`]). Checked after: edges in exactly two
//! faces, fans around vertices, components, the enclosed volume; [`unseen_faces`] says which
//! surface no view saw (for the report, or [`trim`]).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use scanner_core::nalgebra::{Point3, Vector3};

use crate::error::FuseError;
use crate::fuse::Winding;

/// A triangle mesh, mm: what the fusion makes, in the frame of the points it was fused from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Model {
    /// Vertex positions.
    pub vertices: Vec<Point3<f32>>,
    /// Unit vertex normals, outwards.
    pub normals: Vec<Vector3<f32>>,
    /// Vertex colours (empty without colour).
    pub colours: Vec<[u8; 3]>,
    /// Triangles, counter-clockwise seen from outside.
    pub faces: Vec<[u32; 3]>,
}

/// The corners of a grid cube.
const CORNERS: [(usize, usize, usize); 8] = [
    (0, 0, 0),
    (1, 0, 0),
    (0, 1, 0),
    (1, 1, 0),
    (0, 0, 1),
    (1, 0, 1),
    (0, 1, 1),
    (1, 1, 1),
];

/// Empty grid cells around the points.
const MARGIN: usize = 5;
/// Pieces of the fused surface apart from the largest are kept when they have at least this
/// share of its faces: specks of noise go, a part seen from one side only that the fusion could
/// not join (an ear seen from the front alone) stays, as a piece of its own.
const MIN_PIECE: f64 = 0.02;
/// Points averaged for a grid point's signed distance. More smooth more: 24 took the 1280×960
/// demo's mesh p99 against the truth from 0.216 to 0.194 %, but the 640×480 merge test's means
/// from 0.020 / 0.022 % to 0.025 / 0.028 % and the sphere's from 0.010 to 0.024 mm.
const NEIGHBOURS: usize = 8;
/// Grid points within this many cells of a point (and over it) take its signed distance.
const BAND: f64 = 2.0;
/// Points of a smaller weight are less sure ([`off_surface`]; `merge` gives the points on a view's
/// edge 0.05).
const SURE: f64 = 0.5;

/// Most grid points of a fusion (512³). The fine grid is never stored whole — two slices of
/// it at a time (2 MB at most) — and the coarse grid holds one point in 64 (17 MB at most); the
/// rest of the memory is the points' trees and the mesh.
const MAX_CELLS: usize = 512 * 512 * 512;

/// Quality of a fused mesh.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MeshCheck {
    /// Every edge in exactly two faces.
    pub watertight: bool,
    /// Edges used by other than two faces.
    pub open_edges: usize,
    /// Vertices whose faces do not form one fan around them (two cones touching at a point,
    /// or a fan left open).
    pub nonmanifold_vertices: usize,
    /// Connected components.
    pub components: usize,
    /// Enclosed volume, mm³ (positive for outward faces).
    pub volume_mm3: f64,
}

/// Fuses oriented points (normals pointing out of the object) into one mesh with grid cells of
/// `cell` mm.
///
/// # Errors
/// [`FuseError`] for too few points or a grid too large.
pub fn fuse(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    cell: f64,
) -> Result<Model, FuseError> {
    fuse_with(points, normals, &[], cell, |_, _| {})
}

/// [`fuse`] with a weight per point (0 to 1; empty: all 1) — a point that is less sure (on its
/// view's edge) counts for less where surer points saw the same surface — telling `progress`
/// each slice of the grid done (slices done, slices in all).
///
/// # Errors
/// [`FuseError`] for too few points, weights not one per point or outside 0–1 (NaN
/// included), or a grid too large.
pub fn fuse_with(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    weights: &[f64],
    cell: f64,
    progress: impl FnMut(usize, usize),
) -> Result<Model, FuseError> {
    fuse_cut(points, normals, weights, cell, None, progress)
}

/// The side of a plane a fused model keeps: the points `x` with `up · x ≥ at` (`up` a unit
/// vector).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace {
    /// Unit normal, pointing into the kept side.
    pub up: Vector3<f64>,
    /// The plane's offset along `up`, mm.
    pub at: f64,
}

/// [`fuse_with`], the solid cut by a plane when `keep` is given: what lies beyond it goes and
/// the cut is closed flat (the field is the larger of the surface's and the plane's signed
/// distances, so the model stays closed and manifold) — a flat base to print on.
///
/// # Errors
/// As [`fuse_with`].
pub fn fuse_cut(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    weights: &[f64],
    cell: f64,
    keep: Option<HalfSpace>,
    progress: impl FnMut(usize, usize),
) -> Result<Model, FuseError> {
    fuse_filled(points, normals, weights, cell, keep, None, progress).map(|(m, _)| m)
}

/// Where a fusion may fill the surface no view saw as solid: `solid(x)` says whether the grid
/// point `x` may be the object's (the merge's hull of what no view saw through); `floor` (up, unit, and the offset along it)
/// is the plane the object stands on, which the grid reaches down to.
pub struct Fill<'a> {
    /// Whether a point may be the object's.
    pub solid: &'a (dyn Fn(&Point3<f64>) -> bool + Sync),
    /// The plane the object stands on: `up · x = at`.
    pub floor: HalfSpace,
}

/// [`fuse_cut`], and where `fill` is given, the surface no view saw closed by it: a grid point
/// away from the seen surface lies inside when the winding number says so *or* `fill.solid`
/// does. Returns the model and, with `fill`, the volume (mm³) of the model the winding number
/// alone would have closed: the smaller closing, beside the filled one.
///
/// # Errors
/// As [`fuse_with`].
pub fn fuse_filled(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    weights: &[f64],
    cell: f64,
    keep: Option<HalfSpace>,
    fill: Option<&Fill<'_>>,
    mut progress: impl FnMut(usize, usize),
) -> Result<(Model, Option<f64>), FuseError> {
    if normals.len() != points.len() || !(weights.is_empty() || weights.len() == points.len()) {
        return Err(FuseError::Lengths {
            points: points.len(),
            normals: normals.len(),
            weights: weights.len(),
        });
    }
    if let Some((index, &weight)) = weights
        .iter()
        .enumerate()
        .find(|(_, w)| !(0.0..=1.0).contains(*w))
    {
        return Err(FuseError::Weight { index, weight });
    }
    if points.len() < 100 {
        return Err(FuseError::TooFewPoints(points.len()));
    }
    // One point per half cell: finer detail than that the grid cannot show, and dense views
    // (50 000 points on a fist-sized object) would only slow every search.
    let (points, normals, weights) = thin_weighted(points, normals, weights, cell / 2.0);
    let (points, normals, weights) = (&points[..], &normals[..], &weights[..]);
    if points.len() < 100 {
        return Err(FuseError::TooFewPoints(points.len()));
    }
    let mut lo = points[0];
    let mut hi = points[0];
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
        // The fill reaches down to the floor under every point.
        if let Some(f) = fill {
            let down = p - f.floor.up * (f.floor.up.dot(&p.coords) - f.floor.at);
            lo = lo.inf(&down);
            hi = hi.sup(&down);
        }
    }
    let margin = MARGIN as f64 * cell;
    let lo = lo - Vector3::repeat(margin);
    let n = ((hi - lo).map(|v| ((v + margin) / cell).ceil() as usize + 1)).into_owned();
    let (nx, ny, nz) = (n.x, n.y, n.z);
    if nx.saturating_mul(ny).saturating_mul(nz) > MAX_CELLS {
        return Err(FuseError::TooLarge(nx, ny, nz, MAX_CELLS));
    }
    let Some(tree) = crate::spatial::balanced(points) else {
        return Err(FuseError::TooFewPoints(0));
    };
    let area = crate::fuse::winding::spacing_areas(points, &tree);
    let winding = Winding::of_cloud(points, normals, &tree, &area);
    let at = |i: usize, j: usize, k: usize| lo + Vector3::new(i as f64, j as f64, k as f64) * cell;
    // Where no view saw, the value is the winding number's (½ − w) scaled to about a cell.
    let closing = |w: f64| ((0.5 - w) * 2.0 * cell) as f32;
    // A coarse cube whose eight corners are all this far from every point holds no grid point
    // within BAND cells of a point, and no seen surface: its winding number interpolates.
    let far = ((BAND + COARSE as f64) * cell) as f32;
    let coarse = Coarse::new((nx, ny, nz), &at, &tree, &winding, f64::from(far));
    // How far the field's nearest-point search reaches: the band, and with a fill the clearance
    // it tests (FILL_CLEAR, below).
    let clear = (FILL_CLEAR_CELLS * cell).max(FILL_CLEAR_MM);
    let search2 = if fill.is_some() {
        (BAND * cell).max(clear).powi(2)
    } else {
        (BAND * cell).powi(2)
    };
    // A grid point takes the signed distance along the nearest point's normal (positive
    // outside) when it lies over that point: within BAND cells of it and off its normal by less
    // than a cell and twice the points' spacing. Elsewhere — far from every point, or beside
    // the rim of a seen patch, where the tangent planes would run on as sheets — the sign is
    // the winding number's, which closes the holes.
    let field = |i: usize, j: usize, k: usize| {
        let q = at(i, j, k);
        let wound = || {
            if coarse.settled(i, j, k) {
                coarse.winding(i, j, k)
            } else {
                winding.at(&q)
            }
        };
        // Searched only as far as an answer can matter: the band, and with a fill the
        // clearance it tests (an unbounded search far from the points visits much of the tree).
        let Some(m) = tree
            .nearest_n_within::<SquaredEuclidean>(
                &[q.x, q.y, q.z],
                search2,
                std::num::NonZero::<usize>::MIN,
                false,
            )
            .first()
            .copied()
        else {
            return (closing(wound()), Some(f64::INFINITY));
        };
        let p = m.item as usize;
        let s = (q - points[p]).dot(&normals[p]);
        let lateral2 = m.distance - s * s;
        let reach = cell + 2.0 * area[p].sqrt();
        if m.distance <= (BAND * cell).powi(2) && lateral2 <= reach * reach {
            // The mean of the nearest points' signed distances (those facing the nearest's way),
            // weighted by a Gaussian of their distance: views a little apart and noisy points
            // average instead of taking turns (the nearest alone left pits and bumps).
            let (mut sum, mut wsum) = (0.0, 0.0);
            let h2 = (area[p].sqrt() * 2.0 + 0.5 * cell).powi(2);
            for nb in tree.nearest_n::<SquaredEuclidean>(
                &[q.x, q.y, q.z],
                crate::spatial::at_least_one(NEIGHBOURS),
            ) {
                let i = nb.item as usize;
                if normals[i].dot(&normals[p]) < 0.5 {
                    continue;
                }
                let w = weights[i] * (-nb.distance / h2).exp();
                sum += w * (q - points[i]).dot(&normals[i]);
                wsum += w;
            }
            let signed = (sum / wsum) as f32;
            // Beside a less sure point its plane does not set the side where the winding number
            // of all the points clearly says the other ([`off_surface`]'s rule for the grid point):
            // a stray point that stayed raises no bead of surface of its own.
            if weights[p] < SURE {
                let w = wound();
                let against = if signed >= 0.0 {
                    w > 0.5 + OFF_SURFACE_MARGIN
                } else {
                    w < 0.5 - OFF_SURFACE_MARGIN
                };
                if against {
                    return (closing(w), None);
                }
            }
            (signed, None)
        } else {
            (closing(wound()), Some(m.distance))
        }
    };
    // Where the winding number closes (its value below 0 inside), the fill may say inside too,
    // at grid points `d2` (squared, mm²) from the nearest point: those clear of every point by
    // FILL_CLEAR (a seen surface's own outside lies nearer, where what a view saw cannot carve
    // finely enough: its bins span millimetres of depth on a slanted face), and nearer ones the
    // winding number does not put clearly outside.
    let filled = |v: f32, d2: f64, i: usize, j: usize, k: usize| -> f32 {
        let open = d2 >= clear * clear || v < (FILL_WINDING_CELLS * cell) as f32;
        match fill {
            Some(f) if v >= 0.0 && open && (f.solid)(&at(i, j, k)) => -(cell as f32) / 2.0,
            _ => v,
        }
    };
    // One slice of the grid at a time (the field of slice k, the outermost two layers of the
    // grid set outside so that every surface closes inside it), two slices held: the fine grid
    // is never stored whole.
    // Each grid point of rows `rows` of slice k: its value, and the winding number's own
    // (without the fill).
    let rows = |k: usize, rows: std::ops::Range<usize>| -> Vec<(f32, f32)> {
        let mut out = Vec::with_capacity(nx * rows.len());
        let edge = |x: usize, n: usize| x < 2 || x + 2 >= n;
        let finish = |mut v: f32, i: usize, j: usize| {
            if let Some(h) = keep {
                v = v.max((h.at - h.up.dot(&at(i, j, k).coords)) as f32);
            }
            if edge(i, nx) || edge(j, ny) || edge(k, nz) {
                v.max(cell as f32)
            } else {
                v
            }
        };
        for j in rows {
            for i in 0..nx {
                let (v, unseen) = if coarse.far(i, j, k, far) {
                    (closing(coarse.winding(i, j, k)), Some(f64::INFINITY))
                } else {
                    field(i, j, k)
                };
                let f = unseen.map_or(v, |d2| filled(v, d2, i, j, k));
                out.push((finish(f, i, j), finish(v, i, j)));
            }
        }
        out
    };
    // A slice's rows shared among the machine's cores a few at a time (where the surface
    // crosses them they take longer), in order.
    let slice = |k: usize| -> (Vec<f32>, Vec<f32>) {
        let values = crate::spatial::par_runs(ny, ROWS_PER_RUN, |r| rows(k, r));
        let out = values.iter().map(|v| v.0).collect();
        let plain = if fill.is_some() {
            values.iter().map(|v| v.1).collect()
        } else {
            Vec::new()
        };
        (out, plain)
    };
    let mut march = Tetrahedra::new((nx, ny));
    let mut smaller = fill.map(|_| Tetrahedra::new((nx, ny)));
    let (mut lower, mut lower_plain) = slice(0);
    for k in 1..nz {
        let (upper, upper_plain) = slice(k);
        march.layer(&lower, &upper, k - 1, at);
        if let Some(t) = &mut smaller {
            t.layer(&lower_plain, &upper_plain, k - 1, at);
        }
        (lower, lower_plain) = (upper, upper_plain);
        progress(k + 1, nz);
    }
    let mut m = march.mesh;
    // Faces already face outside (each cut is turned towards its outside corners): no flip by
    // the volume's sign, which the full check would compute a second time.
    keep_pieces(&mut m, MIN_PIECE);
    m.normals = vertex_normals(&m);
    let smaller = smaller.map(|t| {
        let mut s = t.mesh;
        keep_pieces(&mut s, MIN_PIECE);
        volume(&s)
    });
    Ok((m, smaller))
}

/// Rows of a grid slice a thread takes at a time.
const ROWS_PER_RUN: usize = 4;

/// Grid points at least this many cells (and [`FILL_CLEAR_MM`]) from every point may be filled
/// ([`fuse_filled`]).
const FILL_CLEAR_CELLS: f64 = 4.0;
/// See [`FILL_CLEAR_CELLS`], mm: the depth a view's bins span on a face seen at 60° (2 mm
/// across), and its tolerance.
const FILL_CLEAR_MM: f64 = 4.0;
/// Nearer grid points may be filled where the winding number is over ¼: the closing's value
/// (½ − w, over half a cell) under this many cells.
const FILL_WINDING_CELLS: f64 = 0.5;

/// The volume a closed mesh encloses, mm³ (positive for outward faces).
fn volume(m: &Model) -> f64 {
    m.faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| m.vertices[i as usize].cast::<f64>().coords);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

/// How far from ½ the winding number of all the points may be where a less sure point lies
/// ([`off_surface`]).
pub(crate) const OFF_SURFACE_MARGIN: f64 = 0.35;

/// For each point, whether it is less sure (weight under `SURE`) and the generalized winding
/// number of all the points puts it clearly inside or outside the surface they wind around (more
/// than `OFF_SURFACE_MARGIN` from ½, where a point on the surface has about ½). A stripe cut by
/// an occluding edge places a point up to 2 mm off the surface, mostly nearer the camera; its
/// plane would raise a bead of surface of its own, and where no other view saw the surface clear
/// nothing else contradicts it ([`crate::fuse::contradicted`]). The margin is wide because
/// near a large hole the winding number of points on the surface falls well below ½ (a median of
/// 0.39 for the 360° demo's edge points moved onto the true surface, 5 % of them under 0.15): at
/// 0.30 the three-view merge test lost surface along its holes (its mesh p99 0.39 % against
/// 0.16 %); at 0.40 fewer strays go and the clean scenes' volumes came out 0.53–0.59 % large
/// (docs/reports.md). The fusion applies the same rule to the grid points beside the less sure
/// points that stay.
pub fn off_surface(points: &[Point3<f64>], normals: &[Vector3<f64>], weights: &[f64]) -> Vec<bool> {
    let sure = |i: usize| weights.get(i).is_none_or(|&w| w >= SURE);
    if (0..points.len()).all(sure) {
        return vec![false; points.len()];
    }
    let Some(tree) = crate::spatial::balanced(points) else {
        return Vec::new();
    };
    let spacing = crate::fuse::winding::spacing_areas(points, &tree);
    let winding = Winding::of_cloud(points, normals, &tree, &spacing);
    points
        .iter()
        .enumerate()
        .map(|(i, p)| !sure(i) && (winding.at(p) - 0.5).abs() > OFF_SURFACE_MARGIN)
        .collect()
}

/// Grid points per coarse grid step: far from the points a coarse grid gives the winding
/// number, interpolated (nearest-point searches and winding sums far from the surface are the
/// slow part of a fusion, and nothing there needs a finer value).
const COARSE: usize = 4;

/// Every [`COARSE`]th grid point's distance to the nearest point (infinite beyond the reach it
/// was searched to) and winding number.
struct Coarse {
    /// Coarse points per axis.
    dims: (usize, usize, usize),
    distance: Vec<f32>,
    winding: Vec<f32>,
}

impl Coarse {
    /// The coarse grid over a fine grid of `(nx, ny, nz)` points placed by `at`, its distances
    /// searched within `reach` mm (an unbounded search far from the points visits much of the
    /// tree, and [`Coarse::far`] asks no more).
    fn new(
        (nx, ny, nz): (usize, usize, usize),
        at: &(impl Fn(usize, usize, usize) -> Point3<f64> + Sync),
        tree: &ImmutableKdTree<f64, 3>,
        winding: &Winding,
        reach: f64,
    ) -> Coarse {
        let dims = (nx / COARSE + 2, ny / COARSE + 2, nz / COARSE + 2);
        let (cx, cy, cz) = dims;
        let values = crate::spatial::par_map(cx * cy * cz, |n| {
            let (i, j, k) = (n % cx, n / cx % cy, n / (cx * cy));
            let q = at(COARSE * i, COARSE * j, COARSE * k);
            let near = tree.nearest_n_within::<SquaredEuclidean>(
                &[q.x, q.y, q.z],
                reach * reach,
                std::num::NonZero::<usize>::MIN,
                false,
            );
            let d = near
                .first()
                .map_or(f32::INFINITY, |m| m.distance.sqrt() as f32);
            (d, winding.at(&q) as f32)
        });
        let (distance, winding) = values.into_iter().unzip();
        Coarse {
            dims,
            distance,
            winding,
        }
    }

    /// The values at the eight corners of the coarse cube holding fine grid point `(i, j, k)`.
    fn corners(&self, values: &[f32], (i, j, k): (usize, usize, usize)) -> [f32; 8] {
        let (cx, cy, _) = self.dims;
        let (a, b, c) = (i / COARSE, j / COARSE, k / COARSE);
        CORNERS.map(|(x, y, z)| values[((c + z) * cy + b + y) * cx + a + x])
    }

    /// The winding number at fine grid point `(i, j, k)`, interpolated.
    fn winding(&self, i: usize, j: usize, k: usize) -> f64 {
        let w = self.corners(&self.winding, (i, j, k));
        let f = |x: usize| (x % COARSE) as f32 / COARSE as f32;
        let (fx, fy, fz) = (f(i), f(j), f(k));
        let lerp = |x: f32, y: f32, t: f32| x + (y - x) * t;
        // CORNERS: x + 2y + 4z
        let x00 = lerp(w[0], w[1], fx);
        let x10 = lerp(w[2], w[3], fx);
        let x01 = lerp(w[4], w[5], fx);
        let x11 = lerp(w[6], w[7], fx);
        f64::from(lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz))
    }

    /// Whether the coarse cube holding `(i, j, k)` has its corners all clearly inside or all
    /// clearly outside: no surface crosses it, and the interpolated winding number serves.
    fn settled(&self, i: usize, j: usize, k: usize) -> bool {
        let w = self.corners(&self.winding, (i, j, k));
        w.iter().all(|&v| v < 0.2) || w.iter().all(|&v| v > 0.8)
    }

    /// Whether every corner of the coarse cube holding `(i, j, k)` lies farther than `far` from
    /// every point.
    fn far(&self, i: usize, j: usize, k: usize, far: f32) -> bool {
        self.corners(&self.distance, (i, j, k))
            .iter()
            .all(|&d| d > far)
    }
}

/// One point per `voxel` mm cube: the mean of its points weighted by `weights` (empty: all 1),
/// the weighted sum of their normals, and their largest weight — a cube where a sure point lies
/// is placed by it, one with edge points alone keeps their low weight. Cubes whose normals
/// cancel are left out.
fn thin_weighted(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    weights: &[f64],
    voxel: f64,
) -> (Vec<Point3<f64>>, Vec<Vector3<f64>>, Vec<f64>) {
    // A weight of 0 counts as a thousandth: the point still places the surface where it alone
    // saw it.
    let weight = |i: u32| weights.get(i as usize).map_or(1.0, |w| w.max(1e-3));
    let (mut p_out, mut n_out, mut w_out) = (Vec::new(), Vec::new(), Vec::new());
    for group in crate::spatial::voxel_groups(points, voxel) {
        let (mut p, mut n, mut sum, mut most) = (Vector3::zeros(), Vector3::zeros(), 0.0, 0.0f64);
        for &i in &group {
            let w = weight(i);
            p += points[i as usize].coords * w;
            n += normals[i as usize] * w;
            sum += w;
            most = most.max(w);
        }
        if n.norm() <= 1e-9 {
            continue;
        }
        p_out.push(Point3::from(p / sum));
        n_out.push(n.normalize());
        w_out.push(most);
    }
    (p_out, n_out, w_out)
}

/// The six tetrahedra of a grid cube, all around its diagonal from corner 0 to corner 7 (corner
/// `x + 2y + 4z`): the same split in every cube, so neighbouring cubes share their faces'
/// diagonals.
const TETRAHEDRA: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// The zero surface of a field on a grid (positive outside) by marching tetrahedra, one layer
/// of cubes at a time: the surface of a field linear over each tetrahedron, which is a closed
/// manifold wherever the grid's edge is outside (no ambiguous case, unlike cubes or surface
/// nets). One vertex per grid edge that the surface crosses; faces turned towards the positive
/// side.
struct Tetrahedra {
    /// Grid points per slice along x and y.
    dims: (usize, usize),
    /// The vertex on each crossed grid edge of the current layer's slices (by the edge's grid
    /// point indices).
    vertex_of: std::collections::HashMap<(usize, usize), u32>,
    mesh: Model,
}

impl Tetrahedra {
    fn new(dims: (usize, usize)) -> Self {
        Tetrahedra {
            dims,
            vertex_of: std::collections::HashMap::new(),
            mesh: Model::default(),
        }
    }

    /// The cubes between slice `k` (`lower`) and slice `k + 1` (`upper`), grid points placed by
    /// `at`.
    fn layer(
        &mut self,
        lower: &[f32],
        upper: &[f32],
        k: usize,
        at: impl Fn(usize, usize, usize) -> Point3<f64>,
    ) {
        let (nx, ny) = self.dims;
        let grid_index = |i: usize, j: usize, k: usize| (k * ny + j) * nx + i;
        let value = |i: usize, j: usize, c: usize| if c == 0 { lower } else { upper }[j * nx + i];
        let (m, vertex_of) = (&mut self.mesh, &mut self.vertex_of);
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let g = CORNERS.map(|(a, b, c)| grid_index(i + a, j + b, k + c));
                let val = CORNERS.map(|(a, b, c)| value(i + a, j + b, c));
                let outside = val.map(|x| x > 0.0);
                if outside.iter().all(|&o| o) || outside.iter().all(|&o| !o) {
                    continue;
                }
                let pos = CORNERS.map(|(a, b, c)| at(i + a, j + b, k + c));
                let mut crossing = |a: usize, b: usize| {
                    let key = (g[a].min(g[b]), g[a].max(g[b]));
                    *vertex_of.entry(key).or_insert_with(|| {
                        let t = f64::from(val[a] / (val[a] - val[b]));
                        m.vertices.push((pos[a] + (pos[b] - pos[a]) * t).cast());
                        m.vertices.len() as u32 - 1
                    })
                };
                let mut faces = Vec::with_capacity(2);
                for tet in TETRAHEDRA {
                    let (ins, outs): (Vec<usize>, Vec<usize>) =
                        tet.iter().partition(|&&c| !outside[c]);
                    // The cut's corners in order around it, as edges (inside, outside).
                    let ring: Vec<(usize, usize)> = match (ins.len(), outs.len()) {
                        (1, 3) => outs.iter().map(|&o| (ins[0], o)).collect(),
                        (3, 1) => ins.iter().map(|&i| (i, outs[0])).collect(),
                        (2, 2) => vec![
                            (ins[0], outs[0]),
                            (ins[0], outs[1]),
                            (ins[1], outs[1]),
                            (ins[1], outs[0]),
                        ],
                        _ => continue,
                    };
                    // Turned so that the normal of the cut through the edges' midpoints points
                    // from the inside corners to the outside ones.
                    let mid = |(a, b): (usize, usize)| (pos[a].coords + pos[b].coords) / 2.0;
                    let normal =
                        (mid(ring[1]) - mid(ring[0])).cross(&(mid(ring[2]) - mid(ring[0])));
                    let centre = |c: &[usize]| {
                        c.iter().map(|&x| pos[x].coords).sum::<Vector3<f64>>() / c.len() as f64
                    };
                    let flip = normal.dot(&(centre(&outs) - centre(&ins))) < 0.0;
                    let ids: Vec<u32> = ring.iter().map(|&(a, b)| crossing(a, b)).collect();
                    let mut push =
                        |f: [u32; 3]| faces.push(if flip { [f[0], f[2], f[1]] } else { f });
                    push([ids[0], ids[1], ids[2]]);
                    if ids.len() == 4 {
                        push([ids[0], ids[2], ids[3]]);
                    }
                }
                m.faces.extend(faces);
            }
        }
        // Edges with an end in slice k are not met again.
        let next = (k + 1) * nx * ny;
        vertex_of.retain(|&(a, _), _| a >= next);
    }
}

/// Marks the faces no view saw: those with a vertex farther than `max_dist` mm from every
/// point (where the fusion closed a gap between the views).
pub fn unseen_faces(m: &Model, points: &[Point3<f64>], max_dist: f64) -> Vec<bool> {
    let tree = crate::spatial::tree(points);
    let seen: Vec<bool> = m
        .vertices
        .iter()
        .map(|v| {
            let v = v.cast::<f64>();
            !tree
                .nearest_n_within::<SquaredEuclidean>(
                    &[v.x, v.y, v.z],
                    max_dist * max_dist,
                    std::num::NonZero::<usize>::MIN,
                    false,
                )
                .is_empty()
        })
        .collect();
    m.faces
        .iter()
        .map(|f| f.iter().any(|&i| !seen[i as usize]))
        .collect()
}

/// A face's area, mm².
fn face_area(m: &Model, f: &[u32; 3]) -> f64 {
    let [a, b, c] = f.map(|i| m.vertices[i as usize].cast::<f64>());
    (b - a).cross(&(c - a)).norm() / 2.0
}

/// The area of `m`'s faces whose corners all lie within `tol` mm of the plane bounding `h` (a
/// flat cut's cap), mm².
pub fn area_on(m: &Model, h: &HalfSpace, tol: f64) -> f64 {
    m.faces
        .iter()
        .filter(|f| {
            f.iter().all(|&i| {
                (h.up.dot(&m.vertices[i as usize].cast::<f64>().coords) - h.at).abs() <= tol
            })
        })
        .map(|f| face_area(m, f))
        .sum()
}

/// The area of `m`, mm².
pub fn area(m: &Model) -> f64 {
    m.faces.iter().map(|f| face_area(m, f)).sum()
}

/// The share of `m`'s area in the faces marked in `marked` (0 for a mesh without area).
pub fn area_share(m: &Model, marked: &[bool]) -> f64 {
    let (mut part, mut all) = (0.0, 0.0);
    for (f, &x) in m.faces.iter().zip(marked) {
        let a = face_area(m, f);
        all += a;
        if x {
            part += a;
        }
    }
    if all > 0.0 { part / all } else { 0.0 }
}

/// Removes the faces marked in `marked` (from [`unseen_faces`]), then the specks left (pieces
/// under `MIN_PIECE` of the largest). Returns the number of faces removed. The mesh is then
/// open where the views left gaps.
pub fn trim(m: &mut Model, marked: &[bool]) -> usize {
    let before = m.faces.len();
    let mut k = 0;
    m.faces.retain(|_| {
        k += 1;
        !marked[k - 1]
    });
    keep_pieces(m, MIN_PIECE);
    m.normals = vertex_normals(m);
    before - m.faces.len()
}

/// Colours each vertex of `m` with the colour of the nearest of `points` (`colours`, one per
/// point); nothing when there are no colours.
pub(crate) fn colour_from(m: &mut Model, points: &[Point3<f64>], colours: &[[u8; 3]]) {
    if colours.len() != points.len() || colours.is_empty() {
        return;
    }
    let tree = crate::spatial::tree(points);
    m.colours = m
        .vertices
        .iter()
        .map(|v| {
            let v = v.cast::<f64>();
            colours[tree.nearest_one::<SquaredEuclidean>(&[v.x, v.y, v.z]).item as usize]
        })
        .collect();
}

/// Indices of the points that are not isolated: whose 8th nearest neighbour is within 4 times
/// the median of that distance (stray points far from the surface would make surfaces of
/// their own).
pub fn inliers(points: &[Point3<f64>]) -> Vec<usize> {
    let tree = crate::spatial::tree(points);
    let d8: Vec<f64> = points
        .iter()
        .map(|p| {
            tree.nearest_n::<SquaredEuclidean>(&[p.x, p.y, p.z], 9)
                .last()
                .map_or(0.0, |n| n.distance.sqrt())
        })
        .collect();
    let mut sorted = d8.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    (0..points.len())
        .filter(|&i| d8[i] <= 4.0 * median)
        .collect()
}

/// Keeps the connected pieces with at least `min_share` of the largest one's faces, and the
/// vertices they use.
fn keep_pieces(m: &mut Model, min_share: f64) {
    let n = m.vertices.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for f in &m.faces {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, f[0]), root(&mut parent, f[k]));
            if a != b {
                parent[a as usize] = b;
            }
        }
    }
    let mut size = std::collections::HashMap::new();
    for f in &m.faces {
        *size.entry(root(&mut parent, f[0])).or_insert(0usize) += 1;
    }
    let largest = size.values().copied().max().unwrap_or(0);
    let keep = |r: u32| {
        size.get(&r)
            .is_some_and(|&s| s as f64 >= min_share * largest as f64)
    };
    let mut new_index = vec![u32::MAX; n];
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for f in &m.faces {
        if !keep(root(&mut parent, f[0])) {
            continue;
        }
        faces.push(f.map(|i| {
            let slot = &mut new_index[i as usize];
            if *slot == u32::MAX {
                *slot = vertices.len() as u32;
                vertices.push(m.vertices[i as usize]);
            }
            *slot
        }));
    }
    m.vertices = vertices;
    m.faces = faces;
}

/// Union-find root with path halving.
fn root(p: &mut [u32], mut i: u32) -> u32 {
    while p[i as usize] != i {
        p[i as usize] = p[p[i as usize] as usize];
        i = p[i as usize];
    }
    i
}

/// Area-weighted vertex normals from the faces.
fn vertex_normals(m: &Model) -> Vec<Vector3<f32>> {
    let mut n = vec![Vector3::zeros(); m.vertices.len()];
    for f in &m.faces {
        let [a, b, c] = f.map(|i| m.vertices[i as usize]);
        let fnormal = (b - a).cross(&(c - a));
        for &i in f {
            n[i as usize] += fnormal;
        }
    }
    n.into_iter()
        .map(|v: Vector3<f32>| if v.norm() > 0.0 { v.normalize() } else { v })
        .collect()
}

/// Vertices whose faces do not form one closed fan: around each vertex the edges opposite it
/// must make one cycle.
fn nonmanifold_vertices(m: &Model) -> usize {
    let mut link: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * m.faces.len());
    for f in &m.faces {
        for k in 0..3 {
            link.push((f[k], f[(k + 1) % 3], f[(k + 2) % 3]));
        }
    }
    link.sort_unstable();
    let mut bad = 0;
    for fan in link.chunk_by(|a, b| a.0 == b.0) {
        // A closed fan: each opposite edge's end starts exactly one other, and following them
        // from the first returns after visiting all. The fan is sorted by the edges' starts.
        if fan.windows(2).any(|w| w[0].1 == w[1].1) {
            bad += 1;
            continue;
        }
        let next = |at: u32| {
            fan.binary_search_by_key(&at, |e| e.1)
                .ok()
                .map(|i| fan[i].2)
        };
        let mut at = fan[0].1;
        let mut steps = 0;
        while let Some(n) = next(at) {
            at = n;
            steps += 1;
            if at == fan[0].1 || steps > fan.len() {
                break;
            }
        }
        if steps != fan.len() || at != fan[0].1 {
            bad += 1;
        }
    }
    bad
}

/// A piece under this share of the model's area is a floater: a few points fused apart from
/// the object (a stray view's edge, a speck of the stand), not a part of it.
pub const FLOATER_SHARE: f64 = 0.02;

/// What a piece of a model is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PieceKind {
    /// The largest piece.
    Main,
    /// A second piece of [`FLOATER_SHARE`] of the area or more: a view placed in the wrong
    /// place, or two objects scanned as one.
    Part,
    /// A piece under [`FLOATER_SHARE`] of the area.
    Floater,
}

/// One connected piece of a model.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Piece {
    /// What it is.
    pub kind: PieceKind,
    /// Its faces.
    pub faces: usize,
    /// Its area, mm², and its share of the model's.
    pub area_mm2: f64,
    /// See `area_mm2`.
    pub area_share: f64,
    /// Its bounding box's size along the model's axes, mm.
    pub extent_mm: [f64; 3],
    /// Its bounding box's centre, mm.
    pub centre_mm: [f64; 3],
}

/// The pieces of `m` (connected by faces), largest area first.
pub fn pieces(m: &Model) -> Vec<Piece> {
    let (roots, _) = components(m);
    let mut by_root: std::collections::BTreeMap<u32, (usize, f64, Point3<f64>, Point3<f64>)> =
        std::collections::BTreeMap::new();
    for f in &m.faces {
        let e = by_root.entry(roots[f[0] as usize]).or_insert((
            0,
            0.0,
            Point3::from([f64::INFINITY; 3]),
            Point3::from([f64::NEG_INFINITY; 3]),
        ));
        e.0 += 1;
        e.1 += face_area(m, f);
        for &i in f {
            let p = m.vertices[i as usize].cast::<f64>();
            e.2 = e.2.inf(&p);
            e.3 = e.3.sup(&p);
        }
    }
    let total: f64 = by_root.values().map(|e| e.1).sum();
    let mut out: Vec<Piece> = by_root
        .into_values()
        .map(|(faces, area, lo, hi)| Piece {
            kind: PieceKind::Part,
            faces,
            area_mm2: area,
            area_share: if total > 0.0 { area / total } else { 0.0 },
            extent_mm: (hi - lo).into(),
            centre_mm: nalgebra::center(&lo, &hi).coords.into(),
        })
        .collect();
    out.sort_by(|a, b| b.area_mm2.total_cmp(&a.area_mm2));
    for (k, p) in out.iter_mut().enumerate() {
        p.kind = if k == 0 {
            PieceKind::Main
        } else if p.area_share < FLOATER_SHARE {
            PieceKind::Floater
        } else {
            PieceKind::Part
        };
    }
    out
}

/// Each vertex's component (a root vertex of it) and which vertices faces use.
fn components(m: &Model) -> (Vec<u32>, Vec<bool>) {
    let mut parent: Vec<u32> = (0..m.vertices.len() as u32).collect();
    let mut used = vec![false; m.vertices.len()];
    for f in &m.faces {
        for &i in f {
            used[i as usize] = true;
        }
        for k in 1..3 {
            let (a, b) = (root(&mut parent, f[0]), root(&mut parent, f[k]));
            if a != b {
                parent[a as usize] = b;
            }
        }
    }
    let roots = (0..m.vertices.len() as u32)
        .map(|i| root(&mut parent, i))
        .collect();
    (roots, used)
}

/// Watertightness, components and the enclosed volume of a mesh.
pub fn check(m: &Model) -> MeshCheck {
    let mut edges: Vec<(u32, u32)> = m
        .faces
        .iter()
        .flat_map(|f| (0..3).map(move |k| (f[k].min(f[(k + 1) % 3]), f[k].max(f[(k + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    // an edge of a closed surface is shared by exactly two faces
    let open_edges = edges
        .chunk_by(|a, b| a == b)
        .filter(|e| e.len() != 2)
        .count();
    let (roots, used) = components(m);
    let components = (0..m.vertices.len())
        .filter(|&i| used[i] && roots[i] == i as u32)
        .count();
    let volume_mm3 = volume(m);
    MeshCheck {
        watertight: open_edges == 0,
        open_edges,
        nonmanifold_vertices: nonmanifold_vertices(m),
        components,
        volume_mm3,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_input_is_refused_not_fused() {
        let points: Vec<Point3<f64>> = (0..500)
            .map(|i| Point3::new(f64::from(i % 20), f64::from(i / 20), 0.0))
            .collect();
        // Too few points.
        assert_eq!(
            fuse(&points[..50], &vec![Vector3::z(); 50], 1.0),
            Err(FuseError::TooFewPoints(50))
        );
        // No normals (all zero): nothing left after thinning.
        assert_eq!(
            fuse(&points, &vec![Vector3::zeros(); 500], 1.0),
            Err(FuseError::TooFewPoints(0))
        );
        // A grid too large for the cell.
        let far = [points.clone(), vec![Point3::new(1.0e4, 1.0e4, 1.0e4)]].concat();
        let mut normals = vec![Vector3::z(); 500];
        normals.push(Vector3::z());
        assert!(matches!(
            fuse(&far, &normals, 1.0),
            Err(FuseError::TooLarge(..))
        ));
        // Every point at one place: one point after thinning.
        let same = vec![Point3::new(1.0, 2.0, 3.0); 500];
        assert_eq!(
            fuse(&same, &vec![Vector3::z(); 500], 1.0),
            Err(FuseError::TooFewPoints(1))
        );
    }

    /// Points of a sphere of radius `r` centred at the origin (Fibonacci spiral) with outward
    /// normals, keeping those with `keep(direction)`.
    fn sphere(
        r: f64,
        n: usize,
        keep: impl Fn(&Vector3<f64>) -> bool,
    ) -> Vec<(Point3<f64>, Vector3<f64>)> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let ring = (1.0 - y * y).sqrt();
                let t = golden * i as f64;
                Vector3::new(ring * t.cos(), y, ring * t.sin())
            })
            .filter(|d| keep(d))
            .map(|d| (Point3::from(d * r), d))
            .collect()
    }

    #[test]
    fn less_sure_points_off_the_surface_all_points_wind_around_are_afloat() {
        // A sphere of radius 30 mm seen clear, and less sure points: on it, 2 mm outside and
        // 2 mm inside it.
        let mut cloud = sphere(30.0, 6000, |_| true);
        let sure = cloud.len();
        let d = Vector3::new(0.6, 0.0, 0.8);
        cloud.extend([
            (Point3::from(d * 30.0), d),
            (Point3::from(d * 32.0), d),
            (Point3::from(d * 28.0), d),
        ]);
        let (points, normals): (Vec<_>, Vec<_>) = cloud.into_iter().unzip();
        let mut weights = vec![1.0; sure];
        weights.extend([0.05; 3]);
        let off = off_surface(&points, &normals, &weights);
        assert!(
            off[..sure].iter().all(|&o| !o),
            "sure points are never off_surface"
        );
        assert_eq!(&off[sure..], &[false, true, true]);
        // All sure (or no weights): none.
        assert!(off_surface(&points, &normals, &[]).iter().all(|&o| !o));
        // The upper half only, its rim less sure: the winding number there falls towards ¼
        // (the hole is as wide as the object), and the rim stays.
        let half = sphere(30.0, 6000, |d| d.y > 0.0);
        let (points, normals): (Vec<_>, Vec<_>) = half.into_iter().unzip();
        let weights: Vec<f64> = points
            .iter()
            .map(|p| if p.y < 3.0 { 0.05 } else { 1.0 })
            .collect();
        let rim = weights.iter().filter(|&&w| w < 1.0).count();
        assert!(rim > 50);
        let off = off_surface(&points, &normals, &weights);
        assert_eq!(off.iter().filter(|&&o| o).count(), 0, "of {rim} rim points");
    }

    #[test]
    fn a_models_pieces_are_named_by_size_largest_first() {
        // a sphere of radius 30 mm, one of 4.5 mm 100 mm away (a floater) and one of 20 mm 150 mm
        // away (a part)
        let mut cloud = sphere(30.0, 6000, |_| true);
        for (r, x) in [(4.5, 100.0), (20.0, -150.0)] {
            cloud.extend(
                sphere(r, 3000, |_| true)
                    .into_iter()
                    .map(|(p, n)| (p + Vector3::new(x, 0.0, 0.0), n)),
            );
        }
        let (points, normals): (Vec<_>, Vec<_>) = cloud.into_iter().unzip();
        let m = fuse(&points, &normals, 1.0).unwrap();
        let p = pieces(&m);
        assert_eq!(check(&m).components, p.len());
        let kinds: Vec<PieceKind> = p.iter().map(|p| p.kind).collect();
        assert_eq!(
            kinds,
            [PieceKind::Main, PieceKind::Part, PieceKind::Floater],
            "{p:?}"
        );
        for (piece, (r, x)) in p.iter().zip([(30.0, 0.0), (20.0, -150.0), (4.5, 100.0)]) {
            assert!((piece.extent_mm[0] - 2.0 * r).abs() < 1.0, "{piece:?}");
            assert!((piece.centre_mm[0] - x).abs() < 0.5, "{piece:?}");
        }
        let shares: f64 = p.iter().map(|p| p.area_share).sum();
        assert!((shares - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_flat_patch_closes_into_one_thin_watertight_piece() {
        // A 30 mm square seen from one side only: the fusion gives it a thickness (the signed
        // distance behind it) and closes it, rather than leaving a sheet.
        let mut points = Vec::new();
        for i in 0..60 {
            for j in 0..60 {
                points.push(Point3::new(f64::from(i) * 0.5, f64::from(j) * 0.5, 0.0));
            }
        }
        let normals = vec![Vector3::z(); points.len()];
        let m = fuse(&points, &normals, 1.0).unwrap();
        let c = check(&m);
        assert!(
            c.watertight && c.nonmanifold_vertices == 0 && c.components == 1,
            "{c:?}"
        );
        assert!(c.volume_mm3 > 0.0, "{c:?}");
        // Its front stays on the patch's plane.
        let front = m
            .vertices
            .iter()
            .filter(|v| v.x > 5.0 && v.x < 25.0 && v.y > 5.0 && v.y < 25.0 && v.z > -0.5)
            .map(|v| v.z.abs())
            .fold(0.0f32, f32::max);
        assert!(front < 0.05, "front {front} mm off the plane");
    }
}
