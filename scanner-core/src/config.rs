//! The fixed capacities of the head and the wire, in one place (smoltcp's way): every buffer of
//! the per-frame path and every size check refers to these.

/// Most lines (columns or rows) per frame the head handles: the stripe extractor's and the
/// pipeline's buffers are this long.
pub const MAX_LINES: usize = 4096;
/// Most bytes a point's coordinates take on the wire: three zigzag varints of at most 5 bytes.
pub const MAX_XYZ_BYTES_PER_POINT: usize = 15;
/// Bytes a point's colour takes on the wire.
pub const RGB_BYTES_PER_POINT: usize = 3;
/// Bytes a point's standard uncertainty takes on the wire.
pub const UNCERTAINTY_BYTES_PER_POINT: usize = 1;
/// Room for a message's fields besides its points (ids, time, plane, counts, lengths), bytes.
pub const MESSAGE_OVERHEAD: usize = 256;
/// Largest message before COBS, bytes: a frame of [`MAX_LINES`] points with colour and
/// uncertainty fits.
pub const MAX_FRAME: usize = MAX_LINES
    * (MAX_XYZ_BYTES_PER_POINT + RGB_BYTES_PER_POINT + UNCERTAINTY_BYTES_PER_POINT)
    + MESSAGE_OVERHEAD;
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
