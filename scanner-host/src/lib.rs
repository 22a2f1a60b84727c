//! `scanner-host`: the PC companion of the scanner head. Reads point packets from a serial port,
//! a recording or stdin, collects them into the structured grid and writes meshes and pictures.
//!
//! Where it sits: `head ─► [scanner-host: link → decoder → journal → grid → mesh → exports] ─►
//! files`. It depends on `scanner-core` alone (the wire format and the camera model):
//! - [`link`]: where the bytes come from (serial, pseudo-terminal, file, stdin);
//! - [`collect`]: the streaming decoder and the grid filling, with the [`journal`];
//! - [`grid`]: the 2-D structured grid with robust cells;
//! - [`mesh`]: triangles from neighbouring cells;
//! - [`export`] and [`outputs`]: OBJ, PLY, STL, depth and preview pictures, the summary, written
//!   atomically;
//! - [`register`], [`refine`], [`merge`], [`fuse`] and [`winding`]: several views of one object
//!   registered into one frame and fused into one mesh (`merge`);
//! - [`check`]: the acceptance check on a known artefact (spheres, a plane);
//! - [`live`]: the live view in a web browser (`receive --view`);
//! - [`cli`]: the command line (the only place `anyhow` is used).
#![deny(missing_docs)]

pub use scanner_io::{errln, outln};

pub mod check;
pub mod cli;
pub mod collect;
pub mod export;
pub mod fuse;
pub mod grid;
pub mod journal;
pub mod link;
pub mod live;
pub mod merge;
pub mod mesh;
pub mod outputs;
pub mod refine;
pub mod register;
pub mod seen;
pub mod select;
pub mod sheet;
pub mod winding;

pub use cli::{Args, Command, OutputArgs, run};
pub use outputs::{FrameChoice, OutputOptions, Summary, replay_into, write_outputs};
