//! The PC companion of the scanner head: reads point packets from a serial port, a recording or
//! stdin, collects them into the structured grid and writes meshes and pictures.
//!
//! Where it sits: `head ─► [scanner-host: link → decoder → journal → grid → exports] ─► files`.
//! At this stage it carries the command line; the decoder, grid and exports come with their
//! issues.
#![deny(missing_docs)]

use clap::Parser;

/// Command line of the host tool.
#[derive(Debug, Parser)]
#[command(
    name = "scanner-host",
    version,
    about = "Host: point packets → grid → OBJ and pictures"
)]
pub struct Args {
    /// Print the conventions of this build and exit.
    #[arg(long)]
    pub info: bool,
}

/// Runs the host tool with parsed arguments.
///
/// # Errors
/// Any failure of the run, with context naming what failed.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.info {
        println!(
            "scanner-host {}: units mm, camera +z forward, +y down",
            env!("CARGO_PKG_VERSION")
        );
    } else {
        println!("scanner-host: nothing to do yet (try --help)");
    }
    Ok(())
}
