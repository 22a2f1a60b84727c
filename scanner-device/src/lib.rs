//! `scanner-device`: the scanner head. Reads camera frames, runs the `scanner-core` pipeline on
//! each and sends compact point packets over a serial link.
//!
//! Where it sits: `camera ─► [scanner-device: source → session (scanner-core per frame) → link]
//! ─► host`. Frame sources ([`source`]: V4L2 cameras, image folders, and with the `rig` feature
//! the virtual rig), the scan session ([`session`]: the per-frame pipeline of `scanner-core` and
//! the wire messages), the preview for aiming ([`preview`]: thumbnails with what the head finds
//! in them), the link to the host ([`link`]) and the command line ([`cli`]: scan, preview, and
//! the calibration and rig commands, which call `scanner-calib` and `scanner-rig`).
//!
//! The arrows run one way: `cli` → `preview` → `session` → [`axis`] (which way the stripe runs)
//! and [`laser_colour`] (what colour it is) and [`marker_turn`] (a turntable's angle from its
//! markers) and [`temporal`] (a shadow sweep read through time) → `source`, `link` → `scanner-core`. The head uses `scanner-calib` for what it finds in a
//! picture (the preview's dots, the session's turntable disc) and the CLI for its procedures;
//! `scanner-rig` with the feature; image and text files come through `scanner-io`. Nothing here
//! is imported by the crates it uses.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! cli
//! calibrate  preview  scan
//! session  report
//! axis  laser_colour  marker_turn  motor  temporal
//! source  link
//! ```
#![deny(missing_docs)]

pub use scanner_io::{errln, outln};

/// An error and its sources as one line, `outer: inner: innermost` (for summaries and messages
/// that go on as text, where `{e:#}` of `anyhow` is not at hand).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut next = e.source();
    while let Some(s) = next {
        text.push_str(": ");
        text.push_str(&s.to_string());
        next = s.source();
    }
    text
}

pub mod axis;
pub mod calibrate;
pub mod cli;
pub mod laser_colour;
pub mod link;
pub mod marker_turn;
pub mod motor;
pub mod preview;
pub mod report;
pub mod scan;
pub mod session;
pub mod source;
pub mod temporal;

pub use cli::{Args, Command, run};
