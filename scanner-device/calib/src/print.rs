//! Printable 1:1 sheets of a board file: each plane's sheet and the image-distance cross, as SVG
//! (exact millimetres, print at 100 % / "actual size") and PNG (at a chosen resolution). Every
//! sheet carries a 100 mm scale ruler to check the print, and the board sheets mark their
//! crease edge.

use image::Rgb;

use scanner_core::nalgebra::Point2;

use super::board::{BoardFile, Charuco, Cross};
use crate::canvas::Canvas;

/// One printable sheet: circles and strokes in mm.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Sheet {
    /// Title printed at the top.
    pub title: String,
    /// Paper width, mm.
    pub width: f64,
    /// Paper height, mm.
    pub height: f64,
    /// Filled black circles: centre x, y and diameter, mm from the top-left corner.
    pub dots: Vec<(f64, f64, f64)>,
    /// Filled black squares: top-left x, y and side, mm.
    pub squares: Vec<(f64, f64, f64)>,
    /// The crease edge's x (mm), for a board sheet.
    pub crease_x: Option<f64>,
    /// Filled black rectangles: left, top, right, bottom, mm.
    pub bars: Vec<[f64; 4]>,
    /// Black circle outlines: centre x, y, diameter and line width, mm.
    pub circles: Vec<(f64, f64, f64, f64)>,
}

const RULER: (f64, f64) = (15.0, 12.0); // left end and distance from the bottom, mm

/// A ChArUco board's ink as squares on the paper (`paper` maps the sheet's `(u, v)` to the
/// paper's `(x, y)`): its dark squares, and each marker's dark cells (its border and the code's
/// dark cells).
fn charuco_squares(c: &Charuco, paper: impl Fn(f64, f64) -> (f64, f64)) -> Vec<(f64, f64, f64)> {
    let Some(b) = c.board() else {
        return Vec::new();
    };
    // A square of side `s` with its board corner at (x, y): on the paper, the least of its
    // corners' coordinates (the board is turned by a quarter turn at most).
    let place = |x: f64, y: f64, s: f64| {
        let corners = [(x, y), (x + s, y), (x, y + s), (x + s, y + s)].map(|(bx, by)| {
            let p = c.on_sheet(Point2::new(bx, by));
            paper(p.x, p.y)
        });
        let min = |f: fn(&(f64, f64)) -> f64| corners.iter().map(f).fold(f64::INFINITY, f64::min);
        (min(|p| p.0), min(|p| p.1), s)
    };
    let mut out = Vec::new();
    let n = b.dictionary.n;
    let cell = c.marker / (n + 2) as f64;
    for y in 0..c.rows {
        for x in 0..c.cols {
            let (x0, y0) = (x as f64 * c.square, y as f64 * c.square);
            let Some(id) = b.marker_in(x, y) else {
                out.push(place(x0, y0, c.square));
                continue;
            };
            let Some(dark) = b.dictionary.dark_cells(id) else {
                continue;
            };
            let m = (c.square - c.marker) / 2.0;
            for (r, q) in dark {
                out.push(place(
                    x0 + m + q as f64 * cell,
                    y0 + m + r as f64 * cell,
                    cell,
                ));
            }
        }
    }
    out
}

impl Sheet {
    /// The board's left (`k = 0`) or right sheet. Seen from the front, the left sheet's crease
    /// edge is its right edge (`u` runs to the left), the right sheet's its left edge.
    pub fn board(board: &BoardFile, k: usize) -> Sheet {
        let (w, h) = (board.sheet.width, board.sheet.height);
        let layout = if k == 0 { &board.left } else { &board.right };
        let mut squares = Vec::new();
        // Sheet (u, v) to the paper's (x, y) from its top left, seen from the front.
        let paper = |u: f64, v: f64| (if k == 0 { w - u } else { u }, h / 2.0 + v);
        let dots = if let Some(c) = &layout.charuco {
            squares = charuco_squares(c, paper);
            Vec::new()
        } else if let Some(c) = layout.chessboard {
            for a in 0..c.cols {
                for b in 0..c.rows {
                    if (a + b) % 2 == 0 {
                        let u = c.u0 - c.square + a as f64 * c.square;
                        let v = c.v0 - c.square + b as f64 * c.square;
                        let x = if k == 0 { w - u - c.square } else { u };
                        squares.push((x, h / 2.0 + v, c.square));
                    }
                }
            }
            Vec::new()
        } else {
            layout
                .points()
                .iter()
                .map(|p| {
                    let x = if k == 0 { w - p.x } else { p.x };
                    (x, h / 2.0 + p.y, board.marker_diameter)
                })
                .collect()
        };
        let what = if let Some(c) = &layout.charuco {
            format!(
                "ChArUco {}x{}, {} mm, markers {} mm, {} {}-{}",
                c.cols,
                c.rows,
                c.square,
                c.marker,
                c.dictionary,
                c.first_id,
                c.first_id + (c.cols * c.rows / 2).max(1) - 1
            )
        } else if layout.chessboard.is_some() {
            format!("a chessboard with {} inner corners", layout.points().len())
        } else {
            format!(
                "{} markers of {} mm",
                layout.points().len(),
                board.marker_diameter
            )
        };
        Sheet {
            title: format!(
                "scanner board - {} sheet - {what} - print at 100 %",
                ["left", "right"][k]
            ),
            width: w,
            height: h,
            dots,
            squares,
            crease_x: Some(if k == 0 { w } else { 0.0 }),
            ..Sheet::default()
        }
    }

    /// The intrinsics target: a dot grid (`calibrate intrinsics`' default, 9×7 dots of 12 mm at
    /// 30 mm), centred with a 20 mm margin and room for the title and the ruler.
    pub fn target(g: &crate::DotGrid) -> Sheet {
        let span = |n: usize| (n.saturating_sub(1)) as f64 * g.pitch + g.dot;
        let (w, h) = (span(g.cols) + 40.0, span(g.rows) + 60.0);
        let (x0, y0) = (20.0 + g.dot / 2.0, 25.0 + g.dot / 2.0);
        Sheet {
            title: format!(
                "intrinsics target: {}x{} dots of {} mm at {} mm - print at 100 % (A3), glue flat",
                g.cols, g.rows, g.dot, g.pitch
            ),
            width: w,
            height: h,
            dots: (0..g.rows)
                .flat_map(|r| {
                    (0..g.cols)
                        .map(move |c| (x0 + c as f64 * g.pitch, y0 + r as f64 * g.pitch, g.dot))
                })
                .collect(),
            ..Sheet::default()
        }
    }

    /// The paper's image-distance cross (Fig. 5): A top, B left, C centre, D right, E bottom.
    pub fn cross(c: &Cross) -> Sheet {
        let (w, h) = (c.arm + 4.0 * c.dot + 40.0, c.arm + 4.0 * c.dot + 60.0);
        let (cx, cy) = (w / 2.0, h / 2.0);
        let a = c.arm / 2.0;
        Sheet {
            title: format!(
                "image-distance cross: |AE| = |BD| = {} mm - print at 100 %",
                c.arm
            ),
            width: w,
            height: h,
            dots: [(0.0, -a), (-a, 0.0), (0.0, 0.0), (a, 0.0), (0.0, a)]
                .iter()
                .map(|(x, y)| (cx + x, cy + y, c.dot))
                .collect(),
            ..Sheet::default()
        }
    }

    /// The top of the crease edge's label, mm: above the middle of the sheet, or where it hides
    /// no ink (a pattern near the crease) higher or lower.
    fn crease_label_y(&self) -> f64 {
        let Some(x) = self.crease_x else {
            return 0.0;
        };
        let (x0, x1) = if x > 0.0 {
            (x - 35.0, x)
        } else {
            (x, x + 35.0)
        };
        let clear = |y: f64| {
            let (y0, y1) = (y - 1.0, y + 7.0);
            let apart = |ax0: f64, ay0: f64, ax1: f64, ay1: f64| {
                ax1 < x0 || ax0 > x1 || ay1 < y0 || ay0 > y1
            };
            self.squares
                .iter()
                .all(|&(sx, sy, side)| apart(sx, sy, sx + side, sy + side))
                && self.dots.iter().all(|&(cx, cy, d)| {
                    apart(cx - d / 2.0, cy - d / 2.0, cx + d / 2.0, cy + d / 2.0)
                })
        };
        let middle = self.height / 2.0 - 24.0;
        (0..)
            .map(|i| f64::from(i) * 2.0)
            .take_while(|&dy| dy < self.height)
            .flat_map(|dy| [middle - dy, middle + dy])
            .find(|&y| y >= 14.0 && y <= self.height - 24.0 && clear(y))
            .unwrap_or(middle)
    }

    /// The sheet as SVG, sized in mm.
    pub fn svg(&self) -> String {
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}mm\" height=\"{h}mm\" viewBox=\"0 0 {w} {h}\">\n\
             <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n\
             <text x=\"10\" y=\"10\" font-family=\"sans-serif\" font-size=\"5\">{t}</text>\n",
            w = self.width,
            h = self.height,
            t = self.title
        );
        for (x, y, d) in &self.dots {
            s += &format!(
                "<circle cx=\"{x:.3}\" cy=\"{y:.3}\" r=\"{:.3}\" fill=\"black\"/>\n",
                d / 2.0
            );
        }
        for (x, y, side) in &self.squares {
            s += &format!(
                "<rect x=\"{x:.3}\" y=\"{y:.3}\" width=\"{side:.3}\" height=\"{side:.3}\" fill=\"black\"/>\n"
            );
        }
        for [x0, y0, x1, y1] in &self.bars {
            s += &format!(
                "<rect x=\"{x0:.3}\" y=\"{y0:.3}\" width=\"{:.3}\" height=\"{:.3}\" fill=\"black\"/>\n",
                x1 - x0,
                y1 - y0
            );
        }
        for (x, y, d, lw) in &self.circles {
            s += &format!(
                "<circle cx=\"{x:.3}\" cy=\"{y:.3}\" r=\"{:.3}\" fill=\"none\" stroke=\"black\" stroke-width=\"{lw}\"/>\n",
                d / 2.0
            );
        }
        if let Some(x) = self.crease_x {
            s += &format!(
                "<line x1=\"{x}\" y1=\"0\" x2=\"{x}\" y2=\"{h}\" stroke=\"black\" stroke-width=\"0.5\" stroke-dasharray=\"4 3\"/>\n\
                 <text x=\"{tx}\" y=\"{ty}\" font-family=\"sans-serif\" font-size=\"4\" text-anchor=\"{anchor}\">crease edge</text>\n",
                h = self.height,
                tx = if x > 0.0 { x - 3.0 } else { x + 3.0 },
                ty = self.crease_label_y() + 4.0,
                anchor = if x > 0.0 { "end" } else { "start" }
            );
        }
        // The ruler: 100 mm with ticks every 10 mm.
        let (x0, y) = (RULER.0, self.height - RULER.1);
        s += &format!("<rect x=\"{x0}\" y=\"{y}\" width=\"100\" height=\"0.6\" fill=\"black\"/>\n");
        for i in 0..=10 {
            let x = x0 + 10.0 * f64::from(i);
            let len = if i % 5 == 0 { 5.0 } else { 3.0 };
            s += &format!(
                "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"0.4\" height=\"{len}\" fill=\"black\"/>\n",
                x - 0.2,
                y - len
            );
        }
        s += &format!(
            "<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"4\">100 mm: measure this to check the print scale</text>\n</svg>\n",
            x0 + 105.0,
            y
        );
        s
    }

    /// The size of the sheet's picture at `px_per_mm`, pixels.
    pub fn png_size(&self, px_per_mm: f64) -> (u64, u64) {
        let side = |mm: f64| ((mm * px_per_mm).round().max(1.0)).min(u64::MAX as f64) as u64;
        (side(self.width), side(self.height))
    }

    /// The sheet's picture at `px_per_mm`, refused beyond [`MAX_PNG_PIXELS`] (before anything is
    /// allocated).
    ///
    /// # Errors
    /// [`PngTooLarge`] with the size it would have.
    pub fn png(&self, px_per_mm: f64) -> Result<image::RgbImage, PngTooLarge> {
        let (w, h) = self.check_png(px_per_mm)?;
        let mut cv = Canvas::blank(w.max(1), h.max(1), Rgb([255, 255, 255]));
        let black = Rgb([0, 0, 0]);
        // Discs with 4×4 supersampled rims.
        for &(x, y, d) in &self.dots {
            let (cx, cy, r) = (x * px_per_mm, y * px_per_mm, d / 2.0 * px_per_mm);
            let ri = r.ceil() as i64 + 1;
            for py in (cy as i64 - ri)..=(cy as i64 + ri) {
                for px in (cx as i64 - ri)..=(cx as i64 + ri) {
                    let mut inside = 0;
                    for sy in 0..4 {
                        for sx in 0..4 {
                            let (fx, fy) = (
                                px as f64 + (sx as f64 + 0.5) / 4.0,
                                py as f64 + (sy as f64 + 0.5) / 4.0,
                            );
                            if (fx - cx).powi(2) + (fy - cy).powi(2) <= r * r {
                                inside += 1;
                            }
                        }
                    }
                    if inside > 0 {
                        let v = (255.0 * (1.0 - f64::from(inside) / 16.0)).round() as u8;
                        cv.dot(px, py, Rgb([v, v, v]));
                    }
                }
            }
        }
        for &[x0, y0, x1, y1] in &self.bars {
            cv.rect(
                x0 * px_per_mm,
                y0 * px_per_mm,
                x1 * px_per_mm,
                y1 * px_per_mm,
                black,
            );
        }
        // Circle outlines, 4×4 supersampled.
        for &(x, y, d, lw) in &self.circles {
            let (cx, cy) = (x * px_per_mm, y * px_per_mm);
            let (r0, r1) = ((d - lw) / 2.0 * px_per_mm, (d + lw) / 2.0 * px_per_mm);
            let ri = r1.ceil() as i64 + 1;
            for py in (cy as i64 - ri)..=(cy as i64 + ri) {
                for px in (cx as i64 - ri)..=(cx as i64 + ri) {
                    let near = ((px as f64 + 0.5 - cx).hypot(py as f64 + 0.5 - cy)
                        - (r0 + r1) / 2.0)
                        .abs();
                    if near > (r1 - r0) / 2.0 + 1.0 {
                        continue;
                    }
                    let mut inside = 0;
                    for sy in 0..4 {
                        for sx in 0..4 {
                            let rr = (px as f64 + (sx as f64 + 0.5) / 4.0 - cx)
                                .hypot(py as f64 + (sy as f64 + 0.5) / 4.0 - cy);
                            if (r0..=r1).contains(&rr) {
                                inside += 1;
                            }
                        }
                    }
                    if inside > 0 {
                        let v = (255.0 * (1.0 - f64::from(inside) / 16.0)).round() as u8;
                        cv.dot(px, py, Rgb([v, v, v]));
                    }
                }
            }
        }
        for &(x, y, side) in &self.squares {
            cv.rect(
                x * px_per_mm,
                y * px_per_mm,
                (x + side) * px_per_mm,
                (y + side) * px_per_mm,
                black,
            );
        }
        let scale = ((px_per_mm * 0.6).round() as u32).max(1);
        cv.text(10.0 * px_per_mm, 6.0 * px_per_mm, &self.title, scale, black);
        if let Some(x) = self.crease_x {
            let xp = (x * px_per_mm).min(f64::from(w) - 1.0);
            let mut y = 0.0;
            while y < f64::from(h) {
                cv.line(
                    (xp, y),
                    (xp, (y + 4.0 * px_per_mm).min(f64::from(h))),
                    0.5 * px_per_mm,
                    black,
                );
                y += 7.0 * px_per_mm;
            }
            let label = "crease edge";
            let tw = label.len() as f64 * 8.0 * f64::from(scale);
            let tx = if x > 0.0 {
                xp - tw - 3.0 * px_per_mm
            } else {
                xp + 3.0 * px_per_mm
            };
            cv.text(tx, self.crease_label_y() * px_per_mm, label, scale, black);
        }
        let (x0, y) = (RULER.0 * px_per_mm, (self.height - RULER.1) * px_per_mm);
        cv.rect(x0, y, x0 + 100.0 * px_per_mm, y + 0.6 * px_per_mm, black);
        for i in 0..=10 {
            let x = x0 + 10.0 * f64::from(i) * px_per_mm;
            let len = if i % 5 == 0 { 5.0 } else { 3.0 } * px_per_mm;
            cv.rect(x - 0.2 * px_per_mm, y - len, x + 0.2 * px_per_mm, y, black);
        }
        cv.text(
            x0 + 105.0 * px_per_mm,
            y - 4.0 * px_per_mm,
            "100 mm: check the print scale",
            scale,
            black,
        );
        Ok(cv.image)
    }
}

impl Sheet {
    /// Whether the sheet's point `(x, y)` (mm from its top-left corner) is inked by a dot, a
    /// square, a bar or a circle outline (the title, the ruler and the crease line aside): what a
    /// camera sees of the print (the virtual rig renders it).
    pub fn ink(&self, x: f64, y: f64) -> bool {
        self.dots
            .iter()
            .any(|&(cx, cy, d)| (x - cx).powi(2) + (y - cy).powi(2) <= (d / 2.0).powi(2))
            || self
                .squares
                .iter()
                .any(|&(x0, y0, s)| (x0..=x0 + s).contains(&x) && (y0..=y0 + s).contains(&y))
            || self
                .bars
                .iter()
                .any(|&[x0, y0, x1, y1]| (x0..=x1).contains(&x) && (y0..=y1).contains(&y))
            || self
                .circles
                .iter()
                .any(|&(cx, cy, d, lw)| (apart(x - cx, y - cy) - d / 2.0).abs() <= lw / 2.0)
    }

    /// Distance (mm) from `(x, y)` to the nearest edge of the ink that [`Sheet::ink`] sees.
    pub fn ink_edge_distance(&self, x: f64, y: f64) -> f64 {
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| {
            let (dx, dy) = ((x0 - x).max(x - x1), (y0 - y).max(y - y1));
            if dx > 0.0 || dy > 0.0 {
                apart(dx.max(0.0), dy.max(0.0))
            } else {
                (-dx).min(-dy)
            }
        };
        let dots = self
            .dots
            .iter()
            .map(|&(cx, cy, d)| (apart(x - cx, y - cy) - d / 2.0).abs());
        let squares = self
            .squares
            .iter()
            .map(|&(x0, y0, s)| rect(x0, y0, x0 + s, y0 + s));
        let bars = self
            .bars
            .iter()
            .map(|&[x0, y0, x1, y1]| rect(x0, y0, x1, y1));
        let circles = self
            .circles
            .iter()
            .map(|&(cx, cy, d, lw)| ((apart(x - cx, y - cy) - d / 2.0).abs() - lw / 2.0).abs());
        dots.chain(squares)
            .chain(bars)
            .chain(circles)
            .fold(f64::INFINITY, f64::min)
    }
}

/// Most pixels of a printable sheet's PNG (A3 at 600 dpi is 70 M; 240 MB as RGB).
pub const MAX_PNG_PIXELS: u64 = 80_000_000;

/// A sheet's PNG would be too large at the asked resolution.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "a {title} PNG would be {width}×{height} pixels (at most {MAX_PNG_PIXELS} pixels): choose a lower --dpi or a smaller sheet"
)]
pub struct PngTooLarge {
    /// The sheet's title.
    pub title: String,
    /// Width it would have, pixels.
    pub width: u64,
    /// Height it would have, pixels.
    pub height: u64,
}

impl Sheet {
    /// The picture's size at `px_per_mm` if it is within [`MAX_PNG_PIXELS`].
    ///
    /// # Errors
    /// [`PngTooLarge`] with the size it would have.
    pub fn check_png(&self, px_per_mm: f64) -> Result<(u32, u32), PngTooLarge> {
        let (w, h) = self.png_size(px_per_mm);
        if w.saturating_mul(h) > MAX_PNG_PIXELS {
            return Err(PngTooLarge {
                title: self.title.clone(),
                width: w,
                height: h,
            });
        }
        Ok((w as u32, h as u32))
    }
}

/// The sheets to print for a board file, with file stems: left, right, the image-distance
/// cross, and the intrinsics target (`calibrate intrinsics`' default dot grid, [`crate::DotGrid::RIG`]).
pub fn sheets(board: &BoardFile) -> [(&'static str, Sheet); 4] {
    [
        ("left-sheet", Sheet::board(board, 0)),
        ("right-sheet", Sheet::board(board, 1)),
        ("cross", Sheet::cross(&board.cross)),
        ("target", Sheet::target(&crate::DotGrid::RIG)),
    ]
}

/// A4 landscape page, mm.
pub const A4: (f64, f64) = (297.0, 210.0);
/// Margin kept free on each tile page (printers do not print to the edge), mm.
const TILE_MARGIN: f64 = 10.0;
/// Overlap of neighbouring tiles, mm: the alignment crosses are printed in it on both.
const TILE_OVERLAP: f64 = 10.0;

/// One A4 tile of a larger sheet.
#[derive(Debug, Clone, PartialEq)]
pub struct Tile {
    /// Row and column (from 0).
    pub at: (usize, usize),
    /// Rows and columns of tiles for the sheet.
    pub of: (usize, usize),
    /// The part of the sheet it shows: x, y, width, height, mm.
    pub area: [f64; 4],
    /// The page as SVG (A4 landscape, 1:1).
    pub svg: String,
}

/// The sheet cut into A4 landscape tiles that overlap by 10 mm, for printers without A3: each
/// tile shows its part of the sheet 1:1 inside a 10 mm margin, crop marks, alignment crosses in
/// the overlaps (the same cross on both neighbours), its place ("tile 1,2 of 2×2") and a 100 mm
/// bar to check the print scale.
pub fn a4_tiles(sheet: &Sheet) -> Vec<Tile> {
    let (tw, th) = (A4.0 - 2.0 * TILE_MARGIN, A4.1 - 2.0 * TILE_MARGIN);
    let count =
        |len: f64, t: f64| (((len - TILE_OVERLAP) / (t - TILE_OVERLAP)).ceil() as usize).max(1);
    let (cols, rows) = (count(sheet.width, tw), count(sheet.height, th));
    // The sheet's own drawing, without its outer element, to place in each tile.
    let full = sheet.svg();
    let inner = full
        .split_once('\n')
        .map_or("", |(_, rest)| rest)
        .trim_end()
        .trim_end_matches("</svg>");
    // Alignment crosses: in the middle of each overlap strip, at a few places along it.
    let mut crosses = Vec::new();
    for c in 1..cols {
        let x = c as f64 * (tw - TILE_OVERLAP) + TILE_OVERLAP / 2.0;
        for k in 1..=3 {
            crosses.push((x, sheet.height * k as f64 / 4.0));
        }
    }
    for r in 1..rows {
        let y = r as f64 * (th - TILE_OVERLAP) + TILE_OVERLAP / 2.0;
        for k in 1..=3 {
            crosses.push((sheet.width * k as f64 / 4.0, y));
        }
    }
    let mut tiles = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let (x0, y0) = (
                c as f64 * (tw - TILE_OVERLAP),
                r as f64 * (th - TILE_OVERLAP),
            );
            let (w, h) = (tw.min(sheet.width - x0), th.min(sheet.height - y0));
            let mut s = format!(
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{pw}mm\" height=\"{ph}mm\" viewBox=\"0 0 {pw} {ph}\">\n\
                 <defs><clipPath id=\"t\"><rect x=\"{x0}\" y=\"{y0}\" width=\"{w}\" height=\"{h}\"/></clipPath></defs>\n\
                 <g transform=\"translate({tx} {ty})\"><g clip-path=\"url(#t)\">\n{inner}\n",
                pw = A4.0,
                ph = A4.1,
                tx = TILE_MARGIN - x0,
                ty = TILE_MARGIN - y0,
            );
            for (x, y) in &crosses {
                if *x >= x0 && *x <= x0 + w && *y >= y0 && *y <= y0 + h {
                    s += &format!(
                        "<path d=\"M {} {y} H {} M {x} {} V {}\" stroke=\"black\" stroke-width=\"0.3\"/>\n",
                        x - 4.0,
                        x + 4.0,
                        y - 4.0,
                        y + 4.0
                    );
                }
            }
            s += "</g></g>\n";
            // Crop marks at the content's corners, outside it.
            let (l, t, rr, b) = (TILE_MARGIN, TILE_MARGIN, TILE_MARGIN + w, TILE_MARGIN + h);
            for (cx, cy, dx, dy) in [
                (l, t, -1.0, -1.0),
                (rr, t, 1.0, -1.0),
                (l, b, -1.0, 1.0),
                (rr, b, 1.0, 1.0),
            ] {
                s += &format!(
                    "<path d=\"M {cx} {} V {} M {} {cy} H {}\" stroke=\"black\" stroke-width=\"0.2\"/>\n",
                    cy + dy * 1.0,
                    cy + dy * 6.0,
                    cx + dx * 1.0,
                    cx + dx * 6.0
                );
            }
            s += &format!(
                "<text x=\"{TILE_MARGIN}\" y=\"6\" font-family=\"sans-serif\" font-size=\"3\">{} - tile {},{} of {rows}x{cols} (row, column): overlap the neighbours by {TILE_OVERLAP} mm so that the crosses meet - print at 100 %</text>\n\
                 <rect x=\"{}\" y=\"{}\" width=\"100\" height=\"1.5\" fill=\"black\"/>\n\
                 <text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"3\">measure this 100 mm bar</text>\n</svg>\n",
                sheet.title,
                r + 1,
                c + 1,
                A4.0 - TILE_MARGIN - 100.0,
                A4.1 - 6.0,
                A4.0 - TILE_MARGIN - 100.0,
                A4.1 - 1.5,
            );
            tiles.push(Tile {
                at: (r, c),
                of: (rows, cols),
                area: [x0, y0, w, h],
                svg: s,
            });
        }
    }
    tiles
}

/// The length of `(dx, dy)`, mm: a square root, not `hypot`'s call (sheet distances never come
/// near overflow, and the rig asks this for every dot at every sample of the disc).
fn apart(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}
