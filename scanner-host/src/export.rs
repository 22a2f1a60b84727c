//! Outputs: OBJ (vertices, per-vertex colour, normals, faces), binary PLY (the same), binary STL,
//! a depth-map PNG in blue–green–red from far to near (the paper's Fig. 7b) and a shaded preview
//! PNG. Every file is written atomically: a temporary file beside it, then a rename, so a crash
//! never leaves a half-written file in place of a good one.

use std::fmt::Write as _;
use std::path::Path;

use image::{Rgb, RgbImage};
use scanner_core::nalgebra::{Point3, Vector3};

use crate::grid::Grid;
use crate::mesh::Mesh;

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The file (or its folder) cannot be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Writes `bytes` to `path` whole or not at all ([`scanner_io::write_atomic`]).
///
/// # Errors
/// [`ExportError::Write`] naming the file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    scanner_io::write_atomic(path, bytes).map_err(|source| ExportError::Write {
        path: path.to_path_buf(),
        source,
    })
}

pub use scanner_io::TempWriter;

/// Like [`write_atomic`], with the file's content streamed by `fill`
/// ([`scanner_io::write_atomic_with`]).
///
/// # Errors
/// [`ExportError::Write`] naming the file, also for an error of `fill`.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut TempWriter) -> std::io::Result<()>,
) -> Result<(), ExportError> {
    scanner_io::write_atomic_with(path, fill).map_err(|source| ExportError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// A file's writer for [`write_files`].
pub type FileWriter<'a> = Box<dyn FnOnce(&mut TempWriter) -> std::io::Result<()> + Send + 'a>;

/// Writes each of `files` (a path and what streams its content) with [`write_atomic_with`],
/// the files at once on their own threads (a fine model's four meshes take seconds each).
///
/// # Errors
/// The first file's error, in the order given; the other files are written all the same.
pub fn write_files(files: Vec<(std::path::PathBuf, FileWriter<'_>)>) -> Result<(), ExportError> {
    std::thread::scope(|s| {
        let running: Vec<_> = files
            .into_iter()
            .map(|(path, fill)| s.spawn(move || write_atomic_with(&path, fill)))
            .collect();
        running
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect::<Vec<_>>()
            .into_iter()
            .collect()
    })
}

/// The mesh as OBJ text (colours as `v x y z r g b` with components in 0–1).
pub fn obj(mesh: &Mesh) -> String {
    let mut v = Vec::new();
    // Writing to memory cannot fail.
    let _ = write_obj(mesh, &mut v);
    String::from_utf8_lossy(&v).into_owned()
}

/// Writes the mesh as OBJ text.
///
/// # Errors
/// The writer's error.
pub fn write_obj(mesh: &Mesh, w: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(
        w,
        "# scanner-host: {} vertices, {} faces; mm, {}",
        mesh.vertices.len(),
        mesh.faces.len(),
        mesh.frame.describe()
    )?;
    for (i, v) in mesh.vertices.iter().enumerate() {
        match mesh.colours.get(i) {
            Some(c) => writeln!(
                w,
                "v {} {} {} {:.4} {:.4} {:.4}",
                v.x,
                v.y,
                v.z,
                f32::from(c[0]) / 255.0,
                f32::from(c[1]) / 255.0,
                f32::from(c[2]) / 255.0
            )?,
            None => writeln!(w, "v {} {} {}", v.x, v.y, v.z)?,
        }
    }
    for n in &mesh.normals {
        writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| i + 1);
        writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
    }
    Ok(())
}

/// The mesh as binary little-endian PLY.
pub fn ply(mesh: &Mesh) -> Vec<u8> {
    let mut v = Vec::new();
    // Writing to memory cannot fail.
    let _ = write_ply(mesh, &mut v);
    v
}

/// Writes the mesh as binary little-endian PLY.
///
/// # Errors
/// The writer's error.
pub fn write_ply(mesh: &Mesh, w: &mut impl std::io::Write) -> std::io::Result<()> {
    let colour = !mesh.colours.is_empty();
    // `quality`: MeshLab's and CloudCompare's name for a per-vertex scalar; here the vertex's
    // standard uncertainty, mm.
    let quality = !mesh.quality.is_empty() && mesh.quality.len() == mesh.vertices.len();
    let mut h = format!(
        "ply\nformat binary_little_endian 1.0\ncomment scanner-host: mm, {}{}\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n",
        mesh.frame.describe(),
        if quality {
            "\ncomment quality: the vertex's standard uncertainty, mm"
        } else {
            ""
        },
        mesh.vertices.len()
    );
    if colour {
        h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if quality {
        h += "property float quality\n";
    }
    let _ = write!(
        h,
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.faces.len()
    );
    w.write_all(h.as_bytes())?;
    for (i, v) in mesh.vertices.iter().enumerate() {
        // a point cloud may come without normals: zeros then, never a short file
        let n = mesh.normals.get(i).copied().unwrap_or_default();
        for x in [v.x, v.y, v.z, n.x, n.y, n.z] {
            w.write_all(&x.to_le_bytes())?;
        }
        if colour {
            w.write_all(&mesh.colours[i])?;
        }
        if quality {
            w.write_all(&mesh.quality[i].to_le_bytes())?;
        }
    }
    for f in &mesh.faces {
        w.write_all(&[3])?;
        for i in f {
            w.write_all(&(*i as i32).to_le_bytes())?;
        }
    }
    Ok(())
}

/// The mesh as binary STL (facet normals; no colour).
pub fn stl(mesh: &Mesh) -> Vec<u8> {
    let mut v = Vec::new();
    // Writing to memory cannot fail.
    let _ = write_stl(mesh, &mut v);
    v
}

/// Writes the mesh as binary STL.
///
/// # Errors
/// The writer's error.
pub fn write_stl(mesh: &Mesh, w: &mut impl std::io::Write) -> std::io::Result<()> {
    let mut head = [0u8; 80];
    let text = b"scanner-host mesh, mm";
    head[..text.len()].copy_from_slice(text);
    w.write_all(&head)?;
    w.write_all(&(mesh.faces.len() as u32).to_le_bytes())?;
    for f in &mesh.faces {
        let [p, q, r] = f.map(|i| mesh.vertices[i as usize]);
        let n = (q - p).cross(&(r - p));
        let n = if n.norm() > 0.0 { n.normalize() } else { n };
        for v in [n.x, n.y, n.z, p.x, p.y, p.z, q.x, q.y, q.z, r.x, r.y, r.z] {
            w.write_all(&v.to_le_bytes())?;
        }
        w.write_all(&[0, 0])?;
    }
    Ok(())
}

/// Writes `mesh` as 3MF (the 3D Consortium's format that slicers read): a ZIP package holding
/// the content types, the package relationship and `3D/3dmodel.model` with one object of the
/// mesh's vertices and triangles in millimetres (stored, not compressed). A mesh coloured per
/// vertex carries its colours through 3MF's materials extension: one `m:colorgroup` with a
/// colour per vertex, each triangle naming its corners' (`p1`–`p3`); the extension is not
/// required, so a reader without it still reads the shape.
///
/// # Errors
/// The writer's error, or the package's.
pub fn write_3mf(
    mesh: &Mesh,
    w: &mut (impl std::io::Write + std::io::Seek),
) -> std::io::Result<()> {
    use std::fmt::Write as _;
    use std::io::Write as _;
    let mut model = String::with_capacity(64 * (mesh.vertices.len() + mesh.faces.len()) + 512);
    let coloured = !mesh.colours.is_empty() && mesh.colours.len() == mesh.vertices.len();
    model.push_str(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<model unit=\"millimeter\" xml:lang=\"en-US\" xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\" xmlns:m=\"http://schemas.microsoft.com/3dmanufacturing/material/2015/02\">\n<resources>\n",
    );
    if coloured {
        model.push_str("<m:colorgroup id=\"2\">\n");
        for [r, g, b] in &mesh.colours {
            let _ = writeln!(model, "<m:color color=\"#{r:02X}{g:02X}{b:02X}\"/>");
        }
        model
            .push_str("</m:colorgroup>\n<object id=\"1\" type=\"model\" pid=\"2\" pindex=\"0\">\n");
    } else {
        model.push_str("<object id=\"1\" type=\"model\">\n");
    }
    model.push_str("<mesh>\n<vertices>\n");
    for v in &mesh.vertices {
        let _ = writeln!(model, "<vertex x=\"{}\" y=\"{}\" z=\"{}\"/>", v.x, v.y, v.z);
    }
    model.push_str("</vertices>\n<triangles>\n");
    for f in &mesh.faces {
        let _ = if coloured {
            writeln!(
                model,
                "<triangle v1=\"{0}\" v2=\"{1}\" v3=\"{2}\" pid=\"2\" p1=\"{0}\" p2=\"{1}\" p3=\"{2}\"/>",
                f[0], f[1], f[2]
            )
        } else {
            writeln!(
                model,
                "<triangle v1=\"{}\" v2=\"{}\" v3=\"{}\"/>",
                f[0], f[1], f[2]
            )
        };
    }
    model.push_str(
        "</triangles>\n</mesh>\n</object>\n</resources>\n<build>\n<item objectid=\"1\"/>\n</build>\n</model>\n",
    );
    let parts: [(&str, &str); 3] = [
        (
            "[Content_Types].xml",
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Types xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\"><Default Extension=\"rels\" ContentType=\"application/vnd.openxmlformats-package.relationships+xml\"/><Default Extension=\"model\" ContentType=\"application/vnd.ms-package.3dmanufacturing-3dmodel+xml\"/></Types>\n",
        ),
        (
            "_rels/.rels",
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\"><Relationship Target=\"/3D/3dmodel.model\" Id=\"rel0\" Type=\"http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel\"/></Relationships>\n",
        ),
        ("3D/3dmodel.model", &model),
    ];
    let mut zip = zip::ZipWriter::new(w);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .large_file(model.len() > u32::MAX as usize / 2);
    for (name, text) in parts {
        zip.start_file(name, options)
            .map_err(std::io::Error::other)?;
        zip.write_all(text.as_bytes())?;
    }
    zip.finish().map_err(std::io::Error::other)?;
    Ok(())
}

/// Fills the triangle with corners `p` (pixels) by `colour(w)` where `w` are barycentric weights;
/// with `depth` (a buffer of the image's size and the corners' depths, larger nearer), only the
/// pixels where it is nearer than what is drawn already.
fn fill_triangle(
    img: &mut RgbImage,
    p: [(f32, f32); 3],
    mut depth: Option<(&mut [f32], [f32; 3])>,
    colour: impl Fn([f32; 3]) -> Rgb<u8>,
) {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let x0 = p
        .iter()
        .map(|q| q.0)
        .fold(f32::INFINITY, f32::min)
        .floor()
        .max(0.0) as i64;
    let x1 = (p
        .iter()
        .map(|q| q.0)
        .fold(f32::NEG_INFINITY, f32::max)
        .ceil() as i64)
        .min(w - 1);
    let y0 = p
        .iter()
        .map(|q| q.1)
        .fold(f32::INFINITY, f32::min)
        .floor()
        .max(0.0) as i64;
    let y1 = (p
        .iter()
        .map(|q| q.1)
        .fold(f32::NEG_INFINITY, f32::max)
        .ceil() as i64)
        .min(h - 1);
    let area = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
    if area.abs() < 1e-6 {
        return;
    }
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
            let e = |a: (f32, f32), b: (f32, f32)| {
                ((b.0 - a.0) * (fy - a.1) - (fx - a.0) * (b.1 - a.1)) / area
            };
            let wts = [e(p[1], p[2]), e(p[2], p[0]), e(p[0], p[1])];
            if wts.iter().any(|&v| v < -1e-4) {
                continue;
            }
            if let Some((buffer, z)) = depth.as_mut() {
                let at = (y * w + x) as usize;
                let here = wts[0] * z[0] + wts[1] * z[1] + wts[2] * z[2];
                if buffer.get(at).is_none_or(|&d| here <= d) {
                    continue;
                }
                buffer[at] = here;
            }
            img.put_pixel(x as u32, y as u32, colour(wts));
        }
    }
}

/// The part of the grid a picture shows (the filled cells with a margin) and its scale.
struct Framing {
    c0: u32,
    r0: u32,
    cols: u32,
    rows: u32,
    k: u32,
}

impl Framing {
    fn of(grid: &Grid) -> Framing {
        let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
        for r in 0..grid.rows {
            for c in 0..grid.cols {
                if grid.at(c, r).count > 0 {
                    (c0, c1, r0, r1) = (c0.min(c), c1.max(c), r0.min(r), r1.max(r));
                }
            }
        }
        if c0 == usize::MAX {
            (c0, c1, r0, r1) = (0, grid.cols - 1, 0, grid.rows - 1);
        }
        let m = ((c1 - c0).max(r1 - r0) / 20).max(4);
        let (c0, r0) = (c0.saturating_sub(m), r0.saturating_sub(m));
        let (c1, r1) = ((c1 + m).min(grid.cols - 1), (r1 + m).min(grid.rows - 1));
        let cols = (c1 - c0 + 1) as u32;
        Framing {
            c0: c0 as u32,
            r0: r0 as u32,
            cols,
            rows: (r1 - r0 + 1) as u32,
            k: 800u32.div_ceil(cols).clamp(1, 8),
        }
    }

    /// Pixel centre of a cell.
    fn px(&self, c: (u32, u32)) -> (f32, f32) {
        (
            (c.0 as f32 - self.c0 as f32 + 0.5) * self.k as f32,
            (c.1 as f32 - self.r0 as f32 + 0.5) * self.k as f32,
        )
    }

    fn size(&self) -> (u32, u32) {
        (self.cols * self.k, self.rows * self.k)
    }
}

/// Blue (far) → green → red (near).
fn bgr_ramp(t: f32) -> Rgb<u8> {
    let t = t.clamp(0.0, 1.0);
    let (r, g, b) = if t < 0.5 {
        let u = t * 2.0;
        (0.0, u, 1.0 - u)
    } else {
        let u = (t - 0.5) * 2.0;
        (u, 1.0 - u, 0.0)
    };
    Rgb([(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8])
}

/// The depth map: the mesh's faces and every filled cell coloured by the distance from the
/// camera, blue far to red near (2nd to 98th percentile), empty space black.
pub fn depth_png(grid: &Grid, mesh: &Mesh) -> RgbImage {
    let v = Framing::of(grid);
    let k = v.k;
    let mut depths: Vec<f32> = (0..grid.rows)
        .flat_map(|r| (0..grid.cols).map(move |c| (c, r)))
        .map(|(c, r)| grid.at(c, r))
        .filter(|c| c.count > 0)
        .map(|c| c.mean[2])
        .collect();
    depths.sort_by(f32::total_cmp);
    let (near, far) = if depths.is_empty() {
        (0.0, 1.0)
    } else {
        (
            depths[depths.len() / 50],
            depths[depths.len() * 49 / 50].max(depths[depths.len() / 50] + 1e-3),
        )
    };
    let ramp = |z: f32| bgr_ramp((far - z) / (far - near));
    let (w, h) = v.size();
    let mut img = RgbImage::from_fn(w, h, |x, y| {
        let cell = grid.at((v.c0 + x / k) as usize, (v.r0 + y / k) as usize);
        if cell.count == 0 {
            Rgb([0, 0, 0])
        } else {
            ramp(cell.mean[2])
        }
    });
    for f in &mesh.faces {
        let p = f.map(|i| v.px(mesh.cells[i as usize]));
        let z = f.map(|i| mesh.vertices[i as usize].z);
        fill_triangle(&mut img, p, None, |w| {
            ramp(w[0] * z[0] + w[1] * z[1] + w[2] * z[2])
        });
    }
    img
}

/// A shaded preview of the mesh seen from the camera: its faces under a light from the camera
/// and above (Lambert, Gouraud-interpolated), in the vertex colours (brightened to use the range)
/// when there are any.
pub fn shaded_png(grid: &Grid, mesh: &Mesh) -> RgbImage {
    let v = Framing::of(grid);
    let k = v.k;
    let (w, h) = v.size();
    let mut img = RgbImage::from_pixel(w, h, Rgb([24, 24, 32]));
    let light = scanner_core::nalgebra::Vector3::new(0.2f32, -0.5, -1.0).normalize();
    // Colours from the reference frame are dim: stretch so that their 95th percentile is 230.
    let mut lum: Vec<f32> = mesh
        .colours
        .iter()
        .map(|c| c.iter().map(|&x| f32::from(x)).fold(0.0, f32::max))
        .collect();
    lum.sort_by(f32::total_cmp);
    let gain = lum
        .get(lum.len() * 95 / 100)
        .map_or(1.0, |&l| 230.0 / l.max(1.0));
    let base = |i: usize| {
        mesh.colours
            .get(i)
            .map_or([200.0, 200.0, 200.0], |c| c.map(|v| f32::from(v) * gain))
    };
    let shade = |i: usize| 0.15 + 0.85 * mesh.normals[i].dot(&light).max(0.0);
    let colour = |i: usize| base(i).map(|v| v * shade(i));
    for f in &mesh.faces {
        let p = f.map(|i| v.px(mesh.cells[i as usize]));
        let c = f.map(|i| colour(i as usize));
        fill_triangle(&mut img, p, None, |w| {
            Rgb([0, 1, 2].map(|ch| {
                (w[0] * c[0][ch] + w[1] * c[1][ch] + w[2] * c[2][ch]).clamp(0.0, 255.0) as u8
            }))
        });
    }
    // Vertices of no face, as single cells.
    let mut in_face = vec![false; mesh.vertices.len()];
    for f in &mesh.faces {
        for &i in f {
            in_face[i as usize] = true;
        }
    }
    for (i, &(c, r)) in mesh.cells.iter().enumerate() {
        if in_face[i] || c < v.c0 || r < v.r0 || c >= v.c0 + v.cols || r >= v.r0 + v.rows {
            continue;
        }
        let px = Rgb(colour(i).map(|v| v.clamp(0.0, 255.0) as u8));
        for dy in 0..k {
            for dx in 0..k {
                img.put_pixel((c - v.c0) * k + dx, (r - v.r0) * k + dy, px);
            }
        }
    }
    img
}

/// Writes a picture as PNG.
///
/// # Errors
/// The writer's error, or the encoder's as an I/O error.
pub fn write_png(img: &RgbImage, w: &mut TempWriter) -> std::io::Result<()> {
    img.write_to(w, image::ImageFormat::Png)
        .map_err(std::io::Error::other)
}

/// Side of one panel of the orbit pictures, pixels.
const PANEL: u32 = 360;

/// Orthographic projection of camera-independent geometry for the orbit pictures: turned by
/// `yaw` about the vertical (+y up) through `centre`, scaled so that `radius` fills the panel.
struct Orbit {
    centre: Vector3<f32>,
    scale: f32,
    cos: f32,
    sin: f32,
}

impl Orbit {
    fn new(points: &[Point3<f32>], yaw_deg: f32) -> Orbit {
        let n = points.len().max(1) as f32;
        let centre = points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
        let radius = points
            .iter()
            .map(|p| (p.coords - centre).norm())
            .fold(1e-3, f32::max);
        let (sin, cos) = yaw_deg.to_radians().sin_cos();
        Orbit {
            centre,
            scale: 0.45 * PANEL as f32 / radius,
            cos,
            sin,
        }
    }

    /// Panel pixel (x right, y down) and depth (larger is nearer the viewer).
    fn project(&self, p: &Point3<f32>) -> (f32, f32, f32) {
        let d = p.coords - self.centre;
        let (x, z) = (
            self.cos * d.x + self.sin * d.z,
            -self.sin * d.x + self.cos * d.z,
        );
        (
            PANEL as f32 / 2.0 + self.scale * x,
            PANEL as f32 / 2.0 - self.scale * d.y,
            z,
        )
    }

    fn turn(&self, n: &Vector3<f32>) -> Vector3<f32> {
        Vector3::new(
            self.cos * n.x + self.sin * n.z,
            n.y,
            -self.sin * n.x + self.cos * n.z,
        )
    }
}

/// A closed mesh (y up) seen from four sides, 90° apart about the vertical, side by side: the
/// turntable picture of a fused model. Shaded grey and smoothly (each vertex's normal the mean of
/// its faces', interpolated across them), the nearest surface at each pixel by a depth buffer,
/// drawn at twice the size and averaged down.
pub fn orbit_png(mesh: &Mesh) -> RgbImage {
    // Each panel drawn at twice its size and averaged down: edges without stairs.
    const SS: u32 = 2;
    let background = Rgb([24, 24, 32]);
    let mut img = RgbImage::from_pixel(4 * PANEL, PANEL, background);
    let light = Vector3::new(0.3f32, 0.5, 1.0).normalize();
    // Smooth shading: each vertex's normal the area-weighted mean of its faces'.
    let mut normals = vec![Vector3::<f32>::zeros(); mesh.vertices.len()];
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
        let n = (b - a).cross(&(c - a));
        for &i in f {
            normals[i as usize] += n;
        }
    }
    let side = (SS * PANEL) as usize;
    for panel in 0..4 {
        let o = Orbit::new(&mesh.vertices, 90.0 * panel as f32);
        let projected: Vec<(f32, f32, f32)> = mesh
            .vertices
            .iter()
            .map(|p| {
                let (x, y, z) = o.project(p);
                (SS as f32 * x, SS as f32 * y, z)
            })
            .collect();
        let bright: Vec<f32> = normals
            .iter()
            .map(|n| {
                n.try_normalize(1e-12)
                    .map_or(0.0, |n| o.turn(&n).dot(&light))
            })
            .collect();
        let mut tile = RgbImage::from_pixel(SS * PANEL, SS * PANEL, background);
        let mut depth = vec![f32::NEG_INFINITY; side * side];
        for face in &mesh.faces {
            let p = face.map(|i| (projected[i as usize].0, projected[i as usize].1));
            let z = face.map(|i| projected[i as usize].2);
            let [a, b, c] = face.map(|i| mesh.vertices[i as usize]);
            // A face turned away that is nearest (a fold of a noisy surface) is lit from its
            // other side: no dark speck.
            let away = o.turn(&(b - a).cross(&(c - a))).z <= 0.0;
            let g = face.map(|i| {
                let l = bright[i as usize];
                40.0 + 200.0 * (if away { -l } else { l }).max(0.0)
            });
            fill_triangle(&mut tile, p, Some((&mut depth, z)), |w| {
                let v = (w[0] * g[0] + w[1] * g[1] + w[2] * g[2]).clamp(0.0, 245.0) as u8;
                Rgb([v, v, v.saturating_add(10)])
            });
        }
        let small =
            image::imageops::resize(&tile, PANEL, PANEL, image::imageops::FilterType::Triangle);
        image::imageops::replace(&mut img, &small, i64::from(panel * PANEL), 0);
    }
    img
}

/// Points in colours (the registered views, each in its own), seen from the front and from the
/// side (90° about the vertical), y up, nearest point on top.
pub fn points_png(points: &[Point3<f32>], colours: &[[u8; 3]]) -> RgbImage {
    let mut img = RgbImage::from_pixel(2 * PANEL, PANEL, Rgb([24, 24, 32]));
    for panel in 0..2u32 {
        let o = Orbit::new(points, 90.0 * panel as f32);
        let mut depth = vec![f32::NEG_INFINITY; (PANEL * PANEL) as usize];
        for (p, c) in points.iter().zip(colours) {
            let (x, y, z) = o.project(p);
            for (dx, dy) in [(0i64, 0i64), (1, 0), (0, 1), (1, 1)] {
                let (px, py) = (x as i64 + dx, y as i64 + dy);
                if px < 0 || py < 0 || px >= i64::from(PANEL) || py >= i64::from(PANEL) {
                    continue;
                }
                let k = (py as u32 * PANEL + px as u32) as usize;
                if z > depth[k] {
                    depth[k] = z;
                    img.put_pixel(panel * PANEL + px as u32, py as u32, Rgb(*c));
                }
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn outputs_get_the_mode_of_any_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let ours = dir.path().join("ours.txt");
        write_atomic(&ours, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&ours), mode(&plain));
    }

    /// The model part of a 3MF package written from `mesh`.
    fn model_3mf(mesh: &Mesh) -> String {
        let mut bytes = std::io::Cursor::new(Vec::new());
        write_3mf(mesh, &mut bytes).unwrap();
        let mut package = zip::ZipArchive::new(bytes).unwrap();
        let mut xml = String::new();
        std::io::Read::read_to_string(&mut package.by_name("3D/3dmodel.model").unwrap(), &mut xml)
            .unwrap();
        xml
    }

    #[test]
    fn a_coloured_mesh_carries_its_vertex_colours_into_3mf() {
        use scanner_core::nalgebra::Point3;
        let mut mesh = Mesh {
            vertices: vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            faces: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
            ..Mesh::default()
        };
        let plain = model_3mf(&mesh);
        assert!(
            !plain.contains("colorgroup") && !plain.contains("p1="),
            "{plain}"
        );
        mesh.colours = vec![[255, 0, 0], [0, 128, 0], [0, 0, 255], [18, 52, 86]];
        let xml = model_3mf(&mesh);
        // The group comes before the object that names it, a colour per vertex in order.
        let group = xml.find("<m:colorgroup id=\"2\">").expect("a colour group");
        assert!(
            group
                < xml
                    .find("<object id=\"1\" type=\"model\" pid=\"2\"")
                    .unwrap()
        );
        let colours: Vec<&str> = xml
            .split("<m:color color=\"#")
            .skip(1)
            .map(|c| &c[..6])
            .collect();
        assert_eq!(colours, ["FF0000", "008000", "0000FF", "123456"]);
        assert!(xml.contains(
            "<triangle v1=\"1\" v2=\"2\" v3=\"3\" pid=\"2\" p1=\"1\" p2=\"2\" p3=\"3\"/>"
        ));
        assert_eq!(xml.matches(" p1=").count(), 4);
        // A colour list of the wrong length is left out, not written half.
        mesh.colours.pop();
        assert!(!model_3mf(&mesh).contains("colorgroup"));
    }

    /// A closed sphere of radius 40 mm, its vertices jittered radially by up to ±0.4 mm (the
    /// roughness of a fused model's 1 mm cells).
    fn rough_sphere() -> Mesh {
        use scanner_core::nalgebra::Point3;
        let (rings, segs) = (90usize, 180usize);
        let mut seed = 12345u64;
        let mut jitter = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % 10_000) as f32 / 10_000.0 - 0.5
        };
        let mut vertices = vec![Point3::new(0.0f32, 40.0, 0.0)];
        for i in 1..rings {
            let th = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segs {
                let ph = std::f32::consts::TAU * j as f32 / segs as f32;
                let r = 40.0 + 0.8 * jitter();
                vertices.push(Point3::new(
                    r * th.sin() * ph.cos(),
                    r * th.cos(),
                    r * th.sin() * ph.sin(),
                ));
            }
        }
        vertices.push(Point3::new(0.0, -40.0, 0.0));
        let last = vertices.len() as u32 - 1;
        let at = |i: usize, j: usize| (1 + (i - 1) * segs + j % segs) as u32;
        let mut faces = Vec::new();
        for j in 0..segs {
            faces.push([0, at(1, j + 1), at(1, j)]);
            faces.push([last, at(rings - 1, j), at(rings - 1, j + 1)]);
        }
        for i in 1..rings - 1 {
            for j in 0..segs {
                faces.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
                faces.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
            }
        }
        Mesh {
            vertices,
            faces,
            ..Mesh::default()
        }
    }

    #[test]
    fn the_turntable_picture_of_a_rough_surface_is_whole_and_smooth() {
        let img = orbit_png(&rough_sphere());
        assert_eq!(img.dimensions(), (4 * PANEL, PANEL));
        let background = Rgb([24u8, 24, 32]);
        let half = PANEL as f32 / 2.0;
        let (mut holes, mut lit, mut steps) = (0, 0, Vec::new());
        for (x, y, p) in img.enumerate_pixels() {
            let (dx, dy) = ((x % PANEL) as f32 + 0.5 - half, y as f32 + 0.5 - half);
            let r = dx.hypot(dy);
            lit += usize::from(*p != background);
            holes += usize::from(r < 0.9 * 0.45 * PANEL as f32 && *p == background);
            if r < 0.85 * 0.45 * PANEL as f32 {
                let next = img.get_pixel(x + 1, y);
                steps.push((i32::from(p[0]) - i32::from(next[0])).abs());
            }
        }
        // Each panel a disc of 0.45 panels' radius (the sphere's, scaled to fit), drawn whole.
        let disc = 4.0 * std::f32::consts::PI * (0.45 * PANEL as f32).powi(2);
        assert!(
            (lit as f32 / disc - 1.0).abs() < 0.05,
            "{lit} lit of {disc}"
        );
        assert_eq!(holes, 0);
        // Shaded smoothly (vertex normals interpolated): neighbouring pixels differ by 2.7 grey
        // levels on average, where shading each face flat by its own normal gave 10.8.
        let mean = steps.iter().sum::<i32>() as f32 / steps.len() as f32;
        assert!(mean < 5.0, "mean step between neighbouring pixels {mean}");
    }
}
