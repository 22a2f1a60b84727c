//! The pure maths of a monocular laser scanner: one webcam, one handheld line laser and a
//! background calibration board of two planes meeting at an angle (Zhang & Yuan, Applied Optics
//! 2012). `no_std`, no heap, no panics on bad numbers: every public function checks its input and
//! returns a typed [`GeomError`] instead of a NaN.
//!
//! # Where it sits in the data path
//! ```text
//! camera frame ─► stripe extraction ─► board stripe points ─► laser plane ─► triangulation ─► points
//!                                       (this crate: camera, geometry)       (scanner-wire carries them)
//! ```
//! Calibration runs once before that path: images of the board give marker pixels, and this crate
//! turns them into the camera's image distance ([`calib`]) and the two board planes
//! ([`geometry::board`]).
//!
//! # Modules
//! - [`camera`]: pinhole with Brown–Conrady distortion; pixel ↔ ray. The paper's model (one image
//!   distance `d_z`, principal point at the image centre, no distortion) is [`Camera::paper`].
//! - [`geometry`]: planes and lines, the paper's three collinear points (eq. 1–6), the board plane
//!   pose from a marker layout, the board, the laser plane, triangulation.
//! - [`calib`]: the image distance from the two-position procedure (eq. 7–9).
//! - [`stripe`]: the laser stripe's centre along each line of a frame.
//! - [`pipeline`]: one frame's stripe, laser plane and points, in fixed memory (the head's loop).
//!
//! The wire's blocks ([`scanner_wire::CameraBlock`], [`scanner_wire::PlaneBlock`]) convert to and
//! from [`Camera`] and the [`geometry`] planes here, where those types live.
//!
//! # Precision
//! Calibration runs once on a PC or the head and uses `f64` ([`geometry::collinear`],
//! [`geometry::pose`], [`calib`]). The per-frame path — pixel → ray, board stripe points, laser
//! plane, triangulation — is generic over [`Real`] and runs in `f32` on the head: per-column state
//! stays small, a Cortex-M4F has only a single-precision FPU, and `f32` keeps about 2e-6 relative
//! on exact data (property tests), i.e. 2 µm at 1 m, far below the stripe noise (~0.1 px ≈ 70 µm at
//! 1 m with f = 1400 px) and the 0.01 mm wire quantum.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! pipeline
//! calib   stripe
//! geometry       colour
//! camera
//! config  error  real
//! ```
#![no_std]
#![deny(missing_docs)]
#![deny(unsafe_code)]

pub mod calib;
pub mod camera;
pub mod colour;
pub mod config;
mod error;
pub mod geometry;
pub mod pipeline;
mod real;
pub mod stripe;

pub use camera::{Camera, Distortion};
pub use error::GeomError;
pub use real::Real;

/// nalgebra types used in the public API, re-exported so that callers use the same version.
pub use nalgebra;
