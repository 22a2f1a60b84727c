//! `scanner-host`: the host tool binary (see the library for what it does).
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = scanner_host::Args::parse();
    match scanner_host::run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            scanner_host::errln!("scanner-host: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
