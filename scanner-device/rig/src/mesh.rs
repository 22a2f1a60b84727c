//! Triangle meshes for the rig: loaded from OBJ with `tobj`, placed in the scene, intersected
//! through a bounding-volume hierarchy (median splits, Möller–Trumbore triangles). Flat
//! triangles: the ground truth is exact on them.

use std::path::Path;

use scanner_core::nalgebra::{Isometry3, Point3, Rotation3, Vector3};

/// A placed triangle mesh with its hierarchy.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneMesh {
    triangles: Vec<[Point3<f64>; 3]>,
    nodes: Vec<Node>,
}

#[derive(Debug, Clone, PartialEq)]
struct Node {
    min: Vector3<f64>,
    max: Vector3<f64>,
    /// Leaf (`count > 0`): triangles `first..first + count`. Inner (`count == 0`): children
    /// `first` and `second` in `nodes`.
    first: usize,
    second: usize,
    count: usize,
}

/// Triangles a leaf holds at most.
const LEAF: usize = 4;

/// Why a mesh file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// Not readable as OBJ.
    #[error("{}", path.display())]
    Obj {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: tobj::LoadError,
    },
    /// Readable, but not a mesh that can be placed (the text says why).
    #[error("{}: {why}", path.display())]
    Unusable {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong.
        why: &'static str,
    },
}

impl SceneMesh {
    /// Loads an OBJ file and places it: scaled so that its height (extent along its own y) is
    /// `height_mm`, turned upright for the camera (+y down), turned by `yaw_deg` about the
    /// vertical, with the centre of its bounding box at `centre`.
    ///
    /// # Errors
    /// The file cannot be read or has no triangles; the message names the file.
    pub fn load(
        path: &Path,
        height_mm: f64,
        yaw_deg: f64,
        centre: Point3<f64>,
    ) -> Result<SceneMesh, MeshError> {
        Ok(SceneMesh::new(Self::triangles_of(
            path, height_mm, yaw_deg, centre,
        )?))
    }

    /// The placed triangles of an OBJ file, as [`SceneMesh::load`] places them.
    ///
    /// # Errors
    /// As [`SceneMesh::load`].
    pub fn triangles_of(
        path: &Path,
        height_mm: f64,
        yaw_deg: f64,
        centre: Point3<f64>,
    ) -> Result<Vec<[Point3<f64>; 3]>, MeshError> {
        let unusable = |why| MeshError::Unusable {
            path: path.to_path_buf(),
            why,
        };
        let (models, _) =
            tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS).map_err(|source| MeshError::Obj {
                path: path.to_path_buf(),
                source,
            })?;
        let mut tris = Vec::new();
        for m in &models {
            let p = &m.mesh.positions;
            let v = |i: u32| -> Option<Point3<f64>> {
                let i = i as usize * 3;
                Some(Point3::new(
                    f64::from(*p.get(i)?),
                    f64::from(*p.get(i + 1)?),
                    f64::from(*p.get(i + 2)?),
                ))
            };
            for f in m.mesh.indices.chunks_exact(3) {
                let (Some(a), Some(b), Some(c)) = (v(f[0]), v(f[1]), v(f[2])) else {
                    return Err(unusable("a face refers to a missing vertex"));
                };
                tris.push([a, b, c]);
            }
        }
        if tris.is_empty() {
            return Err(unusable("no triangles"));
        }
        let (lo, hi) = bounds(tris.iter().flatten());
        let height = hi.y - lo.y;
        if !(height > 0.0) {
            return Err(unusable("the mesh has no height"));
        }
        if !(height_mm > 0.0) {
            return Err(unusable("height_mm must be positive"));
        }
        let mid = (lo + hi) / 2.0;
        let scale = height_mm / height;
        // OBJ y up → camera y down (a turn of π about x), then the yaw about the vertical
        let turn = Rotation3::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let place = |p: Point3<f64>| centre + turn * ((p.coords - mid) * scale);
        Ok(tris.into_iter().map(|t| t.map(place)).collect())
    }

    /// A mesh from placed triangles.
    pub fn new(triangles: Vec<[Point3<f64>; 3]>) -> SceneMesh {
        let mut mesh = SceneMesh {
            triangles,
            nodes: Vec::new(),
        };
        let n = mesh.triangles.len();
        mesh.build(0, n);
        mesh
    }

    /// The mesh moved rigidly by `pose`.
    pub fn moved(&self, pose: &Isometry3<f64>) -> SceneMesh {
        SceneMesh::new(self.triangles.iter().map(|t| t.map(|v| pose * v)).collect())
    }

    /// The mean of the triangles' corners.
    pub fn centroid(&self) -> Point3<f64> {
        let n = (3 * self.triangles.len()).max(1) as f64;
        let sum = self
            .triangles
            .iter()
            .flat_map(|t| t.iter())
            .fold(Vector3::zeros(), |a, v| a + v.coords);
        Point3::from(sum / n)
    }

    /// Distance from `p` to the nearest triangle, mm.
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        self.closest(p).map_or(f64::INFINITY, |c| (c - p).norm())
    }

    /// The nearest point of the surface to `p` (through the hierarchy: a node is opened only
    /// while its box is nearer than the nearest triangle found so far); `None` without triangles.
    pub fn closest(&self, p: &Point3<f64>) -> Option<Point3<f64>> {
        let box_distance2 = |n: &Node| {
            (n.min - p.coords)
                .sup(&(p.coords - n.max))
                .sup(&Vector3::zeros())
                .norm_squared()
        };
        let (mut best2, mut best) = (f64::INFINITY, None);
        let mut stack = [0usize; 64];
        let mut top = usize::from(!self.nodes.is_empty());
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top]];
            if box_distance2(node) >= best2 {
                continue;
            }
            if node.count > 0 || top + 2 > stack.len() {
                let (first, count) = if node.count > 0 {
                    (node.first, node.count)
                } else {
                    (0, self.triangles.len())
                };
                for t in &self.triangles[first..first + count] {
                    let c = closest_on_triangle(p, t);
                    let d2 = (c - p).norm_squared();
                    if d2 < best2 {
                        (best2, best) = (d2, Some(c));
                    }
                }
            } else {
                // the nearer child last, so that it is opened first
                let (a, b) = (node.first, node.second);
                let (near, far) = if box_distance2(&self.nodes[a]) <= box_distance2(&self.nodes[b])
                {
                    (a, b)
                } else {
                    (b, a)
                };
                stack[top] = far;
                stack[top + 1] = near;
                top += 2;
            }
        }
        best
    }

    /// The placed triangles.
    pub fn triangles(&self) -> &[[Point3<f64>; 3]] {
        &self.triangles
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// `true` without triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    fn build(&mut self, first: usize, count: usize) -> usize {
        let (min, max) = bounds(self.triangles[first..first + count].iter().flatten());
        let index = self.nodes.len();
        self.nodes.push(Node {
            min,
            max,
            first,
            second: 0,
            count,
        });
        if count <= LEAF {
            return index;
        }
        // split at the median centroid along the longest axis
        let axis = (max - min).imax();
        let key = |t: &[Point3<f64>; 3]| t[0][axis] + t[1][axis] + t[2][axis];
        self.triangles[first..first + count].sort_by(|a, b| key(a).total_cmp(&key(b)));
        let half = count / 2;
        let left = self.build(first, half);
        let right = self.build(first + half, count - half);
        let node = &mut self.nodes[index];
        node.first = left;
        node.second = right;
        node.count = 0;
        index
    }

    /// The nearest hit of the ray `origin + t·dir` with `t > t_min`: `(t, unit normal)`.
    pub fn hit(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        t_min: f64,
    ) -> Option<(f64, Vector3<f64>)> {
        let inv = dir.map(|d| 1.0 / d);
        let mut best: Option<(f64, Vector3<f64>)> = None;
        let mut stack = [0usize; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top]];
            let limit = best.map_or(f64::INFINITY, |b| b.0);
            if !slab(origin, &inv, &node.min, &node.max, t_min, limit) {
                continue;
            }
            if node.count > 0 {
                for tri in &self.triangles[node.first..node.first + node.count] {
                    if let Some(h) = triangle(origin, dir, tri, t_min)
                        && best.is_none_or(|b| h.0 < b.0)
                    {
                        best = Some(h);
                    }
                }
            } else if top + 2 <= stack.len() {
                stack[top] = node.first;
                stack[top + 1] = node.second;
                top += 2;
            }
        }
        best
    }
}

fn bounds<'a>(points: impl Iterator<Item = &'a Point3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in points {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    (lo, hi)
}

/// Ray–box test (slabs) within `(t_min, t_max)`.
fn slab(
    o: &Point3<f64>,
    inv: &Vector3<f64>,
    min: &Vector3<f64>,
    max: &Vector3<f64>,
    t_min: f64,
    t_max: f64,
) -> bool {
    let (mut t0, mut t1) = (t_min, t_max);
    for k in 0..3 {
        let a = (min[k] - o[k]) * inv[k];
        let b = (max[k] - o[k]) * inv[k];
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        // NaN (a ray in the slab's plane) leaves the bounds unchanged
        t0 = if a > t0 { a } else { t0 };
        t1 = if b < t1 { b } else { t1 };
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Möller–Trumbore: `(t, unit normal facing the ray)`.
fn triangle(
    o: &Point3<f64>,
    d: &Vector3<f64>,
    t: &[Point3<f64>; 3],
    t_min: f64,
) -> Option<(f64, Vector3<f64>)> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - t[0];
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let dist = e2.dot(&q) * inv;
    if dist <= t_min {
        return None;
    }
    let n = e1.cross(&e2).normalize();
    Some((dist, if n.dot(d) > 0.0 { -n } else { n }))
}

/// The point of triangle `t` closest to `p` (Ericson, Real-Time Collision Detection, 5.1.5).
fn closest_on_triangle(p: &Point3<f64>, t: &[Point3<f64>; 3]) -> Point3<f64> {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_through_the_hierarchy_is_the_nearest_of_all_triangles() {
        // A bumpy strip of triangles, and points around and far from it.
        let z = |x: usize, y: usize| ((x * 7 + y * 13) % 5) as f64;
        let mut tris = Vec::new();
        for x in 0..20 {
            for y in 0..20 {
                let p = |a: usize, b: usize| Point3::new(a as f64, b as f64, z(a, b));
                tris.push([p(x, y), p(x + 1, y), p(x + 1, y + 1)]);
                tris.push([p(x, y), p(x + 1, y + 1), p(x, y + 1)]);
            }
        }
        let mesh = SceneMesh::new(tris.clone());
        for k in 0..300 {
            let f = k as f64;
            let p = Point3::new(
                (f * 0.37).sin() * 15.0 + 10.0,
                (f * 0.61).cos() * 15.0 + 10.0,
                (f * 0.23).sin() * 8.0,
            );
            let brute = tris
                .iter()
                .map(|t| (closest_on_triangle(&p, t) - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!((mesh.distance(&p) - brute).abs() < 1e-12, "{p}");
        }
    }
}
