//! Renders the contact sheet of the virtual rig (README, "The virtual rig"): the reference
//! frame and two laser frames of the demo scene side by side, 640×480 each.
//!
//! `cargo run --release -p scanner-device --example contact_sheet [out.png]`

use scanner_device::rig::{Rig, Scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "docs/rig-contact-sheet.png".into());
    let (w, h) = (640u32, 480u32);
    let rig = Rig::new(Scene::demo(w, h))?;
    let frames = rig.scene().laser.frames;
    let tiles = [
        rig.reference(),
        rig.frame(frames / 3)?,
        rig.frame(frames * 2 / 3)?,
    ];
    let gap = 8;
    let mut sheet = image::RgbImage::from_pixel(3 * w + 2 * gap, h, image::Rgb([255, 255, 255]));
    for (k, tile) in tiles.iter().enumerate() {
        let img = image::RgbImage::from_raw(w, h, tile.data.clone()).ok_or("tile size")?;
        image::imageops::overlay(&mut sheet, &img, i64::from(k as u32 * (w + gap)), 0);
    }
    sheet.save(&out)?;
    println!("wrote {out}");
    Ok(())
}
