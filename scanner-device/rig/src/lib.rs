//! `scanner-rig`: the virtual rig — what the scanner head's camera would see, with ground truth.
//!
//! Where it sits: beside the data path, in place of the camera: `[scanner-rig] ─► frames ─► the
//! head`. It depends on `scanner-core` and on `scanner-calib` for the board file (what is
//! printed on the board); nothing but tests, benches, examples and the head's `rig` feature
//! depends on it. The accuracy report against the paper's tables runs it from the tests crate
//! (`scanner_tests::accuracy`).
//!
//! A [`Scene`] describes the camera, the two-plane board, objects in front of it, the hand-held
//! laser's sweep, ambient light and the sensor. A [`Rig`] built from it casts one ray per pixel
//! once (camera, board and objects do not move; only the laser does) into a geometry buffer, and
//! then renders each frame from it:
//! - ambient light on the surface albedo;
//! - the laser: a light plane from a source that sweeps like a hand (deterministic wobble and
//!   jitter per frame), Gaussian across its thickness, falling off with the square of the
//!   distance and with the cosine of incidence, dark where an object hides the surface from the
//!   source; pixels near the stripe are supersampled 3×3 (sub-pixel rays interpolated from the
//!   pixel centres' undistorted coordinates, each cast into the scene) so that the stripe's image
//!   is right to a small fraction of a pixel;
//! - the lens: a Gaussian point-spread function (the ambient image is blurred once, the laser
//!   light splatted through the same kernel per frame);
//! - the sensor: gain, shot and read noise, rounding and clipping to 8 bits; out as RGB, gray or
//!   YUYV like a webcam.
//!
//! [`Rig::truth`] gives, for every column, the exact row where the laser plane meets the visible
//! lit surface, the 3-D point there and the surface it lies on, found by bisection on exact rays.
//!
//! Also: laser speckle (a fixed grain on the lit surface), mains flicker of the ambient light, and
//! motion blur (the light plane moves during the exposure).
//!
//! Objects are analytic shapes or triangle meshes from OBJ files ([`mesh`]). Calibration shots —
//! the paper's cross pattern and planar targets at any pose — are in [`target`].
//!
//! The board's markers come from a board file ([`scanner_calib::board`]): discs or a chessboard
//! per sheet.
//!
//! A turntable scanner with a fixed laser is rendered by [`TurningScan`]: the objects turned a
//! step about the platform's axis in every frame, with their true surfaces and the true
//! calibration.
//!
//! Scenes can be read from TOML ([`Scene::from_toml`]); `scanner-device render` writes a scene's
//! frames as PNG files with their ground truth.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! file  compare  target  turning
//! render
//! scene  mjpeg
//! error
//! surface
//! mesh
//! ```

#![deny(missing_docs)]

pub mod compare;
mod error;
mod file;
pub mod mesh;
mod mjpeg;
mod render;
mod scene;
pub mod surface;
pub mod target;
mod turning;

pub use error::RigError;
pub use mjpeg::{MjpegError, mjpeg};
pub use render::*;
pub use scene::*;
pub use surface::{Hit, Shape, SurfaceId};
pub use turning::{PlatformMarkers, TurningScan};
