//! Prints the Monte Carlo table of the board-plane estimators (README, "Board accuracy").
//!
//! `cargo run --release -p scanner-core --example board_accuracy [trials]`

#[path = "../tests/support/mod.rs"]
mod support;

use support::monte_carlo::run;

fn main() {
    let trials = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2000);
    println!(
        "Board planes from 6 markers per plane, marker noise 0.1 px, stripe noise 0.1 px, {trials} trials per row"
    );
    println!("errors in % of the camera–board distance\n");
    println!("| distance | method | board mean | board max | object mean | object max | failed |");
    println!("|---|---|---|---|---|---|---|");
    for distance in [280.0, 3200.0] {
        for (method, s) in run(distance, 0.1, 0.1, trials, 2012 + distance as u64) {
            println!(
                "| {distance} mm | {method:?} | {:.4} % | {:.4} % | {:.4} % | {:.4} % | {} |",
                s.board_mean, s.board_max, s.object_mean, s.object_max, s.failed
            );
        }
    }
}
