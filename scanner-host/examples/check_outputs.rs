//! Opens a scan's outputs with independent readers — the OBJ with `tobj`, the PLY and STL by
//! their headers, the PNGs with `image` — and checks that they agree with each other.
//!
//! `cargo run -p scanner-host --example check_outputs -- DIR`

use anyhow::{Context, Result, bail, ensure};

fn main() -> Result<()> {
    let dir = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .context("usage: check_outputs DIR")?,
    );
    let (models, _) = tobj::load_obj(
        dir.join("scan.obj"),
        &tobj::LoadOptions {
            single_index: true,
            ..Default::default()
        },
    )
    .context("tobj cannot read scan.obj")?;
    let faces: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    let ply = std::fs::read(dir.join("scan.ply"))?;
    let end = ply
        .windows(11)
        .position(|w| w == b"end_header\n")
        .context("scan.ply has no header")?;
    let header = String::from_utf8_lossy(&ply[..end]);
    let count = |el: &str| -> Result<usize> {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {el} ")))
            .context("scan.ply: element missing")?
            .trim()
            .parse()
            .context("scan.ply: bad count")
    };
    let (pv, pf) = (count("vertex")?, count("face")?);
    ensure!(
        pf == faces,
        "scan.ply has {pf} faces, tobj reads {faces} from scan.obj"
    );
    let stl = std::fs::read(dir.join("scan.stl"))?;
    ensure!(stl.len() >= 84, "scan.stl is too short");
    let sf = u32::from_le_bytes([stl[80], stl[81], stl[82], stl[83]]) as usize;
    ensure!(
        sf == faces && stl.len() == 84 + 50 * sf,
        "scan.stl disagrees: {sf} faces"
    );
    for png in ["depth.png", "preview.png"] {
        let img = image::open(dir.join(png)).with_context(|| format!("cannot read {png}"))?;
        ensure!(
            img.width() > 100 && img.height() > 100,
            "{png} is {}×{}",
            img.width(),
            img.height()
        );
    }
    if faces == 0 {
        bail!("the mesh has no faces");
    }
    println!(
        "outputs agree: {pv} vertices, {faces} faces (OBJ via tobj, PLY, STL); depth.png and preview.png readable"
    );
    Ok(())
}
