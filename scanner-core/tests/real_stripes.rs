//! The real photographs: coverage of the board rows, straightness of each stripe (residual from a
//! fitted quadratic), and the glint on stripe b-left rejected rather than taken as the stripe.
//! Bounds are the figures measured with `cargo run --release -p scanner-core --example
//! real_stripes` (README) with a margin: coverage 98.5–100 %, centroid RMS 0.31–0.41 px and max
//! 1.03–1.38 px, 36 of 71 glint rows rejected and the rest within 1.75 px.

mod support;

use scanner_core::stripe::Estimator;
use support::real::{CASES, analyse};

#[test]
fn real_stripes_are_found_straight_and_the_glint_is_rejected() {
    for case in &CASES {
        let o = analyse(case, Estimator::Centroid);
        let coverage = o.valid as f64 / o.rows as f64;
        println!("{} {}: {o:?}", case.image, case.stripe);
        assert!(
            coverage >= 0.97,
            "{} {}: coverage {coverage}",
            case.image,
            case.stripe
        );
        assert!(
            o.rms <= 0.5 && o.max <= 2.0,
            "{} {}: residual rms {} max {}",
            case.image,
            case.stripe,
            o.rms,
            o.max
        );
        if o.glint_rows > 0 {
            assert!(
                o.glint_rejected * 10 >= o.glint_rows * 4,
                "only {}/{} glint rows rejected",
                o.glint_rejected,
                o.glint_rows
            );
            assert!(
                o.glint_max_off <= 2.5,
                "a glint row's centre is {} px off the stripe",
                o.glint_max_off
            );
        }
        // the paper's estimator on the same rows, for the record: less straight
        let paper = analyse(case, Estimator::Paper);
        assert!(paper.rms > o.rms);
    }
}
