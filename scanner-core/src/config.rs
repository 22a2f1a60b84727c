//! The fixed capacities of the head, in one place (smoltcp's way): every buffer of
//! the per-frame path and every size check refers to these.

/// Most lines (columns or rows) per frame the head handles: the stripe extractor's and the
/// pipeline's buffers are this long. A frame's points travel in one message, so it is the wire's
/// [`MAX_POINTS`](scanner_wire::MAX_POINTS).
pub const MAX_LINES: usize = scanner_wire::MAX_POINTS;
/// Most markers (or corners) of one plane or view the pose and calibration fits take.
pub const MAX_MARKERS: usize = 256;

/// Smallest plausible focal length, in multiples of the image's longer side (a 157° view).
pub const MIN_FOCAL_PER_SIDE: f64 = 0.1;
/// Largest plausible focal length, in multiples of the image's longer side (a 1.1° view).
pub const MAX_FOCAL_PER_SIDE: f64 = 50.0;
/// Largest plausible radial distortion coefficient, by magnitude.
pub const MAX_RADIAL: f64 = 100.0;
/// Largest plausible tangential distortion coefficient, by magnitude.
pub const MAX_TANGENTIAL: f64 = 1.0;
/// Largest plausible distance of a board plane from the camera, mm.
pub const MAX_PLANE_OFFSET_MM: f64 = 100_000.0;
