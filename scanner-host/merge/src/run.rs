//! The merge's one entry point, [`run`]: views in, poses, checks, the model and the report out;
//! and [`find_thickness`], the laser sheet's thickness where the views agree best.

use std::fmt;

use scanner_core::nalgebra::{Isometry3, Point3, Vector3};
use scanner_wire::Header;

use crate::error::MergeError;
use crate::fuse::Closing;
use crate::fuse::Model;
use crate::pose::RegisterOptions;
use crate::pose::Source;
use crate::report::{MergeReport, ThicknessSearch, ThicknessTry};
use crate::view::View;

/// How a merge runs. [`MergeOptions::check`] holds every range.
#[derive(Debug, Clone, PartialEq)]
pub struct MergeOptions {
    /// Voxel size the views are thinned to for the coarse match, mm (more than 0, at most 50).
    pub voxel_mm: f64,
    /// Grid cell of the fusion into one mesh, mm (0.1 to 20).
    pub fuse_cell_mm: f64,
    /// Least share of a view's points that must land on another view for a candidate match
    /// (0.1 to 0.9); lower for views turned far apart, which share less.
    pub min_overlap: f64,
    /// A hint: the object was turned by this many degrees about the vertical between
    /// consecutive views (more than 0, at most 180 either way).
    pub turntable_deg: Option<f64>,
    /// How the surface no view saw is closed.
    pub closing: Closing,
    /// The laser sheet's thickness found by [`find_thickness`], for the report (the views were read
    /// with it).
    pub sheet: Option<ThicknessSearch>,
    /// Pose the views that carry the turntable disc's pose by it (two or more needed).
    pub use_disc: bool,
}

impl Default for MergeOptions {
    fn default() -> Self {
        MergeOptions {
            voxel_mm: 3.0,
            fuse_cell_mm: 1.0,
            min_overlap: 0.4,
            turntable_deg: None,
            closing: Closing::Smooth,
            sheet: None,
            use_disc: true,
        }
    }
}

impl MergeOptions {
    /// Checks every option against its range.
    ///
    /// # Errors
    /// [`MergeError::Option`] naming the first option out of range.
    pub fn check(&self) -> Result<(), MergeError> {
        let bad = |option, must_be, found| {
            Err(MergeError::Option {
                option,
                must_be,
                found,
            })
        };
        if !(self.voxel_mm > 0.0 && self.voxel_mm <= 50.0) {
            return bad("voxel", "more than 0 and at most 50 mm", self.voxel_mm);
        }
        if !(0.1..=20.0).contains(&self.fuse_cell_mm) {
            return bad("fuse-cell", "0.1 to 20 mm", self.fuse_cell_mm);
        }
        if !(0.1..=0.9).contains(&self.min_overlap) {
            return bad("min-overlap", "0.1 to 0.9", self.min_overlap);
        }
        if let Some(t) = self.turntable_deg
            && !(t.abs() > 0.0 && t.abs() <= 180.0)
        {
            return bad(
                "turntable",
                "a step of more than 0 and at most 180 degrees",
                t,
            );
        }
        Ok(())
    }

    fn register(&self) -> RegisterOptions {
        RegisterOptions {
            voxel_mm: self.voxel_mm,
            min_overlap: self.min_overlap,
            ..RegisterOptions::default()
        }
    }
}

/// Where a merge is: for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stage {
    /// `--sheet auto`: registering pairs of views once, without a correction.
    ThicknessRegistering {
        /// Pairs done.
        done: usize,
        /// Pairs in all.
        of: usize,
    },
    /// `--sheet auto`: refining the views read with one thickness.
    ThicknessRefining {
        /// The thickness, mm.
        sigma_mm: f64,
        /// Which try, from 1.
        tried: usize,
        /// Tries in all.
        of: usize,
    },
    /// Registering pairs of views.
    Registering {
        /// Pairs done.
        done: usize,
        /// Pairs in all.
        of: usize,
    },
    /// Refining all views together.
    Refining {
        /// The round, from 1.
        round: usize,
        /// Rounds in all.
        of: usize,
    },
    /// Fusing the views into one mesh.
    Fusing {
        /// Slices of the grid done.
        done: usize,
        /// Slices in all.
        of: usize,
    },
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Stage::ThicknessRegistering { done, of } => {
                write!(
                    f,
                    "--sheet auto: registering pairs of views: {done} of {of}"
                )
            }
            Stage::ThicknessRefining {
                sigma_mm,
                tried,
                of,
            } => write!(
                f,
                "refining all views together, --sheet auto: σ {sigma_mm} mm ({tried} of {of})"
            ),
            Stage::Registering { done, of } => {
                write!(f, "registering pairs of views: {done} of {of}")
            }
            Stage::Refining { round, .. } => {
                write!(f, "refining all views together: round {round}")
            }
            Stage::Fusing { done, of } => write!(
                f,
                "fusing the views into one mesh: {} %",
                100 * done / of.max(1)
            ),
        }
    }
}

/// The views registered, before the plausibility checks and the fusion: what helps to see a
/// wrong registration (each view in its colour) while the fusion runs, or after a refusal.
#[derive(Debug, Clone, Copy)]
pub struct Registered<'a> {
    /// View 0's header: the frame everything is in (its camera, its board).
    pub header: &'a Header,
    /// The report so far (no fusion yet).
    pub report: &'a MergeReport,
    /// Every view's points in view 0's camera frame, views in order.
    pub points: &'a [Point3<f64>],
    /// Their normals.
    pub normals: &'a [Vector3<f64>],
    /// Each point's view colour.
    pub colours: &'a [[u8; 3]],
    /// The points the fusion takes (no isolated or contradicted ones).
    pub fused: &'a [Point3<f64>],
    /// Their view colours.
    pub fused_colours: &'a [[u8; 3]],
}

/// What a merge reports as it goes.
pub trait Progress {
    /// The merge reached `stage`.
    fn stage(&mut self, stage: Stage);
    /// The views are registered (before the checks, which may refuse them).
    fn registered(&mut self, registered: &Registered<'_>) {
        let _ = registered;
    }
}

/// No progress wanted.
impl Progress for () {
    fn stage(&mut self, _: Stage) {}
}

/// A merge's result.
#[derive(Debug, Clone)]
pub struct Merged {
    /// View 0's header: the frame everything is in (its camera, its board).
    pub header: Header,
    /// Every view's pose in view 0's camera frame.
    pub poses: Vec<Isometry3<f64>>,
    /// The one mesh, view 0's camera frame.
    pub model: Model,
    /// What the report says: poses, loop closure, the checks' figures, the fusion.
    pub report: MergeReport,
}

/// Registers `views` of one object, turned between them, into view 0's frame — every pair
/// registered without a guess, the candidates that agree around the loops of views chosen
/// together, all views refined together — checks the result (the loops close, no view's points
/// lie where another saw empty space) and fuses the views into one mesh.
///
/// # Errors
/// [`MergeError`]: an option out of range, fewer than two views or views of another camera, a
/// view that matches none of the others, views refused by a plausibility check (no model), the
/// fusion failing.
pub fn run(
    views: &[View],
    options: &MergeOptions,
    progress: &mut impl Progress,
) -> Result<Merged, MergeError> {
    options.check()?;
    if views.len() < 2 {
        return Err(MergeError::TooFewViews(views.len()));
    }
    let up = match options.closing {
        Closing::FlatBase => Some(views[0].up().ok_or(MergeError::NoUp)?),
        _ => None,
    };
    let o = options.register();
    let source = Source::choose(views, options.use_disc, options.turntable_deg);
    // Without the disc, what stayed still while the object turned is left out of the
    // registration, and the support it stood on out of the model.
    let (moving, for_model, still) = match source {
        Source::Disc => (Vec::new(), Vec::new(), None),
        Source::Turntable(_) | Source::Shape => {
            let (m, f, lost) = crate::pose::still::without_still(views);
            (m, f, Some(lost))
        }
    };
    let (views, model_views) = match source {
        Source::Disc => (views, views),
        Source::Turntable(_) | Source::Shape => (&moving[..], &for_model[..]),
    };
    let registering = |done, of| Stage::Registering { done, of };
    let mut results = match source {
        Source::Disc => crate::pose::disc::disc_poses(views, &o, |done, of| {
            progress.stage(registering(done, of));
        })?,
        Source::Turntable(_) | Source::Shape => {
            crate::pose::register_views(views, &o, source.turntable_deg(), |done, of| {
                progress.stage(registering(done, of));
            })?
        }
    };
    // Disc-posed views keep their disc poses: they are an order of magnitude nearer the truth
    // than what sparse views' points tell (0.007° against the joint refinement's 0.06–0.18° on
    // the rig's 640×480 views), and about a symmetric object's axis the points tell nothing.
    let closure = match source {
        Source::Disc => crate::refine::Closure::default(),
        Source::Turntable(_) | Source::Shape => {
            crate::refine::refine_views(views, &mut results, &o, |round| {
                progress.stage(Stage::Refining {
                    round: round + 1,
                    of: crate::refine::ROUNDS,
                });
            })
        }
    };
    let poses: Vec<Isometry3<f64>> = results.iter().map(|r| r.pose).collect();
    let worst = crate::free::free_space(views, &poses, o.voxel_mm);
    let mut report = MergeReport::registered(
        views,
        &results,
        &closure,
        (worst, crate::free::tolerance(o.voxel_mm)),
        options.sheet.clone(),
    );
    if source == Source::Disc {
        report.disc = Some(crate::pose::disc::report(views, &poses, o.voxel_mm));
        report.disc_scale = crate::check::disc::scale(views).map(|(s, _)| s);
    }
    report.still = still;
    let input = crate::fuse::fusion_input(model_views, &poses);
    let (points, normals) = crate::fuse::registered_points(views, &poses);
    progress.registered(&Registered {
        header: &views[0].header,
        report: &report,
        points: &points,
        normals: &normals,
        colours: &crate::fuse::view_colours(views),
        fused: &input.points,
        fused_colours: &input.colours,
    });
    crate::check::registered(views, source, &closure, worst, o.voxel_mm)?;
    // Views that stood on the disc: the object stands on the disc's plane, and what no view
    // saw through may be filled.
    let hull = (source == Source::Disc)
        .then(|| {
            let k = (0..views.len()).find(|&k| views[k].disc.is_some())?;
            let disc = poses[k] * views[k].disc?;
            Some(crate::fuse::hull::Hull::new(
                views,
                &poses,
                &input.points,
                &disc,
                options.fuse_cell_mm,
            ))
        })
        .flatten();
    let fused = crate::fuse::fuse_views(
        &input,
        options.fuse_cell_mm,
        (options.closing, up),
        hull.as_ref(),
        |done, of| progress.stage(Stage::Fusing { done, of }),
    )
    .map_err(MergeError::Fuse)?;
    Ok(Merged {
        header: views[0].header,
        poses,
        model: fused.model,
        report: MergeReport {
            fusion: Some(fused.figures),
            ..report
        },
    })
}

/// The laser sheet's thicknesses (σ, mm) [`find_thickness`] tries: from none to twice the
/// thickest a scanning line laser's line usually is (a line 5.7 mm wide at half its brightness).
pub fn thickness_tries() -> &'static [f64] {
    &crate::refine::THICKNESS_TRIES
}

/// `--sheet auto`: the laser sheet's thickness where the views agree best. `tries[i]` are the
/// views read with the sheet's correction for the thickness [`thickness_tries`]`()[i]`; the views
/// are registered once without a correction (`tries[0]`), then refined from those poses with
/// each thickness's views and their disagreement measured; the least, refined by a parabola
/// through it and its neighbours, is the thickness found.
///
/// # Errors
/// As [`run`]'s registration; [`MergeError::ThicknessTries`] when `tries` is not one set of views
/// per thickness; [`MergeError::NoThickness`] when the views nowhere overlap.
pub fn find_thickness(
    tries: &[Vec<View>],
    options: &MergeOptions,
    progress: &mut impl Progress,
) -> Result<ThicknessSearch, MergeError> {
    options.check()?;
    let sigmas = thickness_tries();
    if tries.len() != sigmas.len() {
        return Err(MergeError::ThicknessTries {
            views: tries.len(),
            tries: sigmas.len(),
        });
    }
    let o = options.register();
    let registered =
        crate::pose::register_views(&tries[0], &o, options.turntable_deg, |done, of| {
            progress.stage(Stage::ThicknessRegistering { done, of });
        })?;
    let mut tried = Vec::with_capacity(sigmas.len());
    for (i, (&sigma_mm, views)) in sigmas.iter().zip(tries).enumerate() {
        let mut results = registered.clone();
        crate::refine::refine_views(views, &mut results, &o, |_| {
            progress.stage(Stage::ThicknessRefining {
                sigma_mm,
                tried: i + 1,
                of: sigmas.len(),
            });
        });
        tried.push(ThicknessTry {
            sigma_mm,
            disagreement_mm: crate::refine::disagreement(views, &results),
        });
    }
    let measured: Vec<(f64, f64)> = tried
        .iter()
        .map(|t| (t.sigma_mm, t.disagreement_mm.unwrap_or(f64::NAN)))
        .collect();
    let best = crate::refine::best_thickness(&measured).ok_or(MergeError::NoThickness {
        agree_mm: crate::refine::AGREE_MM,
    })?;
    Ok(ThicknessSearch {
        sigma_mm: best,
        tried,
        at_thickest: best >= sigmas[sigmas.len() - 1],
    })
}
