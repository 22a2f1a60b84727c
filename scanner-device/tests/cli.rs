//! The `scanner-device` binary runs, answers `--info`, and refuses a bad flag with a clear message.

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_scanner-device"))
}

#[test]
fn info_prints_conventions() {
    let out = bin().arg("--info").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with("scanner-device "), "{text}");
    assert!(text.contains("units mm"), "{text}");
}

#[test]
fn bad_flag_is_a_usage_error() {
    let out = bin().arg("--no-such-flag").output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("--no-such-flag"), "{err}");
}
