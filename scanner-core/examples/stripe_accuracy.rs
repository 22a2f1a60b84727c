//! Prints the accuracy table of the stripe estimators on synthetic stripes (README, "Stripe
//! accuracy").
//!
//! `cargo run --release -p scanner-core --example stripe_accuracy [repeats]`

#[path = "../tests/support/mod.rs"]
mod support;

use scanner_core::stripe::{Estimator, Method};
use support::stripes::{AMPLITUDES, SIGMAS, bench, mean, percentile};

fn main() {
    let repeats = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(4);
    println!(
        "Synthetic stripes: σ {SIGMAS:?} px, peaks {AMPLITUDES:?} DN, noise σ 2 DN, ambient gradient, \
         {repeats} frames of 200 columns per case. Errors in px over the valid columns."
    );
    println!();
    println!(
        "| method | estimator | peak ≥ 60: mean | p95 | valid | clipped: mean | p95 | peak 30–45: mean | p95 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for method in [Method::Dim, Method::Lim] {
        for est in [Estimator::Paper, Estimator::Centroid, Estimator::Gaussian] {
            let e = bench(est, method, 2.0, repeats);
            let high: Vec<f64> = e.high.iter().chain(&e.clipped).copied().collect();
            println!(
                "| {method:?} | {est:?} | {:.4} | {:.4} | {:.1} % | {:.4} | {:.4} | {:.4} | {:.4} |",
                mean(&high),
                percentile(&high, 0.95),
                100.0 * e.valid_high as f64 / e.judged_high as f64,
                mean(&e.clipped),
                percentile(&e.clipped, 0.95),
                mean(&e.low),
                percentile(&e.low, 0.95),
            );
        }
    }
}
