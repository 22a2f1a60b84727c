//! `scanner-host`: the PC companion of the scanner head. Reads point packets from a serial port,
//! a recording or stdin, collects them into the structured grid and writes meshes and pictures;
//! reads several scans of one object as views for the 360° merge (`scanner-merge`).
//!
//! Where it sits: `head ─► [scanner-host: link → decoder → journal → grid → mesh → exports] ─►
//! files`. It depends on `scanner-wire` (the messages), `scanner-core` (the camera model) and
//! `scanner-merge` (the 360° merge, and its spatial search for the sheet's correction and the
//! check). The command line is the `scanner-host` binary (`scanner-host/cli`): this library has
//! no argument parsing, progress bars or signal handlers.
//! - [`link`]: where the bytes come from (serial, pseudo-terminal, file, stdin);
//! - [`collect`]: the streaming decoder and the grid filling, with the [`journal`];
//! - [`grid`]: the 2-D structured grid with robust cells;
//! - [`thickness`]: the correction of each frame's points for the laser sheet's thickness;
//! - [`mesh`]: triangles from neighbouring cells;
//! - [`export`] and [`outputs`]: OBJ, PLY, STL, 3MF, depth and preview pictures, the summary
//!   (text and JSON), written atomically;
//! - [`platform`]: a fixed-laser turntable scan's points in the platform's frame, and its
//!   closed model;
//! - [`lasers`]: two lasers' models of one object held against each other;
//! - [`views`]: scans read as views for the 360° merge, and the merge of view folders;
//! - [`check`]: the acceptance check on a known artefact (spheres, a plane).
//!
//! The web pages (the live view, the studio) are `scanner-web`'s: this library speaks no HTTP.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! views  check
//! outputs
//! platform  lasers
//! collect  export
//! mesh  journal  thickness
//! grid  link
//! ```
#![deny(missing_docs)]

pub use scanner_io::{errln, outln};

pub mod check;
pub mod collect;
pub mod export;
pub mod grid;
pub mod journal;
pub mod lasers;
pub mod link;
pub mod mesh;
pub mod outputs;
pub mod platform;
pub mod thickness;
pub mod views;

pub use outputs::{FrameChoice, OutputOptions, Summary, replay_into, write_outputs};
