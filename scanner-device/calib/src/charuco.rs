//! The inner corners of a ChArUco board in a gray image, named by the markers around them
//! ([`find_charuco`]).
//!
//! 1. The board's markers among the picture's quads ([`crate::aruco`]); a marker that the
//!    others place elsewhere (a misread code, another board's marker of the same ID) is left
//!    out.
//! 2. Each inner corner touches two light squares: from the markers found in its four squares
//!    (one is enough), a homography predicts where it is.
//! 3. The corner is refined as a chessboard corner (gradients orthogonal, as OpenCV's
//!    `cornerSubPix`) in a window that stays clear of the markers' own corners.
//!
//! A partial view counts: every corner with a marker beside it is named and found.

use image::GrayImage;
use scanner_core::geometry::pose::homography;
use scanner_core::nalgebra::{Point2, Vector2};

use crate::aruco::{ArucoFound, CharucoBoard, Marker, Quad, apply, find_aruco};
use crate::corners::refine;

/// The largest half side of a corner's refinement window, pixels (OpenCV's 10).
const MAX_WINDOW: i64 = 10;
/// The smallest, pixels.
const MIN_WINDOW: i64 = 2;
/// The refinement's Gaussian σ as a share of the window's half side: OpenCV's `cornerSubPix`
/// weights (on rendered ChArUco shots, mean error 0.057 px and worst 0.35 px, where half the
/// half side gave 0.065 px and 0.70 px).
const SPREAD: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// A marker whose centre the board's other markers place farther than this share of a square
/// away is left out.
const MARKER_MISPLACED: f64 = 0.35;

/// The corners found on one board.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CharucoCorners {
    /// Inner corners found: index on the board (OpenCV's numbering) and pixel.
    pub corners: Vec<(usize, Point2<f64>)>,
    /// The board's markers in the picture (only IDs of this board).
    pub markers: ArucoFound,
    /// Markers of this board left out because the others place them elsewhere.
    pub misplaced: Vec<usize>,
}

/// The inner corners of `board` among the quads of a picture ([`crate::aruco::quads`]).
pub fn find_charuco(img: &GrayImage, quads: &[Quad], board: &CharucoBoard) -> CharucoCorners {
    let mut markers = find_aruco(img, quads, &board.dictionary);
    let ids = board.ids();
    markers.markers.retain(|m| ids.contains(&m.id));
    markers.repeated.retain(|id| ids.contains(id));
    let misplaced = drop_misplaced(&mut markers.markers, board);
    let by_square = |x: usize, y: usize| -> Option<&Marker> {
        let id = board.marker_in(x, y)?;
        markers.markers.iter().find(|m| m.id == id)
    };
    let mut corners = Vec::new();
    for k in 0..board.corner_count() {
        let (gx, gy) = (
            k % board.corners_per_row() + 1,
            k / board.corners_per_row() + 1,
        );
        let around: Vec<&Marker> = [(gx - 1, gy - 1), (gx, gy - 1), (gx - 1, gy), (gx, gy)]
            .iter()
            .filter_map(|&(x, y)| by_square(x, y))
            .collect();
        if let Some(p) = corner_near(img, board, k, &around) {
            corners.push((k, p));
        }
    }
    CharucoCorners {
        corners,
        markers,
        misplaced,
    }
}

/// Inner corner `k` from the markers `around` it: predicted by their homography, refined.
fn corner_near(
    img: &GrayImage,
    board: &CharucoBoard,
    k: usize,
    around: &[&Marker],
) -> Option<Point2<f64>> {
    if around.is_empty() {
        return None;
    }
    let mut layout = Vec::new();
    let mut pixels = Vec::new();
    for m in around {
        let on_board = board.marker_corners(m.id)?;
        layout.extend_from_slice(&on_board);
        pixels.extend(m.corners.iter().map(|c| c.coords));
    }
    let hm = homography(&layout, &pixels).ok()?;
    let at = board.corner(k);
    let p = apply(&hm, at.x, at.y)?;
    // Short of the markers' corners by 2 px, as OpenCV's ChArUco detector keeps it.
    let near = pixels
        .iter()
        .map(|c: &Vector2<f64>| (c - p.coords).norm())
        .fold(f64::INFINITY, f64::min);
    let win = ((near - 2.0).floor() as i64).clamp(MIN_WINDOW, MAX_WINDOW);
    // The markers' pixels, grown by the blur, are left out of the window: their edges are no
    // part of the corner.
    let grown: Vec<[Point2<f64>; 4]> = around
        .iter()
        .map(|m| grow(&m.corners, MARKER_GROWTH_PX))
        .collect();
    let keep = |x: Point2<f64>| !grown.iter().any(|q| inside(q, x));
    let q = refine(img, p, (win, SPREAD), keep)?;
    ((q - p).norm() <= win as f64 / 2.0 + 1.0).then_some(q)
}

/// How far past a marker's found outline its pixels are left out of a corner's refinement,
/// pixels: the lens blur and the outline's own error.
const MARKER_GROWTH_PX: f64 = 1.5;

/// A convex quad grown outward by `d` pixels (each corner pushed out along its diagonal).
fn grow(q: &[Point2<f64>; 4], d: f64) -> [Point2<f64>; 4] {
    let c = Point2::from(q.iter().map(|p| p.coords).sum::<Vector2<f64>>() / 4.0);
    q.map(|p| {
        let out = p - c;
        p + out * (d * std::f64::consts::SQRT_2 / out.norm().max(1e-9))
    })
}

/// Whether `x` lies inside a convex quad (either winding).
fn inside(q: &[Point2<f64>; 4], x: Point2<f64>) -> bool {
    let side = |k: usize| {
        let (a, b) = (q[k], q[(k + 1) % 4]);
        (b.x - a.x) * (x.y - a.y) - (b.y - a.y) * (x.x - a.x)
    };
    let s: [f64; 4] = [side(0), side(1), side(2), side(3)];
    s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
}

/// Leaves out markers whose centre the board's other markers (one homography, which lens
/// distortion bends but not by a third of a square) place elsewhere, worst first; their IDs.
fn drop_misplaced(markers: &mut Vec<Marker>, board: &CharucoBoard) -> Vec<usize> {
    let mut out = Vec::new();
    while markers.len() >= 3 {
        let mut worst: Option<(usize, f64)> = None;
        for i in 0..markers.len() {
            let (mut layout, mut pixels) = (Vec::new(), Vec::new());
            for (j, m) in markers.iter().enumerate() {
                if j == i {
                    continue;
                }
                if let Some(c) = board.marker_corners(m.id) {
                    layout.extend_from_slice(&c);
                    pixels.extend(m.corners.iter().map(|c| c.coords));
                }
            }
            let Ok(hm) = homography(&layout, &pixels) else {
                continue;
            };
            let Some(c) = board.marker_corners(markers[i].id) else {
                continue;
            };
            let centre = Point2::from(c.iter().map(|p| p.coords).sum::<Vector2<f64>>() / 4.0);
            let Some(p) = apply(&hm, centre.x, centre.y) else {
                continue;
            };
            // The square's side in pixels there: the marker's side scaled up.
            let square_px = markers[i].side() * board.square / board.marker;
            let miss = (p - markers[i].centre()).norm() / square_px;
            if worst.is_none_or(|w| miss > w.1) {
                worst = Some((i, miss));
            }
        }
        match worst {
            Some((i, miss)) if miss > MARKER_MISPLACED => out.push(markers.remove(i).id),
            _ => break,
        }
    }
    out
}
