//! How soon the head's service answers a command (`scanner-device serve` on the virtual rig,
//! over a pseudo-terminal as over a cable): the round trip of `Hello` from the host's write to
//! its reply, idle and while a 1280×960 sweep streams its points down the same link, and how
//! many preview pictures a second reach the host. `cargo bench -p scanner-device --bench
//! commands`; prints a table. Target (issue 55): a command acknowledged within 100 ms.

use std::io::{Read, Write};
use std::process::{Command as Process, Stdio};
use std::time::{Duration, Instant};

use scanner_wire::{
    Command, CommandFrame, Decoder, MAX_COMMAND_ENCODED, MAX_ENCODED, Message, PreviewRequest,
    SweepRequest, encode_command,
};
use serialport::{SerialPort, TTYPort};

struct Link {
    port: TTYPort,
    decoder: Box<Decoder<MAX_ENCODED>>,
    seq: u32,
    previews: u32,
    pictures: u32,
    picture_bytes: u64,
    done: bool,
}

impl Link {
    /// Sends a command; the time until its reply.
    fn ask(&mut self, command: Command) -> Duration {
        self.seq += 1;
        let seq = self.seq;
        let mut out = [0u8; MAX_COMMAND_ENCODED];
        let n = encode_command(&CommandFrame { seq, command }, &mut out).unwrap();
        let t0 = Instant::now();
        self.port.write_all(&out[..n]).unwrap();
        let mut buf = [0u8; 65536];
        loop {
            assert!(t0.elapsed() < Duration::from_secs(30), "no reply");
            let n = match self.port.read(&mut buf) {
                Ok(n) => n,
                Err(_) => continue,
            };
            let mut answered = false;
            let (previews, done) = (&mut self.previews, &mut self.done);
            let (pictures, bytes) = (&mut self.pictures, &mut self.picture_bytes);
            self.decoder.feed(&buf[..n], |m| match m {
                Ok(Message::Reply(r)) if r.seq == seq => answered = true,
                Ok(Message::Preview(_)) => *previews += 1,
                Ok(Message::Picture(p)) => {
                    *pictures += 1;
                    *bytes += p.jpeg.len() as u64;
                }
                Ok(Message::Status(s)) if s.done => *done = true,
                _ => {}
            });
            if answered {
                return t0.elapsed();
            }
        }
    }
}

fn row(what: &str, mut t: Vec<Duration>) {
    t.sort();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let p = |q: f64| t[((t.len() - 1) as f64 * q).round() as usize];
    println!(
        "| {what} | {} | {:.2} | {:.2} | {:.2} |",
        t.len(),
        ms(p(0.5)),
        ms(p(0.99)),
        ms(*t.last().unwrap())
    );
}

fn main() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/part-360.toml");
    // the rig's true calibration, so that a sweep can start at once
    let text = std::fs::read_to_string(scene).unwrap();
    let parsed =
        scanner_rig::Scene::from_toml_in(&text, std::path::Path::new(scene).parent().unwrap())
            .unwrap();
    let cal = tmp.path().join("cal.toml");
    scanner_rig::Rig::new(parsed)
        .unwrap()
        .truth_calibration()
        .save(&cal)
        .unwrap();
    let (mut port, device) = TTYPort::pair().unwrap();
    port.set_timeout(Duration::from_millis(5)).unwrap();
    let mut child = Process::new(env!("CARGO_BIN_EXE_scanner-device"))
        .args([
            "serve",
            "--source",
            "rig",
            "--scene",
            scene,
            "--calibration",
        ])
        .arg(&cal)
        .arg("--out")
        .arg(format!("serial:{}", device.name().unwrap()))
        .arg("--work")
        .arg(tmp.path().join("work"))
        .current_dir(tmp.path())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut link = Link {
        port,
        decoder: Box::new(Decoder::new()),
        seq: 0,
        previews: 0,
        pictures: 0,
        picture_bytes: 0,
        done: false,
    };
    // the head is listening once it answers
    std::thread::sleep(Duration::from_millis(500));
    link.ask(Command::Hello);
    println!("| state | commands | median ms | p99 ms | max ms |");
    println!("|---|---|---|---|---|");
    let idle: Vec<Duration> = (0..200)
        .map(|_| {
            std::thread::sleep(Duration::from_millis(2));
            link.ask(Command::Hello)
        })
        .collect();
    row("idle", idle);
    link.ask(Command::Sweep(SweepRequest {
        disc: 0,
        axis: 0,
        colour: false,
        keep_board: false,
        frames: 0,
    }));
    let mut sweeping = Vec::new();
    while !link.done && sweeping.len() < 2000 {
        sweeping.push(link.ask(Command::Hello));
        std::thread::sleep(Duration::from_millis(10));
    }
    row("sweeping 1280×960", sweeping);
    let t0 = Instant::now();
    link.ask(Command::Preview(PreviewRequest {
        on: true,
        every: 1,
        scale: 0,
        picture: true,
        zoom: [0; 4],
    }));
    let mut previewing = Vec::new();
    link.previews = 0;
    while t0.elapsed() < Duration::from_secs(5) {
        previewing.push(link.ask(Command::Hello));
        std::thread::sleep(Duration::from_millis(10));
    }
    let secs = t0.elapsed().as_secs_f64();
    let rate = f64::from(link.previews) / secs;
    let pictures = f64::from(link.pictures) / secs;
    let bytes = link.picture_bytes as f64 / f64::from(link.pictures.max(1));
    row("previewing with pictures", previewing);
    link.ask(Command::Stop);
    println!(
        "\npreviews reaching the host: {rate:.1}/s (160×120 thumbnails), with {pictures:.1} pictures/s (1280×960 averaged to 640×480, JPEG {:.1} kB each): {:.1} pictures/s fit a 1 MB/s link",
        bytes / 1e3,
        1e6 / (bytes + 19_500.0)
    );
    let _ = child.kill();
    let _ = child.wait();
}
