//! `scanner-device`: the scanner head binary (see the library for what it does).
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = scanner_device::Args::parse();
    match scanner_device::run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            scanner_device::errln!("scanner-device: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
