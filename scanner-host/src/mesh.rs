//! A triangle mesh from the grid: one vertex per filled cell, two triangles per 2×2 block of
//! filled cells (one where three are filled), none across a depth jump or a hole; vertex normals
//! from the faces, facing the camera.

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
}

impl MeshFrame {
    /// The board frame of `board` (see [`MeshFrame::Board`]).
    pub fn board(board: &Board<f32>) -> MeshFrame {
        let crease = board.crease();
        let mut down = crease.direction().normalize();
        if down.y < 0.0 {
            down = -down;
        }
        let up = -down;
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
            MeshFrame::Camera => *p,
            MeshFrame::Board { rotation, origin } => Point3::from(rotation * (p - origin)),
        }
    }

    /// One line saying which frame, for file headers and the summary.
    pub fn describe(&self) -> String {
        match self {
            MeshFrame::Camera => "camera frame (+x right, +y down, +z forward)".into(),
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
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            min_count: 1,
            max_edge_cells: 4.0,
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
    // Expected distance between neighbouring cells at a point.
    let spacing = |p: &Point3<f32>| -> f32 {
        match grid.cell() {
            Cell::Pixels(s) => (s * f64::from(p.z) / fx) as f32,
            Cell::Mm(s) => s as f32,
        }
    };
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
