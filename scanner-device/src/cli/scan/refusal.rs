//! Why `scan` refuses its options before the first frame: each refusal a kind of its own (its
//! variant's name is the `kind` of `SCANNER_ERRORS=json`), its words naming the option and the
//! file.

use std::path::PathBuf;

use super::shadow::MIN_SHADOW_DEPTH;

/// A scan's options that cannot make a scan.
#[derive(Debug, thiserror::Error)]
pub enum ScanRefusal {
    /// `--markers` names no ArUco dictionary.
    #[error(
        "--markers {0:?} is no ArUco dictionary: give one of OpenCV's, DICT_4X4_50 … DICT_7X7_1000"
    )]
    UnknownDictionary(String),
    /// No calibration file given.
    #[error(
        "no calibration: give --calibration FILE (from `scanner-device calibrate board`; for the virtual rig, `render-calibration` writes truth-calibration.toml)"
    )]
    NoCalibration,
    /// A calibration made for frames of another size.
    #[error(
        "calibration {} is for {}×{} images but {given_by} gives {}×{}",
        path.display(),
        calibration.0,
        calibration.1,
        frames.0,
        frames.1
    )]
    CalibrationSize {
        /// The calibration file.
        path: PathBuf,
        /// Its frame size.
        calibration: (u32, u32),
        /// The source.
        given_by: String,
        /// The source's frame size.
        frames: (usize, usize),
    },
    /// A calibration without the board's planes.
    #[error("{} has no board: run `scanner-device calibrate board` first", .0.display())]
    NoBoard(PathBuf),
    /// `--view` without `--scene`.
    #[error("--view needs --scene: a scene file with [[views]]")]
    ViewWithoutScene,
    /// `--scene` with a source other than the rig.
    #[error("--scene works with the virtual rig only (--source rig)")]
    SceneNotRig,
    /// `--scene` in a build without the rig.
    #[error("--scene {}: this build has no virtual rig (the `rig` feature)", .0.display())]
    NoRig(PathBuf),
    /// More frames than one turn of the platform and its closing frame.
    #[error(
        "{given_by} holds {frames} frames, but the platform turns {turn_deg:.4}° a frame: {per_turn:.0} frames make a turn (and one more to close it); give the turn that was recorded (--frames-per-turn {frames} if these frames make one turn)"
    )]
    BeyondOneTurn {
        /// The source.
        given_by: String,
        /// Its frames.
        frames: usize,
        /// The turn a frame, degrees.
        turn_deg: f64,
        /// Frames a turn.
        per_turn: f64,
    },
    /// `--motor` without a fixed-laser scan.
    #[error(
        "--motor turns a fixed-laser scan's platform: give --fixed-laser, --steps-per-frame and --calibration"
    )]
    MotorWithoutFixedLaser,
    /// A calibration without a platform where one is needed.
    #[error("{option}: {} has no [platform] (the turntable's pose and steps per turn)", path.display())]
    NoPlatform {
        /// The option that needs it.
        option: &'static str,
        /// The calibration file.
        path: PathBuf,
    },
    /// `--fixed-laser N` beyond the file's lasers.
    #[error(
        "--fixed-laser {index}: {} has {lasers} fixed laser plane(s) ([[laser]]){}",
        path.display(),
        if *.lasers == 0 { "; calibrate them or import a scanner's own calibration (`scanner-device import-fabscan`)" } else { "" }
    )]
    NoSuchLaser {
        /// The laser asked for.
        index: usize,
        /// The calibration file.
        path: PathBuf,
        /// Its lasers.
        lasers: usize,
    },
    /// A turn between frames that is no turn.
    #[error("--turn-deg {0}: give a turn between frames of up to ±180°, not 0")]
    TurnDeg(f64),
    /// `--steps-per-frame 0`.
    #[error("--steps-per-frame 0: the platform would not turn")]
    NoSteps,
    /// More than half a turn a frame.
    #[error(
        "--steps-per-frame {steps}: more than half of the platform's {per_turn} steps per turn"
    )]
    StepsOverHalf {
        /// Steps a frame.
        steps: u32,
        /// Steps a turn.
        per_turn: u32,
    },
    /// Fewer than two frames a turn.
    #[error("--frames-per-turn {0}: a turn needs at least 2 frames")]
    FramesPerTurn(u32),
    /// A fixed-laser scan without its turn.
    #[error(
        "--fixed-laser needs the platform's turn between frames: --turn-deg, --steps-per-frame or --frames-per-turn"
    )]
    NoTurn,
    /// A shadow sweep with no frames.
    #[error("--shadow: {0} has no frames")]
    NoShadowFrames(String),
    /// A shadow too faint to find.
    #[error(
        "the shadow is too faint to scan: where it passed it took a median {:.0} % of the light (at least {:.0} % wanted) — a lamp too large, so that its edges are a blur, or too much other light: use a smaller bulb (or take the shade off the lamp), a thicker rod, hold the rod nearer the object, or darken the room (docs/shadow-scanner.md)",
        100.0 * .0,
        100.0 * MIN_SHADOW_DEPTH
    )]
    FaintShadow(f64),
}

/// A scan that ran and gave nothing to build from (its stream and report are written).
#[derive(Debug, thiserror::Error)]
pub enum ScanFailed {
    /// No point: the stripe was wider than the limit on every line it was seen on.
    #[error(
        "no points: on {lines} lines the stripe was wider than the limit of {limit:.0} px (64 px or 4 % of the image width, whichever is more): focus the laser's line, hold it further from the object, or scan at a lower resolution"
    )]
    TooWide {
        /// Lines where it was too wide.
        lines: u64,
        /// The limit, pixels.
        limit: f32,
    },
    /// A shadow sweep whose band had no edge on most lines.
    #[error(
        "the shadow's edges are a blur: its band was seen on {lines} lines but only {edged} had an edge (where half the lamp is hidden): use a smaller bulb (or take the shade off the lamp), a thicker rod, or hold the rod nearer the object (docs/shadow-scanner.md)"
    )]
    BlurredShadow {
        /// Lines the band was seen on.
        lines: u64,
        /// Lines with an edge.
        edged: u64,
    },
    /// A shadow sweep read through time whose edges did not lie in one plane on the board's
    /// planes in enough frames.
    #[error(
        "the board's planes do not hold for this sweep: the shadow's edges of polarity {polarity} lay in one plane on them in only {planes} of the {tried} frames they crossed both planes in (at least {:.0} % wanted) — the board or the camera moved since its planes were measured, or the calibration is another setup's: measure the planes again (docs/shadow-scanner.md)",
        100.0 * crate::temporal::MIN_PLANE_SHARE
    )]
    PlanesContradicted {
        /// The edges' polarity along the image lines (0: dark to lit, 1: lit to dark).
        polarity: usize,
        /// Frames that gave its plane.
        planes: u32,
        /// Frames its plane was looked for in.
        tried: u32,
    },
}
