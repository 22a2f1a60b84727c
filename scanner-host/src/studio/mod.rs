//! The studio: the whole job from one browser page (`scanner-host studio`). The page asks, the
//! studio sends the head its commands ([`head`]) and keeps what comes back in a project folder
//! ([`job`]); the page reads the job and downloads the model. The server is `tiny_http`'s; only
//! fixed routes exist, and files are served by name from a fixed list (no path from a request
//! reaches the file system).
//!
//! Where a command is refused, the page says why in words ([`words`]): the wire carries only
//! numbers.

pub mod head;
pub mod job;
mod server;

pub use server::{MAX_BODY, StudioServer};

use std::path::{Path, PathBuf};
use std::time::Duration;

use scanner_wire::{Command, Outcome, PreviewRequest, Reply, SweepRequest};

use self::head::HeadLink;

/// How long a command may wait for its reply.
pub const REPLY_WITHIN: Duration = Duration::from_secs(5);

/// What the studio's merge runs: the views' journals into the output folder, with the least
/// overlap a match needs (the command line's own merge, handed in).
pub type MergeFn = Box<dyn Fn(&[PathBuf], &Path, f64) -> Result<(), String> + Send + Sync>;

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
}

impl Studio {
    /// The project folder.
    pub fn project(&self) -> &Path {
        &self.link.shared.project
    }
}

/// A command from the page's JSON (`{"command": "shot", "board": true}`).
///
/// # Errors
/// An unknown command or a field of the wrong type, in words.
pub fn command_of(v: &serde_json::Value) -> Result<Command, String> {
    let flag = |k: &str| v[k].as_bool().unwrap_or(false);
    let int = |k: &str, d: i64| -> Result<i64, String> {
        match &v[k] {
            serde_json::Value::Null => Ok(d),
            n => n
                .as_i64()
                .ok_or_else(|| format!("{k} must be a whole number")),
        }
    };
    let narrow = |k: &str, d: i64| -> Result<i32, String> {
        i32::try_from(int(k, d)?).map_err(|_| format!("{k} is out of range"))
    };
    Ok(match v["command"].as_str().unwrap_or("") {
        "hello" => Command::Hello,
        "preview" => Command::Preview(PreviewRequest {
            on: flag("on"),
            every: u16::try_from(int("every", 2)?).map_err(|_| "every is out of range")?,
            scale: u8::try_from(int("scale", 0)?).map_err(|_| "scale is out of range")?,
            picture: v["picture"].as_bool().unwrap_or(true),
            zoom: match v["zoom"].as_array() {
                None => [0; 4],
                Some(z) if z.len() == 4 => {
                    let mut out = [0u16; 4];
                    for (o, n) in out.iter_mut().zip(z) {
                        *o = n
                            .as_u64()
                            .and_then(|n| u16::try_from(n).ok())
                            .ok_or("zoom takes four whole numbers: x, y, width, height")?;
                    }
                    out
                }
                Some(_) => return Err("zoom takes four whole numbers: x, y, width, height".into()),
            },
        }),
        "shot" => Command::Shot {
            board: flag("board"),
        },
        "calibrate" => Command::Calibrate,
        "sweep" => Command::Sweep(SweepRequest {
            disc: u8::try_from(int("disc", 0)?).map_err(|_| "disc is out of range")?,
            axis: u8::try_from(int("axis", 0)?).map_err(|_| "axis is out of range")?,
            colour: flag("colour"),
            keep_board: flag("keep_board"),
            frames: u32::try_from(int("frames", 0)?).map_err(|_| "frames is out of range")?,
        }),
        "stop" => Command::Stop,
        "camera" => Command::Camera {
            control: u8::try_from(int("control", 0)?).map_err(|_| "control is out of range")?,
            value: narrow("value", 0)?,
        },
        "laser" => Command::Laser { on: flag("on") },
        "turn" => Command::Turn {
            steps: narrow("steps", 1)?,
        },
        other => {
            return Err(format!(
                "{:?} is no command (hello, preview, shot, calibrate, sweep, stop, camera, laser, turn)",
                other.chars().take(40).collect::<String>()
            ));
        }
    })
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
        Outcome::Accepted => format!("{name}: done"),
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
