//! `scanner-device`: the scanner head binary (see the library for what it does).
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = scanner_device::Args::parse();
    match scanner_device::run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            scanner_device::errln!("scanner-device: error: {e:#}");
            scanner_io::error_record_if_asked(|| {
                scanner_io::error_record("scanner-device", e.chain())
            });
            let never_on = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<scanner_device::session::SessionError>(),
                    Some(scanner_device::session::SessionError::LaserNeverOn { .. })
                )
            });
            if never_on {
                ExitCode::from(scanner_device::session::EXIT_NO_LASER)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
