//! `scanner-device render`: a scene of the virtual rig to PNG files with ground truth, for anyone
//! who wants to inspect or reuse the frames.
//!
//! Writes into the output folder: `reference.png` (laser off), `frame-NNNN.png` for each frame of
//! the sweep, `truth.csv` (per frame and column: the true stripe row, 3-D point in mm, surface,
//! cosine of the laser's incidence) and `lasers.csv` (per frame: the true light plane
//! `n·x + d = 0` and the source position).

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::rig::{Rgb8, Rig, Scene, SurfaceId};

/// What to render.
#[derive(Debug, Clone)]
pub struct RenderJob {
    /// Scene file; `None` for the demo scene at 640×480.
    pub scene: Option<PathBuf>,
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Write gray PNGs instead of RGB.
    pub gray: bool,
    /// Render at most this many frames of the sweep.
    pub frames: Option<usize>,
}

fn save(img: &Rgb8, path: &Path, gray: bool) -> Result<()> {
    let (w, h) = (img.width as u32, img.height as u32);
    let result = if gray {
        let luma = img.to_format(scanner_core::stripe::PixelFormat::Gray8);
        image::GrayImage::from_raw(w, h, luma)
            .context("gray frame size")?
            .save(path)
    } else {
        image::RgbImage::from_raw(w, h, img.data.clone())
            .context("RGB frame size")?
            .save(path)
    };
    result.with_context(|| format!("writing {}", path.display()))
}

/// Loads the scene of a job.
///
/// # Errors
/// The scene file cannot be read or is not a valid scene; the message names the file.
pub fn load_scene(path: Option<&Path>) -> Result<Scene> {
    match path {
        None => Ok(Scene::demo(640, 480)),
        Some(p) => {
            let text = fs::read_to_string(p)
                .with_context(|| format!("reading scene file {}", p.display()))?;
            let base = p.parent().unwrap_or(Path::new("."));
            Scene::from_toml_in(&text, base).with_context(|| format!("scene file {}", p.display()))
        }
    }
}

/// Renders a job; `progress` is called after each frame with (done, total).
///
/// # Errors
/// A bad scene, or a file that cannot be written; the message names it.
pub fn render(job: &RenderJob, mut progress: impl FnMut(usize, usize)) -> Result<usize> {
    let scene = load_scene(job.scene.as_deref())?;
    let rig = Rig::new(scene).context("building the virtual rig")?;
    fs::create_dir_all(&job.out).with_context(|| format!("creating {}", job.out.display()))?;
    save(&rig.reference(), &job.out.join("reference.png"), job.gray)?;
    let total = job
        .frames
        .unwrap_or(usize::MAX)
        .min(rig.scene().laser.frames);
    let mut truth = String::from("frame,column,row,x_mm,y_mm,z_mm,surface,incidence\n");
    let mut lasers = String::from("frame,nx,ny,nz,d_mm,source_x_mm,source_y_mm,source_z_mm\n");
    for k in 0..total {
        save(
            &rig.frame(k)?,
            &job.out.join(format!("frame-{k:04}.png")),
            job.gray,
        )?;
        for (u, t) in rig.truth(k)?.iter().enumerate() {
            if let Some(t) = t {
                let surface = match t.surface {
                    SurfaceId::Left => "left".to_string(),
                    SurfaceId::Right => "right".to_string(),
                    SurfaceId::Object(n) => format!("object{n}"),
                };
                let p = t.point;
                writeln!(
                    truth,
                    "{k},{u},{:.5},{:.5},{:.5},{:.5},{surface},{:.4}",
                    t.row, p.x, p.y, p.z, t.incidence
                )?;
            }
        }
        let (s, plane) = rig.laser(k)?;
        let n = plane.normal();
        writeln!(
            lasers,
            "{k},{:.9},{:.9},{:.9},{:.6},{:.4},{:.4},{:.4}",
            n.x,
            n.y,
            n.z,
            plane.offset(),
            s.x,
            s.y,
            s.z
        )?;
        progress(k + 1, total);
    }
    for (name, text) in [("truth.csv", truth), ("lasers.csv", lasers)] {
        let path = job.out.join(name);
        fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(total)
}
