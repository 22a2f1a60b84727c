//! The session header: image size, units, the calibration summary and the scan id. The head
//! repeats it, so that a host that joins late can decode.

use serde::{Deserialize, Serialize};

/// How the head finds each frame's laser plane (the pipeline's setting; the header says it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
#[repr(u8)]
pub enum PlaneMethod {
    /// Least squares over all of the stripe's board points, with outlier rejection (default).
    LeastSquares = 0,
    /// The paper's construction (lines MN and QR, crossings S and T).
    Paper = 1,
}
wire_enum!(PlaneMethod, LeastSquares = 0, Paper = 1);

/// The camera on the wire: its nine intrinsics as `f32`, in this order (the same bytes as
/// `[f32; 9]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraBlock {
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Radial distortion k1.
    pub k1: f32,
    /// Radial distortion k2.
    pub k2: f32,
    /// Tangential distortion p1.
    pub p1: f32,
    /// Tangential distortion p2.
    pub p2: f32,
    /// Radial distortion k3.
    pub k3: f32,
}

/// A board plane on the wire: unit normal and offset (mm), `n · x + d = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlaneBlock {
    /// Unit normal, toward the camera.
    pub normal: [f32; 3],
    /// Offset, mm.
    pub offset: f32,
}

/// The session header.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Scan id (random per scan): frames of different scans are not mixed.
    pub scan_id: u32,
    /// Image width, pixels.
    pub width: u16,
    /// Image height, pixels.
    pub height: u16,
    /// Length of one wire unit, micrometres (10: 0.01 mm).
    pub unit_um: u16,
    /// Camera intrinsics.
    pub camera: CameraBlock,
    /// Board planes, left and right.
    pub board: [PlaneBlock; 2],
    /// Whether points carry colour.
    pub colour: bool,
    /// How the laser plane is found.
    pub method: PlaneMethod,
}

impl Header {
    /// The header of a scan: its id, the image size, the calibration, whether points carry
    /// colour and how the laser plane is found; units of [`UNIT_MM`](crate::UNIT_MM).
    pub fn new(
        scan_id: u32,
        (width, height): (u16, u16),
        camera: CameraBlock,
        board: [PlaneBlock; 2],
        colour: bool,
        method: PlaneMethod,
    ) -> Header {
        Header {
            scan_id,
            width,
            height,
            unit_um: (crate::UNIT_MM * 1000.0) as u16,
            camera,
            board,
            colour,
            method,
        }
    }

    /// Length of one wire unit, mm.
    pub fn unit_mm(&self) -> f32 {
        f32::from(self.unit_um) / 1000.0
    }
}

#[cfg(test)]
mod golden_tests {
    use super::*;
    use crate::Message;

    /// Its frame byte for byte, its round trip, every shorter body refused.
    #[test]
    fn header_golden_frame() {
        crate::golden::check(
            Message::Header(Header {
                scan_id: 0xDEAD_BEEF,
                width: 1600,
                height: 1200,
                unit_um: 10,
                camera: CameraBlock {
                    fx: 1400.0,
                    fy: 1400.5,
                    cx: 799.5,
                    cy: 599.5,
                    k1: -0.06,
                    k2: 0.02,
                    p1: 0.0,
                    p2: 0.0,
                    k3: 0.0,
                },
                board: [
                    PlaneBlock {
                        normal: [0.7, 0.0, -0.7],
                        offset: 565.0,
                    },
                    PlaneBlock {
                        normal: [-0.7, 0.0, -0.7],
                        offset: 565.0,
                    },
                ],
                colour: true,
                method: PlaneMethod::Paper,
            }),
            &[
                0, 2, 2, 11, 239, 253, 182, 245, 13, 192, 12, 176, 9, 10, 1, 3, 175, 68, 4, 16,
                175, 68, 4, 224, 71, 68, 12, 224, 21, 68, 143, 194, 117, 189, 10, 215, 163, 60, 1,
                1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 5, 51, 51, 51, 63, 1, 1, 1, 5, 51, 51, 51, 191, 8,
                64, 13, 68, 51, 51, 51, 191, 1, 1, 1, 5, 51, 51, 51, 191, 10, 64, 13, 68, 1, 1,
                177, 167, 7, 153, 0,
            ],
        );
    }
}
