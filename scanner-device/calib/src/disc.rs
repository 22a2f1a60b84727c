//! The turntable disc: printed, cut out and laid under the object, it turns with the object, and
//! its rim markers give its pose in every sweep's laser-off reference frame. The merge then
//! knows how far the object was turned between sweeps from the disc, not from the object's
//! shape (a vase or a cylinder has none to give).
//!
//! The disc (radius `R`, [`Disc::new`]) carries three rings of 24 dark dots at the same 24
//! angles: the outer ring has all 24; the two inner rings have a dot where their code says so
//! ([`CODE`]). Under any turn of the disc by a whole step, at least four dots move to where the
//! print has none in every half of the rim (180°, `disc_code_tells_every_half` checks it), so a
//! disc with half its rim hidden by the object is still identified with a margin of four dots
//! over any other turn; a match whose margin is under [`MIN_MARGIN`] is refused as ambiguous.
//! Also printed: the cut line, a centre cross and a 100 mm scale bar under the object, and
//! the sheet's 100 mm ruler.
//!
//! Disc coordinates (mm): origin at the centre, `u` to the right of the print, `v` down it; the
//! third axis `u × v` points into the table. Dot `j` of each ring lies at angle `2πj/24` from `u`
//! towards `v`.

use image::GrayImage;
use scanner_core::Camera;
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Matrix3, Point2, Vector3};

use crate::CalibError;
use crate::detect::{DetectConfig, find_markers};
use crate::fit::{Prune, fit_sheet, undistorted};
use crate::identify::{Assignment, Orientation, candidates};
use crate::print::Sheet;

/// Dots per ring.
pub const POSITIONS: usize = 24;

/// The two inner rings' codes, position 0 first: `1` a dot.
pub const CODE: [&str; 2] = ["001001010010001101011101", "010111110001001010110000"];

/// Ring radii as fractions of the disc's radius: outer, first and second code ring.
const RINGS: [f64; 3] = [0.905, 0.76, 0.615];

/// Dot diameter as a fraction of the disc's radius.
const DOT: f64 = 0.075;

/// Fewest markers a disc's pose is taken from.
pub const MIN_MARKERS: usize = 12;

/// Least margin, in matched dots, of the disc's identification over any other turn of it.
pub const MIN_MARGIN: usize = 2;

/// The paper a disc is printed on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Paper {
    /// 210 × 297 mm: a disc of 190 mm.
    A4,
    /// 297 × 420 mm: a disc of 277 mm.
    A3,
}

impl Paper {
    /// Width and height, portrait, mm.
    pub fn size(self) -> (f64, f64) {
        match self {
            Paper::A4 => (210.0, 297.0),
            Paper::A3 => (297.0, 420.0),
        }
    }

    /// The name as an option takes it: `a4` or `a3`.
    pub fn name(self) -> &'static str {
        match self {
            Paper::A4 => "a4",
            Paper::A3 => "a3",
        }
    }
}

/// A paper name that is neither `a4` nor `a3` (at most 40 characters of it).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("expected a4 or a3, found {0:?}")]
pub struct UnknownPaper(pub String);

impl std::str::FromStr for Paper {
    type Err = UnknownPaper;
    fn from_str(s: &str) -> Result<Paper, UnknownPaper> {
        match s.to_ascii_lowercase().as_str() {
            "a4" => Ok(Paper::A4),
            "a3" => Ok(Paper::A3),
            _ => Err(UnknownPaper(s.chars().take(40).collect())),
        }
    }
}

/// A turntable disc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disc {
    /// The paper it is printed on.
    pub paper: Paper,
    /// Its radius (the cut line), mm: the paper's width less 20 mm, halved.
    pub radius: f64,
}

impl Disc {
    /// The disc printed on `paper`.
    pub fn new(paper: Paper) -> Disc {
        let (w, _) = paper.size();
        Disc {
            paper,
            radius: (w - 20.0) / 2.0,
        }
    }

    /// Dot diameter, mm.
    pub fn dot(&self) -> f64 {
        DOT * self.radius
    }

    /// The radius inside which nothing is printed but the centre cross and the scale bar: where
    /// the object stands, mm.
    pub fn free_radius(&self) -> f64 {
        (RINGS[2] - DOT) * self.radius
    }

    /// Every dot's centre, disc mm: the outer ring's 24, then the first code ring's, then the
    /// second's (each ring from position 0).
    pub fn layout(&self) -> Vec<Point2<f64>> {
        let mut out = Vec::new();
        for (ring, r) in RINGS.iter().enumerate() {
            for j in 0..POSITIONS {
                if ring > 0 && CODE[ring - 1].as_bytes()[j] != b'1' {
                    continue;
                }
                let a = std::f64::consts::TAU * j as f64 / POSITIONS as f64;
                out.push(Point2::new(
                    r * self.radius * a.cos(),
                    r * self.radius * a.sin(),
                ));
            }
        }
        out
    }

    /// The printable sheet: the disc centred on the paper.
    pub fn sheet(&self) -> Sheet {
        let (w, h) = self.paper.size();
        let (cx, cy) = (w / 2.0, h / 2.0);
        let dot = self.dot();
        let dots = self
            .layout()
            .iter()
            .map(|p| (cx + p.x, cy + p.y, dot))
            .collect();
        // The scale bar (100 mm, 1 mm thick, ticks every 10 mm) a little below the centre,
        // and the centre cross.
        let yb = cy + 0.1 * self.radius;
        let mut bars = vec![[cx - 50.0, yb, cx + 50.0, yb + 1.0]];
        for i in 0..=10 {
            let x = cx - 50.0 + 10.0 * f64::from(i);
            let len = if i % 5 == 0 { 4.0 } else { 2.5 };
            bars.push([x - 0.3, yb - len, x + 0.3, yb]);
        }
        bars.push([cx - 5.0, cy - 0.4, cx + 5.0, cy + 0.4]);
        bars.push([cx - 0.4, cy - 5.0, cx + 0.4, cy + 5.0]);
        Sheet {
            title: format!(
                "turntable disc {} - {} mm - cut along the circle, lay the object on the cross - print at 100 %",
                self.paper.name().to_uppercase(),
                2.0 * self.radius
            ),
            width: w,
            height: h,
            dots,
            bars,
            circles: vec![(cx, cy, 2.0 * self.radius, 0.4)],
            ..Sheet::default()
        }
    }

    /// Where the sheet's point `(x, y)` (mm from its top-left corner) lies on the disc, disc mm.
    pub fn from_sheet(&self, x: f64, y: f64) -> Point2<f64> {
        let (w, h) = self.paper.size();
        Point2::new(x - w / 2.0, y - h / 2.0)
    }

    /// The sheet's point `(x, y)` of the disc point `p`.
    pub fn to_sheet(&self, p: &Point2<f64>) -> (f64, f64) {
        let (w, h) = self.paper.size();
        (p.x + w / 2.0, p.y + h / 2.0)
    }
}

/// The disc as found in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscFit {
    /// Disc → camera.
    pub pose: Pose,
    /// Dots used in the fit.
    pub used: usize,
    /// Dots printed.
    pub of: usize,
    /// RMS reprojection error of the used dots, pixels.
    pub rms_px: f64,
    /// Matched dots of the identification over those of the best other turn of the disc.
    pub margin: usize,
}

impl DiscFit {
    /// The disc's third axis (`u × v`, into the table) in camera coordinates.
    pub fn normal(&self) -> Vector3<f64> {
        self.pose.rotation * Vector3::z()
    }

    /// Angle between the disc's axis and the line of sight to its centre, degrees (0: seen
    /// from straight above).
    pub fn tilt_deg(&self) -> f64 {
        let sight = self.pose.translation.normalize();
        self.normal()
            .dot(&sight)
            .abs()
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }
}

/// Most tilted a disc may be seen and still give its pose, degrees between its axis and the line
/// of sight (its dots are then ellipses a sixth as wide as long).
pub const MAX_TILT_DEG: f64 = 80.0;

/// Why no disc pose was taken from an image.
#[derive(Debug, Clone, PartialEq)]
pub enum DiscMiss {
    /// Fewer than [`MIN_MARKERS`] of its dots were identified (none in view, or hidden).
    TooFewMarkers {
        /// Dots identified.
        found: usize,
        /// Dots printed.
        of: usize,
    },
    /// Two turns of the disc fit its visible dots nearly as well.
    Ambiguous {
        /// Dots matched by the best turn.
        best: usize,
        /// By the next.
        other: usize,
    },
    /// The disc is seen too nearly edge-on.
    Tilted {
        /// Its tilt, degrees.
        tilt_deg: f64,
    },
    /// The identified dots do not fit one pose of the disc.
    PoorFit(CalibError),
}

impl std::fmt::Display for DiscMiss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DiscMiss::TooFewMarkers { found, of } => write!(
                f,
                "{found} of its {of} dots found (at least {MIN_MARKERS} needed): is the disc in view, lit, and not mostly hidden by the object?"
            ),
            DiscMiss::Ambiguous { best, other } => write!(
                f,
                "two turns of the disc fit its dots ({best} and {other} dots): show more of its rim"
            ),
            DiscMiss::Tilted { tilt_deg } => write!(
                f,
                "seen {tilt_deg:.0}° from above (at most {MAX_TILT_DEG}°): raise the camera or tilt it down"
            ),
            DiscMiss::PoorFit(e) => write!(f, "its dots fit no pose: {e}"),
        }
    }
}

/// Finds `disc` in `img` (laser off) seen by `camera`: its dots detected; the outer ring (all
/// 24 dots, the same under every turn) identified, which fixes the disc's image up to a turn;
/// then each of the 24 turns scored by the code rings' dots it finds where it predicts them;
/// the pose fitted with the camera's distortion from the best turn's dots.
///
/// # Errors
/// [`DiscMiss`] with the reason: too few dots, two turns that fit nearly as well, a disc seen
/// edge-on, or dots that fit no pose.
pub fn find_disc(img: &GrayImage, disc: &Disc, camera: &Camera<f64>) -> Result<DiscFit, DiscMiss> {
    let layout = disc.layout();
    let blobs = find_markers(img, &DetectConfig::default()).blobs;
    let features = undistorted(&blobs, camera);
    let orient = Orientation {
        mirrored: false,
        u_along_x: None,
    };
    let too_few = |found| DiscMiss::TooFewMarkers {
        found,
        of: layout.len(),
    };
    // Other dots in the picture (the board's markers, a printed page) can make another ring
    // match first, or crowd the true one: each of the best few rings is tried, with only the
    // dots of its own size, and the one whose best turn matches most dots is taken.
    let rings = candidates(&features, &[], &layout[..POSITIONS], None, orient);
    let mut best: Option<(Assignment, usize)> = None;
    for ring in rings.iter().take(RING_TRIES) {
        let alike = of_ring_size(&features, ring);
        // Every turn of the whole layout through the ring's homography, its dots matched.
        let mut turns: Vec<Assignment> = (0..POSITIONS)
            .map(|k| turned(&features, &alike, &layout, &ring.homography, k, disc.radius))
            .collect();
        turns.sort_by(|a, b| {
            b.matched()
                .cmp(&a.matched())
                .then(a.rms_px.total_cmp(&b.rms_px))
        });
        let other = turns[1].matched();
        let top = turns.swap_remove(0);
        if best
            .as_ref()
            .is_none_or(|(b, _)| top.matched() > b.matched())
        {
            best = Some((top, other));
        }
    }
    let Some((best, other)) = best else {
        return Err(too_few(0));
    };
    let best = &best;
    if best.matched() < MIN_MARKERS {
        return Err(too_few(best.matched()));
    }
    if other + MIN_MARGIN > best.matched() {
        return Err(DiscMiss::Ambiguous {
            best: best.matched(),
            other,
        });
    }
    let fit = fit_sheet(
        "turntable disc",
        camera,
        &layout,
        &blobs,
        best,
        disc.dot() / 2.0,
        Prune::Predicted,
        None,
        crate::fit::MAX_FIT_RMS_PX,
    )
    .map_err(DiscMiss::PoorFit)?;
    let found = DiscFit {
        pose: fit.pose,
        used: fit.used(),
        of: layout.len(),
        rms_px: fit.rms_px,
        margin: best.matched() - other,
    };
    if found.used < MIN_MARKERS {
        return Err(too_few(found.used));
    }
    if found.tilt_deg() > MAX_TILT_DEG {
        return Err(DiscMiss::Tilted {
            tilt_deg: found.tilt_deg(),
        });
    }
    Ok(found)
}

/// Ring candidates [`find_disc`] tries, best first.
const RING_TRIES: usize = 4;

/// Which features are dots of a ring's size: an area within a factor [`DOT_AREA_RATIO`] of the
/// median of the ring's matched dots (the disc's dots differ less than that between its near and
/// far side at any tilt it is accepted at; a board's markers are several times larger).
fn of_ring_size(features: &[crate::detect::Blob], ring: &Assignment) -> Vec<bool> {
    let mut areas: Vec<f64> = ring
        .blob_of
        .iter()
        .flatten()
        .map(|&b| features[b].area)
        .collect();
    areas.sort_by(f64::total_cmp);
    let Some(&median) = areas.get(areas.len() / 2) else {
        return vec![true; features.len()];
    };
    features
        .iter()
        .map(|f| f.area <= median * DOT_AREA_RATIO && f.area * DOT_AREA_RATIO >= median)
        .collect()
}

/// See [`of_ring_size`].
const DOT_AREA_RATIO: f64 = 3.0;

/// The layout turned by `k` steps and mapped by `h` (disc mm → undistorted pixels), each dot
/// matched to the nearest feature (of those `alike`) within a third of the rings' spacing there.
fn turned(
    features: &[crate::detect::Blob],
    alike: &[bool],
    layout: &[Point2<f64>],
    h: &Matrix3<f64>,
    k: usize,
    radius: f64,
) -> Assignment {
    let a = std::f64::consts::TAU * k as f64 / POSITIONS as f64;
    let turn = Matrix3::new(a.cos(), -a.sin(), 0.0, a.sin(), a.cos(), 0.0, 0.0, 0.0, 1.0);
    let hk = h * turn;
    let map = |p: &Point2<f64>| {
        let q = hk * Vector3::new(p.x, p.y, 1.0);
        (q.z.abs() > 1e-12).then(|| Point2::new(q.x / q.z, q.y / q.z))
    };
    let gap = (RINGS[0] - RINGS[1]) * radius;
    let mut used = vec![false; features.len()];
    let (mut blob_of, mut ss, mut n) = (vec![None; layout.len()], 0.0, 0usize);
    for (i, p) in layout.iter().enumerate() {
        let inward = p - p.coords.normalize() * gap;
        let (Some(c), Some(d)) = (map(p), map(&inward)) else {
            continue;
        };
        let tol = 0.35 * (c - d).norm();
        let near = features
            .iter()
            .enumerate()
            .filter(|(b, _)| !used[*b] && alike[*b])
            .map(|(b, f)| (b, (f.centre - c).norm()))
            .filter(|&(_, dist)| dist <= tol)
            .min_by(|x, y| x.1.total_cmp(&y.1));
        if let Some((b, dist)) = near {
            used[b] = true;
            blob_of[i] = Some(b);
            ss += dist * dist;
            n += 1;
        }
    }
    Assignment {
        blob_of,
        homography: hk,
        rms_px: if n > 0 { (ss / n as f64).sqrt() } else { 0.0 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dots of the code rings at `s..s+w` (positions, cyclic) that a turn by `k` positions
    /// moves to where the print has none.
    fn lost(s: usize, w: usize, k: usize) -> usize {
        let bit = |ring: usize, j: usize| CODE[ring].as_bytes()[j % POSITIONS] == b'1';
        (0..w)
            .map(|i| {
                let m = s + i;
                (0..2)
                    .filter(|&r| bit(r, m) && !bit(r, m + POSITIONS - k))
                    .count()
            })
            .sum()
    }

    #[test]
    fn disc_code_tells_every_half() {
        for s in 0..POSITIONS {
            for k in 1..POSITIONS {
                assert!(lost(s, POSITIONS / 2, k) >= 4, "start {s}, turn {k}");
            }
        }
    }

    #[test]
    fn layout_and_sheet_agree() {
        for paper in [Paper::A4, Paper::A3] {
            let d = Disc::new(paper);
            let l = d.layout();
            let ones: usize = CODE.iter().map(|c| c.matches('1').count()).sum();
            assert_eq!(l.len(), POSITIONS + ones);
            let s = d.sheet();
            assert_eq!(s.dots.len(), l.len());
            // every dot inside the cut line, none in the object's free middle
            for p in &l {
                assert!(p.coords.norm() + d.dot() / 2.0 < d.radius);
                assert!(p.coords.norm() - d.dot() / 2.0 > d.free_radius());
                let (x, y) = d.to_sheet(p);
                assert!((d.from_sheet(x, y) - p).norm() < 1e-12);
            }
            // the scale bar is 100 mm and lies in the free middle
            let bar = s.bars[0];
            assert_eq!(bar[2] - bar[0], 100.0);
            let far = d.from_sheet(bar[0], bar[3]);
            assert!(far.coords.norm() < d.free_radius());
        }
    }
}
