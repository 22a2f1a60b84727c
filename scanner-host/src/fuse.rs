//! Fusion of registered views into one closed mesh (issue 17, a first version): a signed
//! distance on a regular grid — at each grid point, the distance to the nearest oriented point
//! along that point's normal (positive outside) — and its zero surface by surface nets (one
//! vertex per cell that the surface crosses, one quad per grid edge that it crosses), of which the
//! largest component is kept. The sign is defined everywhere in the grid: an object seen from all
//! sides closes; where no view saw it, the surface may run to the grid's edge and stay open.
//! Checked after: edges in exactly two faces, components, the enclosed volume.

use kiddo::SquaredEuclidean;
use scanner_core::nalgebra::{Point3, Vector3};

use crate::mesh::Mesh;

/// Why the fusion failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FuseError {
    /// Too few points to reconstruct from.
    #[error("{0} points: at least 100 are needed for a surface")]
    TooFewPoints(usize),
    /// The grid would be too large.
    #[error(
        "a {0}×{1}×{2} grid at this cell size (at most {MAX_CELLS} cells): choose a larger --fuse-cell"
    )]
    TooLarge(usize, usize, usize),
}

/// Most grid points of a fusion (256³: 16.8 M, 200 MB with its values).
pub const MAX_CELLS: usize = 256 * 256 * 256;

/// Quality of a fused mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshCheck {
    /// Every edge in exactly two faces.
    pub watertight: bool,
    /// Edges used by other than two faces.
    pub open_edges: usize,
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
) -> Result<Mesh, FuseError> {
    if points.len() < 100 {
        return Err(FuseError::TooFewPoints(points.len()));
    }
    let mut lo = points[0];
    let mut hi = points[0];
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let margin = 3.0 * cell;
    let lo = lo - Vector3::repeat(margin);
    let n = ((hi - lo).map(|v| ((v + margin) / cell).ceil() as usize + 1)).into_owned();
    let (nx, ny, nz) = (n.x, n.y, n.z);
    if nx.saturating_mul(ny).saturating_mul(nz) > MAX_CELLS {
        return Err(FuseError::TooLarge(nx, ny, nz));
    }
    let tree = crate::register::tree(points);
    let at = |i: usize, j: usize, k: usize| lo + Vector3::new(i as f64, j as f64, k as f64) * cell;
    // The signed distance along the nearest point's normal (positive outside). Far from every
    // point the sign may flip in places no view saw; the largest component of the surface is
    // kept below. Far from the points a coarse grid (every `COARSE`th point) gives the value:
    // nearest-point searches far from a surface are the slow ones.
    let idx = |i: usize, j: usize, k: usize| (k * ny + j) * nx + i;
    let signed = |q: Point3<f64>| {
        let m = tree.nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z]);
        let p = m.item as usize;
        (q - points[p]).dot(&normals[p]) as f32
    };
    const COARSE: usize = 4;
    let (cx, cy, cz) = (nx / COARSE + 2, ny / COARSE + 2, nz / COARSE + 2);
    let mut coarse = vec![0f32; cx * cy * cz];
    for k in 0..cz {
        for j in 0..cy {
            for i in 0..cx {
                coarse[(k * cy + j) * cx + i] = signed(at(COARSE * i, COARSE * j, COARSE * k));
            }
        }
    }
    let far = (2 * COARSE) as f32 * cell as f32;
    let mut sdf = vec![0f32; nx * ny * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                // The nearest coarse point's value, when it says the surface is far.
                let (a, b, c) = (
                    (i + COARSE / 2) / COARSE,
                    (j + COARSE / 2) / COARSE,
                    (k + COARSE / 2) / COARSE,
                );
                let rough = coarse[(c * cy + b) * cx + a];
                sdf[idx(i, j, k)] = if rough.abs() > far {
                    rough
                } else {
                    signed(at(i, j, k))
                };
            }
        }
    }
    let v = |i: usize, j: usize, k: usize| sdf[(k * ny + j) * nx + i];
    // Surface nets: a vertex in each cell the surface crosses, at the mean of the crossings.
    let cells = (nx - 1, ny - 1, nz - 1);
    let cell_index = |i: usize, j: usize, k: usize| (k * cells.1 + j) * cells.0 + i;
    let mut vertex_of = vec![u32::MAX; cells.0 * cells.1 * cells.2];
    let mut m = Mesh::default();
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
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    for k in 0..cells.2 {
        for j in 0..cells.1 {
            for i in 0..cells.0 {
                let c = CORNERS.map(|(a, b, e)| v(i + a, j + b, k + e));
                if c.iter().all(|x| *x > 0.0) || c.iter().all(|x| *x <= 0.0) {
                    continue;
                }
                let mut sum = Vector3::zeros();
                let mut count = 0.0;
                for (a, b) in EDGES {
                    if (c[a] > 0.0) != (c[b] > 0.0) {
                        let t = f64::from(c[a] / (c[a] - c[b]));
                        let pa =
                            Vector3::new(CORNERS[a].0, CORNERS[a].1, CORNERS[a].2).cast::<f64>();
                        let pb =
                            Vector3::new(CORNERS[b].0, CORNERS[b].1, CORNERS[b].2).cast::<f64>();
                        sum += pa + (pb - pa) * t;
                        count += 1.0;
                    }
                }
                let p = at(i, j, k) + sum / count * cell;
                vertex_of[cell_index(i, j, k)] = m.vertices.len() as u32;
                m.vertices.push(p.cast());
            }
        }
    }
    // A quad for each grid edge the surface crosses, joining the four cells around it, turned
    // so that it faces outside (towards the positive end).
    for k in 1..nz - 1 {
        for j in 1..ny - 1 {
            for i in 1..nx - 1 {
                let here = v(i, j, k) > 0.0;
                for axis in 0..3 {
                    let (i2, j2, k2) = match axis {
                        0 => (i + 1, j, k),
                        1 => (i, j + 1, k),
                        _ => (i, j, k + 1),
                    };
                    if i2 >= nx || j2 >= ny || k2 >= nz || (v(i2, j2, k2) > 0.0) == here {
                        continue;
                    }
                    // The four cells sharing this edge, around it.
                    let ring: [(usize, usize, usize); 4] = match axis {
                        0 => [(i, j - 1, k - 1), (i, j, k - 1), (i, j, k), (i, j - 1, k)],
                        1 => [(i - 1, j, k - 1), (i - 1, j, k), (i, j, k), (i, j, k - 1)],
                        _ => [(i - 1, j - 1, k), (i, j - 1, k), (i, j, k), (i - 1, j, k)],
                    };
                    let q = ring.map(|(a, b, e)| vertex_of[cell_index(a, b, e)]);
                    if q.contains(&u32::MAX) {
                        continue;
                    }
                    let (a, b) = if here {
                        ([q[0], q[2], q[1]], [q[0], q[3], q[2]])
                    } else {
                        ([q[0], q[1], q[2]], [q[0], q[2], q[3]])
                    };
                    m.faces.push(a);
                    m.faces.push(b);
                }
            }
        }
    }
    keep_largest_component(&mut m);
    if check(&m).volume_mm3 < 0.0 {
        for f in &mut m.faces {
            f.swap(1, 2);
        }
    }
    m.normals = vertex_normals(&m);
    Ok(m)
}

/// Removes the surface no view saw: faces with a vertex farther than `max_dist` mm from every
/// point (where the fusion's sign ran on into empty space), then all but the largest piece left.
/// Returns the number of faces removed. The mesh is then open where the views left gaps.
pub fn trim_unseen(m: &mut Mesh, points: &[Point3<f64>], max_dist: f64) -> usize {
    let tree = crate::register::tree(points);
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
    let before = m.faces.len();
    m.faces.retain(|f| f.iter().all(|&i| seen[i as usize]));
    keep_largest_component(m);
    m.normals = vertex_normals(m);
    before - m.faces.len()
}

/// Colours each vertex of `m` with the colour of the nearest of `points` (`colours`, one per
/// point); nothing when there are no colours.
pub fn colour_from(m: &mut Mesh, points: &[Point3<f64>], colours: &[[u8; 3]]) {
    if colours.len() != points.len() || colours.is_empty() {
        return;
    }
    let tree = crate::register::tree(points);
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
    let tree = crate::register::tree(points);
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

/// Keeps the faces of the largest connected component (by faces) and the vertices they use.
fn keep_largest_component(m: &mut Mesh) {
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
    let Some((&best, _)) = size
        .iter()
        .max_by_key(|(r, s)| (**s, std::cmp::Reverse(**r)))
    else {
        return;
    };
    let mut new_index = vec![u32::MAX; n];
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for f in &m.faces {
        if root(&mut parent, f[0]) != best {
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
fn vertex_normals(m: &Mesh) -> Vec<Vector3<f32>> {
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

/// Watertightness, components and the enclosed volume of a mesh.
pub fn check(m: &Mesh) -> MeshCheck {
    let mut edges: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    for f in &m.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let open_edges = edges.values().filter(|&&c| c != 2).count();
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
    let components = (0..m.vertices.len() as u32)
        .filter(|&i| used[i as usize] && root(&mut parent, i) == i)
        .count();
    let volume_mm3 = m
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| m.vertices[i as usize].cast::<f64>().coords);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum();
    MeshCheck {
        watertight: open_edges == 0,
        open_edges,
        components,
        volume_mm3,
    }
}
