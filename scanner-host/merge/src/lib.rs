//! `scanner-merge`: several sweeps of one object, turned between them, registered into one
//! frame and fused into one closed mesh — the 360° model.
//!
//! Where it sits: `views (read by the host from its journals) ─► [scanner-merge] ─► poses, the
//! model, the report`. It depends on `scanner-core` alone (the wire's header: each view's
//! camera and board). The input is data ([`View`]: points, normals, colours, uncertainties and
//! the header), the output is data ([`Merged`]: poses, the model, [`MergeReport`]); the one
//! entry point is [`run`], with [`find_sheet`] for the laser sheet's thickness.
//!
//! How: every pair of views is registered into candidate motions without a guess ([`register`]:
//! descriptors, RANSAC, ICP); the candidates that agree around the loops of views are chosen
//! together ([`select`], [`poses`]); all views are refined together ([`refine`], [`joint`]);
//! the result must close its loops and keep out of the space each view saw empty ([`seen`],
//! [`free`]) or no model is written; then the views fuse into one mesh ([`fusion`], [`fuse`],
//! [`winding`]). Views that carry the turntable disc's pose are posed by it instead, and the
//! others fitted onto them ([`disc`]).
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! run
//! report
//! fusion  joint  disc
//! poses
//! free  hull  still
//! view  error
//! fuse  refine  select  seen
//! register  winding
//! spatial
//! ```
#![deny(missing_docs)]

pub mod disc;
pub mod error;
pub mod free;
pub mod fuse;
pub mod fusion;
mod hull;
pub mod joint;
pub mod poses;
pub mod refine;
pub mod register;
pub mod report;
mod run;
pub mod seen;
pub mod select;
pub mod spatial;
mod still;
pub mod view;
pub mod winding;

pub use error::MergeError;
pub use fuse::Model;
pub use fusion::Closing;
pub use report::MergeReport;
pub use run::{MergeOptions, Merged, Progress, Registered, Stage, find_sheet, run, sheet_tries};
pub use view::{Surface, View};
