//! A turntable's angle at each frame from ArUco markers printed on its platform's top: no step
//! count needed, and a motor that lost steps or a belt that jumped is seen, not built into the
//! model.
//!
//! Each marker's corners are found in the frame ([`scanner_calib::aruco`]) and carried along
//! their rays onto the platform's top (its calibrated plane). A marker fixed to the platform
//! lies at `Rz(θ)·m` there, `m` where it lay at turn 0: the frame's turn `θ` is the rotation
//! about the axis that best carries the known markers' corners at turn 0 onto where they are
//! now (least squares over all of them), unwrapped to continue the last frame's. The first
//! frame is turn 0 by definition; a marker first seen later joins at the place its corners
//! give turned back by that frame's turn, and each marker's place at turn 0 is the mean of all
//! its sightings so far.

use std::collections::BTreeMap;

use scanner_calib::aruco::{Dictionary, find_aruco, quads};
use scanner_core::Camera;
use scanner_core::geometry::Platform;
use scanner_core::nalgebra::Point2;

/// A frame's turn farther than this from a steady turn through all the frames is reported,
/// degrees: a motor's lost steps (1.8° for a full step of a common stepper), not the markers'
/// own noise.
pub const UNSTEADY_DEG: f64 = 0.5;

/// The markers and the platform they are printed on, for [`MarkerTurns`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerPlatform {
    /// The markers' dictionary.
    pub dictionary: Dictionary,
    /// The platform (its top is the plane the markers lie on).
    pub platform: Platform<f64>,
}

/// The picture a frame's markers are read in: the channel a laser of `colour` lights least
/// (green for a red laser, red for a green or blue one; luma for a white or unknown one), so
/// that the line crossing a marker does not lighten its dark cells. `None` for a buffer that
/// does not match its size.
pub fn marker_picture(
    frame: &crate::source::OwnedFrame,
    colour: scanner_core::stripe::LaserColour,
) -> Option<image::GrayImage> {
    use scanner_core::colour::yuv_to_rgb;
    use scanner_core::stripe::{LaserColour, PixelFormat};
    let channel = match colour {
        LaserColour::Red => 1,
        LaserColour::Green | LaserColour::Blue => 0,
        LaserColour::White => return frame.luma(),
    };
    let data: Vec<u8> = match frame.format {
        PixelFormat::Gray8 => return frame.luma(),
        PixelFormat::Rgb24 => frame.data.chunks_exact(3).map(|p| p[channel]).collect(),
        PixelFormat::Yuyv => frame
            .data
            .chunks_exact(4)
            .flat_map(|q| {
                let (u, v) = (q[1], q[3]);
                [
                    yuv_to_rgb(q[0], u, v)[channel],
                    yuv_to_rgb(q[2], u, v)[channel],
                ]
            })
            .collect(),
    };
    image::GrayImage::from_raw(frame.width as u32, frame.height as u32, data)
}

/// A frame's turn as its markers gave it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnSeen {
    /// The frame, from 0.
    pub frame: u32,
    /// Its turn from the first frame, radians, counter-clockwise seen from above (unwrapped:
    /// past a whole turn it goes on past 2π).
    pub angle: f64,
    /// Markers it was measured with.
    pub markers: usize,
}

/// The turns of a scan's frames so far, and each marker's place at turn 0.
#[derive(Debug, Clone)]
pub struct MarkerTurns {
    spec: MarkerPlatform,
    camera: Camera<f64>,
    /// Each marker's corners on the top at turn 0 (a running mean) and its sightings.
    known: BTreeMap<usize, ([Point2<f64>; 4], u32)>,
    turns: Vec<TurnSeen>,
    /// Frames looked at that gave no turn (no known marker read).
    missed: Vec<u32>,
}

impl MarkerTurns {
    /// No frame seen yet.
    pub fn new(spec: MarkerPlatform, camera: Camera<f64>) -> MarkerTurns {
        MarkerTurns {
            spec,
            camera,
            known: BTreeMap::new(),
            turns: Vec::new(),
            missed: Vec::new(),
        }
    }

    /// Frame `frame`'s turn from the markers its luma `picture` shows, radians (see
    /// [`TurnSeen::angle`]); `None` when it shows none of the markers seen before (or, for the
    /// first frame with markers, none at all).
    pub fn observe(&mut self, frame: u32, picture: &image::GrayImage) -> Option<f64> {
        let found = find_aruco(
            picture,
            &quads(picture, scanner_calib::aruco::MIN_QUAD_SIDE_PX),
            &self.spec.dictionary,
        );
        let on_top: Vec<(usize, [Point2<f64>; 4])> = found
            .markers
            .iter()
            .filter_map(|m| {
                let mut c = [Point2::origin(); 4];
                for (k, px) in m.corners.iter().enumerate() {
                    c[k] = self.on_top(px)?;
                }
                Some((m.id, c))
            })
            .collect();
        let angle = match self.turns.last() {
            None if !on_top.is_empty() => Some(0.0),
            None => None,
            Some(last) => self
                .turn_of(&on_top)
                .map(|a| last.angle + wrap(a - last.angle)),
        };
        let Some(angle) = angle else {
            self.missed.push(frame);
            return None;
        };
        // a marker seen for the first time joins at its place turned back
        let (s, c) = ((-angle).sin(), (-angle).cos());
        let back = |p: &Point2<f64>| Point2::new(c * p.x - s * p.y, s * p.x + c * p.y);
        for (id, corners) in &on_top {
            self.known
                .entry(*id)
                .or_insert_with(|| (corners.map(|p| back(&p)), 0))
                .1 += 1;
        }
        self.turns.push(TurnSeen {
            frame,
            angle,
            markers: on_top.len(),
        });
        Some(angle)
    }

    /// Where the ray through pixel `px` meets the platform's top, in the platform's frame.
    fn on_top(&self, px: &Point2<f64>) -> Option<Point2<f64>> {
        let ray = self.camera.pixel_to_ray(px).ok()?;
        let (r, o) = (self.spec.platform.rotation(), self.spec.platform.origin());
        let up = r.column(2);
        let t = up.dot(&o.coords) / up.dot(&ray);
        if !(t.is_finite() && t > 0.0) {
            return None;
        }
        let q = r.transpose() * (ray * t - o.coords);
        Some(Point2::new(q.x, q.y))
    }

    /// The turn in `(−π, π]` that best carries the known markers' corners at turn 0 onto
    /// `seen` (least squares about the axis); `None` when no known marker is among them.
    fn turn_of(&self, seen: &[(usize, [Point2<f64>; 4])]) -> Option<f64> {
        let (mut cross, mut dot, mut n) = (0.0, 0.0, 0);
        for (id, corners) in seen {
            let Some((at0, _)) = self.known.get(id) else {
                continue;
            };
            let mean = |c: &[Point2<f64>; 4]| {
                Point2::from(
                    c.iter()
                        .map(|p| p.coords)
                        .sum::<scanner_core::nalgebra::Vector2<f64>>()
                        / 4.0,
                )
            };
            let (a, b) = (mean(at0), mean(corners));
            cross += a.x * b.y - a.y * b.x;
            dot += a.coords.dot(&b.coords);
            n += 1;
        }
        (n > 0).then(|| cross.atan2(dot))
    }

    /// The frames' turns so far, in order.
    pub fn turns(&self) -> &[TurnSeen] {
        &self.turns
    }

    /// What the markers gave: the steady turn per frame and the frames that turned otherwise.
    pub fn summary(&self) -> MarkerSummary {
        let step = median_step(&self.turns);
        let unsteady = step
            .map(|step| {
                self.turns
                    .windows(2)
                    .map(|w| {
                        let frames = f64::from(w[1].frame - w[0].frame);
                        (
                            w[1].frame,
                            (w[1].angle - w[0].angle - step * frames).to_degrees(),
                        )
                    })
                    .filter(|(_, d)| d.abs() > UNSTEADY_DEG)
                    .collect()
            })
            .unwrap_or_default();
        MarkerSummary {
            frames: self.turns.len(),
            missed: self.missed.clone(),
            markers: self.known.keys().copied().collect(),
            step_deg: step.map(f64::to_degrees),
            unsteady,
        }
    }
}

/// What a scan's markers gave, for its report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MarkerSummary {
    /// Frames whose turn the markers gave.
    pub frames: usize,
    /// Frames whose turn they did not give (no known marker read): their points carry no turn.
    pub missed: Vec<u32>,
    /// The markers' IDs seen.
    pub markers: Vec<usize>,
    /// The platform's steady turn per frame: the median of the frames' own, degrees.
    pub step_deg: Option<f64>,
    /// Frames that turned farther than [`UNSTEADY_DEG`] from the steady turn since the frame
    /// before (a slip, a stall), and by how much more, degrees.
    pub unsteady: Vec<(u32, f64)>,
}

/// The median of the frames' turns per frame (each from the frame measured before), radians;
/// `None` for fewer than two frames.
fn median_step(turns: &[TurnSeen]) -> Option<f64> {
    let mut steps: Vec<f64> = turns
        .windows(2)
        .filter(|w| w[1].frame > w[0].frame)
        .map(|w| (w[1].angle - w[0].angle) / f64::from(w[1].frame - w[0].frame))
        .collect();
    if steps.is_empty() {
        return None;
    }
    let mid = steps.len() / 2;
    Some(*steps.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// `a` wrapped into `(−π, π]`.
fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let w = a.rem_euclid(t);
    if w > std::f64::consts::PI { w - t } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn turn(frame: u32, deg: f64) -> TurnSeen {
        TurnSeen {
            frame,
            angle: deg.to_radians(),
            markers: 2,
        }
    }

    #[test]
    fn the_steady_turn_is_the_median_step_and_a_slip_is_reported_at_its_frame() {
        // 3.6° a frame; from frame 40 on, 1.8° further (a lost full step)
        let turns: Vec<TurnSeen> = (0..100)
            .map(|k| turn(k, 3.6 * f64::from(k) + if k >= 40 { 1.8 } else { 0.0 }))
            .collect();
        let step = median_step(&turns).unwrap();
        assert!(
            (step.to_degrees() - 3.6).abs() < 1e-9,
            "{}",
            step.to_degrees()
        );
        let mut m = MarkerTurns::new(
            MarkerPlatform {
                dictionary: Dictionary::named("DICT_4X4_50").unwrap(),
                platform: Platform::new(
                    scanner_core::nalgebra::Matrix3::identity(),
                    scanner_core::nalgebra::Point3::new(0.0, 0.0, 300.0),
                )
                .unwrap(),
            },
            Camera::new(500.0, 500.0, 320.0, 240.0, scanner_core::Distortion::none()).unwrap(),
        );
        m.turns = turns;
        let s = m.summary();
        // frame 40 turned 1.8° more than the others
        assert_eq!(s.unsteady.len(), 1, "{s:?}");
        assert_eq!(s.unsteady[0].0, 40);
        assert!((s.unsteady[0].1 - 1.8).abs() < 1e-6);
        assert_eq!(s.frames, 100);
    }

    #[test]
    fn turns_wrap_into_a_half_turn_either_way() {
        for (a, w) in [
            (0.0, 0.0),
            (3.5, 3.5 - std::f64::consts::TAU),
            (-3.5, -3.5 + std::f64::consts::TAU),
            (7.0, 7.0 - std::f64::consts::TAU),
        ] {
            assert!((wrap(a) - w).abs() < 1e-12, "{a}: {}", wrap(a));
        }
    }
}
