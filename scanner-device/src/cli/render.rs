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

use scanner_calib::DotGrid;
use scanner_calib::board::BoardFile;
use scanner_rig::{Rgb8, Rig, Scene, SurfaceId};

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
    /// Render this view of a scene with views (its true pose goes to `view-pose.txt`).
    pub view: Option<usize>,
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

/// View `k` of a scene (see [`Scene::view`]), or the scene itself.
///
/// # Errors
/// A view the scene does not have.
pub fn view_of(scene: Scene, k: Option<usize>) -> Result<Scene> {
    match k {
        Some(k) => scene.view(k).context("--view"),
        None => Ok(scene),
    }
}

/// A view's true pose as text: `p_view = R · p_scene + t` (R by rows, t in mm).
pub fn pose_text(pose: &scanner_core::nalgebra::Isometry3<f64>) -> String {
    let r = pose.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = pose.translation.vector;
    format!(
        "# the objects' pose in this view: p_view = R p_scene + t (mm)\nR = [[{:.12}, {:.12}, {:.12}], [{:.12}, {:.12}, {:.12}], [{:.12}, {:.12}, {:.12}]]\nt = [{:.9}, {:.9}, {:.9}]\n",
        m[(0, 0)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 0)],
        m[(1, 1)],
        m[(1, 2)],
        m[(2, 0)],
        m[(2, 1)],
        m[(2, 2)],
        t.x,
        t.y,
        t.z
    )
}

/// Loads the scene of a job.
///
/// # Errors
/// The scene file cannot be read or is not a valid scene; the message names the file.
pub fn load_scene(path: Option<&Path>) -> Result<Scene> {
    match path {
        None => Ok(Scene::demo(640, 480)),
        Some(p) => {
            let text = scanner_io::text_file::read(p)
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
    let scene = view_of(load_scene(job.scene.as_deref())?, job.view)?;
    let rig = Rig::new(scene).context("building the virtual rig")?;
    fs::create_dir_all(&job.out).with_context(|| format!("creating {}", job.out.display()))?;
    if job.view.is_some() {
        let path = job.out.join("view-pose.txt");
        fs::write(&path, pose_text(&rig.scene().object_pose))
            .with_context(|| format!("writing {}", path.display()))?;
    }
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

/// Renders calibration images of a rig scene: the board without laser, `shots` dot-grid shots and
/// the cross at 500 and 900 mm (tape distances in `shots.txt`), and the rig's truth as a
/// calibration file (`truth-calibration.toml`: what a perfect calibration would give, for
/// comparison and for tests that want the truth).
///
/// # Errors
/// Unwritable output.
pub fn render_calibration(rig: &Rig, out: &Path, shots: usize) -> Result<()> {
    use scanner_core::nalgebra::Point3;
    use scanner_rig::target::{Pattern, TargetPose};
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let gray = |img: &Rgb8, name: &str| -> Result<()> {
        let p = out.join(name);
        img.to_gray_image()
            .save(&p)
            .with_context(|| format!("cannot write {}", p.display()))
    };
    gray(&rig.reference(), "board.png")?;
    for (i, img) in rig.dot_grid_shots(&DotGrid::RIG, shots).iter().enumerate() {
        let p = out.join(format!("grid-{i:02}.png"));
        img.save(&p)
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    let cross = BoardFile::default().cross;
    let cp = Pattern::Cross {
        arm: cross.arm,
        dot: cross.dot,
    };
    for (name, z) in [("cross-near.png", 500.0), ("cross-far.png", 900.0)] {
        let pose = TargetPose {
            centre: Point3::new(0.0, 0.0, z),
            turn_deg: [0.0; 3],
        };
        gray(&rig.shot(&cp, &pose, z as u64).image, name)?;
    }
    let truth = out.join("truth-calibration.toml");
    rig.truth_calibration()
        .save(&truth)
        .with_context(|| format!("cannot write {}", truth.display()))?;
    let txt = out.join("shots.txt");
    std::fs::write(
        &txt,
        "board.png: the board without laser\n\
         grid-NN.png: a 9x7 dot grid, 30 mm pitch, 12 mm dots\n\
         cross-near.png: the default board's cross, lens centre 500 mm away (a tape from a mark 25 mm behind it reads 525)\n\
         cross-far.png: the same at 900 mm (tape 925)\n\
         truth-calibration.toml: the rig's true camera and board (not an estimate)\n",
    )
    .with_context(|| format!("cannot write {}", txt.display()))?;
    Ok(())
}
