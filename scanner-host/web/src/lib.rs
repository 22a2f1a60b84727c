//! `scanner-web`: the scanner's web pages on one guarded HTTP front. The live view
//! (`scanner-host receive --view`) shows a scan as it streams; the studio
//! (`scanner-host studio`) runs the whole job from one page. Both stand behind [`front`]: a host
//! allow-list (DNS rebinding gets 421), origins checked against that list for every change and
//! every stream, one token rule beyond loopback, and stated limits on headers, bodies,
//! connections and time. The host's library (`scanner-host`) speaks no HTTP; this crate is the
//! only one that does.
//!
//! - [`front`]: who may ask, how much and for how long; the server; files opened safely;
//! - [`assets`]: the pages, their scripts and three.js, embedded;
//! - [`live`]: the live view;
//! - [`studio`]: the studio.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! live  studio
//! assets  front
//! ```
#![deny(missing_docs)]

pub mod assets;
pub mod front;
pub mod live;
pub mod studio;
