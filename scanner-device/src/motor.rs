//! A turntable scanner's motor and lasers over serial, in its own firmware's words: FabScanPi's
//! (G-code lines; every character echoed, then `>` when the command is done) and Ciclop's
//! horus-fw (a grbl: `ok` or `error: …` for each line; moves in degrees). And a frame source
//! that turns the platform one step before every frame after the first.
//!
//! Every command waits for its acknowledgement within a timeout; a reply that never comes, or
//! comes garbled, is an error naming the command and what came back, and the scan ends there
//! with what it already sent kept.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use crate::source::{FrameSource, OwnedFrame, SourceError};

/// Which firmware the board runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    /// FabScanPi's (mariolukas/FabScanPi-Firmware): `G02 T<steps> F<feed>` turns and returns
    /// when done, `M19`/`M20` and `M21`/`M22` switch lasers 0 and 1, `M200` tells the version.
    FabScan,
    /// Ciclop's horus-fw (bqlabs): `G1X<degrees>` moves to an absolute angle, `M71T<n>` and
    /// `M70T<n>` switch laser `n` (from 1), `G50` sets the origin.
    Horus,
}

/// The longest reply line read, bytes.
pub const MAX_REPLY: usize = 256;

/// Why the board did not do what it was told.
#[derive(Debug, thiserror::Error)]
pub enum MotorError {
    /// The port failed.
    #[error("the motor board's port: {0}")]
    Io(#[from] std::io::Error),
    /// No acknowledgement within the timeout.
    #[error("the motor board did not answer {command:?} within {waited_ms} ms (got {got:?})")]
    Timeout {
        /// The command.
        command: String,
        /// How long it waited.
        waited_ms: u64,
        /// What came before the wait ran out.
        got: String,
    },
    /// A reply that is not this firmware's answer to the command.
    #[error("the motor board answered {command:?} with {reply:?}: not {firmware}'s reply")]
    Garbled {
        /// The command.
        command: String,
        /// The reply.
        reply: String,
        /// The firmware spoken.
        firmware: &'static str,
    },
    /// The firmware refused the command.
    #[error("the motor board refused {command:?}: {reply:?}")]
    Refused {
        /// The command.
        command: String,
        /// Its reply.
        reply: String,
    },
    /// The board is not this firmware.
    #[error("the board on the port is not {firmware} (it said {said:?})")]
    WrongFirmware {
        /// The firmware expected.
        firmware: &'static str,
        /// What it said.
        said: String,
    },
}

impl Firmware {
    fn name(self) -> &'static str {
        match self {
            Firmware::FabScan => "FabScanPi's firmware",
            Firmware::Horus => "horus-fw",
        }
    }
}

/// A motor board on a port.
pub struct Controller<P> {
    port: P,
    firmware: Firmware,
    timeout: Duration,
    /// Bytes read past the last line.
    pending: Vec<u8>,
    /// Horus: the platform's angle so far, degrees (its moves are absolute).
    degrees: f64,
    /// Steps in one turn (Horus: to turn steps into degrees).
    steps_per_turn: u32,
    /// Commands acknowledged.
    pub acknowledged: u64,
}

impl<P: Read + Write> Controller<P> {
    /// Greets the board on `port` and checks that it speaks `firmware` (FabScanPi: its version;
    /// Horus: its banner after a reset).
    ///
    /// # Errors
    /// [`MotorError`]: no answer, or another firmware's.
    pub fn connect(
        port: P,
        firmware: Firmware,
        steps_per_turn: u32,
        timeout: Duration,
    ) -> Result<Self, MotorError> {
        let mut c = Controller {
            port,
            firmware,
            timeout,
            pending: Vec::new(),
            degrees: 0.0,
            steps_per_turn: steps_per_turn.max(1),
            acknowledged: 0,
        };
        match firmware {
            Firmware::FabScan => {
                let version = c.command("M200")?;
                if version.is_empty() {
                    return Err(MotorError::WrongFirmware {
                        firmware: firmware.name(),
                        said: version,
                    });
                }
            }
            Firmware::Horus => {
                c.port.write_all(b"\x18\r\n")?;
                let deadline = Instant::now() + c.timeout;
                let banner = loop {
                    let line = c.line(deadline, "a reset (Ctrl-X)")?;
                    if !line.trim().is_empty() {
                        break line;
                    }
                };
                if !banner.starts_with("Horus 0.2") {
                    return Err(MotorError::WrongFirmware {
                        firmware: firmware.name(),
                        said: banner,
                    });
                }
                c.command("G50")?;
            }
        }
        Ok(c)
    }

    /// One line from the board (without its end), waiting until `deadline`.
    fn line(&mut self, deadline: Instant, command: &str) -> Result<String, MotorError> {
        loop {
            if let Some(i) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=i).collect();
                return Ok(String::from_utf8_lossy(&line)
                    .trim_end_matches(['\r', '\n'])
                    .to_string());
            }
            if self.pending.len() > MAX_REPLY {
                return Err(MotorError::Garbled {
                    command: command.into(),
                    reply: String::from_utf8_lossy(&self.pending).into_owned(),
                    firmware: self.firmware.name(),
                });
            }
            if Instant::now() >= deadline {
                return Err(MotorError::Timeout {
                    command: command.into(),
                    waited_ms: self.timeout.as_millis() as u64,
                    got: String::from_utf8_lossy(&self.pending).into_owned(),
                });
            }
            let mut buf = [0u8; 64];
            match self.port.read(&mut buf) {
                Ok(0) => std::thread::sleep(Duration::from_millis(2)),
                Ok(n) => self.pending.extend_from_slice(&buf[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// Sends `command` and waits for its acknowledgement; returns what the board said besides
    /// (FabScanPi: the lines between the echo and `>`).
    ///
    /// # Errors
    /// [`MotorError`]: no acknowledgement in time, a garbled or refusing one.
    pub fn command(&mut self, command: &str) -> Result<String, MotorError> {
        let deadline = Instant::now() + self.timeout;
        let garbled = |reply: String, firmware: Firmware| MotorError::Garbled {
            command: command.into(),
            reply,
            firmware: firmware.name(),
        };
        let said = match self.firmware {
            Firmware::FabScan => {
                self.port.write_all(format!("{command}\n").as_bytes())?;
                let echo = self.line(deadline, command)?;
                if echo.trim() != command {
                    return Err(garbled(echo, self.firmware));
                }
                let mut said = Vec::new();
                loop {
                    let line = self.line(deadline, command)?;
                    if line.trim() == ">" {
                        break said.join("\n");
                    }
                    if said.len() >= 16 {
                        return Err(garbled(said.join("\n"), self.firmware));
                    }
                    said.push(line);
                }
            }
            Firmware::Horus => {
                self.port.write_all(format!("{command}\r\n").as_bytes())?;
                let reply = loop {
                    let line = self.line(deadline, command)?;
                    if !line.trim().is_empty() {
                        break line;
                    }
                };
                if let Some(why) = reply.strip_prefix("error:") {
                    return Err(MotorError::Refused {
                        command: command.into(),
                        reply: why.trim().into(),
                    });
                }
                if reply.trim() != "ok" {
                    return Err(garbled(reply, self.firmware));
                }
                String::new()
            }
        };
        self.acknowledged += 1;
        Ok(said)
    }

    /// Switches laser `n` (from 0) on or off.
    ///
    /// # Errors
    /// As [`Controller::command`].
    pub fn laser(&mut self, n: u8, on: bool) -> Result<(), MotorError> {
        let command = match (self.firmware, n, on) {
            // FabScanPi's server: laser 0 is M21/M22, laser 1 M19/M20
            (Firmware::FabScan, 0, true) => "M21".to_string(),
            (Firmware::FabScan, 0, false) => "M22".to_string(),
            (Firmware::FabScan, _, true) => "M19".to_string(),
            (Firmware::FabScan, _, false) => "M20".to_string(),
            (Firmware::Horus, n, true) => format!("M71T{}", u16::from(n) + 1),
            (Firmware::Horus, n, false) => format!("M70T{}", u16::from(n) + 1),
        };
        self.command(&command).map(|_| ())
    }

    /// Turns the platform by `steps` motor steps (FabScanPi's way: it answers when the turn is
    /// done; horus-fw answers when the move is queued, and a turn of 3.6° at its speed takes
    /// well under the frame's wait).
    ///
    /// # Errors
    /// As [`Controller::command`].
    pub fn turn(&mut self, steps: i64) -> Result<(), MotorError> {
        match self.firmware {
            Firmware::FabScan => self.command(&format!("G02 T{steps} F200")).map(|_| ()),
            Firmware::Horus => {
                self.degrees += 360.0 * steps as f64 / f64::from(self.steps_per_turn);
                self.command(&format!("G1X{:.4}", self.degrees)).map(|_| ())
            }
        }
    }
}

/// A frame source on a turning platform: before every frame after the first, the platform turns
/// `steps`; the laser is switched on before the first frame and off when the frames end.
pub struct Turning<P> {
    inner: Box<dyn FrameSource>,
    controller: Controller<P>,
    laser: u8,
    steps: i64,
    started: bool,
    /// Frames to take (one turn and the closing frame, or as asked).
    frames: u32,
    taken: u32,
}

impl<P: Read + Write> Turning<P> {
    /// `inner`'s frames, the platform turned `steps` between them by `controller`, laser `laser`
    /// on; `frames` frames in all.
    pub fn new(
        inner: Box<dyn FrameSource>,
        controller: Controller<P>,
        laser: u8,
        steps: i64,
        frames: u32,
    ) -> Self {
        Turning {
            inner,
            controller,
            laser,
            steps,
            started: false,
            frames,
            taken: 0,
        }
    }

    fn motor(e: MotorError) -> SourceError {
        SourceError::Motor(e.to_string())
    }
}

impl<P: Read + Write> FrameSource for Turning<P> {
    fn describe(&self) -> String {
        format!(
            "{} on a platform turning {} steps a frame",
            self.inner.describe(),
            self.steps
        )
    }
    fn format(&self) -> scanner_core::stripe::PixelFormat {
        self.inner.format()
    }
    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }
    fn controls(&self) -> scanner_wire::Controls {
        self.inner.controls()
    }
    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        self.inner.reference()
    }
    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        if self.taken >= self.frames {
            self.controller
                .laser(self.laser, false)
                .map_err(Self::motor)?;
            return Ok(None);
        }
        if self.started {
            self.controller.turn(self.steps).map_err(Self::motor)?;
        } else {
            self.controller
                .laser(self.laser, true)
                .map_err(Self::motor)?;
            self.started = true;
        }
        self.taken += 1;
        self.inner.next_frame()
    }
    fn give_back(&mut self, frame: OwnedFrame) {
        self.inner.give_back(frame);
    }
    fn frames_left(&self) -> Option<usize> {
        let own = (self.frames - self.taken) as usize;
        Some(self.inner.frames_left().map_or(own, |n| n.min(own)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A port that answers from a script and records what was written.
    struct Script {
        replies: std::collections::VecDeque<u8>,
        written: Vec<u8>,
    }

    impl Read for Script {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.replies.len());
            for b in buf.iter_mut().take(n) {
                *b = self.replies.pop_front().unwrap_or(0);
            }
            Ok(n)
        }
    }

    impl Write for Script {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.written.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    fn script(replies: &str) -> Script {
        Script {
            replies: replies.bytes().collect(),
            written: Vec::new(),
        }
    }

    #[test]
    fn fabscan_commands_are_echoed_and_acknowledged() {
        let port = script("M200\nv.20210318\n>\nG02 T64 F200\n>\nM21\n>\n");
        let mut c =
            Controller::connect(port, Firmware::FabScan, 6400, Duration::from_millis(50)).unwrap();
        c.turn(64).unwrap();
        c.laser(0, true).unwrap();
        assert_eq!(c.acknowledged, 3);
        assert_eq!(
            String::from_utf8_lossy(&c.port.written),
            "M200\nG02 T64 F200\nM21\n"
        );
    }

    #[test]
    fn horus_moves_in_absolute_degrees() {
        let port = script(
            "\r\nHorus 0.2 ['$' for help]\r\nok\r\nok\r\nok\r\nerror: Bad number format\r\n",
        );
        let mut c =
            Controller::connect(port, Firmware::Horus, 6400, Duration::from_millis(50)).unwrap();
        c.turn(64).unwrap();
        c.turn(64).unwrap();
        let e = c.laser(0, true).unwrap_err();
        assert!(matches!(e, MotorError::Refused { .. }), "{e}");
        assert_eq!(
            String::from_utf8_lossy(&c.port.written),
            "\x18\r\nG50\r\nG1X3.6000\r\nG1X7.2000\r\nM71T1\r\n"
        );
    }

    #[test]
    fn silence_and_garble_are_errors_that_name_the_command() {
        let port = script("M200\nv1\n>\nG02 T64 F2");
        let mut c =
            Controller::connect(port, Firmware::FabScan, 6400, Duration::from_millis(30)).unwrap();
        let e = c.turn(64).unwrap_err();
        assert!(
            matches!(&e, MotorError::Timeout { command, .. } if command == "G02 T64 F200"),
            "{e}"
        );
        let port = script("M200\nv1\n>\nG0? T64 F200\n>\n");
        let mut c =
            Controller::connect(port, Firmware::FabScan, 6400, Duration::from_millis(30)).unwrap();
        let e = c.turn(64).unwrap_err();
        assert!(matches!(e, MotorError::Garbled { .. }), "{e}");
        let port = script("Grbl 1.1h ['$' for help]\r\n");
        let e = Controller::connect(port, Firmware::Horus, 6400, Duration::from_millis(30))
            .err()
            .unwrap();
        assert!(matches!(e, MotorError::WrongFirmware { .. }), "{e}");
    }
}
