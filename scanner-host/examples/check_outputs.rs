//! Opens a scan's outputs with independent readers — the OBJ with `tobj`, the PLY and STL by
//! their headers, the PNGs with `image`, `summary.json` with `serde_json` — and checks that they
//! agree with each other.
//!
//! `cargo run -p scanner-host --example check_outputs -- DIR`

use std::process::ExitCode;

fn main() -> ExitCode {
    match check() {
        Ok(line) => {
            println!("{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("check_outputs: {e}");
            ExitCode::FAILURE
        }
    }
}

/// `Err(why)` when `ok` is false.
fn ensure(ok: bool, why: impl FnOnce() -> String) -> anyhow::Result<()> {
    if ok {
        Ok(())
    } else {
        Err(anyhow::anyhow!(why()))
    }
}

fn check() -> anyhow::Result<String> {
    let dir = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or_else(|| anyhow::anyhow!("usage: check_outputs DIR"))?,
    );
    let read = |name: &str| {
        std::fs::read(dir.join(name)).map_err(|e| anyhow::anyhow!("cannot read {name}: {e}"))
    };
    let (models, _) = tobj::load_obj(
        dir.join("scan.obj"),
        &tobj::LoadOptions {
            single_index: true,
            ..Default::default()
        },
    )
    .map_err(|e| anyhow::anyhow!("tobj cannot read scan.obj: {e}"))?;
    let faces: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    let ply = read("scan.ply")?;
    let end = ply
        .windows(11)
        .position(|w| w == b"end_header\n")
        .ok_or_else(|| anyhow::anyhow!("scan.ply has no header"))?;
    let header = String::from_utf8_lossy(&ply[..end]);
    let count = |el: &str| -> anyhow::Result<usize> {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {el} ")))
            .ok_or_else(|| anyhow::anyhow!("scan.ply: element {el} missing"))?
            .trim()
            .parse()
            .map_err(|e| anyhow::anyhow!("scan.ply: bad count of {el}: {e}"))
    };
    let (pv, pf) = (count("vertex")?, count("face")?);
    ensure(pf == faces, || {
        format!("scan.ply has {pf} faces, tobj reads {faces} from scan.obj")
    })?;
    let stl = read("scan.stl")?;
    ensure(stl.len() >= 84, || "scan.stl is too short".into())?;
    let sf = u32::from_le_bytes([stl[80], stl[81], stl[82], stl[83]]) as usize;
    ensure(sf == faces && stl.len() == 84 + 50 * sf, || {
        format!("scan.stl disagrees: {sf} faces")
    })?;
    for png in ["depth.png", "preview.png"] {
        let img =
            image::open(dir.join(png)).map_err(|e| anyhow::anyhow!("cannot read {png}: {e}"))?;
        ensure(img.width() > 100 && img.height() > 100, || {
            format!("{png} is {}×{}", img.width(), img.height())
        })?;
    }
    let summary: serde_json::Value = serde_json::from_slice(&read("summary.json")?)
        .map_err(|e| anyhow::anyhow!("summary.json: {e}"))?;
    ensure(
        summary["vertices"] == pv && summary["faces"] == faces,
        || format!("summary.json disagrees with the meshes: {summary}"),
    )?;
    ensure(faces > 0, || "the mesh has no faces".into())?;
    Ok(format!(
        "outputs agree: {pv} vertices, {faces} faces (OBJ via tobj, PLY, STL, summary.json); depth.png and preview.png readable"
    ))
}
