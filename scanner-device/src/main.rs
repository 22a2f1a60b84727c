//! `scanner-device`: the scanner head binary (see the library for what it does).
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = match scanner_device::Args::try_parse() {
        Ok(a) => a,
        Err(e) => {
            let refused = e.use_stderr();
            let _ = e.print();
            if refused {
                scanner_io::error_record_if_asked(|| {
                    scanner_io::usage_record(
                        "scanner-device",
                        &format!("{:?}", e.kind()),
                        &e.to_string(),
                    )
                });
            }
            return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
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
