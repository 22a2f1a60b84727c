//! A scanned mesh against the true one, both ways, over the surface a scan saw (issue 17's
//! measure of a fused model): model → truth from area-weighted samples of the model's faces
//! near a scanned point, truth → model from samples of the true surface near a scanned point
//! (so that holes in the model count), and the enclosed volumes.

use std::collections::HashMap;

use scanner_core::nalgebra::Point3;

use crate::mesh::SceneMesh;

/// Area-weighted distances of one direction, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distances {
    /// Area sampled, mm².
    pub area_mm2: f64,
    /// Mean distance.
    pub mean: f64,
    /// 99th percentile (by area).
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

/// Both directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparison {
    /// From the model's seen faces to the true surface.
    pub to_truth: Distances,
    /// From the true surface the scan saw to the model.
    pub to_model: Distances,
}

/// Points near which the surface counts as seen: a hash of cells `reach` wide.
pub struct Seen<'a> {
    points: &'a [Point3<f64>],
    cells: HashMap<[i64; 3], Vec<u32>>,
    reach: f64,
}

impl<'a> Seen<'a> {
    /// The scanned points, and how near one a surface point must be to count as seen, mm.
    pub fn new(points: &'a [Point3<f64>], reach: f64) -> Self {
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, p) in points.iter().enumerate() {
            cells.entry(key(p, reach)).or_default().push(i as u32);
        }
        Seen {
            points,
            cells,
            reach,
        }
    }

    /// Whether `p` lies within the reach of a scanned point.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        let k = key(p, self.reach);
        let r2 = self.reach * self.reach;
        (-1..=1).any(|a| {
            (-1..=1).any(|b| {
                (-1..=1).any(|c| {
                    self.cells
                        .get(&[k[0] + a, k[1] + b, k[2] + c])
                        .is_some_and(|v| {
                            v.iter()
                                .any(|&i| (self.points[i as usize] - p).norm_squared() <= r2)
                        })
                })
            })
        })
    }
}

fn key(p: &Point3<f64>, cell: f64) -> [i64; 3] {
    [p.x, p.y, p.z].map(|v| (v / cell).floor() as i64)
}

/// Compares `model` (triangles, the truth's frame) with `truth` over what `seen` covers:
/// a model face counts when all its corners are seen; a sample of the truth when it is seen.
/// Samples about `spacing` mm apart.
pub fn compare(
    model: &[[Point3<f64>; 3]],
    truth: &SceneMesh,
    seen: &Seen<'_>,
    spacing: f64,
) -> Comparison {
    let seen_faces: Vec<[Point3<f64>; 3]> = model
        .iter()
        .filter(|t| t.iter().all(|p| seen.contains(p)))
        .copied()
        .collect();
    let to_truth: Vec<(f64, f64)> = samples(&seen_faces, spacing)
        .into_iter()
        .map(|(p, a)| (truth.distance(&p), a))
        .collect();
    let model_mesh = SceneMesh::new(model.to_vec());
    let to_model: Vec<(f64, f64)> = samples(truth.triangles(), spacing)
        .into_iter()
        .filter(|(p, _)| seen.contains(p))
        .map(|(p, a)| (model_mesh.distance(&p), a))
        .collect();
    Comparison {
        to_truth: distances(&to_truth),
        to_model: distances(&to_model),
    }
}

/// Points on the triangles, about one per `spacing`² of area (a fixed pattern per triangle),
/// each with the area it stands for.
pub fn samples(tris: &[[Point3<f64>; 3]], spacing: f64) -> Vec<(Point3<f64>, f64)> {
    let mut out = Vec::new();
    for t in tris {
        let area = (t[1] - t[0]).cross(&(t[2] - t[0])).norm() / 2.0;
        let m = ((area / (spacing * spacing)).sqrt().ceil() as usize).clamp(1, 64);
        let each = area / (m * (m + 1) / 2) as f64;
        for i in 0..m {
            for j in 0..m - i {
                let (u, v) = (
                    (i as f64 + 1.0 / 3.0) / m as f64,
                    (j as f64 + 1.0 / 3.0) / m as f64,
                );
                out.push((t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v, each));
            }
        }
    }
    out
}

/// Area-weighted mean, 99th percentile and largest of `(distance, area)`.
fn distances(d: &[(f64, f64)]) -> Distances {
    let total: f64 = d.iter().map(|x| x.1).sum();
    if d.is_empty() || total <= 0.0 {
        return Distances {
            area_mm2: 0.0,
            mean: f64::NAN,
            p99: f64::NAN,
            max: f64::NAN,
        };
    }
    let mut s = d.to_vec();
    s.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mean = s.iter().map(|x| x.0 * x.1).sum::<f64>() / total;
    let mut acc = 0.0;
    let p99 = s
        .iter()
        .find(|x| {
            acc += x.1;
            acc >= 0.99 * total
        })
        .map_or(s[s.len() - 1].0, |x| x.0);
    Distances {
        area_mm2: total,
        mean,
        p99,
        max: s[s.len() - 1].0,
    }
}

/// The volume enclosed by closed, consistently turned triangles (absolute), mm³.
pub fn volume(tris: &[[Point3<f64>; 3]]) -> f64 {
    tris.iter()
        .map(|[a, b, c]| a.coords.dot(&b.coords.cross(&c.coords)) / 6.0)
        .sum::<f64>()
        .abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(half: f64, at: Point3<f64>) -> Vec<[Point3<f64>; 3]> {
        let c = |x: f64, y: f64, z: f64| at + scanner_core::nalgebra::Vector3::new(x, y, z) * half;
        let v = [
            c(-1., -1., -1.),
            c(1., -1., -1.),
            c(1., 1., -1.),
            c(-1., 1., -1.),
            c(-1., -1., 1.),
            c(1., -1., 1.),
            c(1., 1., 1.),
            c(-1., 1., 1.),
        ];
        let quads = [
            [0, 3, 2, 1],
            [4, 5, 6, 7],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [1, 2, 6, 5],
            [0, 4, 7, 3],
        ];
        quads
            .iter()
            .flat_map(|q| [[v[q[0]], v[q[1]], v[q[2]]], [v[q[0]], v[q[2]], v[q[3]]]])
            .collect()
    }

    #[test]
    fn a_shifted_cube_is_off_by_its_shift_where_seen_and_holes_count() {
        let truth = SceneMesh::new(cube(10.0, Point3::origin()));
        assert!((volume(truth.triangles()) - 8000.0).abs() < 1e-9);
        // Seen everywhere: the model shifted by 0.2 mm along x is 0.2 mm off on the faces across
        // x and on none of the others, measured both ways.
        let everywhere: Vec<Point3<f64>> = samples(truth.triangles(), 1.0)
            .into_iter()
            .map(|x| x.0)
            .collect();
        let seen = Seen::new(&everywhere, 1.5);
        let model = cube(10.0, Point3::new(0.2, 0.0, 0.0));
        let c = compare(&model, &truth, &seen, 0.5);
        assert!(
            c.to_truth.max <= 0.2 + 1e-9 && c.to_truth.mean > 0.02,
            "{c:?}"
        );
        assert!(
            c.to_model.max <= 0.2 + 1e-9 && c.to_model.mean > 0.02,
            "{c:?}"
        );
        // A model missing a face: truth → model finds the hole (up to the cube's half size).
        let holed: Vec<_> = model[2..].to_vec();
        let c = compare(&holed, &truth, &seen, 0.5);
        assert!(c.to_model.max > 5.0, "{c:?}");
        // Only what was seen counts: points on one face only (the hole is elsewhere).
        let one_face: Vec<Point3<f64>> =
            everywhere.iter().filter(|p| p.z > 9.99).copied().collect();
        let seen = Seen::new(&one_face, 1.5);
        let c = compare(&holed, &truth, &seen, 0.5);
        // the face (400 mm²) and a band of the reach around it on the sides
        assert!(
            c.to_model.area_mm2 < 400.0 + 4.0 * 20.0 * 1.6 && c.to_model.max <= 0.2 + 1e-9,
            "{c:?}"
        );
        assert!(
            c.to_truth.area_mm2 < 500.0 && c.to_truth.area_mm2 > 300.0,
            "{c:?}"
        );
    }
}
