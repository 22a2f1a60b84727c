//! `scanner-merge`: several sweeps of one object, turned between them, registered into one
//! frame and fused into one closed mesh — the 360° model.
//!
//! Where it sits: `views (read by the host from its journals) ─► [scanner-merge] ─► poses, the
//! model, the report`. It depends on `scanner-core` alone (the wire's header: each view's
//! camera and board). The input is data ([`View`]: points, normals, colours, uncertainties and
//! the header), the output is data ([`Merged`]: poses, the model, [`MergeReport`]); the one
//! entry point is [`run`], with [`find_thickness`] for the laser sheet's thickness.
//!
//! How, in four stages, each a folder whose files are private behind the stage's functions:
//! 1. [`pose`]: where the poses come from is chosen once ([`pose`]'s `Source`): the turntable
//!    disc's pose where two or more views carry it (the others fitted onto them by shape), else
//!    the views' shapes — every pair registered without a guess (descriptors, RANSAC, ICP), the
//!    candidates that agree around the loops of views chosen together, `--turntable`'s step a
//!    hint where given; what stayed still while the object turned is left out;
//! 2. [`refine`]: all views refined together (not the disc-posed ones);
//! 3. `check`: the result must close its loops and keep out of the space each view saw empty
//!    ([`free`], [`depth`]), or no model is written;
//! 4. [`fuse`]: the views fuse into one closed mesh (a screened implicit surface, the winding
//!    number, the space under the object on a disc filled).
//!
//! [`spatial`] (clouds, k-d trees) and [`depth`] (what each view saw) are the tools all stages
//! share. The stages' public functions are there for the benches and the stage tests; a merge
//! goes through [`run`].
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! run
//! report
//! check
//! refine
//! pose
//! free  fuse
//! view  error
//! depth  spatial
//! ```
#![deny(missing_docs)]

mod check;
pub mod depth;
pub mod error;
pub mod free;
pub mod fuse;
pub mod pose;
pub mod refine;
pub mod report;
mod run;
pub mod spatial;
pub mod view;

pub use check::disc::DISC_SIZE_TOLERANCE;
pub use error::MergeError;
pub use fuse::Closing;
pub use fuse::Model;
pub use report::MergeReport;
pub use run::{
    MergeOptions, Merged, Progress, Registered, Stage, find_thickness, run, thickness_tries,
};
pub use view::{ScanPoints, View};
