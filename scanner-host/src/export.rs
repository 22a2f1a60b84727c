//! Outputs: OBJ (vertices, per-vertex colour, normals, faces), binary PLY (the same), binary STL,
//! a depth-map PNG in blue–green–red from far to near (the paper's Fig. 7b) and a shaded preview
//! PNG. Every file is written atomically: a temporary file beside it, then a rename, so a crash
//! never leaves a half-written file in place of a good one.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use image::{Rgb, RgbImage};

use crate::grid::Grid;
use crate::mesh::Mesh;

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename.
///
/// # Errors
/// Names the file and the failure.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let res = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res.with_context(|| format!("cannot write {}", path.display()))
}

/// The mesh as OBJ text (colours as `v x y z r g b` with components in 0–1).
pub fn obj(mesh: &Mesh) -> String {
    let mut s = String::with_capacity(64 * mesh.vertices.len() + 32 * mesh.faces.len());
    let _ = writeln!(
        s,
        "# scanner-host: {} vertices, {} faces; mm, camera coordinates (+y down, +z forward)",
        mesh.vertices.len(),
        mesh.faces.len()
    );
    for (i, v) in mesh.vertices.iter().enumerate() {
        match mesh.colours.get(i) {
            Some(c) => {
                let _ = writeln!(
                    s,
                    "v {} {} {} {:.4} {:.4} {:.4}",
                    v.x,
                    v.y,
                    v.z,
                    f32::from(c[0]) / 255.0,
                    f32::from(c[1]) / 255.0,
                    f32::from(c[2]) / 255.0
                );
            }
            None => {
                let _ = writeln!(s, "v {} {} {}", v.x, v.y, v.z);
            }
        }
    }
    for n in &mesh.normals {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| i + 1);
        let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
    }
    s
}

/// The mesh as binary little-endian PLY.
pub fn ply(mesh: &Mesh) -> Vec<u8> {
    let colour = !mesh.colours.is_empty();
    let mut h = format!(
        "ply\nformat binary_little_endian 1.0\ncomment scanner-host: mm, camera coordinates\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n",
        mesh.vertices.len()
    );
    if colour {
        h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    let _ = write!(
        h,
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.faces.len()
    );
    let mut b = h.into_bytes();
    b.reserve(mesh.vertices.len() * 27 + mesh.faces.len() * 13);
    for (i, (v, n)) in mesh.vertices.iter().zip(&mesh.normals).enumerate() {
        for x in [v.x, v.y, v.z, n.x, n.y, n.z] {
            b.extend_from_slice(&x.to_le_bytes());
        }
        if colour {
            b.extend_from_slice(&mesh.colours[i]);
        }
    }
    for f in &mesh.faces {
        b.push(3);
        for i in f {
            b.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    b
}

/// The mesh as binary STL (facet normals; no colour).
pub fn stl(mesh: &Mesh) -> Vec<u8> {
    let mut b = Vec::with_capacity(84 + 50 * mesh.faces.len());
    let mut head = [0u8; 80];
    let text = b"scanner-host mesh, mm";
    head[..text.len()].copy_from_slice(text);
    b.extend_from_slice(&head);
    b.extend_from_slice(&(mesh.faces.len() as u32).to_le_bytes());
    for f in &mesh.faces {
        let [p, q, r] = f.map(|i| mesh.vertices[i as usize]);
        let n = (q - p).cross(&(r - p));
        let n = if n.norm() > 0.0 { n.normalize() } else { n };
        for v in [n.x, n.y, n.z, p.x, p.y, p.z, q.x, q.y, q.z, r.x, r.y, r.z] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
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

/// Scale so that the picture is at least about 600 pixels wide.
fn scale(grid: &Grid) -> u32 {
    (600 / grid.cols.max(1) as u32).clamp(1, 8)
}

/// The depth map: each filled cell coloured by its distance from the camera, blue far to red
/// near (2nd to 98th percentile), empty cells black.
pub fn depth_png(grid: &Grid) -> RgbImage {
    let k = scale(grid);
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
    RgbImage::from_fn(grid.cols as u32 * k, grid.rows as u32 * k, |x, y| {
        let cell = grid.at((x / k) as usize, (y / k) as usize);
        if cell.count == 0 {
            Rgb([0, 0, 0])
        } else {
            bgr_ramp((far - cell.mean[2]) / (far - near))
        }
    })
}

/// A shaded preview of the mesh seen from the camera: Lambert shading under a light from the
/// camera and above, in the vertex colours when there are any.
pub fn shaded_png(grid: &Grid, mesh: &Mesh) -> RgbImage {
    let k = scale(grid);
    let mut img = RgbImage::from_pixel(
        grid.cols as u32 * k,
        grid.rows as u32 * k,
        Rgb([24, 24, 32]),
    );
    let light = scanner_core::nalgebra::Vector3::new(0.2f32, -0.5, -1.0).normalize();
    for (i, &(c, r)) in mesh.cells.iter().enumerate() {
        let n = mesh.normals[i];
        let shade = 0.15 + 0.85 * n.dot(&light).max(0.0);
        let base = mesh
            .colours
            .get(i)
            .map_or([200.0, 200.0, 200.0], |c| c.map(f32::from));
        let px = Rgb(base.map(|v| (v * shade).clamp(0.0, 255.0) as u8));
        for dy in 0..k {
            for dx in 0..k {
                img.put_pixel(c * k + dx, r * k + dy, px);
            }
        }
    }
    img
}

/// PNG bytes of a picture.
///
/// # Errors
/// Encoding failure.
pub fn png_bytes(img: &RgbImage) -> Result<Vec<u8>> {
    let mut v = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png)?;
    Ok(v)
}
