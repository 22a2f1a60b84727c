//! `scanner-calib`: calibration from images, once, before a scan.
//!
//! Where it sits: `images of the board and a target ─► [scanner-calib] ─► calibration file ─►
//! the head (scanner-device)`. It depends on `scanner-core` alone (the maths: Zhang, poses,
//! planes, eq. 1–9); this crate is the image side (std + `image`).
//!
//! Calibration from images: the printable board ([`board`], [`print`](mod@print)), marker detection
//! ([`detect`]) and identification ([`identify`](mod@identify)), ArUco markers and ChArUco
//! corners ([`aruco`], [`charuco`]), and the three procedures —
//! - [`image_distance`]: the paper's two-position procedure on two images of the cross pattern;
//! - [`intrinsics()`]: full intrinsics from several images of a dot grid (Zhang's method, refined);
//! - [`board_planes`]: both board planes from an image of the board without laser, by the layout
//!   pose (default) and, where the layout is the paper's, by the paper's three-point lines.
//!
//! The results go into one calibration file ([`file`](mod@file)) with an annotated picture ([`overlay`]).
//! A turntable scanner's laser planes and platform come from its own calibration frames
//! ([`fixed`]), or with its camera from another program's files ([`import`](mod@import):
//! FabScanPi, Horus, OpenCV, NumPy).
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! import
//! overlay  fixed
//! planes  distance
//! disc
//! print
//! selfcheck
//! intrinsics  file  spread
//! fit  target
//! identify  charuco
//! corners  lattice  board  canvas
//! detect  blur  speckle  aruco
//! error
//! ```
#![deny(missing_docs)]

/// A number for a message: as is when short, in scientific notation when it would run to many
/// digits (a crafted `1e300` is not printed as a 301-digit number).
pub fn short(x: f64) -> String {
    if x.is_finite() && (x == 0.0 || (1e-3..1e7).contains(&x.abs())) {
        format!("{x}")
    } else {
        format!("{x:.4e}")
    }
}

pub mod aruco;
pub mod blur;
pub mod board;
pub mod canvas;
pub mod charuco;
pub mod corners;
pub mod detect;
pub mod disc;
mod distance;
mod error;
pub mod file;
mod fit;
pub mod fixed;
pub mod identify;
pub mod import;
pub mod intrinsics;
pub mod lattice;
pub mod overlay;
mod planes;
pub mod print;
pub mod selfcheck;
pub mod speckle;
pub mod spread;
mod target;

pub use distance::{cross_span, image_distance};
pub use error::CalibError;
pub use fit::{
    BOARD_ANGLE_DEG, BoardFit, BoardMethod, MAX_FIT_RMS_PX, MAX_SHEET_RMS_PX, MarkerFit, SheetFit,
};
pub use intrinsics::{
    Coverage, Found, FoundGrid, ImageFit, ImageReport, IntrinsicsFit, IntrinsicsOutcome, find_grid,
    intrinsics, intrinsics_auto, intrinsics_from_grids, intrinsics_outcome,
};
pub use planes::{BoardOutcome, TurntableSeen, board_planes, check_size};
pub use target::{DotGrid, Target};
