//! The paper's two-position procedure (eq. 7–9): the image distance from two images of the
//! cross pattern ([`image_distance`]).

use image::GrayImage;
use scanner_core::calib::{CrossShot, ImageDistance};
use scanner_core::nalgebra::Point2;

use crate::detect::{DetectConfig, find_markers};
use crate::identify::{Orientation, identify};

use crate::error::{CalibError, geom};

/// The arm's image length `(|A'E'| + |B'D'|) / 2` of the cross pattern in an image, pixels.
///
/// # Errors
/// [`CalibError::NoMarkers`] or [`CalibError::TooFewMarkers`] when the five dots are not all
/// found.
pub fn cross_span(img: &GrayImage, cross: &crate::board::Cross) -> Result<f64, CalibError> {
    let a = cross.arm / 2.0;
    // A, B, C, D, E
    let layout = [
        Point2::new(0.0, -a),
        Point2::new(-a, 0.0),
        Point2::new(0.0, 0.0),
        Point2::new(a, 0.0),
        Point2::new(0.0, a),
    ];
    let det = find_markers(img, &DetectConfig::default());
    if det.blobs.is_empty() {
        return Err(CalibError::NoMarkers {
            found: det.rejected.len(),
            hint: "is the cross pattern in view and lit?",
        });
    }
    let orient = Orientation {
        mirrored: false,
        u_along_x: None,
    };
    let m = identify(&det.blobs, &[], &layout, orient);
    let px: Vec<Option<Point2<f64>>> = (0..5)
        .map(|i| {
            m.as_ref()
                .and_then(|m| m.blob_of[i])
                .map(|b| det.blobs[b].centre)
        })
        .collect();
    match (px[0], px[1], px[3], px[4]) {
        (Some(a), Some(b), Some(d), Some(e)) if px[2].is_some() => {
            Ok(((a - e).norm() + (b - d).norm()) / 2.0)
        }
        _ => Err(CalibError::TooFewMarkers {
            what: "cross pattern".into(),
            found: px.iter().flatten().count(),
            expected: 5,
            needed: 5,
            missing: (0..5).filter(|&i| px[i].is_none()).collect(),
        }),
    }
}

/// The paper's two-position procedure on two images of the cross: `near`/`far` are the images
/// with their tape-measured distances (mm).
///
/// # Errors
/// From [`cross_span`] (naming the shot), or [`CalibError::Geometry`] for inconsistent data.
pub fn image_distance(
    cross: &crate::board::Cross,
    near: (&GrayImage, f64),
    far: (&GrayImage, f64),
) -> Result<ImageDistance, CalibError> {
    let name = |what: &str, e: CalibError| match e {
        CalibError::TooFewMarkers {
            found,
            expected,
            needed,
            missing,
            ..
        } => CalibError::TooFewMarkers {
            what: format!("cross pattern in the {what} image"),
            found,
            expected,
            needed,
            missing,
        },
        e => e,
    };
    let s1 = cross_span(near.0, cross).map_err(|e| name("near", e))?;
    let s2 = cross_span(far.0, cross).map_err(|e| name("far", e))?;
    scanner_core::calib::image_distance(
        cross.arm,
        CrossShot {
            tape_mm: near.1,
            span_px: s1,
        },
        CrossShot {
            tape_mm: far.1,
            span_px: s2,
        },
    )
    .map_err(geom("image distance"))
}
