//! Stripe extraction: accuracy bounds on the synthetic bench, every rejection reason, every pixel
//! format, row mode, stride and region of interest, hostile frames, and the row-major kernel
//! against a column-by-column reference.

mod support;

use proptest::prelude::*;
use scanner_core::stripe::{
    Axis, Estimator, Extractor, Frame, FrameError, LaserColour, LineStatus, Method, PixelFormat,
    Roi, StripeConfig, StripeError,
};
use support::stripes::{HEIGHT, Synthetic, WIDTH, bench, mean, percentile, synthetic};

type Ex = Extractor<256>;

fn extractor() -> Box<Ex> {
    Box::new(Ex::new())
}

fn gray(data: &[u8]) -> Frame<'_> {
    Frame::packed(data, WIDTH, HEIGHT, PixelFormat::Gray8).unwrap()
}

#[test]
fn accuracy_bounds_of_the_better_estimators() {
    for (method, est) in [
        (Method::Dim, Estimator::Gaussian),
        (Method::Lim, Estimator::Gaussian),
        (Method::Dim, Estimator::Centroid),
        (Method::Lim, Estimator::Centroid),
    ] {
        let e = bench(est, method, 2.0, 2);
        let high: Vec<f64> = e.high.iter().chain(&e.clipped).copied().collect();
        let (m, p95) = (mean(&high), percentile(&high, 0.95));
        let valid = e.valid_high as f64 / e.judged_high as f64;
        println!(
            "{method:?} Gaussian: mean {m:.4} px, p95 {p95:.4} px, valid {:.1} %",
            100.0 * valid
        );
        assert!(m <= 0.05 && p95 <= 0.15, "{method:?}: mean {m}, p95 {p95}");
        assert!(
            valid >= 0.99,
            "{method:?}: only {valid} of the ≥ 60 DN columns valid"
        );
        // the paper's estimator is measured beside it, and is worse
        let paper = bench(Estimator::Paper, method, 2.0, 1);
        let ph: Vec<f64> = paper.high.iter().chain(&paper.clipped).copied().collect();
        assert!(mean(&ph) > 2.0 * m, "paper {} vs {est:?} {m}", mean(&ph));
    }
}

#[test]
fn identical_frames_have_no_stripe() {
    let s = synthetic(2.0, 0.0, 2.0, 3);
    let mut ex = extractor();
    let f = gray(&s.reference);
    let res = ex
        .extract(&f, Some(&f), &StripeConfig::new(Method::Dim, Axis::Columns))
        .unwrap();
    assert!(res.points.iter().all(|p| p.status == LineStatus::NoStripe));
}

/// A frame built from a function of (x, y) → value, with a flat reference at 20 DN.
fn build(f: impl Fn(usize, usize) -> f64) -> (Vec<u8>, Vec<u8>) {
    let mut frame = vec![0u8; WIDTH * HEIGHT];
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            frame[y * WIDTH + x] = (20.0 + f(x, y)).round().clamp(0.0, 255.0) as u8;
        }
    }
    (frame, vec![20u8; WIDTH * HEIGHT])
}

fn gauss(y: usize, c: f64, s: f64) -> f64 {
    let u = y as f64 - c;
    (-u * u / (2.0 * s * s)).exp()
}

fn statuses(frame: &[u8], reference: &[u8]) -> Vec<LineStatus> {
    let mut ex = extractor();
    let res = ex
        .extract(
            &gray(frame),
            Some(&gray(reference)),
            &StripeConfig::new(Method::Dim, Axis::Columns),
        )
        .unwrap();
    res.points.iter().map(|p| p.status).collect()
}

#[test]
fn every_rejection_reason() {
    // two stripes 24 rows apart, the second at 80 %: competing peaks
    let (f, r) = build(|_, y| 150.0 * gauss(y, 20.0, 2.0) + 120.0 * gauss(y, 44.0, 2.0));
    assert!(statuses(&f, &r).iter().all(|&s| s == LineStatus::Ambiguous));
    // a weak second stripe (30 %) is not a rival
    let (f, r) = build(|_, y| 150.0 * gauss(y, 20.0, 2.0) + 45.0 * gauss(y, 44.0, 2.0));
    assert!(statuses(&f, &r).iter().all(|&s| s == LineStatus::Valid));
    // a glint: a clipped plateau 20 rows wide over columns 100..110 of a stripe of σ 2 px
    let (f, r) = build(|x, y| {
        if (100..110).contains(&x) {
            if (22..42).contains(&y) { 400.0 } else { 0.0 }
        } else {
            150.0 * gauss(y, 32.0, 2.0)
        }
    });
    let s = statuses(&f, &r);
    for (x, st) in s.iter().enumerate() {
        let want = if (100..110).contains(&x) {
            LineStatus::Saturated
        } else {
            LineStatus::Valid
        };
        assert_eq!(*st, want, "column {x}");
    }
    // a wide, unclipped blur (σ 8 px, FWHM 19 px) over columns 100..110 of the same stripe:
    // wider than the stripe around it
    let (f, r) = build(|x, y| {
        let s = if (100..110).contains(&x) { 8.0 } else { 2.0 };
        150.0 * gauss(y, 32.0, s)
    });
    let s = statuses(&f, &r);
    for (x, st) in s.iter().enumerate() {
        let want = if (100..110).contains(&x) {
            LineStatus::TooWide
        } else {
            LineStatus::Valid
        };
        assert_eq!(*st, want, "column {x}");
    }
    // the same blur over every column is the stripe
    let (f, r) = build(|_, y| 150.0 * gauss(y, 32.0, 8.0));
    assert!(statuses(&f, &r).iter().all(|&s| s == LineStatus::Valid));
    // a single bright row (a line of hot pixels): too narrow
    let (f, r) = build(|_, y| if y == 30 { 150.0 } else { 0.0 });
    assert!(statuses(&f, &r).iter().all(|&s| s == LineStatus::TooNarrow));
}

#[test]
fn a_stripe_cut_by_an_edge_is_dropped_and_a_dark_speck_is_not() {
    // A stripe of σ 2.5 px over every column; over columns 20..32 the light sheet has passed a
    // surface's border: only the tail beyond 1.3σ falls on it (narrow, weak, its centre pulled
    // 4 px away from the sheet's). Columns 50 and 51: the stripe on a dark speck (narrow and
    // weak too, but only two lines).
    let (f, r) = build(|x, y| {
        let full = 200.0 * gauss(y, 30.0, 2.5);
        if (20..32).contains(&x) {
            if (y as f64) >= 33.25 { full } else { 0.0 }
        } else if (50..52).contains(&x) {
            40.0 * gauss(y, 30.0, 1.0)
        } else {
            full
        }
    });
    let s = statuses(&f, &r);
    for (x, st) in s.iter().enumerate() {
        let want = if (20..32).contains(&x) {
            LineStatus::Cut
        } else {
            LineStatus::Valid
        };
        assert_eq!(*st, want, "column {x}");
    }
    // 0 turns the checks off
    let mut ex = extractor();
    let cfg = StripeConfig {
        cut_width: 0.0,
        edge_ramp: 0.0,
        ..StripeConfig::new(Method::Dim, Axis::Columns)
    };
    let res = ex.extract(&gray(&f), Some(&gray(&r)), &cfg).unwrap();
    assert!(
        res.points[20..32]
            .iter()
            .all(|p| p.status == LineStatus::Valid)
    );
    assert_eq!(LineStatus::Cut.to_string(), "cut by an edge");
}

#[test]
fn formats_agree() {
    let s = synthetic(2.0, 150.0, 2.0, 11);
    let mut ex = extractor();
    let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    let base: Vec<f32> = ex
        .extract(&gray(&s.frame), Some(&gray(&s.reference)), &cfg)
        .unwrap()
        .points
        .iter()
        .map(|p| p.centre)
        .collect();
    // YUYV, white laser: Y in the even bytes, chroma anything
    let white = StripeConfig {
        colour: LaserColour::White,
        ..cfg
    };
    let yuyv = |g: &[u8]| -> Vec<u8> {
        g.iter()
            .enumerate()
            .flat_map(|(i, &v)| [v, (i * 37 % 251) as u8])
            .collect()
    };
    let (fy, ry) = (yuyv(&s.frame), yuyv(&s.reference));
    let f = Frame::packed(&fy, WIDTH, HEIGHT, PixelFormat::Yuyv).unwrap();
    let r = Frame::packed(&ry, WIDTH, HEIGHT, PixelFormat::Yuyv).unwrap();
    let got: Vec<f32> = ex
        .extract(&f, Some(&r), &white)
        .unwrap()
        .points
        .iter()
        .map(|p| p.centre)
        .collect();
    assert_eq!(got, base, "YUYV reads the same luma");
    // RGB: a red laser on gray ambient; the squared added red keeps the centre
    let rgb = |g: &[u8], laser: bool| -> Vec<u8> {
        g.iter()
            .zip(&s.reference)
            .flat_map(|(&v, &a)| if laser { [v, a, a] } else { [a, a, a] })
            .collect()
    };
    let (fr, rr) = (rgb(&s.frame, true), rgb(&s.reference, false));
    let f = Frame::packed(&fr, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
    let r = Frame::packed(&rr, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
    let res = ex.extract(&f, Some(&r), &cfg).unwrap();
    let errs: Vec<f64> = res
        .points
        .iter()
        .zip(&s.truth)
        .filter(|(p, _)| p.status == LineStatus::Valid)
        .map(|(p, t)| (f64::from(p.centre) - t).abs())
        .collect();
    assert!(
        errs.len() >= WIDTH * 99 / 100 && mean(&errs) < 0.05,
        "RGB: {} valid, mean {}",
        errs.len(),
        mean(&errs)
    );
    // RGB LIM by redness finds it
    let res = ex
        .extract(&f, Some(&r), &StripeConfig::new(Method::Lim, Axis::Columns))
        .unwrap();
    assert!(res.valid().count() >= WIDTH * 9 / 10);
}

/// An RGB frame of `s`'s stripe in one channel on a gray ambient, and its reference; with `drop`, the reference is brighter in the
/// other channels by 40 DN everywhere (a change of exposure or white balance between the two).
fn coloured(s: &Synthetic, channel: usize, drop: bool) -> (Vec<u8>, Vec<u8>) {
    let mut f = Vec::with_capacity(s.frame.len() * 3);
    let mut r = Vec::with_capacity(s.frame.len() * 3);
    for (&v, &a) in s.frame.iter().zip(&s.reference) {
        let laser = v.saturating_sub(a);
        for c in 0..3 {
            let own = if c == channel { laser } else { 0 };
            f.push(a.saturating_add(own));
            r.push(if drop && c != channel {
                a.saturating_add(40)
            } else {
                a
            });
        }
    }
    (f, r)
}

#[test]
fn each_laser_colour_is_found_by_its_own_light_and_a_drop_never_makes_a_stripe() {
    let s = synthetic(2.0, 150.0, 2.0, 13);
    let mut ex = extractor();
    for (channel, colour) in [LaserColour::Red, LaserColour::Green, LaserColour::Blue]
        .into_iter()
        .enumerate()
    {
        let (fr, rr) = coloured(&s, channel, true);
        let f = Frame::packed(&fr, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
        let r = Frame::packed(&rr, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
        for method in [Method::Dim, Method::Lim] {
            let cfg = StripeConfig {
                colour,
                ..StripeConfig::new(method, Axis::Columns)
            };
            let res = ex.extract(&f, Some(&r), &cfg).unwrap();
            let errs: Vec<f64> = res
                .points
                .iter()
                .zip(&s.truth)
                .filter(|(p, _)| p.status == LineStatus::Valid)
                .map(|(p, t)| (f64::from(p.centre) - t).abs())
                .collect();
            assert!(
                errs.len() >= WIDTH * 95 / 100 && mean(&errs) < 0.1,
                "{colour:?} {method:?}: {} valid, mean {}",
                errs.len(),
                mean(&errs)
            );
        }
        // The laser of another colour sees nothing in it: the drop of 40 DN in the other
        // channels is no stripe for the difference method, and this laser's light is not theirs.
        let other = LaserColour::ALL[(channel + 1) % 3];
        let cfg = StripeConfig {
            colour: other,
            ..StripeConfig::new(Method::Dim, Axis::Columns)
        };
        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
        assert_eq!(res.valid().count(), 0, "{other:?} in a {colour:?} frame");
    }
    // A white surface brighter than the stripe (a plaster bust under a lamp): by brightness the
    // light-intensity method takes the surface, by redness the stripe.
    let (mut fr, mut rr) = coloured(&s, 0, false);
    for y in 45..55 {
        for p in fr[3 * y * WIDTH..3 * (y + 1) * WIDTH].iter_mut() {
            *p = 235;
        }
        for p in rr[3 * y * WIDTH..3 * (y + 1) * WIDTH].iter_mut() {
            *p = 235;
        }
    }
    let f = Frame::packed(&fr, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
    let r = Frame::packed(&rr, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
    let mut count = |colour: LaserColour| {
        let cfg = StripeConfig {
            colour,
            ..StripeConfig::new(Method::Lim, Axis::Columns)
        };
        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
        res.points
            .iter()
            .zip(&s.truth)
            .filter(|(p, t)| {
                p.status == LineStatus::Valid && (f64::from(p.centre) - **t).abs() < 0.5
            })
            .count()
    };
    let (red, luma) = (count(LaserColour::Red), count(LaserColour::White));
    assert!(
        red >= WIDTH * 95 / 100 && luma == 0,
        "redness {red}, luma {luma}"
    );
    // A frame that only lost light against its reference has no stripe, whatever the colour.
    let (fr, _) = coloured(&s, 0, false);
    let darker: Vec<u8> = s.reference.iter().flat_map(|&a| [a / 2; 3]).collect();
    let brighter: Vec<u8> = fr.iter().map(|&v| v.saturating_add(60)).collect();
    let f = Frame::packed(&darker, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
    let r = Frame::packed(&brighter, WIDTH, HEIGHT, PixelFormat::Rgb24).unwrap();
    for colour in LaserColour::ALL {
        let cfg = StripeConfig {
            colour,
            ..StripeConfig::new(Method::Dim, Axis::Columns)
        };
        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
        assert_eq!(res.valid().count(), 0, "{colour:?}: a drop made a stripe");
    }
}

#[test]
fn yuyv_colours_come_from_the_chroma() {
    // The red stripe as a webcam sends it: YUYV from the RGB frame (BT.601 full range).
    let s = synthetic(2.0, 150.0, 2.0, 17);
    let (fr, rr) = coloured(&s, 0, false);
    let to_yuyv = |rgb: &[u8]| -> Vec<u8> {
        let mut out = Vec::with_capacity(rgb.len() / 3 * 2);
        for pair in rgb.chunks_exact(6) {
            let yuv = |p: &[u8]| {
                let (r, g, b) = (f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
                let y = 0.299 * r + 0.587 * g + 0.114 * b;
                (y, (b - y) / 1.772 + 128.0, (r - y) / 1.402 + 128.0)
            };
            let (y0, u0, v0) = yuv(&pair[..3]);
            let (y1, u1, v1) = yuv(&pair[3..]);
            let q = |v: f64| v.round().clamp(0.0, 255.0) as u8;
            out.extend([q(y0), q((u0 + u1) / 2.0), q(y1), q((v0 + v1) / 2.0)]);
        }
        out
    };
    let (fy, ry) = (to_yuyv(&fr), to_yuyv(&rr));
    let f = Frame::packed(&fy, WIDTH, HEIGHT, PixelFormat::Yuyv).unwrap();
    let r = Frame::packed(&ry, WIDTH, HEIGHT, PixelFormat::Yuyv).unwrap();
    let mut ex = extractor();
    for method in [Method::Dim, Method::Lim] {
        let res = ex
            .extract(&f, Some(&r), &StripeConfig::new(method, Axis::Columns))
            .unwrap();
        let errs: Vec<f64> = res
            .points
            .iter()
            .zip(&s.truth)
            .filter(|(p, _)| p.status == LineStatus::Valid)
            .map(|(p, t)| (f64::from(p.centre) - t).abs())
            .collect();
        assert!(
            errs.len() >= WIDTH * 95 / 100 && mean(&errs) < 0.1,
            "{method:?}: {} valid, mean {}",
            errs.len(),
            mean(&errs)
        );
    }
    // A green laser sees no stripe in a red one's frame.
    let cfg = StripeConfig {
        colour: LaserColour::Green,
        ..StripeConfig::new(Method::Dim, Axis::Columns)
    };
    assert_eq!(ex.extract(&f, Some(&r), &cfg).unwrap().valid().count(), 0);
}

#[test]
fn rows_mode_is_the_transpose() {
    let s = synthetic(1.5, 120.0, 2.0, 21);
    let t = |g: &[u8]| -> Vec<u8> {
        (0..WIDTH)
            .flat_map(|x| (0..HEIGHT).map(move |y| g[y * WIDTH + x]))
            .collect()
    };
    let (ft, rt) = (t(&s.frame), t(&s.reference));
    let mut ex = extractor();
    let cols: Vec<_> = ex
        .extract(
            &gray(&s.frame),
            Some(&gray(&s.reference)),
            &StripeConfig::new(Method::Dim, Axis::Columns),
        )
        .unwrap()
        .points
        .to_vec();
    let f = Frame::packed(&ft, HEIGHT, WIDTH, PixelFormat::Gray8).unwrap();
    let r = Frame::packed(&rt, HEIGHT, WIDTH, PixelFormat::Gray8).unwrap();
    let rows = ex
        .extract(&f, Some(&r), &StripeConfig::new(Method::Dim, Axis::Rows))
        .unwrap();
    assert_eq!(rows.points.len(), WIDTH);
    for (a, b) in cols.iter().zip(rows.points) {
        assert_eq!(a.status, b.status);
        assert!(
            (a.centre - b.centre).abs() < 1e-4,
            "{} vs {}",
            a.centre,
            b.centre
        );
    }
}

#[test]
fn stride_and_roi() {
    let s = synthetic(2.0, 150.0, 2.0, 31);
    let stride = WIDTH + 13;
    let pad = |g: &[u8]| -> Vec<u8> {
        g.chunks(WIDTH)
            .flat_map(|row| row.iter().copied().chain([255u8; 13]))
            .collect()
    };
    let (fp, rp) = (pad(&s.frame), pad(&s.reference));
    let f = Frame::new(&fp, WIDTH, HEIGHT, stride, PixelFormat::Gray8).unwrap();
    let r = Frame::new(&rp, WIDTH, HEIGHT, stride, PixelFormat::Gray8).unwrap();
    let mut ex = extractor();
    let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
    let base: Vec<_> = ex
        .extract(&gray(&s.frame), Some(&gray(&s.reference)), &cfg)
        .unwrap()
        .points
        .to_vec();
    let padded = ex.extract(&f, Some(&r), &cfg).unwrap();
    assert_eq!(padded.points, &base[..], "padding bytes are never read");
    // a region of interest: columns 50..150, rows 10..60
    let roi = Roi {
        x: 50,
        y: 10,
        width: 100,
        height: 50,
    };
    let res = ex
        .extract(
            &f,
            Some(&r),
            &StripeConfig {
                roi: Some(roi),
                ..cfg
            },
        )
        .unwrap();
    assert_eq!((res.first_line, res.points.len()), (50, 100));
    for (i, p) in res.points.iter().enumerate() {
        assert_eq!(p.status, LineStatus::Valid);
        assert!((f64::from(p.centre) - s.truth[50 + i]).abs() < 0.3);
    }
}

#[test]
fn bad_input_is_named() {
    let buf = [0u8; 100];
    assert_eq!(
        Frame::packed(&buf, 0, 10, PixelFormat::Gray8).unwrap_err(),
        FrameError::Empty
    );
    assert_eq!(
        Frame::packed(&buf, 11, 10, PixelFormat::Gray8).unwrap_err(),
        FrameError::BufferTooShort {
            len: 100,
            needed: 110
        }
    );
    assert_eq!(
        Frame::new(&buf, 10, 5, 9, PixelFormat::Gray8).unwrap_err(),
        FrameError::StrideTooShort {
            stride: 9,
            needed: 10
        }
    );
    assert_eq!(
        Frame::packed(&buf, 5, 2, PixelFormat::Yuyv).unwrap_err(),
        FrameError::OddYuyvWidth
    );
    let f = Frame::packed(&buf, 10, 10, PixelFormat::Gray8).unwrap();
    let g = Frame::packed(&buf, 5, 20, PixelFormat::Gray8).unwrap();
    let mut ex = extractor();
    let dim = StripeConfig::new(Method::Dim, Axis::Columns);
    assert_eq!(
        ex.extract(&f, None, &dim).unwrap_err(),
        StripeError::NoReference
    );
    assert_eq!(
        ex.extract(&f, Some(&g), &dim).unwrap_err(),
        StripeError::Frame(FrameError::ReferenceMismatch)
    );
    let roi = Roi {
        x: 5,
        y: 0,
        width: 6,
        height: 10,
    };
    assert_eq!(
        ex.extract(
            &f,
            Some(&f),
            &StripeConfig {
                roi: Some(roi),
                ..dim
            }
        )
        .unwrap_err(),
        StripeError::Frame(FrameError::BadRoi)
    );
    let big = vec![0u8; 300 * 2];
    let wide = Frame::packed(&big, 300, 2, PixelFormat::Gray8).unwrap();
    assert_eq!(
        ex.extract(&wide, Some(&wide), &dim).unwrap_err(),
        StripeError::Frame(FrameError::TooLarge {
            asked: 300,
            capacity: 256
        })
    );
    assert!(matches!(
        ex.extract(
            &f,
            Some(&f),
            &StripeConfig {
                half_window: 0,
                ..dim
            }
        ),
        Err(StripeError::BadConfig(_))
    ));
    for cut_width in [1.0, -0.1, f32::NAN] {
        assert_eq!(
            ex.extract(&f, Some(&f), &StripeConfig { cut_width, ..dim })
                .unwrap_err(),
            StripeError::BadConfig("need 0 ≤ cut_width < 1")
        );
    }
    for e in [
        StripeError::NoReference,
        StripeError::BadConfig("x"),
        StripeError::Frame(FrameError::BadRoi),
    ] {
        assert!(!e.to_string().is_empty());
    }
}

/// Column-by-column reference of the rough stage: the same peak rule written as plain loops; 3×1
/// sums below `floor` (twice the DIM threshold) are not tracked.
fn reference_rough(
    sig: &dyn Fn(usize, usize) -> u16,
    w: usize,
    h: usize,
    sep: u16,
    floor: u16,
) -> Vec<(u16, u16, u16, u16)> {
    (0..w)
        .map(|x| {
            let (mut b, mut ba, mut s, mut sa) = (0u16, 0u16, 0u16, 0u16);
            for y in 1..h.saturating_sub(1) {
                let t = sig(x, y - 1) + sig(x, y) + sig(x, y + 1);
                if t < floor {
                    continue;
                }
                let at = y as u16;
                let far = |a: u16, b: u16| a.wrapping_sub(b) > sep;
                if t >= b {
                    let cb = if far(at, ba) { b } else { 0 };
                    let cs = if far(at, sa) { s } else { 0 };
                    (s, sa) = if cb >= cs { (cb, ba) } else { (cs, sa) };
                    (b, ba) = (t, at);
                } else if far(at, ba) && t > s {
                    (s, sa) = (t, at);
                }
            }
            (b, ba, s, sa)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, cases: 64, ..ProptestConfig::default() })]

    /// Arbitrary bytes, sizes, strides and formats: never a panic, and every valid centre lies
    /// inside the frame with a finite width.
    #[test]
    fn hostile_frames(w in 1usize..40, h in 1usize..40, extra in 0usize..7, fmt in 0usize..3,
                      bytes in prop::collection::vec(any::<u8>(), 0..8000), cols in any::<bool>(), lim in any::<bool>(),
                      est in 0usize..3, colour in 0usize..4) {
        let format = [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb24][fmt];
        let w = if format == PixelFormat::Yuyv { w * 2 } else { w };
        let stride = w * format.bytes_per_pixel() + extra;
        let (half, rest) = bytes.split_at(bytes.len() / 2);
        let (Ok(f), Ok(r)) = (Frame::new(half, w, h, stride, format), Frame::new(rest, w, h, stride, format)) else {
            return Ok(());
        };
        let mut ex = Box::new(Extractor::<128>::new());
        let mut cfg = StripeConfig::new(if lim { Method::Lim } else { Method::Dim }, if cols { Axis::Columns } else { Axis::Rows });
        cfg.estimator = [Estimator::Paper, Estimator::Centroid, Estimator::Gaussian][est];
        cfg.colour = LaserColour::ALL[colour];
        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
        let len = if cols { h } else { w } as f32;
        for p in res.points.iter().filter(|p| p.status == LineStatus::Valid) {
            prop_assert!(p.centre >= -0.5 && p.centre <= len - 0.5, "centre {} outside 0..{len}", p.centre);
            prop_assert!(p.width.is_finite());
        }
    }

    /// The row-major kernel finds the same rough peaks as a column-by-column loop.
    #[test]
    fn kernel_matches_column_reference(w in 3usize..60, h in 3usize..60, seed in any::<u64>(), stripes in 0usize..4) {
        let mut frame = vec![0u8; w * h];
        let mut x = seed | 1;
        for (i, v) in frame.iter_mut().enumerate() {
            x ^= x << 13; x ^= x >> 7; x ^= x << 17;
            let row = i / w;
            let stripe = (0..stripes).any(|k| row == (k * 13 + (x as usize % 3)) % h);
            *v = if stripe { 120 + (x % 120) as u8 } else { (x % 40) as u8 };
        }
        let reference = vec![10u8; w * h];
        let f = Frame::packed(&frame, w, h, PixelFormat::Gray8).unwrap();
        let r = Frame::packed(&reference, w, h, PixelFormat::Gray8).unwrap();
        let mut ex = Box::new(Extractor::<64>::new());
        let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
        let res = ex.extract(&f, Some(&r), &cfg).unwrap();
        let sig = |x: usize, y: usize| u16::from(frame[y * w + x].saturating_sub(10));
        let rough = reference_rough(&sig, w, h, cfg.separation, 2 * res.threshold);
        for (x, (p, &(best, at, second, second_at))) in res.points.iter().zip(&rough).enumerate() {
            // the reported peak is the largest sample within ±2 of the rough centre
            if best == 0 { prop_assert_eq!(p.status, LineStatus::NoStripe); continue; }
            let lo = usize::from(at).saturating_sub(2);
            let hi = (usize::from(at) + 3).min(h);
            let peak = (lo..hi).map(|y| sig(x, y)).max().unwrap();
            prop_assert_eq!(p.peak, peak, "column {}", x);
            let rival = u32::from(second) > 3 * u32::from(res.threshold) && f32::from(second) > cfg.ambiguity * f32::from(best);
            if peak >= res.threshold {
                // a rival is ambiguous unless the band joins the two peaks (the signal between
                // them never below half the second's, per sample): the band's own top
                let (a, b) = (at.min(second_at), at.max(second_at));
                let valley = (a..=b).map(|y| sig(x, usize::from(y))).min().unwrap_or(0);
                let joined = 3 * u32::from(valley) >= u32::from(second) / 2;
                if p.status == LineStatus::Ambiguous {
                    prop_assert!(rival, "column {}", x);
                } else {
                    prop_assert!(!rival || joined, "column {}", x);
                }
            }
        }
    }
}

/// The centre's stated uncertainty (`StripePoint::sigma`) against the centres' real errors on the
/// synthetic bench: the centroid stays within 1.6× the Cramér–Rao bound of a Gaussian profile at
/// every width and peak down to 20 DN (SNR 7 against the difference image's noise), and two
/// stated σ hold about 95 % of the errors.
#[test]
fn the_stated_centre_uncertainty_matches_the_errors_and_the_cramer_rao_bound() {
    use support::stripes::{Stated, stated};
    let mut all = Stated::default();
    for sigma in [1.0, 2.0, 4.0] {
        for amp in [20.0, 45.0, 90.0] {
            let s = stated(sigma, amp, 6);
            let r = s.ratio();
            println!("σ {sigma} px, peak {amp} DN: error / bound {r:.2}");
            assert!((1.0..=1.7).contains(&r), "σ {sigma}, peak {amp}: {r}");
            all.add(&s);
        }
    }
    let within = all.within_2 as f64 / all.valid as f64;
    println!("within 2 stated σ: {:.1} %", 100.0 * within);
    assert!((0.88..=0.985).contains(&within), "{within}");
}

/// A peak's signal back to the DN it stands for: the magnitude itself for gray and a white
/// laser, the root of nine times the squared signal for a coloured laser's difference image.
#[test]
fn a_peaks_signal_is_read_back_as_the_light_added() {
    use scanner_core::stripe::peak_dn;
    let gray = StripeConfig::new(Method::Dim, Axis::Columns);
    assert_eq!(peak_dn(PixelFormat::Gray8, &gray, 66), 66);
    let red = StripeConfig {
        colour: LaserColour::Red,
        ..StripeConfig::new(Method::Dim, Axis::Columns)
    };
    // 120 DN added in red: a signal of 120² / 9 = 1600.
    assert_eq!(peak_dn(PixelFormat::Rgb24, &red, 1600), 120);
    assert_eq!(peak_dn(PixelFormat::Yuyv, &red, 7225), 255);
    let white = StripeConfig {
        colour: LaserColour::White,
        ..red
    };
    assert_eq!(peak_dn(PixelFormat::Rgb24, &white, 90), 90);
}

/// A band across every row (the stripe runs down the frame; row mode): flat-topped between
/// `edges` (each blurred by a Gaussian of σ `blur`, so that its half-maximum lies at the edge),
/// `height` DN above a reference of 20 DN, clipped at 255.
fn band(edges: impl Fn(usize) -> (f64, f64), blur: f64, height: f64) -> (Vec<u8>, Vec<u8>) {
    // the Gaussian's cumulative distribution, from erf (Abramowitz & Stegun 7.1.26, 1.5e-7)
    let erf = |x: f64| {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let poly = t
            * (0.254_829_592
                + t * (-0.284_496_736
                    + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        (1.0 - poly * (-x * x).exp()).copysign(x)
    };
    let erf_like = |u: f64| 0.5 * (1.0 + erf(u / (blur * std::f64::consts::SQRT_2)));
    let mut frame = vec![0u8; WIDTH * HEIGHT];
    for y in 0..HEIGHT {
        let (a, b) = edges(y);
        for x in 0..WIDTH {
            let u = x as f64;
            let v = height * (erf_like(u - a) - erf_like(u - b)).max(0.0);
            frame[y * WIDTH + x] = (20.0 + v).round().clamp(0.0, 255.0) as u8;
        }
    }
    (frame, vec![20u8; WIDTH * HEIGHT])
}

fn rows_cfg() -> StripeConfig {
    StripeConfig {
        edges: true,
        ..StripeConfig::new(Method::Dim, Axis::Rows)
    }
}

#[test]
fn wide_bands_are_located_with_their_edges_and_only_a_band_beyond_the_limit_is_refused() {
    use scanner_core::stripe::{Locate, band_limit};
    let edges = |y: usize| {
        let c = 100.3 + 0.07 * y as f64;
        (c - 20.0, c + 20.0)
    };
    // 40 px, flat-topped and saturated (a 1000 DN band clipped at 255), and 40 px unclipped
    for height in [1000.0, 150.0] {
        let (f, r) = band(edges, 1.5, height);
        let mut ex = extractor();
        let res = ex.extract(&gray(&f), Some(&gray(&r)), &rows_cfg()).unwrap();
        assert_eq!(res.width_limit, band_limit(WIDTH));
        let mut worst = [0f64; 3];
        for (y, p) in res.points.iter().enumerate() {
            assert_eq!(
                p.status,
                LineStatus::Valid,
                "row {y} of the {height} DN band"
            );
            let (a, b) = edges(y);
            let got = [Locate::Centre, Locate::RisingEdge, Locate::FallingEdge]
                .map(|l| f64::from(p.located(l).unwrap().0));
            for (k, truth) in [(a + b) / 2.0, a, b].into_iter().enumerate() {
                worst[k] = worst[k].max((got[k] - truth).abs());
            }
            // clipped, the half-maximum is half the clipped height: further out on the flanks
            let widest = if height > 235.0 { 46.0 } else { 41.0 };
            assert!((39.0..widest).contains(&p.width), "{}", p.width);
        }
        println!("{height} DN band, 40 px: worst error centre / rising / falling {worst:?} px");
        assert!(worst[0] < 0.05, "{worst:?}");
        if height < 235.0 {
            assert!(worst.iter().all(|&e| e < 0.1), "{worst:?}");
        }
        // the next frame knows the stripe's width: peaks 1.5 widths apart to compete
        let res = ex.extract(&gray(&f), Some(&gray(&r)), &rows_cfg()).unwrap();
        assert!(
            (39.0..46.0).contains(&res.typical_width),
            "{}",
            res.typical_width
        );
    }
    // a band 90 px wide in a 200 px image: beyond the limit of 64 px
    let (f, r) = band(|_| (50.0, 140.0), 1.5, 150.0);
    let mut ex = extractor();
    let res = ex.extract(&gray(&f), Some(&gray(&r)), &rows_cfg()).unwrap();
    assert!(res.points.iter().all(|p| p.status == LineStatus::TooWide));
    assert_eq!(res.width_limit, 64.0);
    // a lower limit of one's own is kept
    let cfg = StripeConfig {
        max_width: 30.0,
        ..rows_cfg()
    };
    let (f, r) = band(edges, 1.5, 150.0);
    let res = ex.extract(&gray(&f), Some(&gray(&r)), &cfg).unwrap();
    assert_eq!(res.width_limit, 30.0);
    assert!(res.points.iter().all(|p| p.status == LineStatus::TooWide));
}
