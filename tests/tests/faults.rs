//! Reliability of the link and the host (issue 9, first part):
//! - fault injection between head and host (in the spirit of smoltcp's fault injector): bits
//!   flipped, bytes dropped, garbage inserted, frames duplicated and truncated at 0.1 %, 1 % and
//!   5 % per frame; no corrupted frame is accepted, every intact frame is kept, and the grid equals
//!   the clean run's grid restricted to the intact frames;
//! - crash safety: the host binary killed (SIGKILL) at random moments while receiving; its journal
//!   replays to exactly a prefix of the frames it was sent.

use std::io::Write;
use std::process::{Command, Stdio};

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_core::wire::{Decoder, MAX_ENCODED};
use scanner_device::head::{ScanOptions, run_scan};
use scanner_device::link::Link;
use scanner_device::rig::{Rig, Scene};
use scanner_device::scan_cli::rig_truth;
use scanner_device::source::RigSource;
use scanner_host::collect::{CollectOptions, Collector};

/// A clean recorded stream of a small rig scan, split into its frames (each with its delimiters).
fn clean_frames() -> &'static Vec<Vec<u8>> {
    static F: std::sync::OnceLock<Vec<Vec<u8>>> = std::sync::OnceLock::new();
    F.get_or_init(|| {
        let mut scene = Scene::demo(320, 240);
        scene.laser.frames = 40;
        let rig = Rig::new(scene).unwrap();
        let cal = rig_truth(&rig);
        let mut src = RigSource::new(rig, PixelFormat::Gray8);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s");
        let mut link = Link::spawn(
            Box::new(std::fs::File::create(&path).unwrap()),
            8,
            MAX_ENCODED,
        );
        let opts = ScanOptions {
            head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
            header_every: 10,
            status_every: 10,
            scan_id: 21,
        };
        run_scan(&mut src, &cal, opts, &mut link, |_| {}, |_, _| {}).unwrap();
        link.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        // Frames are 0x00 ‖ body ‖ 0x00.
        let mut frames = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            assert_eq!(bytes[i], 0);
            let end = i + 1 + bytes[i + 1..].iter().position(|&b| b == 0).unwrap();
            frames.push(bytes[i..=end].to_vec());
            i = end + 1;
        }
        frames
    })
}

/// Every accepted message of a byte stream, as text.
fn accepted(bytes: &[u8]) -> Vec<String> {
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    let mut v = Vec::new();
    for c in bytes.chunks(97) {
        d.feed(c, |m| {
            if let Ok(m) = m {
                v.push(format!("{m:?}"));
            }
        });
    }
    v
}

/// The mesh a collector builds from a stream (OBJ text).
fn mesh_of(bytes: &[u8]) -> (String, scanner_host::collect::Counts) {
    let mut c = Collector::new(CollectOptions::default(), None);
    for chunk in bytes.chunks(211) {
        c.feed(chunk).unwrap();
    }
    let grid = c.grid().expect("a header arrived");
    let m = scanner_host::mesh::build(
        grid,
        f64::from(c.header().unwrap().camera[0]),
        &Default::default(),
        false,
    );
    (scanner_host::export::obj(&m), c.counts())
}

/// Faults of one run.
#[derive(Debug, Default, Clone, Copy)]
struct Injected {
    flips: u32,
    drops: u32,
    garbage: u32,
    duplicates: u32,
    truncations: u32,
}

/// The faulty stream, the indices of the frames that arrive intact, and the faults.
fn inject(frames: &[Vec<u8>], rate: f64, seed: u64) -> (Vec<u8>, Vec<usize>, Injected) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let (mut out, mut intact, mut n) = (Vec::new(), Vec::new(), Injected::default());
    for (k, f) in frames.iter().enumerate() {
        let mut f = f.clone();
        let mut ok = true;
        if rng.random_bool(rate) {
            // Garbage before the frame (may contain zeros): the frame's own leading zero cuts it.
            n.garbage += 1;
            let len = rng.random_range(1..40);
            out.extend((0..len).map(|_| rng.random::<u8>()));
        }
        if rng.random_bool(rate) {
            n.flips += 1;
            let i = rng.random_range(1..f.len() - 1);
            f[i] ^= 1 << rng.random_range(0..8);
            ok = false;
        }
        if rng.random_bool(rate) {
            n.drops += 1;
            let i = rng.random_range(1..f.len() - 1);
            f.remove(i);
            ok = false;
        }
        if rng.random_bool(rate) {
            n.truncations += 1;
            let cut = rng.random_range(1..f.len() - 1);
            f.truncate(cut);
            ok = false;
        }
        out.extend(&f);
        if ok {
            intact.push(k);
        }
        if rng.random_bool(rate) {
            n.duplicates += 1;
            out.extend(&f);
        }
    }
    (out, intact, n)
}

#[test]
fn a_faulty_link_never_gets_a_corrupted_frame_accepted() {
    let frames = clean_frames();
    let clean: Vec<String> = frames.iter().flat_map(|f| accepted(f)).collect();
    assert_eq!(clean.len(), frames.len());
    println!(
        "| fault rate per frame | runs | frames sent | faults injected (flip/drop/garbage/dup/trunc) | intact frames lost | corrupted frames accepted |"
    );
    println!("|---|---|---|---|---|---|");
    for rate in [0.001, 0.01, 0.05] {
        let (mut sent, mut lost, mut wrong) = (0usize, 0usize, 0usize);
        let mut total = Injected::default();
        for seed in 0..20u64 {
            let (bytes, intact, n) = inject(frames, rate, seed * 7919 + (rate * 1e4) as u64);
            for (a, b) in [
                (&mut total.flips, n.flips),
                (&mut total.drops, n.drops),
                (&mut total.garbage, n.garbage),
                (&mut total.duplicates, n.duplicates),
                (&mut total.truncations, n.truncations),
            ] {
                *a += b;
            }
            sent += frames.len();
            let got = accepted(&bytes);
            // No corrupted frame accepted: everything accepted is a clean frame.
            wrong += got.iter().filter(|m| !clean.contains(m)).count();
            // Every intact frame kept.
            let mut got_sorted = got.clone();
            got_sorted.sort();
            for k in &intact {
                if got_sorted.binary_search(&clean[*k]).is_err() {
                    lost += 1;
                }
            }
            // The host's grid equals the clean grid of the intact frames.
            let restricted: Vec<u8> = intact.iter().flat_map(|&k| frames[k].clone()).collect();
            if intact.iter().any(|&k| clean[k].starts_with("Header")) {
                let (faulty_mesh, counts) = mesh_of(&bytes);
                let (clean_mesh, _) = mesh_of(&restricted);
                assert_eq!(
                    faulty_mesh, clean_mesh,
                    "rate {rate}, seed {seed}: grids differ ({counts:?})"
                );
            }
        }
        println!(
            "| {:.1} % | 20 | {sent} | {} ({}/{}/{}/{}/{}) | {lost} | {wrong} |",
            rate * 100.0,
            total.flips + total.drops + total.garbage + total.duplicates + total.truncations,
            total.flips,
            total.drops,
            total.garbage,
            total.duplicates,
            total.truncations
        );
        assert_eq!(wrong, 0, "a corrupted frame was accepted at rate {rate}");
        assert_eq!(lost, 0, "an intact frame was lost at rate {rate}");
    }
}

#[test]
fn a_host_killed_at_random_moments_keeps_a_replayable_journal() {
    let frames = clean_frames();
    let clean: Vec<String> = frames.iter().flat_map(|f| accepted(f)).collect();
    let stream: Vec<u8> = frames.concat();
    let mut rng = SmallRng::seed_from_u64(99);
    let mut kills = 0;
    for run in 0..20 {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let mut host = Command::new(scanner_tests::workspace_bin("scanner-host"))
            .args(["receive", "-", "--quiet", "--out", out.to_str().unwrap()])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut stdin = host.stdin.take().unwrap();
        // Send in small chunks with pauses; kill at a random point.
        let kill_at = rng.random_range(0..stream.len());
        let mut sent = 0;
        for chunk in stream.chunks(512) {
            if sent >= kill_at {
                break;
            }
            if stdin.write_all(chunk).is_err() {
                break;
            }
            let _ = stdin.flush();
            sent += chunk.len();
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        std::thread::sleep(std::time::Duration::from_millis(rng.random_range(0..30)));
        host.kill().unwrap(); // SIGKILL
        let _ = host.wait();
        kills += 1;
        let journal = std::fs::read(out.join("journal.stream")).unwrap_or_default();
        let replayed = accepted(&journal);
        // Exactly a prefix of what was sent (a frame cut by the kill is not in it).
        assert!(replayed.len() <= clean.len(), "run {run}");
        assert_eq!(
            replayed[..],
            clean[..replayed.len()],
            "run {run}: the journal is not a prefix of the stream"
        );
        // The replay builds the outputs whenever a header is in it.
        if replayed.iter().any(|m| m.starts_with("Header")) {
            let mut c = Collector::new(CollectOptions::default(), None);
            c.feed(&journal).unwrap();
            scanner_host::write_outputs(&c, &dir.path().join("replay"), 1).unwrap();
        }
    }
    println!("{kills} kills survived: every journal a replayable prefix of the stream");
}
