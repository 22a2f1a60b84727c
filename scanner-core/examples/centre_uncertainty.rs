//! Stripe centres against their stated uncertainty on the synthetic bench: per stripe width and
//! peak, the RMS centre error, the RMS of the Cramér–Rao bound the extractor states
//! (`StripePoint::sigma` without the centroid's efficiency factor) and their ratio, and how many
//! centres lie within two stated σ (95 % for a well-stated Gaussian error).
//!
//! `cargo run --release -p scanner-core --example centre_uncertainty`

#[path = "../tests/support/stripes.rs"]
#[allow(dead_code)]
mod stripes;

use scanner_core::stripe::CENTROID_EFFICIENCY;
use stripes::{Stated, stated};

fn main() {
    println!(
        "| σ px | peak DN | valid | RMS error px | RMS bound px | error / bound | within 2 stated σ |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut all = Stated::default();
    for sigma in [1.0, 1.5, 2.0, 3.0, 4.0] {
        for amp in [20.0, 30.0, 45.0, 60.0, 90.0, 130.0, 180.0] {
            let s = stated(sigma, amp, 6);
            println!(
                "| {sigma} | {amp} | {:.0} % | {:.4} | {:.4} | {:.2} | {:.1} % |",
                100.0 * s.valid as f64 / s.judged as f64,
                (s.e2 / s.valid.max(1) as f64).sqrt(),
                (s.b2 / s.valid.max(1) as f64).sqrt(),
                s.ratio(),
                100.0 * s.within_2 as f64 / s.valid.max(1) as f64
            );
            if amp <= 130.0 {
                all.add(&s);
            }
        }
    }
    println!(
        "\npeaks 20–130 DN: error / bound {:.2}, within 2 stated σ {:.1} % (efficiency factor {CENTROID_EFFICIENCY})",
        all.ratio(),
        100.0 * all.within_2 as f64 / all.valid as f64
    );
}
