//! The real photographs in `tests/data/real-stripes/`: two vertical stripes per image, extracted
//! in row mode with the difference-image method inside a band around each stripe, over the rows
//! where the stripe lies on the flat chessboard. Each stripe's centres are then fitted with a
//! quadratic x(y) (a straight line up to lens distortion).

use scanner_core::stripe::{
    Axis, Estimator, Extractor, Frame, LaserColour, LineStatus, Method, PixelFormat, Roi,
    StripeConfig,
};

/// One stripe of one photograph.
pub struct Case {
    pub image: &'static str,
    pub stripe: &'static str,
    /// Band around the stripe (columns) × the rows where it lies on the board.
    pub roi: Roi,
    /// Rows where the stripe crosses a glint, if any.
    pub glint: Option<(usize, usize)>,
}

/// Bands and board rows read off the photographs (README of the data).
pub const CASES: [Case; 4] = [
    Case {
        image: "board-two-lasers",
        stripe: "left",
        roi: Roi {
            x: 240,
            y: 470,
            width: 70,
            height: 550,
        },
        glint: None,
    },
    Case {
        image: "board-two-lasers",
        stripe: "right",
        roi: Roi {
            x: 555,
            y: 470,
            width: 70,
            height: 550,
        },
        glint: None,
    },
    Case {
        image: "board-two-lasers-b",
        stripe: "left",
        roi: Roi {
            x: 280,
            y: 465,
            width: 70,
            height: 535,
        },
        glint: Some((565, 636)),
    },
    Case {
        image: "board-two-lasers-b",
        stripe: "right",
        roi: Roi {
            x: 605,
            y: 465,
            width: 70,
            height: 535,
        },
        glint: None,
    },
];

pub fn load(name: &str) -> (Vec<u8>, usize, usize) {
    let path = format!(
        "{}/tests/data/real-stripes/{name}.png",
        env!("CARGO_MANIFEST_DIR")
    );
    let img = image::open(&path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    (img.into_raw(), w, h)
}

/// What one stripe gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Board rows judged (outside the glint).
    pub rows: usize,
    /// Of those, rows with a valid centre.
    pub valid: usize,
    /// RMS and largest residual of the valid centres from the fitted quadratic, px.
    pub rms: f64,
    pub max: f64,
    /// RMS of the valid centres' stated uncertainty (`StripePoint::sigma`), px.
    pub stated_rms: f64,
    /// Glint rows, how many of them were rejected, and the largest distance of a valid centre
    /// there from the curve fitted outside the glint.
    pub glint_rows: usize,
    pub glint_rejected: usize,
    pub glint_max_off: f64,
    /// LineStatus counts over all rows of the band.
    pub statuses: Vec<(LineStatus, usize)>,
}

pub fn fit_quadratic(pts: &[(f64, f64)]) -> impl Fn(f64) -> f64 + use<> {
    use scanner_core::nalgebra::{Matrix3, Vector3};
    let y0 = pts.iter().map(|p| p.0).sum::<f64>() / pts.len() as f64;
    let (mut a, mut b) = (Matrix3::zeros(), Vector3::zeros());
    for &(y, x) in pts {
        let u = (y - y0) / 100.0;
        let row = Vector3::new(1.0, u, u * u);
        a += row * row.transpose();
        b += row * x;
    }
    let c = a.cholesky().expect("enough points").solve(&b);
    move |y: f64| {
        let u = (y - y0) / 100.0;
        c[0] + c[1] * u + c[2] * u * u
    }
}

/// A case's photograph and its laser-off reference (RGB), and their size.
pub struct Photograph {
    pub frame: Vec<u8>,
    pub reference: Vec<u8>,
    pub width: usize,
    pub height: usize,
}

impl Photograph {
    pub fn of(case: &Case) -> Self {
        let (frame, width, height) = load(case.image);
        let (reference, _, _) = load(&format!("{}-background", case.image));
        Photograph {
            frame,
            reference,
            width,
            height,
        }
    }

    /// The frame and the reference as the extractor takes them.
    pub fn frames(&self) -> (Frame<'_>, Frame<'_>) {
        let (w, h) = (self.width, self.height);
        (
            Frame::packed(&self.frame, w, h, PixelFormat::Rgb24).unwrap(),
            Frame::packed(&self.reference, w, h, PixelFormat::Rgb24).unwrap(),
        )
    }
}

/// The difference method's settings for a case's board rows.
pub fn board_config(case: &Case) -> StripeConfig {
    StripeConfig {
        roi: Some(case.roi),
        ..StripeConfig::new(Method::Dim, Axis::Rows)
    }
}

pub fn analyse(case: &Case, estimator: Estimator) -> Outcome {
    let photo = Photograph::of(case);
    let (f, r) = photo.frames();
    let mut ex = Box::new(Extractor::<2048>::new());
    let cfg = StripeConfig {
        estimator,
        ..board_config(case)
    };
    let res = ex.extract(&f, Some(&r), &cfg).unwrap();
    let in_glint = |y: usize| case.glint.is_some_and(|(a, b)| (a..b).contains(&y));
    let pts: Vec<(f64, f64)> = res
        .valid()
        .filter(|(y, _)| !in_glint(*y))
        .map(|(y, p)| (y as f64, f64::from(p.centre)))
        .collect();
    let stated: Vec<f64> = res
        .valid()
        .filter(|(y, _)| !in_glint(*y))
        .map(|(_, p)| f64::from(p.sigma))
        .collect();
    let curve = fit_quadratic(&pts);
    let res_px: Vec<f64> = pts.iter().map(|&(y, x)| (x - curve(y)).abs()).collect();
    let rows = (0..res.points.len())
        .filter(|i| !in_glint(res.first_line + i))
        .count();
    let mut glint_rows = 0;
    let mut glint_rejected = 0;
    let mut glint_max_off = 0.0f64;
    for (i, p) in res.points.iter().enumerate() {
        let y = res.first_line + i;
        if in_glint(y) {
            glint_rows += 1;
            if p.status == LineStatus::Valid {
                glint_max_off = glint_max_off.max((f64::from(p.centre) - curve(y as f64)).abs());
            } else {
                glint_rejected += 1;
            }
        }
    }
    let statuses = LineStatus::ALL
        .iter()
        .map(|&s| (s, res.points.iter().filter(|p| p.status == s).count()))
        .filter(|(_, n)| *n > 0)
        .collect();
    Outcome {
        rows,
        valid: pts.len(),
        rms: (res_px.iter().map(|r| r * r).sum::<f64>() / res_px.len() as f64).sqrt(),
        max: res_px.iter().copied().fold(0.0, f64::max),
        stated_rms: (stated.iter().map(|r| r * r).sum::<f64>() / stated.len().max(1) as f64).sqrt(),
        glint_rows,
        glint_rejected,
        glint_max_off,
        statuses,
    }
}

/// One stripe's band over the whole height of the photograph.
#[derive(Debug, Clone)]
pub struct FullHeight {
    /// Board rows and, of those, rows with a valid centre.
    pub board_rows: usize,
    pub board_valid: usize,
    /// Largest distance of a valid centre on a board row outside the glint, and in the glint's
    /// rows, from the line fitted to the difference method's centres outside the glint, px.
    pub max_off: f64,
    pub glint_max_off: f64,
    /// Rows where no laser falls (the laser frame's red channel nowhere in the band more than
    /// 20 DN above the reference's: the wall above the board, the dark base below) and, of
    /// those, rows with a valid centre.
    pub dark_rows: usize,
    pub dark_valid: usize,
}

/// `method` with the laser `colour` on the band of `case` from the top of the photograph down to
/// row `to` (all of it: `usize::MAX`).
pub fn full_height(case: &Case, method: Method, colour: LaserColour, to: usize) -> FullHeight {
    let photo = Photograph::of(case);
    let (f, r) = photo.frames();
    let (frame, reference, w, h) = (&photo.frame, &photo.reference, photo.width, photo.height);
    // The line: the difference method's centres on the board outside the glint.
    let mut ex = Box::new(Extractor::<2048>::new());
    let board = board_config(case);
    let in_glint = |y: usize| case.glint.is_some_and(|(a, b)| (a..b).contains(&y));
    let pts: Vec<(f64, f64)> = ex
        .extract(&f, Some(&r), &board)
        .unwrap()
        .valid()
        .filter(|(y, _)| !in_glint(*y))
        .map(|(y, p)| (y as f64, f64::from(p.centre)))
        .collect();
    let line = fit_quadratic(&pts);
    let band = Roi {
        x: case.roi.x,
        y: 0,
        width: case.roi.width,
        height: h.min(to),
    };
    let cfg = StripeConfig {
        roi: Some(band),
        colour,
        ..StripeConfig::new(method, Axis::Rows)
    };
    let res = ex.extract(&f, Some(&r), &cfg).unwrap();
    let on_board = |y: usize| (case.roi.y..case.roi.y + case.roi.height).contains(&y);
    let dark = |y: usize| {
        (band.x..band.x + band.width).all(|x| {
            let i = (y * w + x) * 3;
            frame[i] <= reference[i].saturating_add(20)
        })
    };
    let mut out = FullHeight {
        board_rows: 0,
        board_valid: 0,
        max_off: 0.0,
        glint_max_off: 0.0,
        dark_rows: 0,
        dark_valid: 0,
    };
    for (y, p) in res.points.iter().enumerate() {
        let valid = p.status == LineStatus::Valid;
        if on_board(y) {
            out.board_rows += 1;
            if valid {
                out.board_valid += 1;
                let off = (f64::from(p.centre) - line(y as f64)).abs();
                if in_glint(y) {
                    out.glint_max_off = out.glint_max_off.max(off);
                } else {
                    out.max_off = out.max_off.max(off);
                }
            }
        } else if dark(y) {
            out.dark_rows += 1;
            out.dark_valid += usize::from(valid);
        }
    }
    out
}

/// A whole photograph's board rows extracted at once, across the full width (both stripes in
/// every row, the chessboard's squares and their edges between): where each row's valid centre
/// lies against the two stripes' curves (each fitted from its own band, [`analyse`]).
#[derive(Debug, Clone)]
pub struct FullWidth {
    /// Board rows, and rows with a valid centre.
    pub rows: usize,
    pub valid: usize,
    /// Valid centres farther than 2.5 px from both stripes outside a glint's rows: points from
    /// something else (a colour fringe at a square's edge, a speck), with their rows and
    /// columns.
    pub off: Vec<(usize, f32)>,
    /// LineStatus counts over the rows.
    pub statuses: Vec<(LineStatus, usize)>,
}

/// [`FullWidth`] of the photograph `image` (its two cases in [`CASES`]) in `format`.
pub fn full_width(image: &str, format: PixelFormat) -> FullWidth {
    let cases: Vec<&Case> = CASES.iter().filter(|c| c.image == image).collect();
    let curves: Vec<_> = cases
        .iter()
        .map(|c| {
            let (frame, w, h) = load(c.image);
            let (reference, _, _) = load(&format!("{}-background", c.image));
            let f = Frame::packed(&frame, w, h, PixelFormat::Rgb24).unwrap();
            let r = Frame::packed(&reference, w, h, PixelFormat::Rgb24).unwrap();
            let mut ex = Box::new(Extractor::<2048>::new());
            let cfg = StripeConfig {
                roi: Some(c.roi),
                ..StripeConfig::new(Method::Dim, Axis::Rows)
            };
            let res = ex.extract(&f, Some(&r), &cfg).unwrap();
            let pts: Vec<(f64, f64)> = res
                .valid()
                .filter(|(y, _)| !c.glint.is_some_and(|(a, b)| (a..b).contains(y)))
                .map(|(y, p)| (y as f64, f64::from(p.centre)))
                .collect();
            fit_quadratic(&pts)
        })
        .collect();
    let (frame, w, h) = load(image);
    let (reference, _, _) = load(&format!("{image}-background"));
    let (frame, reference) = (convert(&frame, format), convert(&reference, format));
    let f = Frame::packed(&frame, w, h, format).unwrap();
    let r = Frame::packed(&reference, w, h, format).unwrap();
    let top = cases.iter().map(|c| c.roi.y).max().unwrap();
    let bottom = cases.iter().map(|c| c.roi.y + c.roi.height).min().unwrap();
    let mut ex = Box::new(Extractor::<2048>::new());
    let cfg = StripeConfig {
        roi: Some(Roi {
            x: 0,
            y: top,
            width: w,
            height: bottom - top,
        }),
        ..StripeConfig::new(Method::Dim, Axis::Rows)
    };
    let res = ex.extract(&f, Some(&r), &cfg).unwrap();
    // (a glint's rows pull the stripe's centre by up to 2.5 px: judged by [`analyse`])
    let in_glint = |y: usize| {
        cases
            .iter()
            .any(|c| c.glint.is_some_and(|(a, b)| (a..b).contains(&y)))
    };
    let off = res
        .valid()
        .filter(|(y, p)| {
            !in_glint(*y)
                && curves
                    .iter()
                    .all(|c| (f64::from(p.centre) - c(*y as f64)).abs() > 2.5)
        })
        .map(|(y, p)| (y, p.centre))
        .collect();
    let statuses = LineStatus::ALL
        .iter()
        .map(|&s| (s, res.points.iter().filter(|p| p.status == s).count()))
        .filter(|(_, n)| *n > 0)
        .collect();
    FullWidth {
        rows: res.points.len(),
        valid: res.valid().count(),
        off,
        statuses,
    }
}

/// Packed RGB24 bytes in `format` (gray by BT.601 luma, YUYV as a webcam packs pairs).
pub fn convert(rgb: &[u8], format: PixelFormat) -> Vec<u8> {
    use scanner_core::colour::{luma, rgb_pair_to_yuyv};
    match format {
        PixelFormat::Rgb24 => rgb.to_vec(),
        PixelFormat::Gray8 => rgb.chunks(3).map(|p| luma([p[0], p[1], p[2]])).collect(),
        PixelFormat::Yuyv => rgb
            .chunks(6)
            .flat_map(|p| rgb_pair_to_yuyv([p[0], p[1], p[2]], [p[3], p[4], p[5]]))
            .collect(),
    }
}
