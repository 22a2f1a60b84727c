//! The link to the host: a serial port, a file or stdout, written by its own thread so that a
//! slow link never blocks the camera. Encoded frames travel in a fixed pool of buffers: when
//! every buffer is waiting for the link, the next point packet is dropped whole (and counted) —
//! the stream is never cut inside a frame.

use std::io::Write;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};

/// Where the stream goes, parsed from `serial:PATH[@BAUD]`, `file:PATH` (or a path) and `-`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    /// A serial port and its baud rate.
    Serial {
        /// Device path, e.g. `/dev/ttyUSB0`.
        path: String,
        /// Baud rate.
        baud: u32,
    },
    /// A file (created or truncated).
    File(std::path::PathBuf),
    /// Standard output.
    Stdout,
}

impl std::str::FromStr for Target {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "-" {
            return Ok(Target::Stdout);
        }
        if let Some(rest) = s.strip_prefix("serial:") {
            let (path, baud) = match rest.split_once('@') {
                Some((p, b)) => (
                    p,
                    b.parse::<u32>()
                        .map_err(|_| format!("{s:?}: {b:?} is not a baud rate"))?,
                ),
                None => (rest, 921_600),
            };
            if path.is_empty() {
                return Err(format!("{s:?}: no serial device path"));
            }
            return Ok(Target::Serial {
                path: path.to_string(),
                baud,
            });
        }
        let path = s.strip_prefix("file:").unwrap_or(s);
        if path.is_empty() {
            return Err("empty output path".into());
        }
        Ok(Target::File(path.into()))
    }
}

impl Target {
    /// Opens the target for writing.
    ///
    /// # Errors
    /// Names the device or file and why it cannot be opened.
    pub fn open(&self) -> Result<Box<dyn Write + Send>> {
        Ok(match self {
            Target::Stdout => Box::new(std::io::stdout()),
            Target::File(p) => Box::new(
                std::fs::File::create(p)
                    .with_context(|| format!("cannot write the stream to {}", p.display()))?,
            ),
            Target::Serial { path, baud } => Box::new(
                serialport::new(path, *baud)
                    .timeout(Duration::from_secs(2))
                    .open_native()
                    .with_context(|| format!("cannot open serial port {path} at {baud} baud"))?,
            ),
        })
    }
}

/// What the link did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Bytes written.
    pub bytes: u64,
    /// Frames written.
    pub frames: u64,
    /// Point packets dropped because the link was busy.
    pub dropped: u64,
}

/// A filled buffer and how many of its bytes to write.
type Filled = (Vec<u8>, usize);

/// A writer thread fed through a bounded pool of buffers. Buffers keep their full length: a
/// message is encoded into the front of one and sent with its length, so nothing is cleared or
/// zeroed per packet.
pub struct Link {
    tx: Option<SyncSender<Filled>>,
    back: Receiver<Vec<u8>>,
    free: Vec<Vec<u8>>,
    thread: Option<JoinHandle<std::io::Result<u64>>>,
    stats: LinkStats,
}

impl Link {
    /// Starts the writer on `out` with `depth` buffers of `capacity` bytes (allocated now, once).
    pub fn spawn(mut out: Box<dyn Write + Send>, depth: usize, capacity: usize) -> Link {
        let depth = depth.max(1);
        let (tx, rx) = sync_channel::<Filled>(depth);
        let (back_tx, back) = sync_channel::<Vec<u8>>(depth);
        let thread = std::thread::spawn(move || -> std::io::Result<u64> {
            let mut bytes = 0u64;
            while let Ok((buf, len)) = rx.recv() {
                out.write_all(&buf[..len.min(buf.len())])?;
                out.flush()?;
                bytes += len as u64;
                // The pool is as large as the channel: this never blocks for long.
                if back_tx.send(buf).is_err() {
                    break;
                }
            }
            out.flush()?;
            Ok(bytes)
        });
        Link {
            tx: Some(tx),
            back,
            free: (0..depth).map(|_| vec![0; capacity]).collect(),
            thread: Some(thread),
            stats: LinkStats::default(),
        }
    }

    fn reclaim(&mut self) {
        while let Ok(b) = self.back.try_recv() {
            self.free.push(b);
        }
    }

    /// A free buffer (its full length, old contents), or `None` when every buffer is waiting
    /// for the link.
    pub fn buffer(&mut self) -> Option<Vec<u8>> {
        self.reclaim();
        self.free.pop()
    }

    /// Counts a frame dropped for want of a buffer.
    pub fn count_drop(&mut self) {
        self.stats.dropped += 1;
    }

    /// Queues the first `len` bytes of a buffer.
    ///
    /// # Errors
    /// The writer has stopped (the link failed): the error says why.
    pub fn send(&mut self, buf: Vec<u8>, len: usize) -> Result<()> {
        let tx = self
            .tx
            .as_ref()
            .ok_or_else(|| anyhow!("link already closed"))?;
        match tx.try_send((buf, len)) {
            Ok(()) => {
                self.stats.frames += 1;
                self.stats.bytes += len as u64;
                Ok(())
            }
            Err(TrySendError::Full((b, _))) => {
                // Cannot happen with the pool as large as the channel; keep the buffer.
                self.free.push(b);
                self.stats.dropped += 1;
                Ok(())
            }
            Err(TrySendError::Disconnected(_)) => Err(self.failure()),
        }
    }

    /// Waits for a free buffer (for messages that must not be dropped: the final status).
    ///
    /// # Errors
    /// The writer has stopped.
    pub fn buffer_blocking(&mut self) -> Result<Vec<u8>> {
        if let Some(b) = self.buffer() {
            return Ok(b);
        }
        match self.back.recv() {
            Ok(b) => Ok(b),
            Err(_) => Err(self.failure()),
        }
    }

    fn failure(&mut self) -> anyhow::Error {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Err(e))) => anyhow!("the link failed: {e}"),
            Some(Err(_)) => anyhow!("the link's writer panicked"),
            _ => anyhow!("the link closed"),
        }
    }

    /// What has been queued and dropped so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Closes the link after everything queued is written.
    ///
    /// # Errors
    /// The link failed.
    pub fn finish(mut self) -> Result<LinkStats> {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(_))) | None => Ok(self.stats),
            Some(Ok(Err(e))) => bail!("the link failed: {e}"),
            Some(Err(_)) => bail!("the link's writer panicked"),
        }
    }
}
