//! What a merge reports, as data ([`MergeReport`], written as `merge-report.json`) and as the
//! text a user reads (`merge-report.txt`, [`MergeReport::text`]). The fields are described in
//! docs/reports.md.

use std::fmt::Write as _;

use scanner_core::nalgebra::Isometry3;
use serde::Serialize;

use crate::depth::Conflict;
use crate::error::MergeError;
use crate::fuse::{Closing, FusionFigures};
use crate::pose::ViewResult;
use crate::refine::Closure;
use crate::refine::LoopError;
use crate::view::View;

/// Everything a merge found, in the order the report tells it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeReport {
    /// The laser sheet's thickness found (`--sheet auto`); `None` when it was given.
    pub sheet_search: Option<ThicknessSearch>,
    /// Each view, in order: view 0 fixes the frame.
    pub views: Vec<ViewReport>,
    /// The views refined as turns about one axis (a turntable's), if any.
    pub turns: Option<TurnsReport>,
    /// How well the loops of views close.
    pub closure: ClosureReport,
    /// The views' points against the space the other views saw empty.
    pub free_space: FreeSpaceReport,
    /// The fusion into one model; `None` when the merge stopped before it.
    pub fusion: Option<FusionFigures>,
    /// Why the merge wrote no model, when a plausibility check refused the views.
    pub refused: Option<Refusal>,
    /// The views posed by the turntable disc, when two or more carried its pose.
    pub disc: Option<Vec<crate::pose::disc::DiscView>>,
    /// Without the disc: per view, the points left out because they stayed still while the
    /// object turned (a table, a stand, a disc not posed).
    pub still: Option<Vec<usize>>,
    /// The grid cell (image pixels) the views were read again with when, at the cells chosen
    /// for their images, too few of their points matched to register them; `None` when read
    /// as chosen.
    pub finer_cell_px: Option<f64>,
    /// The turntable disc's size as the laser measured it, as a share of the size chosen (the
    /// disc-posed views' median; 1: the right disc); `None`: no disc, or too few points on it.
    pub disc_scale: Option<f64>,
}

/// `--sheet auto`: each thickness tried and where the views agree best.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThicknessSearch {
    /// The thickness taken, mm (σ across the sheet).
    pub sigma_mm: f64,
    /// Each thickness tried with the views' disagreement at it.
    pub tried: Vec<ThicknessTry>,
    /// Whether the thickest tried was taken (the sheet may be thicker, or the views disagree
    /// for another reason).
    pub at_thickest: bool,
}

/// One thickness `--sheet auto` tried.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ThicknessTry {
    /// σ, mm.
    pub sigma_mm: f64,
    /// RMS distance between overlapping views' surfaces, mm; `None` where none overlap.
    pub disagreement_mm: Option<f64>,
}

/// One view in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewReport {
    /// Its place in the merge, from 0.
    pub index: usize,
    /// Its name (the path it was read from).
    pub name: String,
    /// Points after thinning.
    pub points: usize,
    /// Of them, those clear of the view's edges (the ones the joint refinement pairs).
    pub clear_points: usize,
    /// The view it was registered onto; `None` for view 0.
    pub onto: Option<usize>,
    /// The share of its points within the registration's tolerance of that view.
    pub overlap: Option<f64>,
    /// The RMS point-to-plane residual of that registration, mm.
    pub rms_mm: Option<f64>,
    /// Other views a candidate motion of which agrees with the poses (pairs closing loops).
    pub agrees: Vec<usize>,
    /// Its rotation from view 0, degrees.
    pub rotation_deg: f64,
    /// Its pose in view 0's camera frame: the rotation as a unit quaternion `[w, x, y, z]`.
    pub rotation: [f64; 4],
    /// …and the translation, mm.
    pub translation_mm: [f64; 3],
    /// Whether a candidate of it agreed with `--turntable`'s step.
    pub on_turntable: bool,
    /// Its angle about the turntable's axis, degrees (0–360), when refined as a turn.
    pub turn_deg: Option<f64>,
    /// With the laser sheet's correction: the samples it moved and all samples.
    pub sheet_moved: Option<[u64; 2]>,
}

/// The views refined as turns about one axis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TurnsReport {
    /// Whether `--turntable` gave the step (otherwise the merge found the turns itself).
    pub hinted: bool,
    /// The views refined as turns, each with its angle.
    pub views: Vec<Turn>,
}

/// One view's turn about the turntable's axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Turn {
    /// The view.
    pub view: usize,
    /// Its angle about the axis, degrees (0–360, the first view turned forwards).
    pub deg: f64,
}

/// The loop closure before and after the joint refinement.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosureReport {
    /// Pairs of views that close loops.
    pub pairs: usize,
    /// The worst of them before the joint refinement (`None`: no pair overlaps enough).
    pub before: Option<LoopError>,
    /// After it.
    pub after: Option<LoopError>,
}

/// The free-space check's worst pair of views.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FreeSpaceReport {
    /// How far in front of what a view saw a point must lie to count, mm.
    pub tolerance_mm: f64,
    /// The pair with the largest share in front; `None` when no view's points fall on
    /// another's seen surface.
    pub worst: Option<Conflict>,
    /// That share (0–1).
    pub worst_share: Option<f64>,
}

/// Why a merge was refused.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refusal {
    /// Which check refused it.
    pub check: RefusalCheck,
    /// What the refusal says.
    pub message: String,
}

/// The plausibility check that refused a merge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RefusalCheck {
    /// A loop of views did not close.
    LoopOpen,
    /// A view's points lie where another view saw empty space.
    SeenThrough,
    /// A view posed by the turntable disc lies far from its disc pose.
    DiscMoved,
    /// The laser measures the disc at another size than the one chosen.
    DiscSize,
}

impl MergeReport {
    /// The report of views registered to `results`, their loops `closure` and their worst
    /// free-space conflict `worst` (tolerance `tolerance_mm`), before any fusion.
    pub(crate) fn registered(
        views: &[View],
        results: &[ViewResult],
        closure: &Closure,
        (worst, tolerance_mm): (Option<Conflict>, f64),
        sheet_search: Option<ThicknessSearch>,
    ) -> MergeReport {
        let turned: Vec<Turn> = results
            .iter()
            .enumerate()
            .filter_map(|(view, r)| r.turn_deg.map(|deg| Turn { view, deg }))
            .collect();
        MergeReport {
            sheet_search,
            views: views
                .iter()
                .zip(results)
                .enumerate()
                .map(|(k, (v, r))| view_report(k, v, r))
                .collect(),
            turns: (!turned.is_empty()).then(|| TurnsReport {
                hinted: results.iter().any(|r| r.on_turntable),
                views: turned,
            }),
            closure: ClosureReport {
                pairs: closure.pairs,
                before: closure.before,
                after: closure.after,
            },
            free_space: FreeSpaceReport {
                tolerance_mm,
                worst,
                worst_share: worst.map(|c| c.share()),
            },
            fusion: None,
            refused: None,
            disc: None,
            still: None,
            finer_cell_px: None,
            disc_scale: None,
        }
    }

    /// This report with the refusal `e` (a plausibility check's) in it.
    pub fn refused_by(&self, e: &MergeError) -> MergeReport {
        let check = match e {
            MergeError::LoopOpen { .. } => RefusalCheck::LoopOpen,
            MergeError::SeenThrough { .. } => RefusalCheck::SeenThrough,
            MergeError::DiscMoved { .. } => RefusalCheck::DiscMoved,
            MergeError::DiscSize { .. } => RefusalCheck::DiscSize,
            _ => return self.clone(),
        };
        MergeReport {
            refused: Some(Refusal {
                check,
                message: e.to_string(),
            }),
            ..self.clone()
        }
    }

    /// The report as the lines a user reads.
    pub fn text(&self) -> String {
        let mut s = String::new();
        if let Some(search) = &self.sheet_search {
            s += &sheet_line(search);
        }
        if let Some(px) = self.finer_cell_px {
            let _ = writeln!(
                s,
                "the views read again at {px} px cells: at the cells chosen for their images too few points matched to register them"
            );
        }
        s += "view | points (clear of its edges) | registered onto | overlap | residual RMS | also agrees with | rotation from view 0\n";
        for v in &self.views {
            let (onto, overlap, rms) = match (v.onto, v.overlap, v.rms_mm) {
                (Some(j), Some(o), Some(r)) => (
                    format!("view {j}"),
                    format!("{:.0} %", 100.0 * o),
                    format!("{r:.3} mm"),
                ),
                _ => ("(the reference)".into(), "—".into(), "—".into()),
            };
            let agrees = if v.agrees.is_empty() {
                "—".to_string()
            } else {
                format!("views {}", list(&v.agrees))
            };
            let _ = writeln!(
                s,
                "{} ({}) | {} ({}) | {onto} | {overlap} | {rms} | {agrees} | {:.3}°",
                v.index, v.name, v.points, v.clear_points, v.rotation_deg
            );
        }
        if let Some(d) = &self.disc {
            let by: Vec<String> = d
                .iter()
                .map(|v| match (v.by_disc, v.agreement) {
                    (true, Some(a)) => format!(
                        "view {} by the disc ({:.0} % of its points on the others')",
                        v.view,
                        100.0 * a
                    ),
                    (true, None) => format!("view {} by the disc", v.view),
                    _ => format!("view {} by its shape onto the disc-posed views", v.view),
                })
                .collect();
            let _ = writeln!(s, "turntable disc: {}", by.join(", "));
        }
        if let Some(t) = &self.turns {
            let how = if t.hinted {
                "--turntable"
            } else {
                "found: the views are turns about one axis"
            };
            let turned: Vec<String> = t
                .views
                .iter()
                .map(|t| format!("view {} {:.2}°", t.view, t.deg))
                .collect();
            let _ = writeln!(
                s,
                "turntable ({how}): refined as turns about one axis: {}",
                turned.join(", ")
            );
        }
        let moved: Vec<String> = self
            .views
            .iter()
            .filter_map(|v| {
                v.sheet_moved
                    .map(|[m, all]| format!("view {} {m} of {all}", v.index))
            })
            .collect();
        if !moved.is_empty() {
            let _ = writeln!(
                s,
                "points moved to where the laser sheet's middle crosses the surface (--sheet): {}",
                moved.join(", ")
            );
        }
        s += &closure_line(&self.closure);
        s += &free_space_line(&self.free_space);
        if let Some(f) = &self.fusion {
            s += &fusion_lines(f);
        }
        if let Some(r) = &self.refused {
            let _ = writeln!(s, "refused: {}", r.message);
        }
        s
    }
}

/// The report's entry for view `k`.
fn view_report(k: usize, v: &View, r: &ViewResult) -> ViewReport {
    let q = r.pose.rotation;
    let t = r.pose.translation.vector;
    ViewReport {
        index: k,
        name: v.name.clone(),
        points: r.points,
        clear_points: v.clear_points(),
        onto: r.onto,
        overlap: r.fit.map(|f| f.overlap),
        rms_mm: r.fit.map(|f| f.rms_mm),
        agrees: r.agrees.clone(),
        rotation_deg: r.pose.rotation.angle().to_degrees(),
        rotation: [q.w, q.i, q.j, q.k],
        translation_mm: [t.x, t.y, t.z],
        on_turntable: r.on_turntable,
        turn_deg: r.turn_deg,
        sheet_moved: v.sheet_moved.map(|(m, all)| [m, all]),
    }
}

impl ViewReport {
    /// Its pose in view 0's camera frame.
    pub fn pose(&self) -> Isometry3<f64> {
        use scanner_core::nalgebra::{Quaternion, Translation3, UnitQuaternion};
        let [w, i, j, k] = self.rotation;
        let [x, y, z] = self.translation_mm;
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_quaternion(Quaternion::new(w, i, j, k)),
        )
    }
}

fn list(v: &[usize]) -> String {
    v.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// `--sheet auto`'s line.
fn sheet_line(search: &ThicknessSearch) -> String {
    let tried: Vec<String> = search
        .tried
        .iter()
        .map(|t| match t.disagreement_mm {
            Some(d) => format!("{} mm: {d:.4} mm", t.sigma_mm),
            None => format!("{} mm: NaN mm", t.sigma_mm),
        })
        .collect();
    let mut line = format!(
        "laser sheet (--sheet auto): σ {:.2} mm, where the views agree best (RMS between overlapping views, σ {})",
        search.sigma_mm,
        tried.join(", ")
    );
    if search.at_thickest {
        line += "; the thickest tried: the sheet may be thicker, or the views disagree for another reason (look at views.png)";
    }
    line.push('\n');
    line
}

/// The loop-closure line.
fn closure_line(c: &ClosureReport) -> String {
    let show = |e: &Option<LoopError>| match e {
        Some(e) => format!(
            "{:.3}° {:.3} mm (view {} onto view {})",
            e.rotation_deg, e.translation_mm, e.view, e.onto
        ),
        None => "—".into(),
    };
    let pairs = match c.pairs {
        1 => "1 pair".to_string(),
        n => format!("{n} pairs"),
    };
    match (c.before, c.after) {
        (None, None) => format!(
            "loop closure: no loop to close ({pairs} of views besides the registered ones agree, none overlapping enough to tell)\n"
        ),
        (b, a) => format!(
            "loop closure (the worst of {pairs} of views that close loops, each registered directly against their poses): {} before the joint refinement, {} after\n",
            show(&b),
            show(&a)
        ),
    }
}

/// The free-space line.
fn free_space_line(f: &FreeSpaceReport) -> String {
    match f.worst {
        Some(c) => format!(
            "free space (each view's points against what the others saw empty, more than {:.1} mm in front): the worst, view {} against view {}: {:.2} % of {} points\n",
            f.tolerance_mm,
            c.view,
            c.seen_by,
            100.0 * c.share(),
            c.tested
        ),
        None => "free space: no view's points fall on another's seen surface\n".into(),
    }
}

/// The fusion's lines.
fn fusion_lines(f: &FusionFigures) -> String {
    let mut s = format!(
        "points on the views' edges left out of the fusion: {} more than {} mm off the surface another view saw clear of its edges, {} where the winding number of all the points is over {} from ½ (off the surface they wind around)\n",
        f.contradicted, f.edge_off_mm, f.off_surface, f.off_surface_margin
    );
    let reach = f.unseen_reach_mm;
    s += &match (f.closing, f.trimmed_faces) {
        (Closing::Trim, Some(removed)) => format!(
            "trimmed {removed} faces ({:.1} % of the area) farther than {reach:.1} mm from every point: surface no view saw\n",
            100.0 * f.unseen_share
        ),
        _ => format!(
            "surface no view saw (farther than {reach:.1} mm from every point): {:.1} % of the area, closed by the points' winding number (--trim-unseen removes it)\n",
            100.0 * f.unseen_share
        ),
    };
    if let Some(base) = f.base_mm2 {
        let _ = writeln!(
            s,
            "closed flat at the bottom, level with the lowest point a view saw: a base of {base:.0} mm² (--flat-base)"
        );
    }
    if f.coloured {
        s += "model coloured per vertex from the views (the nearest point's colour)\n";
    }
    let c = &f.check;
    let _ = writeln!(
        s,
        "model: {} vertices, {} faces, {}, {} component(s)",
        f.vertices,
        f.faces,
        if c.watertight {
            format!("watertight, volume {:.0} mm³", c.volume_mm3)
        } else {
            format!("{} open edges (no volume)", c.open_edges)
        },
        c.components,
    );
    if f.pieces.len() > 1 {
        let _ = writeln!(
            s,
            "the model is {} pieces, not one (the merge refuses to call it merged): {}",
            f.pieces.len(),
            f.pieces
                .iter()
                .map(|p| format!(
                    "{} {:.0}×{:.0}×{:.0} mm at ({:.0}, {:.0}, {:.0}), {:.1} % of the area",
                    match p.kind {
                        crate::fuse::PieceKind::Main => "the largest",
                        crate::fuse::PieceKind::Part =>
                            "a part (a view in the wrong place, or a second object)",
                        crate::fuse::PieceKind::Floater => "a floater",
                    },
                    p.extent_mm[0],
                    p.extent_mm[1],
                    p.extent_mm[2],
                    p.centre_mm[0],
                    p.centre_mm[1],
                    p.centre_mm[2],
                    100.0 * p.area_share
                ))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    s
}
