//! The `scanner-device` binary runs, answers `--info`, and refuses a bad flag with a clear message.

#[test]
fn info_and_usage_errors() {
    scanner_tests::check_cli(env!("CARGO_BIN_EXE_scanner-device"), "scanner-device");
}
