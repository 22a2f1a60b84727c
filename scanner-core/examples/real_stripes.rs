//! Prints the extraction figures on the real photographs (README, "Real photographs").
//!
//! `cargo run --release -p scanner-core --example real_stripes`

#[path = "../tests/support/mod.rs"]
mod support;

use scanner_core::stripe::{Estimator, LaserColour, Method};
use support::real::{CASES, analyse, full_height};

fn main() {
    println!(
        "Real photographs (Jesus89/3DScanScience, CC BY-SA 4.0): row mode, DIM with a red laser (the light added to red, squared), band of 70 columns per stripe, board rows only."
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
    println!();
    println!(
        "The same bands over the photograph's height (centroid): the board's rows, the rows where no laser falls (the laser frame's red nowhere more than 20 DN above the reference: the wall above, the dark base below), and the distance of each valid centre from the line fitted to DIM's centres outside the glint. LIM runs from the top to the board's end (below it the turntable is lit as red as the laser)."
    );
    println!();
    println!(
        "| photo | stripe | method, laser | board rows valid | worst off the line (glint rows) | rows without laser | centres there |"
    );
    println!("|---|---|---|---|---|---|---|");
    for case in &CASES {
        let end = case.roi.y + case.roi.height;
        for (name, method, colour, to) in [
            ("DIM, red", Method::Dim, LaserColour::Red, usize::MAX),
            ("DIM, white", Method::Dim, LaserColour::White, usize::MAX),
            ("LIM, red", Method::Lim, LaserColour::Red, end),
            ("LIM, white", Method::Lim, LaserColour::White, end),
        ] {
            let o = full_height(case, method, colour, to);
            let glint = if case.glint.is_some() {
                format!(" ({:.2} px)", o.glint_max_off)
            } else {
                String::new()
            };
            println!(
                "| {} | {} | {name} | {}/{} ({:.1} %) | {:.2} px{glint} | {} | {} |",
                case.image,
                case.stripe,
                o.board_valid,
                o.board_rows,
                100.0 * o.board_valid as f64 / o.board_rows as f64,
                o.max_off,
                o.dark_rows,
                o.dark_valid
            );
        }
    }
}
