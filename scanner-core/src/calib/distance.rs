//! Camera–image distance calibration by the paper's two-position procedure (section 3A, eq. 7–9).
//!
//! A cross pattern with arm length `D_AE` (mm) is fixed to a wall. The camera is placed so that the
//! cross's centre images at the image centre, at two distances. At each, the user tape-measures the
//! distance from a mark on the camera to the pattern (`D_O'C`, `D_O''C`) and the software measures
//! the arm's image length (`D_A'E'`, `D_A''E''`, pixels). Each tape reading includes the same
//! unknown offset ε between the mark and the true lens centre. By similar triangles (eq. 7):
//! ```text
//! d_z / D_A'E' = (D_O'C − ε) / D_AE,    d_z / D_A''E'' = (D_O''C − ε) / D_AE
//! ```
//! so that (eq. 9, and eq. 8 corrected as in `NOTES.md`: the printed one has wrong units)
//! ```text
//! d_z = D_A'E' · D_A''E'' · (D_O''C − D_O'C) / (D_AE · (D_A'E' − D_A''E''))
//! ε   = (D_O'C · D_A'E' − D_O''C · D_A''E'') / (D_A'E' − D_A''E'')
//! ```

use crate::GeomError;

/// One position of the two-position procedure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossShot {
    /// Tape-measured distance from the mark on the camera to the pattern centre, mm.
    pub tape_mm: f64,
    /// Image length of the pattern arm, pixels.
    pub span_px: f64,
}

/// Result of the two-position procedure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageDistance {
    /// Image distance `d_z` (the focal length), pixels.
    pub d_z: f64,
    /// Offset ε between the mark and the lens centre, mm (tape reading − true distance).
    pub epsilon_mm: f64,
}

/// Image distance and mark offset from two shots of the cross pattern with arm length
/// `pattern_mm`.
///
/// # Errors
/// [`GeomError::NotFinite`]; [`GeomError::BadParameter`] for a non-positive length, equal tape
/// distances, or image spans that do not shrink with distance; [`GeomError::IllConditioned`] if
/// the offset puts the lens behind the pattern.
pub fn image_distance(
    pattern_mm: f64,
    near: CrossShot,
    far: CrossShot,
) -> Result<ImageDistance, GeomError> {
    let all = [
        pattern_mm,
        near.tape_mm,
        near.span_px,
        far.tape_mm,
        far.span_px,
    ];
    if !all.iter().all(|v| v.is_finite()) {
        return Err(GeomError::NotFinite);
    }
    if !all.iter().all(|v| *v > 0.0) {
        return Err(GeomError::BadParameter(
            "pattern length, distances and spans must be positive",
        ));
    }
    let (d1, s1, d2, s2) = (near.tape_mm, near.span_px, far.tape_mm, far.span_px);
    let dd = d2 - d1;
    let ds = s1 - s2;
    // The farther shot must show the arm smaller; otherwise the data contradicts the model.
    if dd == 0.0 || ds == 0.0 || dd.signum() != ds.signum() {
        return Err(GeomError::BadParameter(
            "the farther shot must have the shorter image span",
        ));
    }
    let d_z = s1 * s2 * dd / (pattern_mm * ds);
    let epsilon_mm = (d1 * s1 - d2 * s2) / ds;
    if !(d_z.is_finite() && epsilon_mm.is_finite()) {
        return Err(GeomError::IllConditioned);
    }
    if !(d1.min(d2) - epsilon_mm > 0.0) {
        return Err(GeomError::IllConditioned);
    }
    Ok(ImageDistance { d_z, epsilon_mm })
}
