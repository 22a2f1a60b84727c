//! Workspace-level end-to-end tests live in `tests/tests/`; this library holds what tests across
//! the workspace share.
#![deny(missing_docs)]

use std::process::Command;

/// Checks a binary of the workspace from the outside: `--info` succeeds and starts with its name
/// and the unit convention, and an unknown flag is a usage error (exit code 2) that names the
/// flag. `exe` is the binary's path (`env!("CARGO_BIN_EXE_…")` in the calling test).
///
/// # Panics
/// When a check fails: this is a test helper.
pub fn check_cli(exe: &str, name: &str) {
    let out = Command::new(exe)
        .arg("--info")
        .output()
        .expect("binary runs");
    assert!(out.status.success(), "{name} --info failed");
    let text = String::from_utf8(out.stdout).expect("UTF-8 output");
    assert!(text.starts_with(&format!("{name} ")), "{text}");
    assert!(text.contains("units mm"), "{text}");

    let out = Command::new(exe)
        .arg("--no-such-flag")
        .output()
        .expect("binary runs");
    assert_eq!(
        out.status.code(),
        Some(2),
        "{name}: a bad flag is a usage error"
    );
    let err = String::from_utf8(out.stderr).expect("UTF-8 output");
    assert!(err.contains("--no-such-flag"), "{err}");
}
