//! The intrinsics targets the options name, checked.

use anyhow::{Result, bail};

use scanner_calib::{DotGrid, Target, short};

pub(super) fn chessboard_target((cols, rows): (usize, usize), square: f64) -> Result<Target> {
    if !(square > 0.0 && square <= 1000.0) {
        bail!(
            "--square must be between 0 and 1000 mm, found {}",
            short(square)
        );
    }
    if cols < 3 || rows < 3 {
        bail!(
            "a chessboard needs at least 3x3 squares (2x2 inner corners), found {cols}x{rows} squares"
        );
    }
    Ok(Target::Chessboard { cols, rows, square })
}

pub(super) fn charuco_target(
    (cols, rows): (usize, usize),
    square: f64,
    marker: Option<f64>,
    dictionary: &str,
    first_id: usize,
) -> Result<Target> {
    // The squares are checked as a chessboard's.
    chessboard_target((cols, rows), square)?;
    let Some(marker) = marker else {
        bail!("--charuco needs --marker: the markers' side, mm (OpenCV's markerLength)");
    };
    if !(marker > 0.0 && marker < square) {
        bail!(
            "--marker {} mm: a ChArUco marker is smaller than its square ({} mm)",
            short(marker),
            short(square)
        );
    }
    let Some(dict) = scanner_calib::aruco::Dictionary::named(dictionary) else {
        bail!(
            "--dictionary {dictionary}: not one of OpenCV's predefined dictionaries ({})",
            scanner_calib::aruco::DICTIONARIES.join(", ")
        );
    };
    let board = scanner_calib::aruco::CharucoBoard {
        cols,
        rows,
        square,
        marker,
        dictionary: dict,
        first_id,
    };
    if board.ids().end > dict.count {
        bail!(
            "a ChArUco board of {cols}x{rows} squares has {} markers: from ID {first_id} they run past the {} codes of {dictionary}",
            board.marker_count(),
            dict.count
        );
    }
    Ok(Target::Charuco(board))
}

pub(super) fn dot_target((cols, rows): (usize, usize), pitch: f64, dot: f64) -> Result<Target> {
    if !(pitch > dot && dot > 0.0 && pitch <= 1000.0) {
        bail!(
            "--pitch ({} mm) must exceed --dot ({} mm), both positive and at most 1000 mm",
            short(pitch),
            short(dot)
        );
    }
    Ok(Target::Dots(DotGrid {
        cols,
        rows,
        pitch,
        dot,
    }))
}
