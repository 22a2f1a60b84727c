//! The generalized winding number of oriented points (Barill et al., "Fast winding numbers for
//! soups and clouds", 2018): `w(q) = Σ aᵢ (pᵢ − q)·nᵢ / (4π |pᵢ − q|³)`, each point standing for
//! a small disc of area `aᵢ` with outward normal `nᵢ`. Inside a closed surface `w` is 1, outside
//! 0; where the surface has holes it falls smoothly from 1 to 0 across them, so `w = ½` closes
//! the holes (the fusion uses it where no view saw the surface). Evaluated by Barnes–Hut: a
//! binary tree of the points, each node summed as one dipole (its area-weighted centre and the
//! sum of its `aᵢ nᵢ`) when the query is farther than `BETA` times the node's radius.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use scanner_core::nalgebra::{Point3, Vector3};

/// A node is summed as one dipole when the query lies farther than `BETA` × its radius from
/// its centre (the paper's accuracy parameter; 2 gives errors well under 1 %).
const BETA: f64 = 3.0;
/// Points per leaf (summed exactly).
const LEAF: usize = 16;
/// Neighbours counted for a point's spacing: the disc to its `AREA_K`th neighbour holds
/// `AREA_K + 1` points. Wide enough to span several stripes of a sweep, so that the spacing is
/// the surface's and not one stripe's.
const AREA_K: usize = 32;

/// Each point's share of the surface by the density around it, mm²: the disc to its
/// [`AREA_K`]th neighbour shared by the points in it. Smooth from point to point (the fusion
/// takes its square root as the points' local spacing), but short of the area: on the 360°
/// demo's points its sum falls about 3 % short, which moves the closure of a hole 60 mm wide
/// by half a millimetre inwards; [`areas`] gives the area.
pub(crate) fn spacing_areas(points: &[Point3<f64>], tree: &ImmutableKdTree<f64, 3>) -> Vec<f64> {
    crate::spatial::par_map(points.len(), |i| {
        let p = &points[i];
        let r2 = tree
            .nearest_n::<SquaredEuclidean>(
                &[p.x, p.y, p.z],
                crate::spatial::at_least_one(AREA_K + 1),
            )
            .last()
            .map_or(0.0, |n| n.distance);
        std::f64::consts::PI * r2 / (AREA_K + 1) as f64
    })
}

/// Neighbours whose bisectors bound a point's cell in [`areas`].
const CELL_K: usize = 16;

/// Each point's share of the surface, mm²: its Voronoi cell among its [`CELL_K`] nearest
/// neighbours that face its way (normals within 60°), in its tangent plane (Barill et al.'s
/// choice for point clouds), bounded by a square of half-side the local spacing
/// (`√spacing[i]`, [`spacing_areas`]) — so that a point on the rim of a hole stands for half a
/// spacing beyond itself, not for the hole. Points at one place share their cell; where views
/// overlap, their points share the area instead of counting it twice.
pub(crate) fn areas(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    spacing: &[f64],
    tree: &ImmutableKdTree<f64, 3>,
) -> Vec<f64> {
    let mut cell: Vec<[f64; 2]> = Vec::with_capacity(4 + CELL_K);
    let mut clipped: Vec<[f64; 2]> = Vec::with_capacity(4 + CELL_K);
    points
        .iter()
        .zip(normals)
        .zip(spacing)
        .enumerate()
        .map(|(i, ((p, n), &a))| {
            let half = a.sqrt();
            if !(half > 0.0) || !(n.norm() > 0.0) {
                return a.max(0.0);
            }
            // a basis of the tangent plane
            let u = n
                .cross(&if n.x.abs() < 0.9 {
                    Vector3::x()
                } else {
                    Vector3::y()
                })
                .normalize();
            let v = n.cross(&u);
            cell.clear();
            cell.extend([[-half, -half], [half, -half], [half, half], [-half, half]]);
            let mut sharing = 1.0;
            for m in tree.nearest_n::<SquaredEuclidean>(
                &[p.x, p.y, p.z],
                crate::spatial::at_least_one(CELL_K + 1),
            ) {
                let j = m.item as usize;
                if j == i || normals[j].dot(n) < 0.5 {
                    continue;
                }
                let d = points[j] - p;
                let q = [d.dot(&u), d.dot(&v)];
                let q2 = q[0] * q[0] + q[1] * q[1];
                if q2 < 1e-12 {
                    sharing += 1.0;
                    continue;
                }
                // the side of the bisector nearer this point: x·q ≤ |q|²/2
                clip(&cell, q, q2 / 2.0, &mut clipped);
                std::mem::swap(&mut cell, &mut clipped);
                if cell.is_empty() {
                    break;
                }
            }
            polygon_area(&cell) / sharing
        })
        .collect()
}

/// `poly` clipped to the half-plane `x·q ≤ b` (Sutherland–Hodgman), into `out`.
fn clip(poly: &[[f64; 2]], q: [f64; 2], b: f64, out: &mut Vec<[f64; 2]>) {
    out.clear();
    let side = |x: &[f64; 2]| x[0] * q[0] + x[1] * q[1] - b;
    for (k, a) in poly.iter().enumerate() {
        let c = &poly[(k + 1) % poly.len()];
        let (sa, sc) = (side(a), side(c));
        if sa <= 0.0 {
            out.push(*a);
        }
        if (sa < 0.0 && sc > 0.0) || (sa > 0.0 && sc < 0.0) {
            let t = sa / (sa - sc);
            out.push([a[0] + t * (c[0] - a[0]), a[1] + t * (c[1] - a[1])]);
        }
    }
}

/// The area of a simple polygon (the shoelace formula).
fn polygon_area(poly: &[[f64; 2]]) -> f64 {
    let twice: f64 = poly
        .iter()
        .zip(poly.iter().cycle().skip(1))
        .map(|(a, c)| a[0] * c[1] - c[0] * a[1])
        .sum();
    twice.abs() / 2.0
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
    /// `areas`).
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

    /// The winding number of oriented `points` (their k-d tree `tree`, their spacing areas
    /// `spacing` from `spacing_areas`), each weighed by its Voronoi cell (`areas`).
    pub fn of_cloud(
        points: &[Point3<f64>],
        normals: &[Vector3<f64>],
        tree: &ImmutableKdTree<f64, 3>,
        spacing: &[f64],
    ) -> Self {
        Winding::new(points, normals, &areas(points, normals, spacing, tree))
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
        let tree = crate::spatial::balanced(&p).unwrap();
        let a = areas(&p, &nn, &spacing_areas(&p, &tree), &tree);
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
