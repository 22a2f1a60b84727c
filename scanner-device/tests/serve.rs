//! The head as a service (`scanner-device serve`) on a pseudo-terminal, as a Pi's head sits at
//! the end of its cable: every command answered, bad ones refused with their reasons, and a
//! whole job (shots, calibration, a preview, sweeps at turned views) taken by commands alone.

use std::io::{Read, Write};
use std::path::Path;
use std::process::{Child, Command as Process, Stdio};
use std::time::{Duration, Instant};

use scanner_tests::workspace_bin;
use scanner_wire::{
    Calibrated, Command, CommandFrame, Decoder, HeadState, MAX_COMMAND_ENCODED, MAX_ENCODED,
    Message, Outcome, PreviewRequest, Reply, ShotTaken, Status, SweepRequest, encode_command,
};
use serialport::{SerialPort, TTYPort};

/// What the host heard, owned.
#[derive(Debug, Clone, PartialEq)]
enum Heard {
    Reply(Reply),
    Shot(ShotTaken),
    Calibrated(Calibrated),
    Header(u32),
    Points(u32, u32),
    Status(Status),
    Preview(u32, u16, u16),
    Notice(scanner_wire::Notice),
    Other,
}

/// A head serving on a pseudo-terminal, and the host's end.
struct Head {
    child: Child,
    port: TTYPort,
    decoder: Box<Decoder<MAX_ENCODED>>,
    heard: Vec<Heard>,
    seq: u32,
}

impl Drop for Head {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Head {
    fn start(work: &Path, extra: &[&str]) -> Head {
        Head::start_on("rig", work, extra)
    }

    fn start_on(source: &str, work: &Path, extra: &[&str]) -> Head {
        let (mut port, device) = TTYPort::pair().expect("a pseudo-terminal pair");
        port.set_timeout(Duration::from_millis(50)).unwrap();
        let name = device.name().unwrap();
        let child = Process::new(workspace_bin("scanner-device"))
            .args(["serve", "--source", source, "--out"])
            .arg(format!("serial:{name}"))
            .arg("--work")
            .arg(work)
            .args(extra)
            .current_dir(work.parent().unwrap())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("the head starts");
        // the device end stays open here too, so that the head may open it at its pace
        std::mem::forget(device);
        Head {
            child,
            port,
            decoder: Box::new(Decoder::new()),
            heard: Vec::new(),
            seq: 0,
        }
    }

    fn write(&mut self, bytes: &[u8]) {
        self.port.write_all(bytes).unwrap();
        self.port.flush().unwrap();
    }

    fn frame(seq: u32, command: Command) -> Vec<u8> {
        let mut out = [0u8; MAX_COMMAND_ENCODED];
        let n = encode_command(&CommandFrame { seq, command }, &mut out).unwrap();
        out[..n].to_vec()
    }

    /// Reads what has arrived within `wait`.
    fn pump(&mut self, wait: Duration) {
        let t0 = Instant::now();
        let mut buf = [0u8; 8192];
        while t0.elapsed() < wait {
            let n = match self.port.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(e) => panic!("reading the link: {e}"),
            };
            let heard = &mut self.heard;
            self.decoder.feed(&buf[..n], |m| {
                heard.push(match m.expect("the head sends good frames") {
                    Message::Reply(r) => Heard::Reply(r),
                    Message::Shot(s) => Heard::Shot(s),
                    Message::Calibrated(c) => Heard::Calibrated(c),
                    Message::Header(h) => Heard::Header(h.scan_id),
                    Message::Points(p) => Heard::Points(p.scan_id, p.count),
                    Message::Status(s) => Heard::Status(s),
                    Message::Preview(p) => Heard::Preview(p.scan_id, p.width, p.height),
                    Message::Notice(n) => Heard::Notice(n),
                    _ => Heard::Other,
                });
            });
        }
    }

    /// Waits until `f` finds something among what was heard since `from`.
    fn until<T>(&mut self, from: usize, within: Duration, f: impl Fn(&Heard) -> Option<T>) -> T {
        let t0 = Instant::now();
        loop {
            if let Some(t) = self.heard[from..].iter().find_map(&f) {
                return t;
            }
            assert!(
                t0.elapsed() < within,
                "nothing wanted within {within:?}; heard {:?}",
                &self.heard[from.min(self.heard.len())..]
            );
            self.pump(Duration::from_millis(50));
        }
    }

    /// Sends a command, and its reply: sent again with the same number every half second
    /// until one comes (as a host does: the head may not be listening yet, or a frame was
    /// damaged).
    fn ask(&mut self, command: Command) -> Reply {
        self.seq += 1;
        let seq = self.seq;
        let from = self.heard.len();
        let t0 = Instant::now();
        loop {
            self.write(&Self::frame(seq, command));
            let t1 = Instant::now();
            while t1.elapsed() < Duration::from_millis(500) {
                self.pump(Duration::from_millis(20));
                if let Some(r) = self.heard[from..].iter().find_map(|h| match h {
                    Heard::Reply(r) if r.seq == seq => Some(*r),
                    _ => None,
                }) {
                    return r;
                }
            }
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "no reply to {command:?}"
            );
        }
    }
}

fn sweep(frames: u32) -> Command {
    Command::Sweep(SweepRequest {
        disc: 0,
        axis: 0,
        colour: false,
        keep_board: false,
        frames,
    })
}

#[test]
fn bad_commands_are_refused_with_their_reasons() {
    let tmp = tempfile::tempdir().unwrap();
    let mut h = Head::start(&tmp.path().join("work"), &[]);
    let hello = h.ask(Command::Hello);
    assert_eq!(
        (hello.outcome, hello.state),
        (Outcome::Accepted, HeadState::Idle)
    );

    // out of order: no calibration, nothing to stop, no shots
    assert_eq!(h.ask(sweep(0)).outcome, Outcome::NotCalibrated);
    assert_eq!(h.ask(Command::Stop).outcome, Outcome::NothingToStop);
    let r = h.ask(Command::Calibrate);
    assert_eq!((r.outcome, r.field, r.detail), (Outcome::TooFewShots, 1, 3));

    // out of range, with the field and its limit
    let r = h.ask(Command::Preview(PreviewRequest {
        on: true,
        every: 0,
        scale: 0,
        picture: false,
        zoom: [0; 4],
    }));
    assert_eq!(
        (r.outcome, r.field, r.detail),
        (Outcome::OutOfRange, 2, 1000)
    );
    let r = h.ask(Command::Preview(PreviewRequest {
        on: true,
        every: 5,
        scale: 64,
        picture: false,
        zoom: [0; 4],
    }));
    // the head's own limit: a 640×480 picture keeps at least 8 pixels a side at scale 60
    assert_eq!((r.outcome, r.field, r.detail), (Outcome::OutOfRange, 3, 60));
    let r = h.ask(Command::Turn { steps: 0 });
    assert_eq!((r.outcome, r.field), (Outcome::OutOfRange, 1));

    // the rig's camera: exposure and gain, within their ranges (its limit told); no focus
    let camera = |control, value| Command::Camera { control, value };
    assert_eq!(h.ask(camera(0, 100)).outcome, Outcome::Accepted);
    let r = h.ask(camera(0, 0));
    assert_eq!((r.outcome, r.field, r.detail), (Outcome::OutOfRange, 2, 1));
    let r = h.ask(camera(1, 5000));
    assert_eq!(
        (r.outcome, r.field, r.detail),
        (Outcome::OutOfRange, 2, 1000)
    );
    let r = h.ask(camera(4, 100));
    assert_eq!((r.outcome, r.field), (Outcome::OutOfRange, 1));
    // what this head has not got: a focus, a turntable (the demo scene has one view)
    assert_eq!(h.ask(camera(2, 100)).outcome, Outcome::NotHere);
    assert_eq!(h.ask(Command::Turn { steps: 1 }).outcome, Outcome::NotHere);

    // unknown: a newer host's command 12, its number kept
    let from = h.heard.len();
    h.write(&raw_command(&[0x63, 12]));
    let r = h.until(from, Duration::from_secs(10), |x| match x {
        Heard::Reply(r) if r.seq == 0x63 => Some(*r),
        _ => None,
    });
    assert_eq!((r.outcome, r.detail), (Outcome::Unknown, 12));
    // malformed: a sweep cut short
    let from = h.heard.len();
    h.write(&raw_command(&[0x64, 4, 1]));
    let r = h.until(from, Duration::from_secs(10), |x| match x {
        Heard::Reply(r) if r.seq == 0x64 => Some(*r),
        _ => None,
    });
    assert_eq!(r.outcome, Outcome::Malformed);
    // oversized: refused unread, and the link goes on
    let from = h.heard.len();
    let mut big = vec![0u8];
    big.extend(std::iter::repeat_n(0x41u8, 5000));
    big.push(0);
    h.write(&big);
    let r = h.until(from, Duration::from_secs(10), |x| match x {
        Heard::Reply(r) if r.outcome == Outcome::Oversized => Some(*r),
        _ => None,
    });
    assert_eq!(r.seq, 0);
    // a damaged frame gets no reply; the next good one does
    let mut damaged = Head::frame(500, Command::Hello);
    damaged[3] ^= 0x10;
    h.write(&damaged);
    assert_eq!(h.ask(Command::Hello).outcome, Outcome::Accepted);

    // busy: a preview runs; a sweep waits for it to stop; a shot does not (the preview makes
    // way and comes back after it)
    let on = Command::Preview(PreviewRequest {
        on: true,
        every: 2,
        scale: 0,
        picture: false,
        zoom: [0; 4],
    });
    let r = h.ask(on);
    assert_eq!(
        (r.outcome, r.state),
        (Outcome::Accepted, HeadState::Previewing)
    );
    let from = h.heard.len();
    let r = h.ask(Command::Shot { board: false });
    assert_eq!(
        (r.outcome, r.state),
        (Outcome::Accepted, HeadState::Calibrating)
    );
    h.until(from, Duration::from_secs(60), |x| match x {
        Heard::Shot(s) => Some(s.seq),
        _ => None,
    });
    let from = h.heard.len();
    h.until(from, Duration::from_secs(20), |x| match x {
        Heard::Preview(_, w, hh) => Some((*w, *hh)),
        _ => None,
    });
    let r = h.ask(sweep(10));
    assert_eq!((r.outcome, r.state), (Outcome::Busy, HeadState::Previewing));
    let r = h.ask(Command::Stop);
    assert_eq!(r.outcome, Outcome::Accepted);
    let t0 = Instant::now();
    while h.ask(Command::Hello).state != HeadState::Idle {
        assert!(t0.elapsed() < Duration::from_secs(20), "the preview stops");
        std::thread::sleep(Duration::from_millis(50));
    }

    // the same number again: answered again, not done twice
    h.seq += 1;
    let seq = h.seq;
    let shot = Head::frame(seq, Command::Shot { board: true });
    let from = h.heard.len();
    h.write(&shot);
    h.until(from, Duration::from_secs(30), |x| match x {
        Heard::Shot(s) if s.seq == seq => Some(*s),
        _ => None,
    });
    h.write(&shot);
    h.pump(Duration::from_millis(800));
    let replies = h.heard[from..]
        .iter()
        .filter(|x| matches!(x, Heard::Reply(r) if r.seq == seq))
        .count();
    let shots = h.heard[from..]
        .iter()
        .filter(|x| matches!(x, Heard::Shot(s) if s.seq == seq))
        .count();
    assert_eq!((replies, shots), (2, 1));
}

/// A command frame around any body, as a buggy or newer host would send it.
fn raw_command(body: &[u8]) -> Vec<u8> {
    let crc = crc32(&[&[scanner_wire::VERSION], body].concat());
    let mut raw = vec![scanner_wire::VERSION];
    raw.extend_from_slice(body);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0u8];
    out.extend(cobs_encode(&raw));
    out.push(0);
    out
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn cobs_encode(raw: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for block in raw.split(|&b| b == 0) {
        // blocks of at most 254 bytes: a command is far shorter
        out.push(block.len() as u8 + 1);
        out.extend_from_slice(block);
    }
    out
}

#[test]
fn a_whole_job_by_commands_shots_calibration_and_sweeps_at_turned_views() {
    let tmp = tempfile::tempdir().unwrap();
    let work = tmp.path().join("work");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/part-360.toml");
    let mut h = Head::start(&work, &["--scene", scene]);

    for k in 0..6u16 {
        let r = h.ask(Command::Shot { board: false });
        assert_eq!(r.outcome, Outcome::Accepted);
        let seq = r.seq;
        let from = 0;
        let s = h.until(from, Duration::from_secs(60), |x| match x {
            Heard::Shot(s) if s.seq == seq => Some(*s),
            _ => None,
        });
        assert_eq!((s.found, s.kept), (0, k + 1), "{s:?}");
        assert!(s.points >= 40 && s.cover != 0, "{s:?}");
    }
    let r = h.ask(Command::Calibrate);
    assert_eq!((r.outcome, r.field), (Outcome::TooFewShots, 2));
    let r = h.ask(Command::Shot { board: true });
    let seq = r.seq;
    let s = h.until(0, Duration::from_secs(60), |x| match x {
        Heard::Shot(s) if s.seq == seq => Some(*s),
        _ => None,
    });
    assert_eq!(s.found, 0, "{s:?}");
    let r = h.ask(Command::Calibrate);
    assert_eq!(r.outcome, Outcome::Accepted);
    let seq = r.seq;
    let c = h.until(0, Duration::from_secs(120), |x| match x {
        Heard::Calibrated(c) if c.seq == seq => Some(*c),
        _ => None,
    });
    assert_eq!(c.result, 0, "{c:?}");
    assert!(c.rms_px < 0.3 && c.board_rms_px < 0.5, "{c:?}");
    // the calibration the head made is the rig's own camera and board
    let made = scanner_calib::file::CalibrationFile::load(&work.join("calibration.toml")).unwrap();
    let text = std::fs::read_to_string(scene).unwrap();
    let scene =
        scanner_rig::Scene::from_toml_in(&text, Path::new(scene).parent().unwrap()).unwrap();
    let truth = scanner_rig::Rig::new(scene).unwrap().truth_calibration();
    let (m, t) = (made.camera().unwrap(), truth.camera().unwrap());
    let fx = (m.fx() / t.fx() - 1.0).abs();
    assert!(fx < 0.002, "fx {} against {}", m.fx(), t.fx());

    // sweeps at two views of the turntable, turned between them
    let mut ids = Vec::new();
    for _ in 0..2 {
        let from = h.heard.len();
        let r = h.ask(sweep(0));
        assert_eq!(
            (r.outcome, r.state),
            (Outcome::Accepted, HeadState::Sweeping)
        );
        let done = h.until(from, Duration::from_secs(120), |x| match x {
            Heard::Status(s) if s.done => Some(*s),
            _ => None,
        });
        assert!(done.points > 1000, "{done:?}");
        ids.push(done.scan_id);
        // turned as soon as the sweep's last status arrives: the head does not answer "busy"
        // for the moment its worker takes to return
        assert_eq!(h.ask(Command::Turn { steps: 1 }).outcome, Outcome::Accepted);
    }
    assert_ne!(ids[0], ids[1], "each sweep is a scan of its own");

    // a sweep stopped midway ends with a final status that says so
    let from = h.heard.len();
    h.ask(sweep(0));
    h.until(from, Duration::from_secs(60), |x| match x {
        Heard::Points(..) => Some(()),
        _ => None,
    });
    assert_eq!(h.ask(Command::Stop).outcome, Outcome::Accepted);
    let done = h.until(from, Duration::from_secs(60), |x| match x {
        Heard::Status(s) if s.done => Some(*s),
        _ => None,
    });
    assert_eq!(done.ended, scanner_wire::EndReason::Stopped);
}

/// A head that stops hearing its host (a crashed studio, a silent cable) switches its laser
/// off, and says so (once) when the host is heard again.
#[test]
fn a_silent_host_gets_the_laser_switched_off_and_is_told() {
    let tmp = tempfile::tempdir().unwrap();
    let mut h = Head::start(&tmp.path().join("head"), &[]);
    assert_eq!(
        h.ask(Command::Laser { on: true }).outcome,
        Outcome::Accepted
    );
    // nothing for longer than the head waits
    let quiet = scanner_device::cli::serve::LASER_SAFE_AFTER + Duration::from_millis(1500);
    let t0 = Instant::now();
    while t0.elapsed() < quiet {
        h.pump(Duration::from_millis(100));
    }
    let from = h.heard.len();
    assert_eq!(h.ask(Command::Hello).outcome, Outcome::Accepted);
    let told = h.until(from, Duration::from_secs(10), |x| match x {
        Heard::Notice(n) if n.kind == scanner_wire::NoticeKind::LaserOffUnheard => Some(*n),
        _ => None,
    });
    assert!(
        u64::from(told.seconds) >= scanner_device::cli::serve::LASER_SAFE_AFTER.as_secs(),
        "{told:?}"
    );
    // told once: a host that keeps talking hears it no more
    let from = h.heard.len();
    for _ in 0..3 {
        assert_eq!(h.ask(Command::Hello).outcome, Outcome::Accepted);
    }
    h.pump(Duration::from_millis(300));
    assert!(
        !h.heard[from..]
            .iter()
            .any(|x| matches!(x, Heard::Notice(_))),
        "{:?}",
        &h.heard[from..]
    );
}

/// A real camera's exposure set by hand through the service: accepted and set on the device
/// (the head's log names it), refused as out of range beyond the camera's own limit.
#[test]
#[ignore = "needs a V4L2 camera with a manual exposure (SCANNER_CAMERA=/dev/videoN, default /dev/video0)"]
fn a_real_cameras_exposure_is_set_by_hand_through_the_service() {
    let device = std::env::var("SCANNER_CAMERA").unwrap_or_else(|_| "/dev/video0".into());
    let tmp = tempfile::tempdir().unwrap();
    let mut h = Head::start_on(&device, &tmp.path().join("work"), &[]);
    let camera = |control, value| Command::Camera { control, value };
    let r = h.ask(camera(0, 100));
    assert_eq!(r.outcome, Outcome::Accepted, "exposure 100 (10 ms): {r:?}");
    let r = h.ask(camera(0, 1_000_000));
    assert_eq!((r.outcome, r.field), (Outcome::OutOfRange, 2), "{r:?}");
    assert!(r.detail > 100, "the camera's largest exposure: {r:?}");
}
