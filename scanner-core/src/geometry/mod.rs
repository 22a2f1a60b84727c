//! Geometry of the scanner: planes and lines, the board, the laser plane, triangulation.
//!
//! Data flows through these modules in this order:
//! - calibration (once, `f64`): [`collinear`] (paper eq. 1–6) and [`pose`] (layout homography +
//!   refinement) give the two board planes, [`board`] joins them into a [`Board`] with its crease
//!   line `L_c` and opening angle;
//! - per frame (`f32` on the head): stripe pixels on the board become 3-D points on the board
//!   planes, [`laser`] fits the laser plane to them, [`triangulate`] intersects every other stripe
//!   pixel's ray with that plane and tells where the point lies;
//! - a turntable scanner's fixed laser (its plane calibrated once): [`platform`] carries each
//!   frame's points into the frame of the turning platform.

pub mod board;
pub mod collinear;
pub mod fit;
pub mod laser;
pub mod plane;
pub mod platform;
pub mod pose;
pub mod triangulate;

pub use board::{Board, Surface};
pub use fit::{LineFit, PlaneFit, fit_line, fit_plane};
pub use laser::{LaserFitConfig, LaserPlane, LaserQuality};
pub use plane::{Line, Plane};
pub use platform::Platform;
pub use pose::{Pose, PoseFit};
pub use triangulate::Limits;
