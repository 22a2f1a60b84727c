//! The calibration, board and scene file parsers on any text.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(c) = scanner_calib::file::CalibrationFile::parse(text, "fuzz") {
        let _ = c.camera();
        let _ = c.board();
    }
    if let Ok(b) = scanner_calib::board::BoardFile::parse(text, "fuzz") {
        let _ = b.left.points();
        let _ = scanner_rig::Markers::from(&b);
    }
    // Scenes are parsed, not built (building renders: too slow to fuzz).
    let _ = scanner_rig::Scene::from_toml(text);
});
