//! The ambient-light report (the paper's Table 1): `cargo run --release -p scanner-rig
//! --example ambient_report`. On the virtual rig (640×480 demo scene), for a few laser powers,
//! the largest ambient level (rig units: radiance on a white surface; the demo uses 0.45) at
//! which the stripe is still extracted on ≥ 95 % of the object's columns (valid and within 1 px
//! of the true stripe), for the light-intensity (LIM) and difference-image (DIM) methods.

use scanner_core::stripe::{Axis, Extractor, Frame, Method, PixelFormat, StripeConfig};
use scanner_rig::{Rig, Scene, SurfaceId};

/// Fraction of object columns extracted correctly over a few frames of the sweep.
fn success(power: f64, ambient: f64, method: Method, ex: &mut Extractor<1024>) -> f64 {
    let mut s = Scene::demo(640, 480);
    s.laser.power = power;
    s.ambient = ambient;
    let rig = Rig::new(s).expect("rig");
    let (w, h) = (640, 480);
    let reference = rig.reference().to_format(PixelFormat::Gray8);
    let reference = Frame::packed(&reference, w, h, PixelFormat::Gray8).expect("frame");
    let cfg = StripeConfig::new(method, Axis::Columns);
    let (mut good, mut total) = (0usize, 0usize);
    for k in [24, 30, 36, 42] {
        let truth = rig.truth(k).expect("truth");
        let data = rig.frame(k).expect("frame").to_format(PixelFormat::Gray8);
        let frame = Frame::packed(&data, w, h, PixelFormat::Gray8).expect("frame");
        let Ok(res) = ex.extract(&frame, Some(&reference), &cfg) else {
            total += truth
                .iter()
                .flatten()
                .filter(|t| matches!(t.surface, SurfaceId::Object(_)))
                .count();
            continue;
        };
        for (x, t) in truth.iter().enumerate() {
            let Some(t) = t else { continue };
            if !matches!(t.surface, SurfaceId::Object(_)) || t.incidence < 0.2 {
                continue;
            }
            total += 1;
            let p = res.points[x - res.first_line];
            if p.status == scanner_core::stripe::LineStatus::Valid
                && (f64::from(p.centre) - t.row).abs() <= 1.0
            {
                good += 1;
            }
        }
    }
    good as f64 / total.max(1) as f64
}

fn main() {
    let mut ex = Box::new(Extractor::<1024>::new());
    let levels: Vec<f64> = (0..32).map(|i| 0.02 * 1.25f64.powi(i)).collect();
    println!("| laser power | LIM: largest ambient | DIM: largest ambient | DIM / LIM |");
    println!("|---|---|---|---|");
    for power in [1.5, 3.0, 6.0] {
        let mut best = [0.0f64; 2];
        for (m, method) in [Method::Lim, Method::Dim].into_iter().enumerate() {
            for &a in &levels {
                if success(power, a, method, &mut ex) >= 0.95 {
                    best[m] = a;
                } else if best[m] > 0.0 {
                    break;
                }
            }
        }
        let show = |v: f64| {
            if v > 0.0 {
                format!("{v:.2}")
            } else {
                format!("< {:.2}", levels[0])
            }
        };
        let ratio = if best[0] > 0.0 {
            format!("{:.1}×", best[1] / best[0])
        } else {
            "—".into()
        };
        println!(
            "| {power} | {} | {} | {ratio} |",
            show(best[0]),
            show(best[1])
        );
    }
    println!(
        "\nAt the darkest ambient tried, LIM finds {:.0} % of the object's columns at power 1.5 (the sphere's dark texture cells reflect too little), DIM {:.0} %.",
        100.0 * success(1.5, levels[0], Method::Lim, &mut ex),
        100.0 * success(1.5, levels[0], Method::Dim, &mut ex)
    );
    println!(
        "Ambient levels step by 1.25×; the demo scene's ambient is 0.45, where a white surface reads about 80 DN. The paper (Table 1): DIM tolerates about 2.5× more ambient light than LIM."
    );
}
