//! The scanner head: reads camera frames (V4L2, image files or the virtual rig), runs the
//! `scanner-core` pipeline on each and sends compact point packets over a serial link.
//!
//! Where it sits: `camera ─► [scanner-device: sources → scanner-core per frame → link] ─► host`.
//! At this stage it carries the command line, the frame-source interface ([`source`]) and the
//! virtual rig ([`rig`]); V4L2 capture, the per-frame pipeline and the link come with their
//! issues.
#![deny(missing_docs)]

pub mod rig;
pub mod source;

use clap::Parser;

/// Command line of the scanner head.
#[derive(Debug, Parser)]
#[command(
    name = "scanner-device",
    version,
    about = "Scanner head: camera → points → serial link"
)]
pub struct Args {
    /// Print the fixed capacities and conventions of this build and exit.
    #[arg(long)]
    pub info: bool,
}

/// Runs the scanner head with parsed arguments.
///
/// # Errors
/// Any failure of the run, with context naming what failed.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.info {
        println!(
            "scanner-device {}: units mm, camera +z forward, +y down; markers per plane ≤ {}",
            env!("CARGO_PKG_VERSION"),
            scanner_core::geometry::pose::MAX_MARKERS
        );
    } else {
        println!("scanner-device: nothing to do yet (try --help)");
    }
    Ok(())
}
