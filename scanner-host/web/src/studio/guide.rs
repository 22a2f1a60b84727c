//! The calibration's guide and its verdicts: from the shots the head judged, where the next
//! target shot should go and what is still missing (nothing is "enough" while the coverage map
//! has an empty region); from the calibration's figures, a verdict per figure (good, usable,
//! redo) with the reason and what to do, in the page's terms.

use serde::Serialize;

use super::job::{CalibrationResult, Job, SetupCheck};

/// Target shots the guide asks for at least.
pub const TARGET_SHOTS: usize = 6;
/// Cells of a region of the coverage map the target must have covered for the region to count.
pub const REGION_CELLS: u32 = 2;
/// The spread of the kept shots' tilts about each of the picture's axes the guide asks for,
/// degrees (about 20° each way): shots facing the camera cannot tell the focal length from
/// the distance.
pub const TILT_SPREAD_DEG: i16 = 40;

/// The coverage map's 8 columns (and rows) in three bands: the two outer cells each side, the
/// four between.
const BANDS: [(u32, u32); 3] = [(0, 2), (2, 6), (6, 8)];
/// The regions' names, row by row.
const NAMES: [&str; 9] = [
    "top left",
    "top",
    "top right",
    "left",
    "centre",
    "right",
    "bottom left",
    "bottom",
    "bottom right",
];
/// The order the guide asks for missing regions in: the corners first (where a lens bends
/// most), then the edges, then the centre.
const ORDER: [usize; 9] = [0, 2, 6, 8, 1, 3, 5, 7, 4];

/// One region of the picture (a third of it each way, the outer bands narrower).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapRegion {
    /// Its name (`top left`, …, `centre`).
    pub name: &'static str,
    /// `x0, y0, x1, y1` as fractions of the picture: where to draw it.
    pub rect: [f32; 4],
    /// Cells of it the kept target shots covered.
    pub covered: u32,
    /// Covered enough ([`REGION_CELLS`]).
    pub done: bool,
}

/// What the guide asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AskKind {
    /// A target shot in an empty region.
    Region,
    /// Target shots tilted more.
    Tilt,
    /// More target shots.
    TargetShots,
    /// The board's shot.
    BoardShot,
}

/// One thing still missing, with what to do on the page.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ask {
    /// What.
    pub kind: AskKind,
    /// The region (index into [`Guide::regions`]) a [`AskKind::Region`] ask is for.
    pub region: Option<usize>,
    /// What to do, in the page's terms.
    pub words: String,
}

/// Where the calibration stands.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Guide {
    /// The nine regions, row by row.
    pub regions: Vec<MapRegion>,
    /// What is still missing, the next first.
    pub asks: Vec<Ask>,
    /// Nothing is missing: the calibration may run.
    pub ready: bool,
    /// Target shots kept.
    pub target_shots: usize,
    /// A board shot kept.
    pub board_shot: bool,
    /// The kept target shots' spread of tilt about the picture's horizontal and vertical axes,
    /// degrees.
    pub tilt_spread_deg: [i16; 2],
}

/// The guide of a job's shots.
pub fn guide(job: &Job) -> Guide {
    let cover = job.cover();
    let mut regions = Vec::with_capacity(9);
    for (r, rows) in BANDS.iter().enumerate() {
        for (c, cols) in BANDS.iter().enumerate() {
            let mut covered = 0;
            for y in rows.0..rows.1 {
                for x in cols.0..cols.1 {
                    covered += ((cover >> (y * 8 + x)) & 1) as u32;
                }
            }
            regions.push(MapRegion {
                name: NAMES[r * 3 + c],
                rect: [
                    cols.0 as f32 / 8.0,
                    rows.0 as f32 / 8.0,
                    cols.1 as f32 / 8.0,
                    rows.1 as f32 / 8.0,
                ],
                covered,
                done: covered >= REGION_CELLS,
            });
        }
    }
    let kept: Vec<_> = job.shots.iter().filter(|s| s.kept && !s.board).collect();
    let spread = |axis: usize| -> i16 {
        let t = kept.iter().map(|s| i16::from(s.tilt_deg[axis]));
        t.clone().max().unwrap_or(0) - t.min().unwrap_or(0)
    };
    let tilt_spread_deg = [spread(0), spread(1)];
    let board_shot = job.shots.iter().any(|s| s.kept && s.board);
    let mut asks = Vec::new();
    for &k in &ORDER {
        if !regions[k].done {
            asks.push(Ask {
                kind: AskKind::Region,
                region: Some(k),
                words: format!(
                    "Hold the target in the {} of the picture (the orange box) and press Shot of the target.",
                    regions[k].name
                ),
            });
        }
    }
    let tilts = [(0, "forward and back"), (1, "left and right")];
    for (axis, how) in tilts {
        if tilt_spread_deg[axis] < TILT_SPREAD_DEG {
            asks.push(Ask {
                kind: AskKind::Tilt,
                region: None,
                words: format!(
                    "Tilt the target {how} (about 20° each way) for the next shots: so far they span {}° of the {TILT_SPREAD_DEG}° asked for.",
                    tilt_spread_deg[axis]
                ),
            });
        }
    }
    if kept.len() < TARGET_SHOTS {
        asks.push(Ask {
            kind: AskKind::TargetShots,
            region: None,
            words: format!(
                "Take {} more shot(s) of the target, each at a new place or tilt.",
                TARGET_SHOTS - kept.len()
            ),
        });
    }
    if !board_shot {
        asks.push(Ask {
            kind: AskKind::BoardShot,
            region: None,
            words: "Take the board's shot: laser off, nothing in front of it, both sheets in view."
                .into(),
        });
    }
    Guide {
        regions,
        ready: asks.is_empty(),
        asks,
        target_shots: kept.len(),
        board_shot,
        tilt_spread_deg,
    }
}

/// A figure's verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Grade {
    /// As good as this kind of scanner gets.
    Good,
    /// Scans will work, less accurately: redo when there is time.
    Usable,
    /// Do this part again before scanning.
    Redo,
}

/// One figure of the calibration, judged.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FigureVerdict {
    /// `camera`, `board`, `laser`.
    pub part: &'static str,
    /// The figure (`rms_px`, `halves_px`, `regions`, `board_rms_px`, `board_angle_deg`,
    /// `laser_lines_pct`).
    pub figure: &'static str,
    /// Its value (`None`: not measured; the reason says why).
    pub value: Option<f64>,
    /// Its unit (`px`, `°`, `%`, `of 9`).
    pub unit: &'static str,
    /// The verdict.
    pub grade: Grade,
    /// Why, as a kind (`within`, `above_good`, `above_usable`, `failed`, `not_measured`, …).
    pub why: &'static str,
    /// What it means and what to do, in the page's terms.
    pub words: String,
}

/// The RMS reprojection error a good calibration of a webcam stays under, and the one beyond
/// which the calibration refuses itself (`scanner_calib::intrinsics::MAX_RMS_PX`), pixels.
pub const RMS_PX: (f64, f64) = (0.5, 1.0);
/// The two halves' calibrations projecting apart by at most this much, pixels, is good; up to
/// the second, usable (a third of a stripe's width and a whole pixel).
pub const HALVES_PX: (f64, f64) = (0.25, 0.75);
/// A board sheet's markers fitting their layout within this much is good; the second is the
/// board calibration's own limit (`scanner_calib::fit::MAX_SHEET_RMS_PX`), pixels.
pub const BOARD_RMS_PX: (f64, f64) = (0.2, 0.5);
/// The sheets' angle off 90° that is good, and off which it is usable, degrees (a board is
/// built at about 90°; another angle usually means a sheet came loose or bent).
pub const BOARD_ANGLE_OFF_DEG: (f64, f64) = (10.0, 30.0);
/// Regions of the nine the target must have covered to be good, and usable.
pub const REGIONS: (u32, u32) = (9, 7);

/// `value` judged against `(good, usable)` limits (smaller is better).
fn graded(value: Option<f64>, limits: (f64, f64)) -> (Grade, &'static str) {
    match value {
        None => (Grade::Redo, "not_measured"),
        Some(v) if v <= limits.0 => (Grade::Good, "within"),
        Some(v) if v <= limits.1 => (Grade::Usable, "above_good"),
        Some(_) => (Grade::Redo, "above_usable"),
    }
}

/// The calibration's figures, each judged, with the set-up's laser check (the last preview).
pub fn verdicts(
    c: &CalibrationResult,
    guide: &Guide,
    preview: Option<&SetupCheck>,
) -> Vec<FigureVerdict> {
    let f = |v: Option<f32>| v.map(f64::from);
    let intrinsics = c.result != "intrinsics_failed";
    let mut out = Vec::new();
    let (grade, why) = if intrinsics {
        graded(f(c.rms_px), RMS_PX)
    } else {
        (Grade::Redo, "failed")
    };
    out.push(FigureVerdict {
        part: "camera",
        figure: "rms_px",
        value: f(c.rms_px),
        unit: "px",
        grade,
        why,
        words: match grade {
            Grade::Good => "The lens model fits every shot.".into(),
            Grade::Usable => "The lens model fits loosely: a blurred or bent target? Take sharper shots with the target flat and calibrate again.".into(),
            Grade::Redo => "The camera's calibration failed its checks: take more target shots, flat, sharp, tilted and in every region, and calibrate again.".into(),
        },
    });
    let (grade, why) = match f(c.halves_px) {
        None if intrinsics => (Grade::Usable, "not_measured"),
        v => graded(v, HALVES_PX),
    };
    out.push(FigureVerdict {
        part: "camera",
        figure: "halves_px",
        value: f(c.halves_px),
        unit: "px",
        grade,
        why,
        words: match (grade, why) {
            (_, "not_measured") => "Too few shots to check the calibration against itself: take at least six target shots.".into(),
            (Grade::Good, _) => "Two calibrations from half the shots each agree.".into(),
            _ => "Calibrations from half the shots each disagree: the shots do not pin the lens down. Take more shots with the target nearer (about two fifths of the picture wide), tilted about 20° each way, in every region, and calibrate again.".into(),
        },
    });
    let covered = guide.regions.iter().filter(|r| r.done).count() as u32;
    let (grade, why) = match covered {
        n if n >= REGIONS.0 => (Grade::Good, "within"),
        n if n >= REGIONS.1 => (Grade::Usable, "regions_missing"),
        _ => (Grade::Redo, "regions_missing"),
    };
    out.push(FigureVerdict {
        part: "camera",
        figure: "regions",
        value: Some(f64::from(covered)),
        unit: "of 9",
        grade,
        why,
        words: if grade == Grade::Good {
            "The target was seen in every region of the picture.".into()
        } else {
            let missing: Vec<&str> = guide.regions.iter().filter(|r| !r.done).map(|r| r.name).collect();
            format!(
                "The target was never seen in the {}: points there are less accurate. Take shots there and calibrate again.",
                missing.join(", ")
            )
        },
    });
    let board = c.result == "calibrated";
    let (grade, why) = match (intrinsics, board) {
        (false, _) => (Grade::Redo, "not_measured"),
        (true, false) => (Grade::Redo, "failed"),
        _ => graded(f(c.board_rms_px), BOARD_RMS_PX),
    };
    out.push(FigureVerdict {
        part: "board",
        figure: "board_rms_px",
        value: f(c.board_rms_px),
        unit: "px",
        grade,
        why,
        words: match (grade, why) {
            (_, "not_measured") => "The board waits for the camera's calibration.".into(),
            (Grade::Good, _) => "Each sheet's dots lie where its printed layout puts them.".into(),
            (Grade::Usable, _) => "The sheets' dots fit their layout loosely: is a sheet curled or not flat on its backing? Flatten it and take the board's shot again.".into(),
            _ => "The board was not found in its shot: take the board's shot again, laser off, both sheets in view and lit.".into(),
        },
    });
    let off = f(c.board_angle_deg).map(|a| (a - 90.0).abs());
    let (grade, why) = if board {
        graded(off, BOARD_ANGLE_OFF_DEG)
    } else {
        (Grade::Redo, "not_measured")
    };
    out.push(FigureVerdict {
        part: "board",
        figure: "board_angle_deg",
        value: f(c.board_angle_deg),
        unit: "°",
        grade,
        why,
        words: match grade {
            Grade::Good => "The sheets meet at about a right angle, as the board is built.".into(),
            _ if !board => "The sheets' angle waits for the board's shot.".into(),
            _ => "The sheets do not meet at about 90°: has a sheet come loose or the crease opened? Fix the board and take its shot again.".into(),
        },
    });
    let (grade, why, value) = match preview {
        None => (Grade::Redo, "not_measured", None),
        Some(p) if p.verdict == "good" => (Grade::Good, "within", Some(p.laser_lines_pct)),
        Some(p) => (Grade::Redo, "setup_not_good", Some(p.laser_lines_pct)),
    };
    out.push(FigureVerdict {
        part: "laser",
        figure: "laser_lines_pct",
        value,
        unit: "%",
        grade,
        why,
        words: match (grade, preview) {
            (Grade::Good, _) => "The laser line crosses both sheets: its plane is found in every frame.".into(),
            (_, None) => "The laser is checked in the preview: press Preview on with the laser across both sheets.".into(),
            (_, Some(p)) => format!(
                "The last preview's verdict was {}: fix it (see Set-up) before sweeping.",
                p.verdict
            ),
        },
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::studio::job::ShotRecord;

    fn shot(cover: u64, tilt: [i8; 2]) -> ShotRecord {
        ShotRecord {
            board: false,
            kept: true,
            found: "kept".into(),
            points: 40,
            cover,
            tilt_deg: tilt,
        }
    }

    /// Shots all in the top left corner: the guide asks for the eight other regions, the
    /// other corners first, and for tilt, and is not ready; the map filled, the shots tilted
    /// and the board shot taken, it is.
    #[test]
    fn a_corner_only_job_is_asked_for_the_rest_and_a_full_one_is_ready() {
        let corner = 0b11 | 0b11 << 8;
        let mut job = Job {
            shots: (0..6).map(|_| shot(corner, [5, 5])).collect(),
            ..Job::default()
        };
        let g = guide(&job);
        assert!(!g.ready);
        assert!(g.regions[0].done);
        let regions: Vec<usize> = g.asks.iter().filter_map(|a| a.region).collect();
        assert_eq!(regions, [2, 6, 8, 1, 3, 5, 7, 4]);
        let kinds: Vec<AskKind> = g.asks.iter().map(|a| a.kind).collect();
        assert!(kinds.contains(&AskKind::Tilt) && kinds.contains(&AskKind::BoardShot));
        assert!(!kinds.contains(&AskKind::TargetShots));
        job.shots = vec![shot(u64::MAX, [-25, -22]), shot(u64::MAX, [20, 22])];
        let g = guide(&job);
        assert_eq!(
            g.asks.iter().map(|a| a.kind).collect::<Vec<_>>(),
            [AskKind::TargetShots, AskKind::BoardShot]
        );
        job.shots.extend((0..4).map(|_| shot(1, [0, 0])));
        job.shots.push(ShotRecord {
            board: true,
            ..shot(0, [0, 0])
        });
        let g = guide(&job);
        assert!(g.ready, "{:?}", g.asks);
        assert_eq!(g.tilt_spread_deg, [45, 44]);
    }

    /// A shot the head did not keep covers nothing.
    #[test]
    fn shots_not_kept_count_for_nothing() {
        let mut s = shot(u64::MAX, [30, 30]);
        s.kept = false;
        let g = guide(&Job {
            shots: vec![s],
            ..Job::default()
        });
        assert_eq!(g.target_shots, 0);
        assert!(g.regions.iter().all(|r| !r.done));
    }

    fn result(rms: f32, halves: Option<f32>, board: f32, angle: f32) -> CalibrationResult {
        CalibrationResult {
            result: "calibrated".into(),
            shots: 8,
            rms_px: Some(rms),
            halves_px: halves,
            board_rms_px: Some(board),
            board_angle_deg: Some(angle),
        }
    }

    fn grades(v: &[FigureVerdict]) -> Vec<(&'static str, Grade)> {
        v.iter().map(|v| (v.figure, v.grade)).collect()
    }

    /// Each figure gets its own verdict: good within the good limit, usable up to the usable
    /// one, redo beyond or when not measured.
    #[test]
    fn every_figure_has_its_own_verdict() {
        let full = guide(&Job {
            shots: vec![shot(u64::MAX, [-25, -25]), shot(u64::MAX, [25, 25])],
            ..Job::default()
        });
        let good = verdicts(&result(0.2, Some(0.1), 0.05, 91.0), &full, None);
        assert_eq!(
            grades(&good),
            [
                ("rms_px", Grade::Good),
                ("halves_px", Grade::Good),
                ("regions", Grade::Good),
                ("board_rms_px", Grade::Good),
                ("board_angle_deg", Grade::Good),
                ("laser_lines_pct", Grade::Redo),
            ]
        );
        assert_eq!(good[5].why, "not_measured");
        let mixed = verdicts(&result(0.7, Some(2.0), 0.3, 115.0), &full, None);
        assert_eq!(
            grades(&mixed)[..5],
            [
                ("rms_px", Grade::Usable),
                ("halves_px", Grade::Redo),
                ("regions", Grade::Good),
                ("board_rms_px", Grade::Usable),
                ("board_angle_deg", Grade::Usable),
            ]
        );
        let mut failed = result(0.0, None, 0.0, 0.0);
        failed.result = "board_failed".into();
        let v = verdicts(&failed, &full, None);
        assert_eq!(v[3].grade, Grade::Redo);
        assert_eq!(v[3].why, "failed");
        assert_eq!(v[4].why, "not_measured");
    }
}
