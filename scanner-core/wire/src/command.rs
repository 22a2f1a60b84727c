//! What the host asks of the head ([`Command`], host → head) and the head's answer to each
//! ([`Reply`], head → host). Commands travel in frames like the head's messages (version byte,
//! postcard, CRC, COBS), each as a [`CommandFrame`] that numbers it, so that every answer names
//! the command it answers and a command sent again after a link fault is recognised.
//!
//! The wire carries numbers; the words (why a command was refused, what to do) are the ends'.

use serde::{Deserialize, Serialize};

/// Largest command frame before COBS, bytes (version, body and CRC): a command is a handful
/// of numbers, so anything longer is refused unread.
pub const MAX_COMMAND: usize = 64;
/// Largest encoded command frame, COBS overhead and both delimiters included.
pub const MAX_COMMAND_ENCODED: usize = cobs::max_encoding_length(MAX_COMMAND) + 2;

/// A command with its number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct CommandFrame {
    /// The command's number, chosen by the host: its reply carries it. A command received
    /// again with the number of the last one is not done twice; its reply is sent again.
    pub seq: u32,
    /// What to do.
    pub command: Command,
}

/// What the host asks of the head.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Command {
    /// Nothing: the reply tells what the head is doing (and that it hears).
    Hello,
    /// The camera's picture with what the head finds in it, about once a second.
    Preview(PreviewRequest),
    /// Take a calibration shot: the intrinsics target, or the board with the laser off.
    Shot {
        /// The board (laser off) rather than the intrinsics target.
        board: bool,
    },
    /// Calibrate from the shots taken: the intrinsics, then the board's planes.
    Calibrate,
    /// Take a sweep with these options.
    Sweep(SweepRequest),
    /// Stop what runs (a sweep or the preview), with its final message.
    Stop,
    /// Set a camera control.
    Camera {
        /// Which: [`Adjustable`] as its number.
        control: u8,
        /// Its value (the V4L2 value).
        value: i32,
    },
    /// Switch the laser on or off, where the head switches it.
    Laser {
        /// On.
        on: bool,
    },
    /// Turn the turntable by this many of its steps (negative: the other way), where the head
    /// has one.
    Turn {
        /// Steps.
        steps: i32,
    },
}

/// Commands this version knows: a frame whose variant is beyond is [`Outcome::Unknown`].
pub const COMMANDS: u32 = 9;

/// The preview's settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PreviewRequest {
    /// On, or off.
    pub on: bool,
    /// A picture every this many frames, 1 to [`PREVIEW_MAX_EVERY`].
    pub every: u16,
    /// Camera pixels per picture pixel, 1 to [`PREVIEW_MAX_SCALE`]; 0: the smallest that
    /// keeps the picture within the preview's limits.
    pub scale: u8,
    /// Also send the picture at up to full resolution (a JPEG), with each preview.
    pub picture: bool,
    /// The part of the picture to send, camera pixels: `x, y, width, height`; all 0: the whole
    /// picture (averaged down to 640 × 480 at most). A part of at most 640 × 480 comes at full
    /// resolution: a zoom.
    pub zoom: [u16; 4],
}

/// Smallest zoomed part of the picture, camera pixels a side.
pub const MIN_ZOOM: u16 = 16;
/// Most frames between two preview pictures.
pub const PREVIEW_MAX_EVERY: u16 = 1000;
/// Largest preview scale.
pub const PREVIEW_MAX_SCALE: u8 = 64;

/// A sweep's options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SweepRequest {
    /// Look for the turntable disc: 0 no, 1 on A4 paper, 2 on A3.
    pub disc: u8,
    /// Which way the stripe runs: 0 find it, 1 rows (a vertical stripe), 2 columns.
    pub axis: u8,
    /// Colour each point from the reference.
    pub colour: bool,
    /// Send the board's stripe points too.
    pub keep_board: bool,
    /// Stop after this many frames; 0: at the source's end or a stop.
    pub frames: u32,
}

/// A camera control a [`Command::Camera`] sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Adjustable {
    /// Exposure time (V4L2 `exposure_absolute`, units of 100 µs).
    Exposure = 0,
    /// Gain.
    Gain = 1,
    /// Focus (V4L2 `focus_absolute`).
    Focus = 2,
    /// White balance (V4L2 `white_balance_temperature`, kelvin).
    WhiteBalance = 3,
}

impl Adjustable {
    /// Its name, for people (`exposure`, `gain`, `focus`, `white balance`).
    pub fn name(self) -> &'static str {
        match self {
            Adjustable::Exposure => "exposure",
            Adjustable::Gain => "gain",
            Adjustable::Focus => "focus",
            Adjustable::WhiteBalance => "white balance",
        }
    }

    /// The control numbered `n`.
    pub fn from_u8(n: u8) -> Option<Adjustable> {
        match n {
            0 => Some(Adjustable::Exposure),
            1 => Some(Adjustable::Gain),
            2 => Some(Adjustable::Focus),
            3 => Some(Adjustable::WhiteBalance),
            _ => None,
        }
    }
}

/// Camera controls set by hand, in the camera's units (V4L2: exposure in 100 µs, white balance
/// in kelvin); `None`: the camera's own, which the head locks for each scan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ByHand {
    /// Exposure.
    pub exposure: Option<i32>,
    /// Gain.
    pub gain: Option<i32>,
    /// Focus.
    pub focus: Option<i32>,
    /// White balance.
    pub white_balance: Option<i32>,
}

impl ByHand {
    /// Sets one.
    pub fn set(&mut self, control: Adjustable, value: i32) {
        *match control {
            Adjustable::Exposure => &mut self.exposure,
            Adjustable::Gain => &mut self.gain,
            Adjustable::Focus => &mut self.focus,
            Adjustable::WhiteBalance => &mut self.white_balance,
        } = Some(value);
    }

    /// Those set, in the order they are set on a camera.
    pub fn each(&self) -> impl Iterator<Item = (Adjustable, i32)> {
        [
            (Adjustable::Exposure, self.exposure),
            (Adjustable::Gain, self.gain),
            (Adjustable::Focus, self.focus),
            (Adjustable::WhiteBalance, self.white_balance),
        ]
        .into_iter()
        .filter_map(|(c, v)| v.map(|v| (c, v)))
    }
}

/// Largest value of a camera control on the wire (a camera's own range is narrower).
pub const MAX_CONTROL_VALUE: i32 = 1_000_000;
/// Most turntable steps one command turns, either way.
pub const MAX_TURN_STEPS: i32 = 1_000_000;
/// An accepted turn's reply carries the angle turned in its `detail` (hundredths of a degree)
/// and where the turntable stands now in its `field` (from 1); this `detail`: the angle is not
/// known (a motor without its steps' angle).
pub const TURN_UNKNOWN: i32 = i32::MIN;

/// Which field of a command is out of range (the reply's `field`), numbered from 1 in the
/// command's order of fields.
pub type Field = u8;

impl Command {
    /// Whether every field is within the wire's ranges; the first that is not. The head checks
    /// what only it knows (its camera's ranges, the picture's size) after this.
    ///
    /// # Errors
    /// The field out of range and its limit.
    pub fn check(&self) -> Result<(), (Field, i32)> {
        match *self {
            Command::Preview(p) => {
                if p.on && !(1..=PREVIEW_MAX_EVERY).contains(&p.every) {
                    return Err((2, i32::from(PREVIEW_MAX_EVERY)));
                }
                if p.scale > PREVIEW_MAX_SCALE {
                    return Err((3, i32::from(PREVIEW_MAX_SCALE)));
                }
                let [_, _, w, h] = p.zoom;
                if p.zoom != [0; 4] && (w < MIN_ZOOM || h < MIN_ZOOM) {
                    return Err((5, i32::from(MIN_ZOOM)));
                }
            }
            Command::Sweep(s) => {
                if s.disc > 2 {
                    return Err((1, 2));
                }
                if s.axis > 2 {
                    return Err((2, 2));
                }
            }
            Command::Camera { control, value } => {
                if Adjustable::from_u8(control).is_none() {
                    return Err((1, 3));
                }
                if !(0..=MAX_CONTROL_VALUE).contains(&value) {
                    return Err((2, MAX_CONTROL_VALUE));
                }
            }
            Command::Turn { steps } => {
                if steps == 0 || !(-MAX_TURN_STEPS..=MAX_TURN_STEPS).contains(&steps) {
                    return Err((1, MAX_TURN_STEPS));
                }
            }
            Command::Hello
            | Command::Shot { .. }
            | Command::Calibrate
            | Command::Stop
            | Command::Laser { .. } => {}
        }
        Ok(())
    }

    /// Its name in reports: `hello`, `preview`, `shot`, `calibrate`, `sweep`, `stop`,
    /// `camera`, `laser`, `turn`.
    pub fn name(&self) -> &'static str {
        match self {
            Command::Hello => "hello",
            Command::Preview(_) => "preview",
            Command::Shot { .. } => "shot",
            Command::Calibrate => "calibrate",
            Command::Sweep(_) => "sweep",
            Command::Stop => "stop",
            Command::Camera { .. } => "camera",
            Command::Laser { .. } => "laser",
            Command::Turn { .. } => "turn",
        }
    }
}

/// What the head is doing (in every [`Reply`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum HeadState {
    /// Waiting for a command.
    Idle = 0,
    /// Sending preview pictures.
    Previewing = 1,
    /// Sweeping.
    Sweeping = 2,
    /// Taking a shot or calibrating.
    Calibrating = 3,
}
wire_enum!(
    HeadState,
    Idle = 0,
    Previewing = 1,
    Sweeping = 2,
    Calibrating = 3
);

/// What became of a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum Outcome {
    /// Accepted: done, or started (a sweep, the preview, a shot: their own messages follow).
    Accepted = 0,
    /// A command this head does not know (a newer host): `detail` is its variant.
    Unknown = 1,
    /// A field out of range: `field` names it (from 1), `detail` is its limit.
    OutOfRange = 2,
    /// Something else runs (the reply's `state`): stop it first.
    Busy = 3,
    /// A sweep needs a calibration: calibrate first.
    NotCalibrated = 4,
    /// Too few shots to calibrate: `field` 1 the target's, 2 the board's; `detail` how many
    /// are needed.
    TooFewShots = 5,
    /// Nothing runs to stop.
    NothingToStop = 6,
    /// This head has no such thing (a camera control, a laser switch, a turntable).
    NotHere = 7,
    /// A frame longer than [`MAX_COMMAND`]: not read (`seq` 0).
    Oversized = 8,
    /// A known command whose fields do not decode.
    Malformed = 9,
    /// A version of the wire this head does not read: `detail` is it.
    Version = 10,
    /// Accepted, tried, and failed: the camera refused the value, the calibration failed its
    /// checks, the source ended (the head's own message or log says more).
    Failed = 11,
}
wire_enum!(
    Outcome,
    Accepted = 0,
    Unknown = 1,
    OutOfRange = 2,
    Busy = 3,
    NotCalibrated = 4,
    TooFewShots = 5,
    NothingToStop = 6,
    NotHere = 7,
    Oversized = 8,
    Malformed = 9,
    Version = 10,
    Failed = 11
);

impl Outcome {
    /// Its name in reports: `accepted`, `unknown`, `out_of_range`, `busy`, `not_calibrated`,
    /// `too_few_shots`, `nothing_to_stop`, `not_here`, `oversized`, `malformed`, `version`,
    /// `failed`.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Accepted => "accepted",
            Outcome::Unknown => "unknown",
            Outcome::OutOfRange => "out_of_range",
            Outcome::Busy => "busy",
            Outcome::NotCalibrated => "not_calibrated",
            Outcome::TooFewShots => "too_few_shots",
            Outcome::NothingToStop => "nothing_to_stop",
            Outcome::NotHere => "not_here",
            Outcome::Oversized => "oversized",
            Outcome::Malformed => "malformed",
            Outcome::Version => "version",
            Outcome::Failed => "failed",
        }
    }
}

/// The head's answer to one command (head → host).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Reply {
    /// The command's number (0 when it could not be read).
    pub seq: u32,
    /// What became of it.
    pub outcome: Outcome,
    /// What the head is doing now.
    pub state: HeadState,
    /// With [`Outcome::OutOfRange`] and [`Outcome::TooFewShots`]: which field or shots; 0
    /// otherwise.
    pub field: u8,
    /// A number the outcome explains (a limit, a count, a version); 0 otherwise.
    pub detail: i32,
}

/// Why a command frame was not read as a command (after its COBS, CRC and version passed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandError {
    /// A command this version does not know: its number and its variant.
    Unknown(u32, u32),
    /// Its number could be read, its fields not.
    Malformed(u32),
    /// Not even its number could be read.
    Unreadable,
}

impl core::fmt::Display for CommandError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Unknown(seq, v) => write!(f, "command {seq}: unknown command {v}"),
            Self::Malformed(seq) => write!(f, "command {seq}: its fields do not decode"),
            Self::Unreadable => f.write_str("a frame that is not a command"),
        }
    }
}

impl core::error::Error for CommandError {}

/// Reads a command frame's body (postcard, after the version byte).
///
/// # Errors
/// [`CommandError`]: unknown, malformed, unreadable.
pub fn parse(body: &[u8]) -> Result<CommandFrame, CommandError> {
    let (seq, rest): (u32, _) =
        postcard::take_from_bytes(body).map_err(|_| CommandError::Unreadable)?;
    let (variant, _): (u32, _) =
        postcard::take_from_bytes(rest).map_err(|_| CommandError::Malformed(seq))?;
    if variant >= COMMANDS {
        return Err(CommandError::Unknown(seq, variant));
    }
    match postcard::take_from_bytes::<CommandFrame>(body) {
        Ok((frame, [])) => Ok(frame),
        _ => Err(CommandError::Malformed(seq)),
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn reply_golden_frame() {
        crate::golden::check(
            Message::Reply(Reply {
                seq: 7,
                outcome: Outcome::Busy,
                state: HeadState::Sweeping,
                field: 0,
                detail: -3,
            }),
            &[0, 6, 2, 9, 7, 3, 2, 6, 5, 128, 204, 135, 254, 0],
        );
    }
}

#[cfg(test)]
mod command_golden {
    use super::*;

    /// Every command: its body's bytes (after the version byte), read back by [`parse`], and
    /// every shorter body refused.
    #[test]
    fn each_command_has_its_bytes() {
        let preview = PreviewRequest {
            on: true,
            every: 2,
            scale: 4,
            picture: true,
            zoom: [16, 32, 640, 480],
        };
        let sweep = SweepRequest {
            disc: 1,
            axis: 2,
            colour: true,
            keep_board: false,
            frames: 300,
        };
        let cases: [(Command, &[u8]); 9] = [
            (Command::Hello, &[172, 2, 0]),
            (
                Command::Preview(preview),
                &[172, 2, 1, 1, 2, 4, 1, 16, 32, 128, 5, 224, 3],
            ),
            (Command::Shot { board: true }, &[172, 2, 2, 1]),
            (Command::Calibrate, &[172, 2, 3]),
            (Command::Sweep(sweep), &[172, 2, 4, 1, 2, 1, 0, 172, 2]),
            (Command::Stop, &[172, 2, 5]),
            (
                Command::Camera {
                    control: 1,
                    value: -5,
                },
                &[172, 2, 6, 1, 9],
            ),
            (Command::Laser { on: true }, &[172, 2, 7, 1]),
            (Command::Turn { steps: -200 }, &[172, 2, 8, 143, 3]),
        ];
        for (command, golden) in cases {
            let frame = CommandFrame { seq: 300, command };
            let mut buf = [0u8; MAX_COMMAND];
            let body = postcard::to_slice(&frame, &mut buf).unwrap();
            assert_eq!(&body[..], golden, "{command:?}: now {:?}", &body[..]);
            assert_eq!(parse(golden), Ok(frame));
            for cut in 0..golden.len() {
                assert!(parse(&golden[..cut]).is_err(), "{command:?} cut to {cut}");
            }
        }
    }

    /// The largest command (every field at its type's largest) fits [`MAX_COMMAND`] with its
    /// version and CRC.
    #[test]
    fn the_largest_command_fits_its_buffer() {
        let widest = [
            Command::Preview(PreviewRequest {
                on: true,
                every: u16::MAX,
                scale: u8::MAX,
                picture: true,
                zoom: [u16::MAX; 4],
            }),
            Command::Sweep(SweepRequest {
                disc: u8::MAX,
                axis: u8::MAX,
                colour: true,
                keep_board: true,
                frames: u32::MAX,
            }),
            Command::Camera {
                control: u8::MAX,
                value: i32::MIN,
            },
        ];
        for command in widest {
            let mut buf = [0u8; MAX_COMMAND];
            let frame = CommandFrame {
                seq: u32::MAX,
                command,
            };
            let n = postcard::to_slice(&frame, &mut buf).unwrap().len();
            assert!(1 + n + 4 <= MAX_COMMAND, "{command:?}: {n} bytes");
        }
    }
}
