//! `merge` (and `receive --merge`): arguments, then a checked plan (the merge's options in
//! range), then the run — the views read and merged by the library — and the files written:
//! views.ply and views.png as soon as the views are registered, the model and the reports
//! (text and JSON) at the end; a refused merge leaves the views and the report to look at.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use scanner_host::export::{self, write_atomic, write_atomic_with};
use scanner_host::grid::Cell;
use scanner_host::mesh::{Mesh, MeshFrame};
use scanner_host::views::{MergeProgress, Thickness, ViewsError, merge_folders};
use scanner_host::{errln, outln};
use scanner_merge::{Closing, MergeError, MergeOptions, MergeReport, Progress, Registered, Stage};
use scanner_web::live::LiveView;

use crate::show::progress_bar;

/// What a refused merge leaves to look at (those written before it stopped).
pub const REFUSED_FILES: &[&str] = &[
    "views.png",
    "views.ply",
    "merge-report.txt",
    "merge-report.json",
];

/// What a merge writes.
const MODEL_FILES: [&str; 9] = [
    "model.obj",
    "model.ply",
    "model.stl",
    "model.3mf",
    "model.png",
    "views.png",
    "views.ply",
    "merge-report.txt",
    "merge-report.json",
];

/// A merge, checked.
#[derive(Debug, Clone)]
pub struct MergePlan {
    /// The views: receive output folders or journals.
    pub views: Vec<PathBuf>,
    /// The output folder.
    pub out: PathBuf,
    /// Each view's grid cell (`None`: in proportion to its image, [`scanner_host::views::cell_for`]).
    pub cell: Option<Cell>,
    /// The laser sheet's thickness.
    pub sheet: Thickness,
    /// The merge's options.
    pub options: MergeOptions,
    /// No progress display.
    pub quiet: bool,
}

impl MergePlan {
    /// Checks a merge's options (every range, in [`MergeOptions::check`] and the sheet's).
    ///
    /// # Errors
    /// An option out of range.
    pub fn new(
        views: &[PathBuf],
        out: &Path,
        (cell, sheet): (Option<Cell>, Thickness),
        options: MergeOptions,
        quiet: bool,
    ) -> Result<MergePlan> {
        options.check()?;
        if let Thickness::Mm(mm) = sheet {
            scanner_host::thickness::check_thickness(mm)?;
        }
        Ok(MergePlan {
            views: views.to_vec(),
            out: out.to_path_buf(),
            cell,
            sheet,
            options,
            quiet,
        })
    }

    /// The closing `--trim-unseen` and `--flat-base` ask for (clap keeps them apart).
    pub fn closing(trim_unseen: bool, flat_base: bool) -> Closing {
        match (trim_unseen, flat_base) {
            (true, _) => Closing::Trim,
            (false, true) => Closing::FlatBase,
            (false, false) => Closing::Smooth,
        }
    }
}

/// The merge's progress on the terminal and the live view, and what it writes as soon as the
/// views are registered.
struct Shown<'a> {
    pb: indicatif::ProgressBar,
    view: Option<&'a LiveView>,
    out: &'a Path,
    /// The last text shown on the page (the fusion's percentages come often).
    last: String,
    /// The report as the views were registered (written if a check refuses them).
    registered: Option<MergeReport>,
    /// A file that could not be written while the merge ran.
    failed: Option<anyhow::Error>,
}

impl Shown<'_> {
    fn say(&mut self, text: String) {
        self.pb.set_message(text.clone());
        self.pb.tick();
        if let Some(v) = self.view
            && text != self.last
        {
            v.stage(&text);
        }
        self.last = text;
    }

    /// views.ply and views.png: every view in its colour, the board's frame like the model.
    fn write_views(&self, r: &Registered<'_>, frame: MeshFrame) -> Result<()> {
        std::fs::create_dir_all(self.out)
            .with_context(|| format!("cannot create the output folder {}", self.out.display()))?;
        let mut all = Mesh {
            vertices: r.points.iter().map(|p| p.cast()).collect(),
            normals: r.normals.iter().map(|n| n.cast()).collect(),
            colours: r.colours.to_vec(),
            ..Mesh::default()
        };
        all.into_frame(frame);
        write_atomic(&self.out.join("views.ply"), &export::ply(&all))?;
        let fused: Vec<_> = r.fused.iter().map(|p| frame.point(&p.cast())).collect();
        write_atomic_with(&self.out.join("views.png"), |w| {
            export::write_png(&export::points_png(&fused, r.fused_colours), w)
        })?;
        if let Some(v) = self.view {
            // While the fusion runs, or to see which view went wrong when a check refuses them.
            for (pts, rgb) in fused.chunks(8192).zip(r.fused_colours.chunks(8192)) {
                v.points(pts, rgb);
            }
        }
        Ok(())
    }
}

impl Progress for Shown<'_> {
    fn stage(&mut self, stage: Stage) {
        self.say(stage.to_string());
    }

    fn registered(&mut self, r: &Registered<'_>) {
        // views the turntable disc posed rest on the disc, not on pairwise matches: their
        // agreement where they overlap and the free-space check stand for the loops
        if r.report.closure.after.is_none() && r.report.disc.is_none() {
            errln!(
                "warning: no loop of views to check the registration by (each view rests on one pairwise match): look at views.png before trusting the model; a view that overlaps two others closes a loop"
            );
        }
        if let Err(e) = self.write_views(r, frame_of(r.header)) {
            self.failed.get_or_insert(e);
        }
        self.registered = Some(r.report.clone());
    }
}

impl MergeProgress for Shown<'_> {
    fn reading(&mut self, view: usize, sheet_mm: f64) {
        let what = if sheet_mm > 0.0 {
            format!(" (the sheet's correction at σ {sheet_mm} mm)")
        } else {
            String::new()
        };
        self.say(format!("reading view {view}{what}"));
    }

    fn finer(&mut self, cell_px: f64, why: &MergeError) {
        errln!("note: {why}\nnote: reading the views again with cells of {cell_px} px");
    }
}

/// The board's frame of a view 0 (the camera's when it carries no board).
fn frame_of(header: &scanner_wire::Header) -> MeshFrame {
    scanner_core::geometry::Board::<f32>::try_from(header.board)
        .map(|b| MeshFrame::board(&b))
        .unwrap_or_default()
}

/// Writes `report` as merge-report.txt and merge-report.json into `out`.
fn write_report(out: &Path, report: &MergeReport) -> Result<()> {
    write_atomic(&out.join("merge-report.txt"), report.text().as_bytes())?;
    let json = serde_json::to_vec_pretty(report).context("the merge report as JSON")?;
    write_atomic(&out.join("merge-report.json"), &json)?;
    Ok(())
}

/// Runs a merge and writes its files; with a live view, shows the views and then the model.
///
/// # Errors
/// A view that cannot be read, the merge refused or failed, a file that cannot be written.
pub fn run(plan: &MergePlan, view: Option<&LiveView>) -> Result<()> {
    let mut shown = Shown {
        pb: progress_bar(plan.quiet),
        view,
        out: &plan.out,
        last: String::new(),
        registered: None,
        failed: None,
    };
    let merged = merge_folders(
        &plan.views,
        plan.cell,
        plan.sheet,
        &plan.options,
        &mut shown,
    );
    shown.pb.finish_and_clear();
    if let Some(e) = shown.failed.take() {
        return Err(e);
    }
    let merged = match merged {
        Ok(m) => m,
        Err(ViewsError::Merge(e)) if e.is_implausible() => {
            if let Some(report) = &shown.registered {
                let report = report.refused_by(&e);
                write_report(&plan.out, &report)?;
                outln!("{}", report.text().trim_end());
            }
            return Err(e.into());
        }
        Err(e) => return Err(e.into()),
    };
    let mut model = Mesh::from(merged.model);
    model.into_frame(frame_of(&merged.header));
    let out = &plan.out;
    write_atomic_with(&out.join("model.png"), |w| {
        export::write_png(&export::orbit_png(&model), w)
    })?;
    write_atomic_with(&out.join("model.obj"), |w| export::write_obj(&model, w))?;
    write_atomic_with(&out.join("model.ply"), |w| export::write_ply(&model, w))?;
    write_atomic_with(&out.join("model.stl"), |w| export::write_stl(&model, w))?;
    write_atomic_with(&out.join("model.3mf"), |w| export::write_3mf(&model, w))?;
    write_report(out, &merged.report)?;
    outln!("{}", merged.report.text().trim_end());
    outln!(
        "wrote model.obj, model.ply, model.stl, model.3mf (one mesh, y up), model.png (from four sides), views.ply and views.png (each view in its colour), merge-report.txt and .json to {}",
        out.display()
    );
    if let Some(v) = view {
        // a model in pieces is not said to be merged: the page shows how many
        let pieces = merged.report.fusion.as_ref().map_or(1, |f| f.pieces.len());
        let ended = if pieces > 1 {
            format!("a model in {pieces} pieces, not one: see the report")
        } else {
            "merged".to_string()
        };
        v.finish(None, Some(model), out, &MODEL_FILES, &ended);
    }
    Ok(())
}

/// Keeps the live view up after a merge ([`crate::show::linger`]); a merge that stopped is
/// shown on the page as stopped, with what it left in `dir`, and its error said before the page
/// lingers (the exit status still fails).
///
/// # Errors
/// The merge's own error, once the page is closed.
pub fn linger(v: &LiveView, merged: Result<()>, dir: &Path, for_secs: Option<f64>) -> Result<()> {
    if let Err(e) = &merged {
        errln!("scanner-host: error: {e:#}");
        v.stopped(dir, REFUSED_FILES, &format!("{e:#}"));
    }
    crate::show::linger(v, for_secs);
    merged.map_err(|_| anyhow::anyhow!("the merge stopped (the reason above)"))
}

/// `receive --merge`: the session's journal split into one view per scan, each view's
/// outputs written, and the views merged into OUT/model with `options` (checked before the
/// session: `receive`'s `--turntable` and `--min-overlap`, the merge's defaults otherwise).
///
/// # Errors
/// The journal cannot be split, a view's outputs cannot be written, the merge fails.
pub fn sweeps(
    out: &crate::receive::OutputPlan,
    options: MergeOptions,
    view: Option<&LiveView>,
) -> Result<()> {
    let folders = scanner_host::views::split_scans(&out.dir.join("journal.stream"), &out.dir)?;
    for f in &folders {
        let c =
            scanner_host::outputs::replay(out.collect, &f.join("journal.stream"), out.sheet_mm)?;
        let s = scanner_host::write_outputs(&c, f, &out.outputs)?;
        outln!(
            "{}: {}",
            f.display(),
            s.text().lines().next().unwrap_or_default()
        );
    }
    let plan = MergePlan::new(
        &folders,
        &out.dir.join("model"),
        (Some(out.collect.cell), Thickness::Mm(out.sheet_mm)),
        options,
        out.quiet,
    )?;
    run(&plan, view)
}
