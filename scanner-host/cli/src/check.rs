//! `check`: arguments, then a checked plan (the artefact's sizes and the tolerances in range),
//! then the run — the scan read, the artefact measured, the report (text and JSON) and the
//! residual picture written.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use scanner_host::check::{CheckFigures, SheetMoved, Tolerances};
use scanner_host::export::{self, write_atomic, write_atomic_with};
use scanner_host::grid::Cell;
use scanner_host::mesh::MeshFrame;
use scanner_host::outln;

/// A check, its figures in range.
#[derive(Debug, Clone)]
pub struct CheckPlan {
    /// The scan of the artefact.
    pub scan: PathBuf,
    /// Sphere diameters, mm (none, one or two).
    pub spheres: Vec<f64>,
    /// The nominal spacing of two spheres, mm.
    pub spacing: Option<f64>,
    /// Check the largest plane's flatness.
    pub plane: bool,
    /// The tolerances, % of the distance.
    pub tolerances: Tolerances,
    /// The scan's grid cell.
    pub cell: Cell,
    /// The laser sheet's thickness, mm.
    pub sheet_mm: f64,
    /// The output folder.
    pub out: PathBuf,
}

impl CheckPlan {
    /// Checks every figure against its range.
    ///
    /// # Errors
    /// A figure out of range, named.
    pub fn check(self) -> Result<CheckPlan> {
        scanner_host::thickness::check_thickness(self.sheet_mm)?;
        if self.spheres.len() > 2 {
            anyhow::bail!(
                "--sphere is given once or twice (a bar of two spheres), found {} times",
                self.spheres.len()
            );
        }
        for d in &self.spheres {
            if !(1.0..=500.0).contains(d) {
                anyhow::bail!("--sphere must be a diameter of 1 to 500 mm, found {d}");
            }
        }
        if let Some(s) = self.spacing
            && !(1.0..=5000.0).contains(&s)
        {
            anyhow::bail!("--spacing must be 1 to 5000 mm, found {s}");
        }
        let t = &self.tolerances;
        for (name, v) in [
            ("--size-tolerance", t.size_pct),
            ("--form-tolerance", t.form_pct),
            ("--flatness-tolerance", t.flatness_pct),
        ] {
            if !(v > 0.0 && v <= 10.0) {
                anyhow::bail!("{name} must be more than 0 and at most 10 %, found {v}");
            }
        }
        Ok(self)
    }
}

/// Runs the check and writes check-report.txt, check-report.json and check-residuals.png.
///
/// # Errors
/// The scan cannot be read, the artefact is not found, a file cannot be written, or a figure
/// fails its tolerance.
pub fn run(plan: &CheckPlan) -> Result<()> {
    let view = scanner_host::views::load_view(0, &plan.scan, plan.cell, plan.sheet_mm)
        .context("reading the scan")?;
    let (points, normals) = (&view.cloud.points, &view.cloud.normals);
    let report = scanner_host::check::check(
        points,
        normals,
        &plan.spheres,
        plan.spacing,
        plan.plane,
        plan.tolerances,
    )?;
    let figures = CheckFigures {
        sheet: view.sheet_moved.map(|(moved, of)| SheetMoved {
            sigma_mm: plan.sheet_mm,
            moved,
            of,
        }),
        ..report.figures()
    };
    let mut text = figures.text();
    // The residual picture: the checked points in the board's frame, coloured by residual.
    let scale = report
        .spheres
        .iter()
        .map(|s| s.form.rms)
        .chain(report.plane.iter().map(|p| p.flatness.rms))
        .fold(0.0, f64::max)
        * 3.0;
    let scale = scale.max(0.02);
    let frame = scanner_core::geometry::Board::<f32>::try_from(view.header.board)
        .map(|b| MeshFrame::board(&b))
        .unwrap_or_default();
    // One band per checked feature (each sphere, the plane), each from the front and the side.
    let panels: Vec<image::RgbImage> = report
        .features(points)
        .map(|feature| {
            let (pts, colours): (Vec<_>, Vec<_>) = feature
                .map(|(p, r)| {
                    (
                        frame.point(&p.cast::<f32>()),
                        scanner_host::check::residual_colour(r, scale),
                    )
                })
                .unzip();
            export::points_png(&pts, &colours)
        })
        .collect();
    let width = panels.iter().map(image::RgbImage::width).max().unwrap_or(1);
    let height: u32 = panels.iter().map(image::RgbImage::height).sum();
    let mut picture = image::RgbImage::new(width, height.max(1));
    let mut y = 0;
    for p in &panels {
        image::imageops::replace(&mut picture, p, 0, i64::from(y));
        y += p.height();
    }
    text += &format!(
        "check-residuals.png: each checked feature (top to bottom as above) from the front and the side, blue {:.3} mm inside … white 0 … red {:.3} mm outside\n",
        -scale, scale
    );
    let out: &Path = &plan.out;
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the output folder {}", out.display()))?;
    write_atomic_with(&out.join("check-residuals.png"), |w| {
        export::write_png(&picture, w)
    })?;
    write_atomic(&out.join("check-report.txt"), text.as_bytes())?;
    let json = serde_json::to_vec_pretty(&figures).context("the check report as JSON")?;
    write_atomic(&out.join("check-report.json"), &json)?;
    outln!("{}", text.trim_end());
    if !figures.pass {
        anyhow::bail!(
            "the check failed: see {} (a figure beyond its tolerance)",
            out.join("check-report.txt").display()
        );
    }
    Ok(())
}
