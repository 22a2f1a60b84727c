//! Prints the extraction figures on the real photographs (README, "Real photographs").
//!
//! `cargo run --release -p scanner-core --example real_stripes`

#[path = "../tests/support/mod.rs"]
mod support;

use scanner_core::stripe::Estimator;
use support::real::{CASES, analyse};

fn main() {
    println!(
        "Real photographs (Jesus89/3DScanScience, CC BY-SA 4.0): row mode, DIM (eq. 11 on RGB), band of 70 columns per stripe, board rows only."
    );
    println!();
    println!(
        "| photo | stripe | estimator | valid rows | residual RMS | residual max | glint rows rejected | glint: worst valid off the line | statuses |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for case in &CASES {
        for est in [Estimator::Paper, Estimator::Centroid, Estimator::Gaussian] {
            let o = analyse(case, est);
            let glint = if o.glint_rows > 0 {
                (
                    format!("{}/{}", o.glint_rejected, o.glint_rows),
                    format!("{:.2} px", o.glint_max_off),
                )
            } else {
                ("—".into(), "—".into())
            };
            let statuses: Vec<String> =
                o.statuses.iter().map(|(s, n)| format!("{s} {n}")).collect();
            println!(
                "| {} | {} | {est:?} | {}/{} ({:.1} %) | {:.3} px | {:.2} px | {} | {} | {} |",
                case.image,
                case.stripe,
                o.valid,
                o.rows,
                100.0 * o.valid as f64 / o.rows as f64,
                o.rms,
                o.max,
                glint.0,
                glint.1,
                statuses.join(", ")
            );
        }
    }
}
