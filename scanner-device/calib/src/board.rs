//! The board file: what is printed on the two sheets of the calibration board.
//!
//! TOML, lengths in mm. Sheet coordinates: `u` from the crease outward along the sheet, `v` along
//! the crease, downward when the board stands upright, `v = 0` at the same height on both sheets
//! (print both sheets at 100 % and glue each with its crease edge on the fold). Each sheet lists
//! its markers either one by one or as a grid:
//!
//! ```toml
//! marker_diameter = 27.5          # dark circles
//! [sheet]                          # paper size, for printing (A3 landscape here)
//! width = 420.0                    # along u
//! height = 297.0                   # along v
//! [left]                           # the paper's layout: two lines of three markers
//! grid = { cols = 3, rows = 2, u0 = 66.0, v0 = -110.0, du = 110.0, dv = 220.0 }
//! [right]
//! markers = [[66.0, -110.0], [176.0, -110.0], [286.0, -110.0],
//!            [66.0, 110.0], [176.0, 110.0], [286.0, 110.0]]
//! # or, instead of discs, a chessboard whose inner corners are the markers:
//! # chessboard = { cols = 8, rows = 6, square = 30.0, u0 = 60.0, v0 = -60.0 }
//! # or a ChArUco board (OpenCV's layout), its inner corners named by its markers' IDs:
//! # charuco = { cols = 7, rows = 5, square = 25.0, marker = 19.0, dictionary = "DICT_4X4_50",
//! #             first_id = 0, u0 = 33.0, v0 = -62.5, x = "+v", y = "+u" }
//! [cross]                          # the image-distance pattern (paper Fig. 5)
//! arm = 200.0                      # |AE| = |BD|
//! dot = 12.0
//! ```
//!
//! [`BoardFile::default`] is the paper's layout above; `scanner-device board` writes it out and
//! prints its sheets.

use std::path::Path;

use scanner_core::config::MAX_MARKERS;
use scanner_core::nalgebra::Point2;

use crate::aruco::{CharucoBoard, Dictionary};
use crate::short;

/// The largest sheet side, mm: any board a room holds (the paper's set-up at 3.2 m has sheets
/// of 1.65 × 1.55 m). It bounds the numbers, not the work: that is bounded by the markers per
/// sheet ([`MAX_MARKERS`]) and, when printing, by the picture's size (`--dpi`).
pub const MAX_SHEET_MM: f64 = 10_000.0;
use serde::{Deserialize, Serialize};

/// A grid of markers on a sheet: `cols` along `u` from `u0` in steps of `du`, `rows` along `v`
/// from `v0` in steps of `dv`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerGrid {
    /// Markers along `u`.
    pub cols: usize,
    /// Lines of markers along `v`.
    pub rows: usize,
    /// First marker's `u`, mm.
    pub u0: f64,
    /// First line's `v`, mm.
    pub v0: f64,
    /// Step along `u`, mm.
    pub du: f64,
    /// Step along `v`, mm.
    pub dv: f64,
}

impl Chessboard {
    /// Inner corners, row by row (along `u` first).
    pub fn corners(&self) -> Vec<Point2<f64>> {
        (0..self.rows.saturating_sub(1))
            .flat_map(|r| {
                (0..self.cols.saturating_sub(1)).map(move |c| {
                    Point2::new(
                        self.u0 + c as f64 * self.square,
                        self.v0 + r as f64 * self.square,
                    )
                })
            })
            .collect()
    }
}

/// A chessboard on a sheet: `cols × rows` squares of side `square`, its first inner corner at
/// `(u0, v0)`; the inner corners are the sheet's markers (row by row, along `u` first).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Chessboard {
    /// Squares along `u`.
    pub cols: usize,
    /// Squares along `v`.
    pub rows: usize,
    /// Square side, mm.
    pub square: f64,
    /// First inner corner's `u`, mm.
    pub u0: f64,
    /// First inner corner's `v`, mm.
    pub v0: f64,
}

/// A direction on a sheet: along `u` or `v`, either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SheetAxis {
    /// Along `+u` (away from the crease).
    #[serde(rename = "+u")]
    PlusU,
    /// Along `−u`.
    #[serde(rename = "-u")]
    MinusU,
    /// Along `+v`.
    #[serde(rename = "+v")]
    PlusV,
    /// Along `−v`.
    #[serde(rename = "-v")]
    MinusV,
}

impl SheetAxis {
    /// As the board file writes it.
    pub fn name(self) -> &'static str {
        match self {
            SheetAxis::PlusU => "+u",
            SheetAxis::MinusU => "-u",
            SheetAxis::PlusV => "+v",
            SheetAxis::MinusV => "-v",
        }
    }

    /// The unit vector `(u, v)`.
    pub fn unit(self) -> [f64; 2] {
        match self {
            SheetAxis::PlusU => [1.0, 0.0],
            SheetAxis::MinusU => [-1.0, 0.0],
            SheetAxis::PlusV => [0.0, 1.0],
            SheetAxis::MinusV => [0.0, -1.0],
        }
    }
}

fn axis_u() -> SheetAxis {
    SheetAxis::PlusU
}

fn axis_v() -> SheetAxis {
    SheetAxis::PlusV
}

/// A ChArUco board on a sheet, as OpenCV lays it out ([`CharucoBoard`]): its inner corners are
/// the sheet's markers, in OpenCV's order; its first inner corner lies at `(u0, v0)`, and the
/// board's `x` (along its first row, as printed) and `y` (down its first column) run along the
/// sheet's directions `x` and `y`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Charuco {
    /// Squares along the board's `x`.
    pub cols: usize,
    /// Squares along its `y`.
    pub rows: usize,
    /// Square side, mm.
    pub square: f64,
    /// Marker side, mm.
    pub marker: f64,
    /// OpenCV's name of the markers' dictionary, e.g. `DICT_4X4_50`.
    pub dictionary: String,
    /// The first marker's ID.
    #[serde(default)]
    pub first_id: usize,
    /// The first inner corner's `u`, mm.
    pub u0: f64,
    /// Its `v`, mm.
    pub v0: f64,
    /// The sheet direction of the board's `x`.
    #[serde(default = "axis_u")]
    pub x: SheetAxis,
    /// The sheet direction of the board's `y`.
    #[serde(default = "axis_v")]
    pub y: SheetAxis,
}

impl Charuco {
    /// The board as detection sees it (`None` for an unknown dictionary).
    pub fn board(&self) -> Option<CharucoBoard> {
        Some(CharucoBoard {
            cols: self.cols,
            rows: self.rows,
            square: self.square,
            marker: self.marker,
            dictionary: Dictionary::named(&self.dictionary)?,
            first_id: self.first_id,
        })
    }

    /// A point of the board (board mm) on the sheet.
    pub fn on_sheet(&self, p: Point2<f64>) -> Point2<f64> {
        let (ax, ay) = (self.x.unit(), self.y.unit());
        let (bx, by) = (p.x - self.square, p.y - self.square);
        Point2::new(
            self.u0 + bx * ax[0] + by * ay[0],
            self.v0 + bx * ax[1] + by * ay[1],
        )
    }

    /// Inner corners on the sheet, in OpenCV's order (row by row along the board's `x`).
    pub fn corners(&self) -> Vec<Point2<f64>> {
        let per = self.cols.saturating_sub(1);
        (0..per * self.rows.saturating_sub(1))
            .map(|k| {
                self.on_sheet(Point2::new(
                    (k % per + 1) as f64 * self.square,
                    (k / per + 1) as f64 * self.square,
                ))
            })
            .collect()
    }
}

/// One sheet's markers: listed discs, a grid of discs, a chessboard or a ChArUco board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SheetLayout {
    /// Marker centres `[u, v]`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub markers: Option<Vec<[f64; 2]>>,
    /// Or a grid of them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<MarkerGrid>,
    /// Or a chessboard instead of discs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chessboard: Option<Chessboard>,
    /// Or a ChArUco board.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub charuco: Option<Charuco>,
}

/// Paper size of a sheet, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SheetSize {
    /// Along `u` (from the crease edge).
    pub width: f64,
    /// Along `v`.
    pub height: f64,
}

/// The image-distance cross (paper Fig. 5): dots A (top), B (left), C (centre), D (right),
/// E (bottom), `|AE| = |BD| = arm`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cross {
    /// Distance A–E (and B–D), mm.
    pub arm: f64,
    /// Dot diameter, mm.
    pub dot: f64,
}

/// The board file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardFile {
    /// Diameter of the dark circular markers, mm.
    pub marker_diameter: f64,
    /// Paper size of each sheet.
    pub sheet: SheetSize,
    /// The left sheet (left in the camera's image).
    pub left: SheetLayout,
    /// The right sheet.
    pub right: SheetLayout,
    /// The image-distance pattern.
    pub cross: Cross,
}

/// Why a board file is unusable.
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// Not readable.
    #[error("board file {path}")]
    Read {
        /// The file.
        path: String,
        /// What went wrong.
        #[source]
        source: std::io::Error,
    },
    /// Not TOML of this shape.
    #[error("board file {path}")]
    Toml {
        /// The file.
        path: String,
        /// What is wrong.
        #[source]
        source: toml::de::Error,
    },
    /// Cannot be written as TOML.
    #[error("board file: cannot be written as TOML")]
    Serialize(#[source] toml::ser::Error),
    /// Readable, but the numbers do not describe a usable board.
    #[error("board file: {0}")]
    Invalid(String),
    /// A ChArUco sheet of a dictionary OpenCV does not predefine.
    #[error(
        "board file: [{sheet}].charuco: unknown dictionary {dictionary:?}; OpenCV's predefined ones are {}",
        crate::aruco::DICTIONARIES.join(", ")
    )]
    UnknownDictionary {
        /// `left` or `right`.
        sheet: String,
        /// The name given.
        dictionary: String,
    },
    /// A ChArUco sheet whose marker IDs run past its dictionary's codes.
    #[error(
        "board file: [{sheet}].charuco: {markers} markers from ID {first_id} run past the {codes} codes of {dictionary}"
    )]
    IdsPastDictionary {
        /// `left` or `right`.
        sheet: String,
        /// Its markers.
        markers: usize,
        /// Its first ID.
        first_id: usize,
        /// Codes the dictionary has.
        codes: usize,
        /// The dictionary.
        dictionary: String,
    },
    /// Axes that lay a ChArUco sheet mirrored.
    #[error(
        "board file: [{sheet}].charuco: x = \"{x}\" and y = \"{y}\" lay the board mirrored (its markers would not read): change the sign of one"
    )]
    Mirrored {
        /// `left` or `right`.
        sheet: String,
        /// Its x axis.
        x: String,
        /// Its y axis.
        y: String,
    },
    /// Both sheets ChArUco boards of one dictionary whose IDs overlap.
    #[error(
        "board file: [left] and [right] are both ChArUco boards of {dictionary} with marker IDs {}–{} and {}–{}: the two sheets must not share IDs (print one with another dictionary or `first_id`)",
        left.0,
        left.1,
        right.0,
        right.1
    )]
    SharedIds {
        /// The dictionary.
        dictionary: String,
        /// The left sheet's first and last ID.
        left: (usize, usize),
        /// The right sheet's.
        right: (usize, usize),
    },
}

impl Default for BoardFile {
    /// The paper's layout: on each sheet two lines of three markers, 110 mm apart along the sheet,
    /// the lines 220 mm apart, 27.5 mm discs, on A3 landscape; a 200 mm cross.
    fn default() -> Self {
        let grid = MarkerGrid {
            cols: 3,
            rows: 2,
            u0: 66.0,
            v0: -110.0,
            du: 110.0,
            dv: 220.0,
        };
        BoardFile {
            marker_diameter: 27.5,
            sheet: SheetSize {
                width: 420.0,
                height: 297.0,
            },
            left: SheetLayout {
                markers: None,
                grid: Some(grid),
                chessboard: None,
                charuco: None,
            },
            right: SheetLayout {
                markers: None,
                grid: Some(grid),
                chessboard: None,
                charuco: None,
            },
            cross: Cross {
                arm: 200.0,
                dot: 12.0,
            },
        }
    }
}

impl BoardFile {
    /// A two-plane board of ChArUco sheets (`scanner-device board --charuco`): on each A3 sheet
    /// 10×7 squares of 30 mm with markers of 22 mm from `DICT_5X5_100` (the left sheet IDs 0–34,
    /// the right one 35–69), 60 mm from the crease (clear of its label), centred along it.
    pub fn charuco_default() -> BoardFile {
        let sheet = |first_id: usize, left: bool| SheetLayout {
            markers: None,
            grid: None,
            chessboard: None,
            charuco: Some(Charuco {
                cols: 10,
                rows: 7,
                square: 30.0,
                marker: 22.0,
                dictionary: "DICT_5X5_100".into(),
                first_id,
                // The board's x runs away from the crease on the right sheet, towards it on the
                // left one (whose u runs to the left): both print upright.
                u0: if left { 330.0 } else { 90.0 },
                v0: -75.0,
                x: if left {
                    SheetAxis::MinusU
                } else {
                    SheetAxis::PlusU
                },
                y: SheetAxis::PlusV,
            }),
        };
        BoardFile {
            left: sheet(0, true),
            right: sheet(35, false),
            ..BoardFile::default()
        }
    }
}

impl SheetLayout {
    /// How many markers (or inner corners) the sheet has, from the counts alone (nothing is
    /// allocated); `None` when it has none of the three kinds or the count overflows.
    pub fn count(&self) -> Option<usize> {
        if let Some(c) = &self.charuco {
            return c
                .cols
                .saturating_sub(1)
                .checked_mul(c.rows.saturating_sub(1));
        }
        if let Some(c) = self.chessboard {
            return c
                .cols
                .saturating_sub(1)
                .checked_mul(c.rows.saturating_sub(1));
        }
        if let Some(m) = &self.markers {
            return Some(m.len());
        }
        self.grid.and_then(|g| g.cols.checked_mul(g.rows))
    }

    /// Marker centres in order: listed ones as listed, a grid row by row (along `u` first).
    pub fn points(&self) -> Vec<Point2<f64>> {
        if let Some(c) = &self.charuco {
            return c.corners();
        }
        if let Some(c) = self.chessboard {
            return c.corners();
        }
        if let Some(m) = &self.markers {
            return m.iter().map(|p| Point2::new(p[0], p[1])).collect();
        }
        match self.grid {
            Some(g) => (0..g.rows)
                .flat_map(|r| {
                    (0..g.cols)
                        .map(move |c| Point2::new(g.u0 + c as f64 * g.du, g.v0 + r as f64 * g.dv))
                })
                .collect(),
            None => Vec::new(),
        }
    }

    /// For a chessboard sheet: per marker (inner corner, in [`Self::points`] order), whether its
    /// (+u, +v) square is dark, as [`crate::print`] prints it (the first square is dark).
    pub fn corner_colours(&self) -> Option<Vec<bool>> {
        let c = self.chessboard?;
        let per_row = c.cols.saturating_sub(1);
        Some(
            (0..per_row * c.rows.saturating_sub(1))
                .map(|k| (k % per_row + k / per_row) % 2 == 0)
                .collect(),
        )
    }

    /// Radius of this sheet's markers as the calibration models them: the discs' radius, or 0
    /// for chessboard corners.
    pub fn marker_radius(&self, diameter: f64) -> f64 {
        if self.chessboard.is_some() || self.charuco.is_some() {
            0.0
        } else {
            diameter / 2.0
        }
    }

    /// The paper's two lines of three equally spaced markers, if that is this layout:
    /// `[[a, b, c], [d, e, f]]` as layout indices.
    pub fn paper_lines(&self) -> Option<[[usize; 3]; 2]> {
        let p = self.points();
        if p.len() != 6 {
            return None;
        }
        let line = |i: usize| {
            let (a, b, c) = (p[i], p[i + 1], p[i + 2]);
            let mid = (a.coords + c.coords) / 2.0;
            let len = (c - a).norm();
            ((b.coords - mid).norm() < 1e-6 * len && len > 0.0).then_some([i, i + 1, i + 2])
        };
        Some([line(0)?, line(3)?])
    }
}

impl BoardFile {
    /// Reads and checks a board file.
    ///
    /// # Errors
    /// [`BoardError`] naming the file and what is wrong.
    pub fn load(path: &Path) -> Result<BoardFile, BoardError> {
        let text = scanner_io::text_file::read(path).map_err(|source| BoardError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses and checks a board file's text; `name` names it in errors.
    ///
    /// # Errors
    /// [`BoardError`] naming the file and what is wrong.
    pub fn parse(text: &str, name: &str) -> Result<BoardFile, BoardError> {
        let b: BoardFile = toml::from_str(text).map_err(|source| BoardError::Toml {
            path: name.to_string(),
            source,
        })?;
        b.check()?;
        Ok(b)
    }

    /// The file's text (TOML).
    ///
    /// # Errors
    /// [`BoardError::Serialize`] for a value TOML cannot hold.
    pub fn to_toml(&self) -> Result<String, BoardError> {
        let body = toml::to_string(self).map_err(BoardError::Serialize)?;
        Ok(format!(
            "# Calibration board for scanner-device (lengths in mm). Sheet coordinates: u from the\n\
             # crease outward, v along the crease (down), v = 0 at the same height on both sheets.\n\
             # Each sheet: `markers = [[u, v], ...]` or `grid = {{ cols, rows, u0, v0, du, dv }}`.\n{body}"
        ))
    }

    /// Checks that the numbers describe a usable board.
    ///
    /// # Errors
    /// [`BoardError::Invalid`] naming the problem.
    pub fn check(&self) -> Result<(), BoardError> {
        let bad = |s: String| Err(BoardError::Invalid(s));
        if !(self.marker_diameter > 0.0 && self.marker_diameter.is_finite()) {
            return bad(format!(
                "marker_diameter must be positive, found {}",
                self.marker_diameter
            ));
        }
        if !(self.sheet.width > 0.0
            && self.sheet.height > 0.0
            && self.sheet.width <= MAX_SHEET_MM
            && self.sheet.height <= MAX_SHEET_MM)
        {
            return bad(format!(
                "[sheet]: width and height must be between 0 and {MAX_SHEET_MM} mm, found {} × {}",
                short(self.sheet.width),
                short(self.sheet.height)
            ));
        }
        if !(self.cross.arm > 2.0 * self.cross.dot && self.cross.dot > 0.0) {
            return bad("cross: arm must exceed twice the dot diameter, both positive".into());
        }
        for (name, s) in [("left", &self.left), ("right", &self.right)] {
            let kinds = [
                s.markers.is_some(),
                s.grid.is_some(),
                s.chessboard.is_some(),
                s.charuco.is_some(),
            ];
            if kinds.iter().filter(|&&k| k).count() != 1 {
                return bad(format!(
                    "[{name}]: give exactly one of `markers`, `grid`, `chessboard` or `charuco`"
                ));
            }
            if s.count().is_none_or(|n| n > MAX_MARKERS) {
                return bad(format!(
                    "[{name}]: {} markers or corners; at most {MAX_MARKERS} per sheet",
                    s.count()
                        .map_or_else(|| "too many".to_string(), |n| n.to_string())
                ));
            }
            if let Some(c) = &s.charuco {
                self.check_charuco(name, c)?;
                continue;
            }
            if let Some(c) = s.chessboard {
                if !(c.cols >= 3 && c.rows >= 3 && c.square > 0.0) {
                    return bad(format!(
                        "[{name}].chessboard: needs at least 3×3 squares and a positive square"
                    ));
                }
                let (u_lo, u_hi) = (c.u0 - c.square, c.u0 + (c.cols - 1) as f64 * c.square);
                let (v_lo, v_hi) = (c.v0 - c.square, c.v0 + (c.rows - 1) as f64 * c.square);
                if u_lo < 0.0
                    || u_hi > self.sheet.width
                    || v_lo < -self.sheet.height / 2.0
                    || v_hi > self.sheet.height / 2.0
                {
                    return bad(format!(
                        "[{name}].chessboard: runs off the {}×{} mm sheet",
                        self.sheet.width, self.sheet.height
                    ));
                }
                continue;
            }
            if let Some(g) = s.grid
                && !(g.cols >= 1 && g.rows >= 1 && g.du > 0.0 && g.dv > 0.0)
            {
                return bad(format!("[{name}].grid: counts and steps must be positive"));
            }
            let p = s.points();
            if p.len() < 4 {
                return bad(format!(
                    "[{name}]: {} markers; a sheet needs at least 4 (the paper uses 6)",
                    p.len()
                ));
            }
            for (i, a) in p.iter().enumerate() {
                if !(a.x.is_finite() && a.y.is_finite()) {
                    return bad(format!("[{name}]: marker {i} is not a number"));
                }
                let r = self.marker_diameter / 2.0;
                if a.x - r < 0.0
                    || a.x + r > self.sheet.width
                    || (a.y.abs() + r) > self.sheet.height / 2.0
                {
                    return bad(format!(
                        "[{name}]: marker {i} at ({}, {}) is off the {}×{} mm sheet",
                        a.x, a.y, self.sheet.width, self.sheet.height
                    ));
                }
                for (j, b) in p.iter().enumerate().skip(i + 1) {
                    if (a - b).norm() < 1.5 * self.marker_diameter {
                        return bad(format!(
                            "[{name}]: markers {i} and {j} are closer than 1.5 diameters"
                        ));
                    }
                }
            }
        }
        if let (Some(l), Some(r)) = (&self.left.charuco, &self.right.charuco)
            && let (Some(a), Some(b)) = (l.board(), r.board())
            && a.dictionary == b.dictionary
            && a.ids().start < b.ids().end
            && b.ids().start < a.ids().end
        {
            return Err(BoardError::SharedIds {
                dictionary: l.dictionary.clone(),
                left: (a.ids().start, a.ids().end - 1),
                right: (b.ids().start, b.ids().end - 1),
            });
        }
        Ok(())
    }

    /// A ChArUco sheet's numbers: a known dictionary holding its IDs, markers smaller than
    /// the squares, the board on the sheet.
    fn check_charuco(&self, name: &str, c: &Charuco) -> Result<(), BoardError> {
        let bad = |s: String| Err(BoardError::Invalid(s));
        let Some(b) = c.board() else {
            return Err(BoardError::UnknownDictionary {
                sheet: name.to_string(),
                dictionary: c.dictionary.chars().take(40).collect(),
            });
        };
        if !(c.cols >= 3 && c.rows >= 3) {
            return bad(format!(
                "[{name}].charuco: needs at least 3×3 squares, found {}×{}",
                c.cols, c.rows
            ));
        }
        if !(c.square > 0.0 && c.marker > 0.0 && c.marker < c.square && c.square.is_finite()) {
            return bad(format!(
                "[{name}].charuco: the marker side ({} mm) must be positive and smaller than the square's ({} mm)",
                short(c.marker),
                short(c.square)
            ));
        }
        if b.ids().end > b.dictionary.count {
            return Err(BoardError::IdsPastDictionary {
                sheet: name.to_string(),
                markers: b.marker_count(),
                first_id: c.first_id,
                codes: b.dictionary.count,
                dictionary: c.dictionary.clone(),
            });
        }
        let (ax, ay) = (c.x.unit(), c.y.unit());
        if ax[0] * ay[0] + ax[1] * ay[1] != 0.0 {
            return bad(format!(
                "[{name}].charuco: x and y must run along different sheet directions (u and v)"
            ));
        }
        // Seen from the front, the right sheet's (u, v) turn as the board's (x, y) do, the
        // left sheet's (its u runs to the left) the other way: else the board is mirrored.
        let turn = ax[0] * ay[1] - ax[1] * ay[0];
        if (turn > 0.0) != (name == "right") {
            return Err(BoardError::Mirrored {
                sheet: name.to_string(),
                x: c.x.name().to_string(),
                y: c.y.name().to_string(),
            });
        }
        let (w, h) = (c.cols as f64 * c.square, c.rows as f64 * c.square);
        let outline =
            [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)].map(|(x, y)| c.on_sheet(Point2::new(x, y)));
        if !(c.u0.is_finite() && c.v0.is_finite())
            || outline.iter().any(|p| {
                p.x < -1e-9
                    || p.x > self.sheet.width + 1e-9
                    || p.y.abs() > self.sheet.height / 2.0 + 1e-9
            })
        {
            return bad(format!(
                "[{name}].charuco: runs off the {}×{} mm sheet",
                self.sheet.width, self.sheet.height
            ));
        }
        Ok(())
    }
}
