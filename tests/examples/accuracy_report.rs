//! The accuracy report (the paper's Table 3): `cargo run --release -p scanner-rig --example
//! accuracy_report [-- FRAMES [DISTANCE…]]`. The paper's setup on the virtual rig at 1600×1200: camera–board
//! distance 280, 400, 800, 1600 and 3200 mm, marker spacing 40, 60, 120, 240, 480 mm; intrinsics
//! and board calibrated from rendered images; two spheres and a tilted plane scanned; both board
//! constructions; and 3200 mm again with a weak laser (a stripe about 30 DN above
//! the background in noise of σ ≈ 3 DN).

use scanner_tests::accuracy::Light;

fn main() {
    let frames: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(80);
    let only: Vec<f64> = std::env::args()
        .skip(2)
        .filter_map(|s| s.parse().ok())
        .collect();
    let (w, h) = (1600, 1200);
    let t = std::time::Instant::now();
    let (camera, k3_fixed) = scanner_tests::accuracy::calibrate_camera(w, h);
    eprintln!(
        "intrinsics calibrated from 12 rendered dot-grid images in {:.1} s{}",
        t.elapsed().as_secs_f64(),
        if k3_fixed {
            " (k3 fixed at 0: no shot reaches the image's border)"
        } else {
            ""
        }
    );
    let mut rows = Vec::new();
    for (d, _) in scanner_tests::accuracy::PAPER_MEAN_MM {
        if !only.is_empty() && !only.contains(&d) {
            continue;
        }
        let t = std::time::Instant::now();
        rows.extend(scanner_tests::accuracy::run_distance(
            &camera,
            w,
            h,
            d,
            frames,
            Light::Normal,
        ));
        eprintln!("{d} mm done in {:.1} s", t.elapsed().as_secs_f64());
    }
    // the weak stripe at the longest distance
    if only.is_empty() || only.contains(&3200.0) {
        rows.extend(scanner_tests::accuracy::run_distance(
            &camera,
            w,
            h,
            3200.0,
            frames,
            Light::Weak,
        ));
    }
    print!("{}", scanner_tests::accuracy::table(&rows));
}
