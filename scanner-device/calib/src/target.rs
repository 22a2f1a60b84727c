//! The calibration targets people print: a dot grid or a chessboard ([`Target`]).

use scanner_core::nalgebra::Point2;

use crate::aruco::CharucoBoard;

/// A dot-grid calibration target: `cols × rows` dots, `pitch` apart, centred, `x` right and `y`
/// down as printed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DotGrid {
    /// Dots per row.
    pub cols: usize,
    /// Rows.
    pub rows: usize,
    /// Centre-to-centre distance, mm.
    pub pitch: f64,
    /// Dot diameter, mm.
    pub dot: f64,
}

impl DotGrid {
    /// The dot grid the rig's calibration shots show (9×7 dots, 30 mm pitch, 12 mm dots).
    pub const RIG: DotGrid = DotGrid {
        cols: 9,
        rows: 7,
        pitch: 30.0,
        dot: 12.0,
    };

    /// Dot centres, row by row.
    pub fn points(&self) -> Vec<Point2<f64>> {
        (0..self.rows)
            .flat_map(|r| {
                (0..self.cols).map(move |c| {
                    Point2::new(
                        (c as f64 - (self.cols - 1) as f64 / 2.0) * self.pitch,
                        (r as f64 - (self.rows - 1) as f64 / 2.0) * self.pitch,
                    )
                })
            })
            .collect()
    }
}

/// A planar target for intrinsics: a dot grid or a chessboard.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// Dark dots.
    Dots(DotGrid),
    /// A chessboard of `cols × rows` squares of side `square` (mm), centred; its inner corners
    /// are the features.
    Chessboard {
        /// Squares per row.
        cols: usize,
        /// Rows of squares.
        rows: usize,
        /// Square side, mm.
        square: f64,
    },
    /// A ChArUco board: its inner corners, named by the markers around them, are the features
    /// (OpenCV's order and coordinates, from the board's top left), so partial views count.
    Charuco(CharucoBoard),
}

impl Target {
    /// Feature positions on the sheet, row by row.
    pub fn points(&self) -> Vec<Point2<f64>> {
        match *self {
            Target::Dots(g) => g.points(),
            Target::Chessboard { cols, rows, square } => (1..rows)
                .flat_map(|r| {
                    (1..cols).map(move |c| {
                        Point2::new(
                            (c as f64 - cols as f64 / 2.0) * square,
                            (r as f64 - rows as f64 / 2.0) * square,
                        )
                    })
                })
                .collect(),
            Target::Charuco(b) => (0..b.corner_count()).map(|k| b.corner(k)).collect(),
        }
    }

    /// Radius the calibration models the features with (0 for corners).
    pub fn radius(&self) -> f64 {
        match *self {
            Target::Dots(g) => g.dot / 2.0,
            Target::Chessboard { .. } | Target::Charuco(_) => 0.0,
        }
    }

    pub(crate) fn name(&self) -> &'static str {
        match self {
            Target::Dots(_) => "dot grid",
            Target::Chessboard { .. } => "chessboard",
            Target::Charuco(_) => "ChArUco board",
        }
    }

    /// Columns × rows of the feature grid (a chessboard's inner corners).
    pub fn grid(&self) -> (usize, usize) {
        match *self {
            Target::Dots(g) => (g.cols, g.rows),
            Target::Chessboard { cols, rows, .. } => {
                (cols.saturating_sub(1), rows.saturating_sub(1))
            }
            Target::Charuco(b) => (b.corners_per_row(), b.rows.saturating_sub(1)),
        }
    }

    /// For a chessboard: its inner corner `(c, r)` has its (+x, +y) square dark when `c + r`
    /// is even (the first square is dark); `None` for dots.
    pub(crate) fn dark_even(&self) -> Option<bool> {
        match self {
            Target::Dots(_) | Target::Charuco(_) => None,
            Target::Chessboard { .. } => Some(true),
        }
    }

    /// What the grid counts.
    pub(crate) fn unit(&self) -> &'static str {
        match self {
            Target::Dots(_) => "dots",
            Target::Chessboard { .. } | Target::Charuco(_) => "inner corners",
        }
    }
}
