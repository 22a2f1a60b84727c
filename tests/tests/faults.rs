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
use scanner_device::link::Link;
use scanner_device::session::truth_calibration;
use scanner_device::session::{ScanOptions, run_scan};
use scanner_device::source::RigSource;
use scanner_host::collect::{CollectOptions, Collector};
use scanner_rig::{Rig, Scene};
use scanner_wire::{Decoder, MAX_ENCODED};

/// Outputs in the camera frame, where the rig's truth is.
const CAMERA: scanner_host::OutputOptions = scanner_host::OutputOptions {
    min_count: 1,
    frame: scanner_host::FrameChoice::Camera,
    bridge_gaps: true,
};

/// A clean recorded stream of a small rig scan, split into its frames (each with its delimiters).
fn clean_frames() -> &'static Vec<Vec<u8>> {
    static F: std::sync::OnceLock<Vec<Vec<u8>>> = std::sync::OnceLock::new();
    F.get_or_init(|| {
        let mut scene = Scene::demo(320, 240);
        scene.laser.frames = 40;
        let rig = Rig::new(scene).unwrap();
        let cal = truth_calibration(&rig);
        let mut src = RigSource::new(rig, PixelFormat::Gray8);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s");
        let opts = ScanOptions {
            head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
            header_every: 10,
            status_every: 10,
            scan_id: 21,
            find_axis: false,
            find_colour: false,
            disc: None,
            fixed: None,
            markers: None,
            shadow: false,
            temporal: false,
        };
        scanner_tests::record_scan(
            &mut src,
            &cal,
            opts,
            Box::new(std::fs::File::create(&path).unwrap()),
        );
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
        f64::from(c.header().unwrap().camera.fx),
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
            scanner_host::write_outputs(&c, &dir.path().join("replay"), &CAMERA).unwrap();
        }
    }
    println!("{kills} kills survived: every journal a replayable prefix of the stream");
}

#[test]
fn faults_on_a_pseudo_terminal_link_between_head_and_host() {
    use serialport::{SerialPort, TTYPort};
    use std::io::Read;
    // head → pty A → fault-injecting proxy → pty B → host.
    let (a_head, mut a_proxy) = TTYPort::pair().unwrap();
    let (mut b_proxy, mut b_host) = TTYPort::pair().unwrap();
    a_proxy
        .set_timeout(std::time::Duration::from_millis(500))
        .unwrap();
    b_host
        .set_timeout(std::time::Duration::from_millis(500))
        .unwrap();
    let rate = 0.2;
    let proxy = std::thread::spawn(move || {
        // Frames are delimited by zeros: forward each whole frame with faults, count them.
        let mut rng = SmallRng::seed_from_u64(4242);
        let (mut buf, mut frame, mut faults, mut frames) = ([0u8; 4096], Vec::new(), 0u32, 0u32);
        let mut damaged = Vec::new();
        let mut idle = 0;
        while idle < 6 {
            let n = match a_proxy.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    idle += 1;
                    continue;
                }
                Err(_) => break,
            };
            idle = 0;
            for &b in &buf[..n] {
                frame.push(b);
                if b == 0 && frame.len() > 2 {
                    frames += 1;
                    let mut f = std::mem::take(&mut frame);
                    let mut hurt = false;
                    if rng.random_bool(rate) {
                        faults += 1;
                        let i = rng.random_range(1..f.len() - 1);
                        match rng.random_range(0..4) {
                            0 => {
                                f[i] ^= 1 << rng.random_range(0..8);
                                hurt = true;
                            }
                            1 => {
                                f.remove(i);
                                hurt = true;
                            }
                            2 => {
                                f.truncate(i);
                                hurt = true;
                            }
                            _ => f.extend_from_within(..),
                        }
                    }
                    damaged.push(hurt);
                    b_proxy.write_all(&f).unwrap();
                } else if b == 0 {
                    frame = vec![0];
                }
            }
        }
        (frames, faults, damaged)
    });
    let host = std::thread::spawn(move || {
        let mut c = Collector::new(CollectOptions::default(), None);
        let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
        let (mut buf, mut got, mut idle) = ([0u8; 4096], Vec::new(), 0);
        while idle < 8 {
            match b_host.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    idle = 0;
                    c.feed(&buf[..n]).unwrap();
                    d.feed(&buf[..n], |m| {
                        if let Ok(m) = m {
                            got.push(format!("{m:?}"));
                        }
                    });
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => idle += 1,
                Err(_) => break,
            }
        }
        (got, c.counts())
    });
    let mut scene = Scene::demo(320, 240);
    scene.laser.frames = 40;
    let rig = Rig::new(scene).unwrap();
    let cal = truth_calibration(&rig);
    let mut src = RigSource::new(rig, PixelFormat::Gray8);
    let dir = tempfile::tempdir().unwrap();
    let clean_path = dir.path().join("clean");
    // The head writes to pty A and, for comparison, the same bytes to a file.
    struct Tee(TTYPort, std::fs::File);
    impl Write for Tee {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.write_all(b)?;
            self.1.write_all(b)?;
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.0.flush()?;
            self.1.flush()
        }
    }
    let tee = Tee(
        a_head.try_clone_native().unwrap(),
        std::fs::File::create(&clean_path).unwrap(),
    );
    let mut link = Link::spawn(Box::new(tee), 64, MAX_ENCODED);
    let opts = ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        header_every: 10,
        status_every: 10,
        scan_id: 31,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    };
    run_scan(&mut src, &cal, opts, &mut link, |_| {}, |_, _| {}).unwrap();
    link.finish().unwrap();
    let (frames, faults, damaged) = proxy.join().unwrap();
    let (got, counts) = host.join().unwrap();
    drop(a_head);
    let clean = accepted(&std::fs::read(&clean_path).unwrap());
    let wrong = got.iter().filter(|m| !clean.contains(m)).count();
    println!(
        "over ptys at {:.0} %: {frames} frames, {faults} faults, {} accepted, {} rejected, {wrong} wrongly accepted",
        rate * 100.0,
        got.len(),
        counts.decode.rejected()
    );
    assert_eq!(frames as usize, clean.len(), "the proxy saw every frame");
    assert!(faults > 0);
    assert_eq!(wrong, 0);
    for (k, m) in clean.iter().enumerate() {
        assert!(damaged[k] || got.contains(m), "intact frame {k} was lost");
    }
}
