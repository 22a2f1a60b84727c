//! The laser-off reference is checked for the laser before a scan starts: each averaged frame
//! against the average, on the rig and on real photographs, in each pixel format.

use scanner_core::stripe::PixelFormat;
use scanner_device::source::{
    FrameSource, OwnedFrame, RigSource, SourceError, laser_off_reference, load_frame, stripe_lines,
};
use scanner_rig::{Rig, Scene};

/// `f` with seeded sensor-like noise (±4 levels), as consecutive laser-off frames differ.
fn noisy(f: &OwnedFrame, seed: u64) -> OwnedFrame {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let data = f
        .data
        .iter()
        .map(|&v| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (i32::from(v) + (x % 9) as i32 - 4).clamp(0, 255) as u8
        })
        .collect();
    OwnedFrame { data, ..f.clone() }
}

#[test]
fn laser_off_frames_pass_and_a_sweep_in_the_reference_is_refused_on_the_rig() {
    for format in [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb24] {
        let mut source = RigSource::new(Rig::new(Scene::demo(640, 480)).unwrap(), format);
        let reference = source.reference().unwrap();
        let off: Vec<_> = (0..8).map(|i| noisy(&reference, i)).collect();
        laser_off_reference(&off).unwrap_or_else(|e| panic!("{format:?}: {e}"));
        // Frames from the middle of the sweep, where the stripe crosses the board.
        let on: Vec<_> = (0..48)
            .filter_map(|_| source.next_frame().unwrap())
            .skip(40)
            .collect();
        assert_eq!(on.len(), 8);
        match laser_off_reference(&on) {
            Err(SourceError::LaserInReference { frames: 8, .. }) => {}
            other => panic!(
                "{format:?}: laser frames taken as a reference: {:?}",
                other.err()
            ),
        }
        // One laser frame among laser-off ones is found too.
        let mut mixed = off.clone();
        mixed[5] = on[0].clone();
        match laser_off_reference(&mixed) {
            Err(SourceError::LaserInReference { frame: 6, .. }) => {}
            other => panic!(
                "{format:?}: the 6th frame with the laser not found: {:?}",
                other.err()
            ),
        }
    }
}

#[test]
fn real_photographs_the_laser_frame_among_laser_off_ones_is_found() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scanner-core/tests/data/real-stripes");
    for stem in ["board-two-lasers", "board-two-lasers-b"] {
        for format in [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb24] {
            let on = load_frame(&dir.join(format!("{stem}.png")), format, 0).unwrap();
            let off = load_frame(&dir.join(format!("{stem}-background.png")), format, 0).unwrap();
            let mut frames: Vec<_> = (0..8).map(|i| noisy(&off, i)).collect();
            laser_off_reference(&frames).unwrap_or_else(|e| panic!("{stem} {format:?}: {e}"));
            frames[2] = on.clone();
            match laser_off_reference(&frames) {
                Err(SourceError::LaserInReference {
                    frame: 3,
                    lines,
                    total,
                    ..
                }) => eprintln!("{stem} {format:?}: laser frame: stripe on {lines} of {total}"),
                other => panic!(
                    "{stem} {format:?}: the laser frame not found: {:?}",
                    other.err()
                ),
            }
            let (lines, _) = stripe_lines(&noisy(&off, 9), &off).unwrap();
            eprintln!("{stem} {format:?}: a noisy laser-off frame: stripe on {lines} lines");
        }
    }
}
