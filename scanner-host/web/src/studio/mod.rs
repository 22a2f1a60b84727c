//! The studio: the whole job from one browser page (`scanner-host studio`). The page asks, the
//! studio sends the head its commands ([`head`]) and keeps what comes back in a project folder
//! ([`job`]); the page reads the job, turns the model and each view in its 3-D viewer and
//! downloads the model. The server is the front's ([`crate::front`]); only fixed routes exist,
//! and files are served by name from a fixed list (no path from a request reaches the file
//! system).
//!
//! Where a command is refused, the page says why in words ([`words`]) and by kind: the wire
//! carries only numbers.

pub mod camera;
pub mod guide;
pub mod head;
pub mod job;
pub mod merge_words;
mod server;

pub use server::StudioServer;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

use axum::http::StatusCode;
use scanner_wire::{Command, Outcome, PreviewRequest, Reply, SweepRequest};

use self::head::{HeadError, HeadLink};
use self::job::Problem;

/// How long a command may wait for its reply.
pub const REPLY_WITHIN: Duration = Duration::from_secs(5);

/// How long a command the head calls busy with a sweep whose last status has arrived is asked
/// again: the head's worker is ending (its last packets are on the link before it returns).
pub const SWEEP_ENDING_WITHIN: Duration = Duration::from_secs(3);

/// Why the merge the studio ran failed (its report says more).
#[derive(Debug, thiserror::Error)]
pub enum MergeFailed {
    /// The merge refused the views: shown in the page's terms ([`merge_words::merge_refusal`]).
    #[error(transparent)]
    Refused(scanner_merge::MergeError),
    /// Anything else (a file that cannot be read or written): the merge's own words.
    #[error("{0}")]
    Other(String),
}

/// What the studio's merge runs: the views' journals into the output folder, with the least
/// overlap a match needs (the command line's own merge, handed in).
pub type MergeFn = Box<dyn Fn(&[PathBuf], &Path, f64) -> Result<(), MergeFailed> + Send + Sync>;

/// Why a command from the page was not answered by the head.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// The studio holds it back: a sweep is asked for or runs (a second would be refused by the
    /// head, or race the first).
    #[error("a sweep runs already: wait for it to end, or press Stop")]
    SweepRuns,
    /// The studio holds the calibration back: the guide still asks for shots (the coverage
    /// map has an empty region, the shots are not tilted enough, or the board's shot is
    /// missing).
    #[error("calibrate: not yet: {} thing(s) to do first, the list under the coverage map; the first: {}", .0.len(), .0.first().map_or("", |a| a.words.as_str()))]
    NotReady(Vec<guide::Ask>),
    /// The head did not answer, or the link cannot be written.
    #[error(transparent)]
    Head(#[from] HeadError),
}

impl SendError {
    /// The kind, as the page and the tests name it.
    pub fn kind(&self) -> &'static str {
        match self {
            SendError::SweepRuns => "busy",
            SendError::NotReady(_) => "not_ready",
            SendError::Head(HeadError::NoAnswer(_)) => "no_answer",
            SendError::Head(HeadError::Write(_)) => "link_failed",
        }
    }

    /// The status answered.
    pub fn status(&self) -> StatusCode {
        match self {
            SendError::SweepRuns | SendError::NotReady(_) => StatusCode::CONFLICT,
            SendError::Head(_) => StatusCode::GATEWAY_TIMEOUT,
        }
    }
}

/// The files a merge writes that the page offers.
pub const MODEL_FILES: [&str; 7] = [
    "model.3mf",
    "model.stl",
    "model.obj",
    "model.ply",
    "model.png",
    "views.png",
    "merge-report.json",
];

/// The studio: the link to the head, the project, the merge.
pub struct Studio {
    /// The link.
    pub link: HeadLink,
    /// The merge.
    pub merge: MergeFn,
    /// Held while a sweep command is on its way: one at a time.
    sweeping: Mutex<()>,
}

impl Studio {
    /// The studio of `link`, merging with `merge`.
    pub fn new(link: HeadLink, merge: MergeFn) -> Studio {
        Studio {
            link,
            merge,
            sweeping: Mutex::new(()),
        }
    }

    /// The project folder.
    pub fn project(&self) -> &Path {
        &self.link.shared.project
    }

    /// Sends a command from the page and waits for the head's answer; the answer in words.
    /// A sweep is sent only while no other is asked for or runs, and only its own refusal
    /// takes back the view it was to open: a command the head refuses changes nothing of the
    /// job.
    ///
    /// # Errors
    /// [`SendError`]: held back, or not answered.
    pub fn send(&self, cmd: Command) -> Result<(Reply, String), SendError> {
        if matches!(cmd, Command::Calibrate) {
            let g = guide::guide(&self.link.shared.job());
            if !g.ready {
                return Err(SendError::NotReady(g.asks));
            }
        }
        let sweep = matches!(cmd, Command::Sweep(_));
        let _one = if sweep {
            let gate = self.sweeping.try_lock().map_err(|_| SendError::SweepRuns)?;
            let mut job = self.link.shared.job();
            if job.awaiting_sweep || job.views.iter().any(|v| !v.done) {
                return Err(SendError::SweepRuns);
            }
            job.awaiting_sweep = true;
            if let Command::Sweep(r) = cmd {
                job.asked_disc = match r.disc {
                    1 => Some("a4".into()),
                    2 => Some("a3".into()),
                    _ => None,
                };
            }
            Some(gate)
        } else {
            None
        };
        let asked = self.ask_past_sweep_end(cmd);
        let mut job = self.link.shared.job();
        let mut save = false;
        let answer = match asked {
            Ok(r) => {
                let said = words(&cmd, &r);
                if r.outcome == Outcome::Accepted && matches!(cmd, Command::Laser { on: true }) {
                    job.head.laser_off_unheard_s = None;
                }
                if r.outcome == Outcome::Accepted && sweep && job.awaiting_sweep {
                    job.sweep_accepted = true;
                }
                if r.outcome == Outcome::Accepted && matches!(cmd, Command::Turn { .. }) {
                    job.say(said.clone());
                }
                if let (Outcome::Accepted, Command::Camera { control, value }) = (r.outcome, cmd)
                    && let Some(c) = scanner_wire::Adjustable::from_u8(control)
                {
                    job.camera.set(c, value);
                    job.say(said.clone());
                    save = true;
                }
                if r.outcome != Outcome::Accepted {
                    if sweep {
                        job.awaiting_sweep = false;
                    }
                    job.say(said.clone());
                }
                Ok((r, said))
            }
            Err(e) => {
                // unanswered: the head may still have taken it (its header opens the view)
                if sweep {
                    job.awaiting_sweep = false;
                }
                Err(e.into())
            }
        };
        if save && let Err(e) = job.save(self.project()) {
            job.say(format!("the job could not be kept: {e}"));
        }
        answer
    }

    /// Sends the head the camera controls the job keeps (set by hand on the page before the
    /// studio stopped), each once; what the head says goes into the log.
    pub fn restore_camera(&self) {
        let settings = self.link.shared.job().camera;
        for (control, value) in settings.each() {
            let cmd = Command::Camera {
                control: control as u8,
                value,
            };
            let line = match self.link.ask(cmd, REPLY_WITHIN) {
                Ok(r) => format!("restored from the job: {}", words(&cmd, &r)),
                Err(e) => format!("camera: not restored from the job: {e}"),
            };
            self.link.shared.job().say(line);
        }
    }

    /// Asks the head; a "busy with a sweep" while every view of the job has ended (the sweep's
    /// last status came, its worker not yet returned) is asked again, as a new command, for up
    /// to [`SWEEP_ENDING_WITHIN`].
    fn ask_past_sweep_end(&self, cmd: Command) -> Result<Reply, HeadError> {
        let until = std::time::Instant::now() + SWEEP_ENDING_WITHIN;
        loop {
            let asked = self.link.ask(cmd, REPLY_WITHIN);
            let ending = matches!(&asked, Ok(r) if r.outcome == Outcome::Busy
                && r.state == scanner_wire::HeadState::Sweeping)
                && self.link.shared.job().views.iter().all(|v| v.done);
            if !ending || std::time::Instant::now() >= until {
                return asked;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// The disc's diameter, mm, of the paper named as the page and the job name it (`a4`, `a3`).
fn disc_mm(paper: &str) -> Option<f64> {
    let p: scanner_calib::disc::Paper = paper.parse().ok()?;
    Some(2.0 * scanner_calib::disc::Disc::new(p).radius)
}

/// What a merge's report says against calling its model merged, in the page's terms: more than
/// one piece; the disc measured at another size than the one chosen (`papers`: the disc each
/// merged view asked for). Empty: nothing.
pub fn merge_verdict(
    report: Option<&serde_json::Value>,
    papers: &[Option<String>],
) -> Vec<Problem> {
    let mut out = Vec::new();
    let Some(r) = report else {
        return out;
    };
    if let Some(c) = r["fusion"]["check"]["components"].as_u64()
        && c > 1
    {
        // each piece by its size and share of the surface, largest first
        let pieces: Vec<String> = r["fusion"]["pieces"]
            .as_array()
            .map(Vec::as_slice)
            .unwrap_or_default()
            .iter()
            .map(|p| {
                let mm = |k: usize| p["extent_mm"][k].as_f64().unwrap_or(f64::NAN);
                let what = match p["kind"].as_str() {
                    Some("floater") => "a floater",
                    Some("part") => "a part",
                    _ => "the largest",
                };
                format!(
                    "{what} {:.0} × {:.0} × {:.0} mm ({:.1} % of the surface)",
                    mm(0),
                    mm(1),
                    mm(2),
                    100.0 * p["area_share"].as_f64().unwrap_or(f64::NAN)
                )
            })
            .collect();
        out.push(Problem {
            kind: "pieces".into(),
            words: format!(
                "the model is {c} pieces, not one ({}): a view sits in the wrong place (is the disc size on the page the one you printed?) or a piece floats apart; untick the view that does not fit and merge again",
                pieces.join("; ")
            ),
        });
    }
    if let Some(share) = r["disc_scale"].as_f64()
        && (r["refused"]["check"] == "disc_size"
            || (share - 1.0).abs() > scanner_merge::DISC_SIZE_TOLERANCE)
    {
        let chosen = papers.iter().flatten().next();
        let words = match chosen.and_then(|p| Some((p, disc_mm(p)?))) {
            Some((paper, mm)) => format!(
                "the laser measures the disc at {:.0} mm across, not the {:.0} mm of the {} disc chosen: choose the disc size you printed in Scanning, sweep the views again and merge",
                share * mm,
                mm,
                paper.to_uppercase()
            ),
            None => format!(
                "the laser measures the disc at {:.1} % of the size chosen: choose the disc size you printed in Scanning, sweep the views again and merge",
                100.0 * share
            ),
        };
        out.push(Problem {
            kind: "disc_size".into(),
            words,
        });
    }
    out
}

/// A command as the page writes it: `{"command": "shot", "board": true}`, every field but the
/// command's name optional (the defaults below). serde reads it; a name that is no command, a
/// field of the wrong type or out of its type's range is a [`serde_json::Error`] that names it.
/// The head judges the values' own limits (a preview's scale, a zoom's size) and answers with
/// its reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(tag = "command", rename_all = "lowercase")]
pub enum PageCommand {
    /// [`Command::Hello`].
    Hello,
    /// [`Command::Preview`]: a picture every 2 frames, the smallest scale, the whole picture.
    Preview {
        /// On.
        #[serde(default)]
        on: bool,
        /// A picture every this many frames.
        #[serde(default = "every_default")]
        every: u16,
        /// Camera pixels per picture pixel; 0: the smallest that fits.
        #[serde(default)]
        scale: u8,
        /// The full-resolution picture too.
        #[serde(default = "yes")]
        picture: bool,
        /// `x, y, width, height`; all 0: the whole picture.
        #[serde(default)]
        zoom: [u16; 4],
    },
    /// [`Command::Shot`].
    Shot {
        /// The board rather than the intrinsics target.
        #[serde(default)]
        board: bool,
    },
    /// [`Command::Calibrate`].
    Calibrate,
    /// [`Command::Sweep`].
    Sweep {
        /// 0 no disc, 1 A4, 2 A3.
        #[serde(default)]
        disc: u8,
        /// 0 find it, 1 rows, 2 columns.
        #[serde(default)]
        axis: u8,
        /// Colour the points.
        #[serde(default)]
        colour: bool,
        /// Send the board's points too.
        #[serde(default)]
        keep_board: bool,
        /// Stop after this many frames; 0: never.
        #[serde(default)]
        frames: u32,
    },
    /// [`Command::Stop`].
    Stop,
    /// [`Command::Camera`].
    Camera {
        /// [`scanner_wire::Adjustable`] as its number.
        #[serde(default)]
        control: u8,
        /// Its value.
        #[serde(default)]
        value: i32,
    },
    /// [`Command::Laser`].
    Laser {
        /// On.
        #[serde(default)]
        on: bool,
    },
    /// [`Command::Turn`]: one step unless told.
    Turn {
        /// Steps (negative: the other way).
        #[serde(default = "one")]
        steps: i32,
    },
}

fn every_default() -> u16 {
    2
}

fn yes() -> bool {
    true
}

fn one() -> i32 {
    1
}

impl From<PageCommand> for Command {
    fn from(c: PageCommand) -> Command {
        match c {
            PageCommand::Hello => Command::Hello,
            PageCommand::Preview {
                on,
                every,
                scale,
                picture,
                zoom,
            } => Command::Preview(PreviewRequest {
                on,
                every,
                scale,
                picture,
                zoom,
            }),
            PageCommand::Shot { board } => Command::Shot { board },
            PageCommand::Calibrate => Command::Calibrate,
            PageCommand::Sweep {
                disc,
                axis,
                colour,
                keep_board,
                frames,
            } => Command::Sweep(SweepRequest {
                disc,
                axis,
                colour,
                keep_board,
                frames,
            }),
            PageCommand::Stop => Command::Stop,
            PageCommand::Camera { control, value } => Command::Camera { control, value },
            PageCommand::Laser { on } => Command::Laser { on },
            PageCommand::Turn { steps } => Command::Turn { steps },
        }
    }
}

/// What a reply means, in words for the page.
pub fn words(command: &Command, r: &Reply) -> String {
    let name = command.name();
    let doing = match r.state {
        scanner_wire::HeadState::Idle => "nothing",
        scanner_wire::HeadState::Previewing => "the preview",
        scanner_wire::HeadState::Sweeping => "a sweep",
        scanner_wire::HeadState::Calibrating => "a shot or the calibration",
    };
    match r.outcome {
        Outcome::Accepted => match command {
            Command::Camera { control, value } => format!(
                "{name}: {} set to {value}",
                scanner_wire::Adjustable::from_u8(*control)
                    .map_or("control", scanner_wire::Adjustable::name)
            ),
            Command::Turn { .. } if r.detail != scanner_wire::TURN_UNKNOWN => format!(
                "{name}: done, turned {:.1}°{}",
                f64::from(r.detail) / 100.0,
                if r.field > 0 {
                    format!(" (now at position {})", r.field)
                } else {
                    String::new()
                }
            ),
            // work that runs on: its outcome comes in the job (a shot, the calibration, a view)
            Command::Shot { .. } | Command::Calibrate | Command::Sweep(_) => {
                format!("{name}: started")
            }
            _ => format!("{name}: done"),
        },
        Outcome::Unknown => format!("{name}: the head does not know this command (update it)"),
        Outcome::OutOfRange => format!(
            "{name}: field {} is out of range (limit {})",
            r.field, r.detail
        ),
        Outcome::Busy => format!("{name}: the head is busy with {doing}: stop it first"),
        Outcome::NotCalibrated => {
            format!("{name}: calibrate first (take the shots the calibration asks for)")
        }
        Outcome::TooFewShots if r.field == 2 => {
            format!("{name}: take a shot of the board first (laser off, both sheets in view)")
        }
        Outcome::TooFewShots => format!(
            "{name}: take at least {} shots of the target first, tilted and in every corner",
            r.detail
        ),
        Outcome::NothingToStop => format!("{name}: nothing runs"),
        Outcome::NotHere => {
            format!("{name}: this head has none (no such control, laser switch or turntable)")
        }
        Outcome::Oversized | Outcome::Malformed | Outcome::Version => {
            format!("{name}: the head could not read it ({})", r.outcome.name())
        }
        Outcome::Failed => format!("{name}: the head tried and failed (see its log)"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(json: &str) -> Result<Command, serde_json::Error> {
        serde_json::from_str::<PageCommand>(json).map(Command::from)
    }

    #[test]
    fn a_model_in_pieces_is_a_problem_and_one_piece_is_not() {
        let piece = |kind: &str, share: f64| {
            serde_json::json!({"kind": kind, "faces": 10, "area_mm2": 1.0, "area_share": share,
                "extent_mm": [60.0, 40.0, 20.0], "centre_mm": [0.0, 0.0, 0.0]})
        };
        let two = serde_json::json!({"fusion": {"check": {"components": 2},
            "pieces": [piece("main", 0.99), piece("floater", 0.01)]}});
        let kinds: Vec<String> = merge_verdict(Some(&two), &[])
            .into_iter()
            .map(|p| p.kind)
            .collect();
        assert_eq!(kinds, ["pieces"]);
        let one = serde_json::json!({"fusion": {"check": {"components": 1},
            "pieces": [piece("main", 1.0)]}});
        assert!(merge_verdict(Some(&one), &[]).is_empty());
    }

    #[test]
    fn the_pages_commands_with_their_defaults() {
        assert_eq!(read(r#"{"command":"hello"}"#).unwrap(), Command::Hello);
        assert_eq!(
            read(r#"{"command":"preview","on":true}"#).unwrap(),
            Command::Preview(PreviewRequest {
                on: true,
                every: 2,
                scale: 0,
                picture: true,
                zoom: [0; 4]
            })
        );
        assert_eq!(
            read(r#"{"command":"turn"}"#).unwrap(),
            Command::Turn { steps: 1 }
        );
        assert_eq!(
            read(r#"{"command":"sweep","disc":2,"frames":7}"#).unwrap(),
            Command::Sweep(SweepRequest {
                disc: 2,
                axis: 0,
                colour: false,
                keep_board: false,
                frames: 7
            })
        );
    }

    #[test]
    fn a_bad_command_names_what_is_wrong() {
        let fly = read(r#"{"command":"fly"}"#).unwrap_err().to_string();
        assert!(fly.contains("fly"), "{fly}");
        let range = read(r#"{"command":"sweep","disc":300}"#).unwrap_err();
        assert!(range.is_data(), "{range}");
        assert!(read(r#"{"command":"preview","zoom":[1,2,3]}"#).is_err());
        assert!(read(r#"{"on":true}"#).is_err());
    }
}
