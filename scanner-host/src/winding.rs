//! The generalized winding number of oriented points (Barill et al., "Fast winding numbers for
//! soups and clouds", 2018): `w(q) = Σ aᵢ (pᵢ − q)·nᵢ / (4π |pᵢ − q|³)`, each point standing for
//! a small disc of area `aᵢ` with outward normal `nᵢ`. Inside a closed surface `w` is 1, outside
//! 0; where the surface has holes it falls smoothly from 1 to 0 across them, so `w = ½` closes
//! the holes (the fusion uses it where no view saw the surface). Evaluated by Barnes–Hut: a
//! binary tree of the points, each node summed as one dipole (its area-weighted centre and the
//! sum of its `aᵢ nᵢ`) when the query is farther than [`BETA`] times the node's radius.

use kiddo::SquaredEuclidean;
use scanner_core::nalgebra::{Point3, Vector3};

/// A node is summed as one dipole when the query lies farther than `BETA` × its radius from
/// its centre (the paper's accuracy parameter; 2 gives errors well under 1 %).
pub const BETA: f64 = 3.0;
/// Points per leaf (summed exactly).
const LEAF: usize = 16;
/// Neighbours counted for a point's area: the disc to its `AREA_K`th neighbour holds
/// `AREA_K + 1` points. Wide enough to span several stripes of a sweep: with 8 the rig's
/// sphere (stripes 2 mm apart, points 0.3 mm apart along them) summed to 86 % of its area and
/// its winding number inside to 0.86; with 32, 99 %.
pub const AREA_K: usize = 32;

/// Each point's share of the surface, mm²: the disc to its [`AREA_K`]th neighbour shared by the
/// points in it (so where views overlap, their points share the area instead of counting twice).
pub fn areas(points: &[Point3<f64>], tree: &kiddo::KdTree<f64, 3>) -> Vec<f64> {
    points
        .iter()
        .map(|p| {
            let r2 = tree
                .nearest_n::<SquaredEuclidean>(&[p.x, p.y, p.z], AREA_K + 1)
                .last()
                .map_or(0.0, |n| n.distance);
            std::f64::consts::PI * r2 / (AREA_K + 1) as f64
        })
        .collect()
}

/// A node of the tree: points `start..end` of the reordered arrays.
#[derive(Debug, Clone, Copy)]
struct Node {
    centre: Point3<f64>,
    dipole: Vector3<f64>,
    radius: f64,
    start: u32,
    end: u32,
    /// Index of the first child (the second follows it); 0 for a leaf.
    child: u32,
}

/// Oriented points ready for winding-number queries.
#[derive(Debug, Clone)]
pub struct Winding {
    points: Vec<Point3<f64>>,
    /// `aᵢ nᵢ`, per reordered point.
    weighted: Vec<Vector3<f64>>,
    /// Per reordered point, the squared radius of its disc (queries closer are held off it).
    disc2: Vec<f64>,
    nodes: Vec<Node>,
}

impl Winding {
    /// Builds the tree of `points` with outward `normals` and each point's `area` (mm², from
    /// [`areas`]).
    pub fn new(points: &[Point3<f64>], normals: &[Vector3<f64>], area: &[f64]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut w = Winding {
            points: Vec::new(),
            weighted: Vec::new(),
            disc2: Vec::new(),
            nodes: Vec::new(),
        };
        if !points.is_empty() {
            w.nodes.push(Node {
                centre: Point3::origin(),
                dipole: Vector3::zeros(),
                radius: 0.0,
                start: 0,
                end: points.len() as u32,
                child: 0,
            });
            w.split(0, &mut order, points);
        }
        w.points = order.iter().map(|&i| points[i as usize]).collect();
        w.weighted = order
            .iter()
            .map(|&i| normals[i as usize] * area[i as usize])
            .collect();
        w.disc2 = order
            .iter()
            .map(|&i| area[i as usize] / std::f64::consts::PI)
            .collect();
        let area: Vec<f64> = order.iter().map(|&i| area[i as usize]).collect();
        for k in (0..w.nodes.len()).rev() {
            w.summarise(k, &area);
        }
        w
    }

    /// Splits node `k` at the median of its longest side until leaves hold [`LEAF`] points.
    fn split(&mut self, k: usize, order: &mut [u32], points: &[Point3<f64>]) {
        let (start, end) = (self.nodes[k].start as usize, self.nodes[k].end as usize);
        if end - start <= LEAF {
            return;
        }
        let part = &mut order[start..end];
        let mut lo = points[part[0] as usize];
        let mut hi = lo;
        for &i in part.iter() {
            lo = lo.inf(&points[i as usize]);
            hi = hi.sup(&points[i as usize]);
        }
        let axis = (hi - lo).imax();
        let mid = part.len() / 2;
        part.select_nth_unstable_by(mid, |&a, &b| {
            points[a as usize][axis].total_cmp(&points[b as usize][axis])
        });
        let first = self.nodes.len();
        self.nodes[k].child = first as u32;
        for (s, e) in [(start, start + mid), (start + mid, end)] {
            self.nodes.push(Node {
                centre: Point3::origin(),
                dipole: Vector3::zeros(),
                radius: 0.0,
                start: s as u32,
                end: e as u32,
                child: 0,
            });
        }
        self.split(first, order, points);
        self.split(first + 1, order, points);
    }

    /// Fills node `k`'s centre, dipole and radius from its points (reordered, with their areas).
    fn summarise(&mut self, k: usize, area: &[f64]) {
        let n = self.nodes[k];
        let range = n.start as usize..n.end as usize;
        let (mut sum_a, mut centre, mut dipole) = (0.0, Vector3::zeros(), Vector3::zeros());
        for i in range.clone() {
            let a = area[i].max(1e-12);
            sum_a += a;
            centre += a * self.points[i].coords;
            dipole += self.weighted[i];
        }
        let centre = Point3::from(centre / sum_a);
        let radius = self.points[range]
            .iter()
            .map(|p| (p - centre).norm())
            .fold(0.0, f64::max);
        let node = &mut self.nodes[k];
        node.centre = centre;
        node.dipole = dipole;
        node.radius = radius;
    }

    /// The winding number at `q` (about 1 inside, 0 outside, ½ on the surface or across holes).
    pub fn at(&self, q: &Point3<f64>) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let mut sum = 0.0;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let d = n.centre - q;
            let r2 = d.norm_squared();
            if r2 > (BETA * n.radius).powi(2).max(1e-12) {
                sum += n.dipole.dot(&d) / (r2 * r2.sqrt());
            } else if n.child == 0 || top + 2 > stack.len() {
                for i in n.start as usize..n.end as usize {
                    let d = self.points[i] - q;
                    let r2 = d.norm_squared().max(self.disc2[i]).max(1e-12);
                    sum += self.weighted[i].dot(&d) / (r2 * r2.sqrt());
                }
            } else {
                stack[top] = n.child;
                stack[top + 1] = n.child + 1;
                top += 2;
            }
        }
        sum / (4.0 * std::f64::consts::PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points of a sphere of radius `r` (Fibonacci spiral), keeping those with `keep(direction)`.
    fn sphere(r: f64, n: usize, keep: impl Fn(&Vector3<f64>) -> bool) -> Winding {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (mut p, mut nn) = (Vec::new(), Vec::new());
        for i in 0..n {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let ring = (1.0 - y * y).sqrt();
            let d = Vector3::new(
                ring * (golden * i as f64).cos(),
                y,
                ring * (golden * i as f64).sin(),
            );
            if keep(&d) {
                p.push(Point3::from(d * r));
                nn.push(d);
            }
        }
        let tree = crate::register::tree(&p);
        let a = areas(&p, &tree);
        Winding::new(&p, &nn, &a)
    }

    #[test]
    fn one_inside_a_closed_cloud_zero_outside_a_half_across_its_hole() {
        let w = sphere(30.0, 20_000, |_| true);
        for q in [Point3::origin(), Point3::new(10.0, -12.0, 5.0)] {
            assert!((w.at(&q) - 1.0).abs() < 0.03, "inside {q}: {}", w.at(&q));
        }
        // 3 mm (four point spacings) under the surface, where single points' areas show.
        let q = Point3::new(0.0, 27.0, 0.0);
        assert!(w.at(&q) > 0.85, "inside {q}: {}", w.at(&q));
        for q in [Point3::new(0.0, 33.0, 0.0), Point3::new(80.0, 0.0, 0.0)] {
            assert!(w.at(&q).abs() < 0.03, "outside {q}: {}", w.at(&q));
        }
        // The upper half only: a half at the centre of the opening, the sign of the side away
        // from it.
        let half = sphere(30.0, 20_000, |d| d.y > 0.0);
        assert!(
            (half.at(&Point3::origin()) - 0.5).abs() < 0.03,
            "{}",
            half.at(&Point3::origin())
        );
        assert!(half.at(&Point3::new(0.0, 20.0, 0.0)) > 0.75);
        assert!(half.at(&Point3::new(0.0, -20.0, 0.0)) < 0.25);
        // No points: zero everywhere.
        let none = Winding::new(&[], &[], &[]);
        assert_eq!(none.at(&Point3::origin()), 0.0);
    }

    #[test]
    fn the_tree_sums_as_the_points_do() {
        let w = sphere(30.0, 3_000, |d| d.x < 0.5);
        for q in [
            Point3::new(3.0, 4.0, 5.0),
            Point3::new(35.0, 0.0, 2.0),
            Point3::new(0.0, 0.0, 60.0),
        ] {
            let exact: f64 = w
                .points
                .iter()
                .zip(&w.weighted)
                .zip(&w.disc2)
                .map(|((p, a), d2)| {
                    let d = p - q;
                    let r2 = d.norm_squared().max(*d2);
                    a.dot(&d) / (r2 * r2.sqrt())
                })
                .sum::<f64>()
                / (4.0 * std::f64::consts::PI);
            assert!(
                (w.at(&q) - exact).abs() < 0.01,
                "{q}: tree {} exact {exact}",
                w.at(&q)
            );
        }
    }
}
