//! Which way the laser stripe runs across the image, from the first laser frame against the
//! reference: the head finds the stripe's centre along each column for a horizontal stripe and
//! along each row for a vertical one.

use scanner_core::stripe::{Axis, Extractor, LineStatus, StripeConfig};

use crate::source::OwnedFrame;

/// Why a frame does not tell which way the stripe runs.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum AxisError {
    /// The frame and the reference differ in size or format.
    #[error("the first laser frame does not match the reference")]
    Mismatch,
    /// The stripe is found on too few lines either way, or on as many both ways.
    #[error(
        "the first laser frame does not tell which way the stripe runs (a stripe found on {columns_pct:.0} % of the columns and {rows_pct:.0} % of the rows): give --columns for a horizontal stripe (the laser sweeps up and down) or --rows for a vertical one (it sweeps sideways), and check the laser is on after the reference"
    )]
    Undecided {
        /// Share of the columns with a valid centre, %.
        columns_pct: f64,
        /// Share of the rows with a valid centre, %.
        rows_pct: f64,
    },
}

/// Which way the stripe runs in a laser frame: the axis along which the extractor (with the
/// scan's settings `cfg`, its axis aside) finds a valid centre on the larger share of the lines
/// — a stripe across the lines is found on most of them, one along them on few. It must be found
/// on at least a tenth of the lines one way, and on twice the share of the other.
///
/// # Errors
/// [`AxisError`]: why the frame does not tell, with what to give instead (`--rows` or
/// `--columns`).
pub fn stripe_axis(
    frame: &OwnedFrame,
    reference: &OwnedFrame,
    cfg: &StripeConfig,
) -> Result<Axis, AxisError> {
    let (columns, rows) = valid_shares(frame, reference, cfg)?;
    if columns >= 0.1 && columns >= 2.0 * rows {
        Ok(Axis::Columns)
    } else if rows >= 0.1 && rows >= 2.0 * columns {
        Ok(Axis::Rows)
    } else {
        Err(AxisError::Undecided {
            columns_pct: 100.0 * columns,
            rows_pct: 100.0 * rows,
        })
    }
}

/// The share of the lines the extractor (with `cfg`, its axis aside) finds a valid stripe
/// centre on, read along columns and along rows.
///
/// # Errors
/// [`AxisError::Mismatch`] when the frame and the reference differ in size or format.
pub fn valid_shares(
    frame: &OwnedFrame,
    reference: &OwnedFrame,
    cfg: &StripeConfig,
) -> Result<(f64, f64), AxisError> {
    let (Ok(f), Ok(r)) = (frame.view(), reference.view()) else {
        return Err(AxisError::Mismatch);
    };
    let mut ex = Box::new(Extractor::<{ scanner_core::config::MAX_LINES }>::new());
    let mut share = |axis: Axis| {
        let c = StripeConfig { axis, ..*cfg };
        ex.extract(&f, Some(&r), &c).map_or(0.0, |found| {
            let valid = found
                .points
                .iter()
                .filter(|p| p.status == LineStatus::Valid)
                .count();
            valid as f64 / found.points.len().max(1) as f64
        })
    };
    Ok((share(Axis::Columns), share(Axis::Rows)))
}

/// An axis's flag and the line it reads: `--columns` a horizontal line, `--rows` a vertical one.
pub fn words(a: Axis) -> (&'static str, &'static str) {
    match a {
        Axis::Columns => ("--columns", "horizontal"),
        Axis::Rows => ("--rows", "vertical"),
    }
}
