//! A triangle mesh from the grid: one vertex per filled cell (and, where asked, one for each
//! empty cell of a short gap between two stripes' cells on one surface), two triangles per 2×2
//! block of filled cells (one where three are filled), none across a depth jump or a hole;
//! vertex normals from the faces, facing the camera.

use scanner_core::geometry::Board;
use scanner_core::nalgebra::{Matrix3, Point3, Vector3};

use crate::grid::{Cell, Grid};

/// A mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, mm, camera coordinates.
    pub vertices: Vec<Point3<f32>>,
    /// Unit vertex normals, towards the camera.
    pub normals: Vec<Vector3<f32>>,
    /// Vertex colours (empty without colour).
    pub colours: Vec<[u8; 3]>,
    /// Vertex standard uncertainties, mm (empty when the points carried none): the PLY's
    /// `quality`.
    pub quality: Vec<f32>,
    /// Triangles, counter-clockwise seen from the camera.
    pub faces: Vec<[u32; 3]>,
    /// Grid cell of each vertex (column, row).
    pub cells: Vec<(u32, u32)>,
    /// The last `bridged.len()` vertices were not measured: each lies between these two
    /// vertices, across a gap between stripes (see [`MeshOptions::bridge_cells`]).
    pub bridged: Vec<[u32; 2]>,
    /// The frame the vertices and normals are in.
    pub frame: MeshFrame,
}

/// The frame a mesh is written in.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum MeshFrame {
    /// The camera's: mm, +x right, +y down, +z forward (the head's wire coordinates).
    #[default]
    Camera,
    /// The board's, for y-up viewers (MeshLab, Blender, CloudCompare): +y up along the crease,
    /// +z towards the camera (between the two sheets' normals), +x to the right; the origin on
    /// the crease where it passes closest to the camera. `p_board = rotation · (p_camera − origin)`.
    Board {
        /// Rows: the board's x, y, z axes in camera coordinates.
        rotation: Matrix3<f32>,
        /// The origin in camera coordinates.
        origin: Point3<f32>,
    },
    /// A fixed-laser turntable scan's: the turning platform's frame for y-up viewers, +y up the
    /// axis, the origin on the axis at the platform's top, +x and −z on the top as it stood at
    /// the first frame (`crate::platform`).
    Platform,
}

impl MeshFrame {
    /// Up (the board's +y, along the crease) in camera coordinates; `None` in the camera's own
    /// frame, which has no up.
    pub fn up(&self) -> Option<Vector3<f64>> {
        match self {
            MeshFrame::Board { rotation, .. } => Some(rotation.row(1).transpose().cast()),
            MeshFrame::Camera | MeshFrame::Platform => None,
        }
    }

    /// The board frame of `board` (see [`MeshFrame::Board`]).
    pub fn board(board: &Board<f32>) -> MeshFrame {
        let crease = board.crease();
        let up = board.up();
        let down = -up;
        // The normals face the camera: their sum points from the crease towards it.
        let towards = board.left().normal() + board.right().normal();
        // Made exactly perpendicular to the crease.
        let z = (towards - up * up.dot(&towards)).normalize();
        let x = up.cross(&z);
        let p = crease.point().coords;
        let origin = Point3::from(p - down * p.dot(&down));
        MeshFrame::Board {
            rotation: Matrix3::from_rows(&[x.transpose(), up.transpose(), z.transpose()]),
            origin,
        }
    }

    /// A point in camera coordinates, in this frame.
    pub fn point(&self, p: &Point3<f32>) -> Point3<f32> {
        match self {
            MeshFrame::Camera | MeshFrame::Platform => *p,
            MeshFrame::Board { rotation, origin } => Point3::from(rotation * (p - origin)),
        }
    }

    /// One line saying which frame, for file headers and the summary.
    pub fn describe(&self) -> String {
        match self {
            MeshFrame::Camera => "camera frame (+x right, +y down, +z forward)".into(),
            MeshFrame::Platform => "platform frame, y up: +y up the turning axis, origin on the axis at the platform's top, +x and -z on the top as it stood at the first frame".into(),
            MeshFrame::Board {
                rotation: r,
                origin: o,
            } => format!(
                "board frame, y up (+y up the crease, +z towards the camera, origin on the crease nearest the camera); from camera coordinates p = R (p_camera - o), R = [[{:.6}, {:.6}, {:.6}], [{:.6}, {:.6}, {:.6}], [{:.6}, {:.6}, {:.6}]], o = [{:.3}, {:.3}, {:.3}]",
                r[(0, 0)],
                r[(0, 1)],
                r[(0, 2)],
                r[(1, 0)],
                r[(1, 1)],
                r[(1, 2)],
                r[(2, 0)],
                r[(2, 1)],
                r[(2, 2)],
                o.x,
                o.y,
                o.z
            ),
        }
    }
}

impl From<scanner_merge::Model> for Mesh {
    /// The merge's model as a mesh in the camera's frame (view 0's), without grid cells or
    /// uncertainties.
    fn from(m: scanner_merge::Model) -> Mesh {
        Mesh {
            vertices: m.vertices,
            normals: m.normals,
            colours: m.colours,
            faces: m.faces,
            ..Mesh::default()
        }
    }
}

impl Mesh {
    /// Moves the mesh from camera coordinates into `frame` (a rotation: faces keep their
    /// winding). A mesh already in another frame than the camera's is left as it is.
    pub fn into_frame(&mut self, frame: MeshFrame) {
        if self.frame != MeshFrame::Camera {
            return;
        }
        if let MeshFrame::Board { rotation, .. } = frame {
            for v in &mut self.vertices {
                *v = frame.point(v);
            }
            for n in &mut self.normals {
                *n = rotation * *n;
            }
        }
        self.frame = frame;
    }
}

/// Meshing settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    /// Cells with fewer samples are left out.
    pub min_count: u32,
    /// An edge longer than this many expected cell spacings is a depth jump (no face).
    pub max_edge_cells: f32,
    /// Empty cells in a gap of up to this many cells along a column or a row, between two
    /// filled cells on one surface (no depth jump between them), get a vertex on the straight
    /// line between those two: a hand's sweep moves unevenly, and where its stripe jumped
    /// more than a cell between two frames a row of cells got no point (slits across the
    /// model). 0: none.
    pub bridge_cells: usize,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            min_count: 1,
            max_edge_cells: 4.0,
            bridge_cells: 0,
        }
    }
}

/// Builds the mesh of `grid`; `colour` keeps the cells' colours.
pub fn build(grid: &Grid, fx: f64, opts: &MeshOptions, colour: bool) -> Mesh {
    let (cols, rows) = (grid.cols, grid.rows);
    let mut index = vec![u32::MAX; cols * rows];
    let mut m = Mesh::default();
    for r in 0..rows {
        for c in 0..cols {
            let cell = grid.at(c, r);
            if cell.count >= opts.min_count.max(1) {
                index[r * cols + c] = m.vertices.len() as u32;
                m.vertices.push(Point3::from(cell.mean));
                m.cells.push((c as u32, r as u32));
                if colour {
                    m.colours
                        .push(cell.rgb.map(|v| v.round().clamp(0.0, 255.0) as u8));
                }
            }
        }
    }
    // vertices across the gaps between stripes, after the measured ones
    for r in 0..rows {
        for c in 0..cols {
            if index[r * cols + c] != u32::MAX {
                continue;
            }
            let Some(((a, ka), (b, kb))) = gap_ends(grid, fx, opts, (c, r), opts.bridge_cells)
            else {
                continue;
            };
            let (ia, ib) = (index[a.1 * cols + a.0], index[b.1 * cols + b.0]);
            let t = ka as f32 / (ka + kb) as f32;
            let (pa, pb) = (m.vertices[ia as usize], m.vertices[ib as usize]);
            index[r * cols + c] = m.vertices.len() as u32;
            m.vertices.push(pa + (pb - pa) * t);
            m.cells.push((c as u32, r as u32));
            m.bridged.push([ia, ib]);
            if colour {
                let (ca, cb) = (m.colours[ia as usize], m.colours[ib as usize]);
                m.colours.push([0, 1, 2].map(|k| {
                    (f32::from(ca[k]) + (f32::from(cb[k]) - f32::from(ca[k])) * t).round() as u8
                }));
            }
        }
    }
    let spacing = |p: &Point3<f32>| cell_spacing(grid, fx, p);
    let ok = |a: u32, b: u32, limit: f32| {
        (m.vertices[a as usize] - m.vertices[b as usize]).norm() <= limit
    };
    let mut faces = Vec::new();
    for r in 0..rows.saturating_sub(1) {
        for c in 0..cols.saturating_sub(1) {
            let q = [
                index[r * cols + c],
                index[r * cols + c + 1],
                index[(r + 1) * cols + c],
                index[(r + 1) * cols + c + 1],
            ];
            let [a, b, d, e] = q;
            let tri = |x: u32, y: u32, z: u32| -> Option<[u32; 3]> {
                if x == u32::MAX || y == u32::MAX || z == u32::MAX {
                    return None;
                }
                let lim = opts.max_edge_cells
                    * spacing(&m.vertices[x as usize])
                    * std::f32::consts::SQRT_2;
                (ok(x, y, lim) && ok(y, z, lim) && ok(z, x, lim)).then_some([x, y, z])
            };
            // Split along the shorter diagonal when all four are there.
            let (t1, t2) = if a != u32::MAX && b != u32::MAX && d != u32::MAX && e != u32::MAX {
                let ae = (m.vertices[a as usize] - m.vertices[e as usize]).norm();
                let bd = (m.vertices[b as usize] - m.vertices[d as usize]).norm();
                if ae <= bd {
                    (tri(a, e, b), tri(a, d, e))
                } else {
                    (tri(a, d, b), tri(b, d, e))
                }
            } else {
                // Three filled: their triangle.
                let three: Vec<u32> = q.iter().copied().filter(|&i| i != u32::MAX).collect();
                match three[..] {
                    [x, y, z] => (tri(x, y, z), None),
                    _ => (None, None),
                }
            };
            faces.extend(t1);
            faces.extend(t2);
        }
    }
    // Orient towards the camera and accumulate area-weighted normals.
    let mut normals = vec![Vector3::<f32>::zeros(); m.vertices.len()];
    for f in &mut faces {
        let [p, q, s] = f.map(|i| m.vertices[i as usize]);
        let mut n = (q - p).cross(&(s - p));
        if n.dot(&(-p.coords)) < 0.0 {
            f.swap(1, 2);
            n = -n;
        }
        for i in *f {
            normals[i as usize] += n;
        }
    }
    m.normals = normals
        .into_iter()
        .zip(&m.vertices)
        .map(|(n, p)| {
            let l = n.norm();
            if l > 0.0 {
                n / l
            } else {
                -p.coords.normalize()
            }
        })
        .collect();
    m.faces = faces;
    m
}

/// Expected distance between neighbouring cells of `grid` at `p`, mm.
fn cell_spacing(grid: &Grid, fx: f64, p: &Point3<f32>) -> f32 {
    match grid.cell() {
        Cell::Pixels(s) => (s * f64::from(p.z) / fx) as f32,
        Cell::Mm(s) => s as f32,
    }
}

/// Whether filled cells `a` and `b`, `steps` cell spacings apart, lie on one surface (no
/// depth jump between them: within the mesh's `max_edge_cells` spacings a step).
fn on_one_surface(
    grid: &Grid,
    fx: f64,
    opts: &MeshOptions,
    a: (usize, usize),
    b: (usize, usize),
    steps: f32,
) -> bool {
    let (p, q) = (
        Point3::from(grid.at(a.0, a.1).mean),
        Point3::from(grid.at(b.0, b.1).mean),
    );
    (p - q).norm() <= opts.max_edge_cells * cell_spacing(grid, fx, &p) * steps
}

/// A filled cell (column, row) at the end of a gap, and how many cells from the gap's cell.
type GapEnd = ((usize, usize), usize);

/// The two filled cells on one surface that the empty cell `at` lies between, along its
/// column or else its row, each at most `gap` cells from it, and how many cells away.
fn gap_ends(
    grid: &Grid,
    fx: f64,
    opts: &MeshOptions,
    (c, r): (usize, usize),
    gap: usize,
) -> Option<(GapEnd, GapEnd)> {
    let (cols, rows) = (grid.cols, grid.rows);
    let filled = |c: usize, r: usize| grid.at(c, r).count >= opts.min_count.max(1);
    let along = |step: (isize, isize)| -> Option<((usize, usize), usize)> {
        (1..=gap).find_map(|k| {
            let cc = c.checked_add_signed(step.0 * k as isize)?;
            let rr = r.checked_add_signed(step.1 * k as isize)?;
            (cc < cols && rr < rows && filled(cc, rr)).then_some(((cc, rr), k))
        })
    };
    [((0, -1), (0, 1)), ((-1, 0), (1, 0))]
        .into_iter()
        .find_map(|(back, ahead)| {
            let (a, b) = (along(back)?, along(ahead)?);
            on_one_surface(grid, fx, opts, a.0, b.0, (a.1 + b.1) as f32).then_some((a, b))
        })
}

/// Gaps between sweeps' stripes up to this many cells along a row or column are bridged when
/// [`edge_cells`] looks for the view's edges: a sweep leaves rows of empty cells between its
/// stripes that are not the surface's edge.
pub const EDGE_GAP_CELLS: usize = 2;

/// The cells within `reach` cells (8-neighbour steps) of an edge of the view's surface: a cell
/// beside one that is neither filled nor a bridged gap between stripes ([`EDGE_GAP_CELLS`]), or
/// beside a filled cell across a depth jump (farther than the mesh's `max_edge_cells` spacings).
/// One flag per cell, row-major; `false` for empty cells.
///
/// Near an occluding edge or a shadow's border the stripe's profile is cut: its centre is pulled
/// off the light sheet's and the point lands up to millimetres off the surface, mostly nearer the
/// camera (on the 360° demo's views, one step from an edge at 2-pixel cells: p99 0.9–2.2 mm off
/// the true surface, against 0.27–0.36 mm clear of them; `merge_report` in docs/reports.md). A
/// merge registers and fuses without them where other views saw the same surface.
pub fn edge_cells(grid: &Grid, fx: f64, opts: &MeshOptions, reach: usize) -> Vec<bool> {
    let (cols, rows) = (grid.cols, grid.rows);
    let filled = |c: usize, r: usize| grid.at(c, r).count >= opts.min_count.max(1);
    // Two filled cells `steps` cells apart lie on one surface.
    let continuous = |a: (usize, usize), b: (usize, usize), steps: f32| {
        on_one_surface(grid, fx, opts, a, b, steps)
    };
    let bridged = |c: usize, r: usize| gap_ends(grid, fx, opts, (c, r), EDGE_GAP_CELLS).is_some();
    // Edge sources: filled cells beside the outside or across a jump.
    let mut distance = vec![usize::MAX; cols * rows];
    let mut queue = std::collections::VecDeque::new();
    for r in 0..rows {
        for c in 0..cols {
            if !filled(c, r) {
                continue;
            }
            let at_edge = (-1isize..=1).any(|dr| {
                (-1isize..=1).any(|dc| {
                    if dc == 0 && dr == 0 {
                        return false;
                    }
                    let (Some(cc), Some(rr)) = (c.checked_add_signed(dc), r.checked_add_signed(dr))
                    else {
                        return true;
                    };
                    if cc >= cols || rr >= rows {
                        return true;
                    }
                    if filled(cc, rr) {
                        let steps = if dc != 0 && dr != 0 {
                            std::f32::consts::SQRT_2
                        } else {
                            1.0
                        };
                        !continuous((c, r), (cc, rr), steps)
                    } else {
                        !bridged(cc, rr)
                    }
                })
            });
            if at_edge {
                distance[r * cols + c] = 0;
                queue.push_back((c, r));
            }
        }
    }
    // Spread over filled cells, `reach` steps.
    while let Some((c, r)) = queue.pop_front() {
        let d = distance[r * cols + c];
        if d >= reach {
            continue;
        }
        for dr in -1isize..=1 {
            for dc in -1isize..=1 {
                let (Some(cc), Some(rr)) = (c.checked_add_signed(dc), r.checked_add_signed(dr))
                else {
                    continue;
                };
                if cc < cols && rr < rows && filled(cc, rr) && distance[rr * cols + cc] > d + 1 {
                    distance[rr * cols + cc] = d + 1;
                    queue.push_back((cc, rr));
                }
            }
        }
    }
    distance.iter().map(|&d| d <= reach).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanner_core::camera::{Camera, Distortion};
    use scanner_core::nalgebra::Point2;

    /// A sweep's stripes (every third pixel row) over a wall 500 mm away, pixels 10–69 by 10–49,
    /// with a block standing 50 mm out of it over pixels 40–69 by 10–29; cells of 2 pixels.
    fn swept_wall() -> (Grid, f64) {
        let fx = 100.0;
        let camera = Camera::new(fx, fx, 40.0, 30.0, Distortion::none()).unwrap();
        let mut grid = Grid::new(camera, 80, 60, Cell::Pixels(2.0), 800.0, 5.0).unwrap();
        for v in (10..50).step_by(3) {
            for u in 10..70 {
                let depth = if u >= 40 && v < 30 { 450.0 } else { 500.0 };
                let ray = camera
                    .pixel_to_ray(&Point2::new(f64::from(u) + 0.5, f64::from(v) + 0.5))
                    .unwrap();
                let p = Point3::from(ray / ray.z * depth).cast::<f32>();
                assert!(grid.insert(&p, None, None));
            }
        }
        (grid, fx)
    }

    #[test]
    fn gaps_between_stripes_are_bridged_on_one_surface_and_not_across_a_jump() {
        let (grid, fx) = swept_wall();
        let open = build(&grid, fx, &MeshOptions::default(), false);
        let opts = MeshOptions {
            bridge_cells: EDGE_GAP_CELLS,
            ..MeshOptions::default()
        };
        let m = build(&grid, fx, &opts, false);
        assert!(open.bridged.is_empty());
        assert!(!m.bridged.is_empty());
        assert_eq!(m.vertices.len(), open.vertices.len() + m.bridged.len());
        assert!(m.faces.len() > open.faces.len());
        for (k, &[a, b]) in m.bridged.iter().enumerate() {
            let v = m.vertices[open.vertices.len() + k];
            let (pa, pb) = (m.vertices[a as usize], m.vertices[b as usize]);
            // on the wall or on the block, never between them
            assert!((pa.z - pb.z).abs() < 1.0, "{pa} {pb}");
            assert!(
                (v.z - 500.0).abs() < 1.0 || (v.z - 450.0).abs() < 1.0,
                "{v}"
            );
        }
        // no cell between the block and the wall got a vertex
        let depth = |p: &Point3<f32>| p.z;
        assert!(m.vertices.iter().all(|p| {
            let z = depth(p);
            (z - 500.0).abs() < 1.0 || (z - 450.0).abs() < 1.0
        }));
    }

    #[test]
    fn edges_are_the_outline_and_depth_jumps_not_the_gaps_between_stripes() {
        let (grid, fx) = swept_wall();
        let edges = edge_cells(&grid, fx, &MeshOptions::default(), 1);
        let at = |u: usize, v: usize| edges[(v / 2) * grid.cols + u / 2];
        let filled = |u: usize, v: usize| grid.at(u / 2, v / 2).count > 0;
        // the wall's middle and the block's middle: clear, though every other cell row is a
        // gap between stripes
        for (u, v) in [(20, 40), (24, 43), (56, 19), (60, 22)] {
            assert!(filled(u, v), "({u}, {v}) has a stripe");
            assert!(!at(u, v), "({u}, {v}) is clear of the edges");
        }
        // the outline, and both sides of the block's step (along its left side and its foot)
        for (u, v) in [
            (10, 40),
            (68, 40),
            (30, 10),
            (30, 49),
            (38, 19),
            (40, 19),
            (56, 28),
            (56, 31),
        ] {
            assert!(filled(u, v), "({u}, {v}) has a stripe");
            assert!(at(u, v), "({u}, {v}) is on an edge");
        }
        // empty cells are never flagged; a wider reach flags more
        assert!(
            (0..grid.rows)
                .flat_map(|r| (0..grid.cols).map(move |c| (c, r)))
                .all(|(c, r)| grid.at(c, r).count > 0 || !edges[r * grid.cols + c])
        );
        let count = |e: &[bool]| e.iter().filter(|&&x| x).count();
        assert!(count(&edge_cells(&grid, fx, &MeshOptions::default(), 2)) > count(&edges));
    }
}
