//! Renders the contact sheet of the virtual rig (README, "The virtual rig"): the reference
//! frame, two laser frames of the demo scene and a calibration shot (a tilted chessboard), side
//! by side, 640×480 each.
//!
//! `cargo run --release -p scanner-rig --example contact_sheet [out.png]`

use scanner_core::nalgebra::Point3;
use scanner_rig::target::{Pattern, TargetPose};
use scanner_rig::{Rig, Scene};

fn main() -> anyhow::Result<()> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "docs/rig-contact-sheet.png".into());
    let (w, h) = (640u32, 480u32);
    let rig = Rig::new(Scene::demo(w, h))?;
    let frames = rig.scene().laser.frames;
    let chessboard = Pattern::Chessboard {
        cols: 9,
        rows: 6,
        square: 30.0,
    };
    let pose = TargetPose {
        centre: Point3::new(0.0, 0.0, 650.0),
        turn_deg: [-10.0, 25.0, 0.0],
    };
    let tiles = [
        rig.reference(),
        rig.frame(frames / 3)?,
        rig.frame(frames * 2 / 3)?,
        rig.shot(&chessboard, &pose, 1).image,
    ];
    let gap = 8;
    let n = tiles.len() as u32;
    let mut sheet =
        image::RgbImage::from_pixel(n * w + (n - 1) * gap, h, image::Rgb([255, 255, 255]));
    for (k, tile) in tiles.iter().enumerate() {
        let img = image::RgbImage::from_raw(w, h, tile.data.clone())
            .ok_or_else(|| anyhow::anyhow!("tile size"))?;
        image::imageops::overlay(&mut sheet, &img, i64::from(k as u32 * (w + gap)), 0);
    }
    sheet.save(&out)?;
    println!("wrote {out}");
    Ok(())
}
