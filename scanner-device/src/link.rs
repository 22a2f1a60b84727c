//! The link to the host: a serial port, a file or stdout, written by its own thread so that a
//! slow link never blocks the camera. Encoded frames travel in a fixed pool of buffers: when
//! every buffer is waiting for the link, the next point packet is dropped whole (and counted) —
//! the stream is never cut inside a frame.

use std::io::Write;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::Duration;

use scanner_io::link_spec::{SerialSpec, SpecError};

/// Why the link could not be opened or stopped working.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// `--out` names nothing a stream can go to.
    #[error("{text:?}: {why}")]
    BadTarget {
        /// What was given.
        text: String,
        /// What is wrong with it.
        why: SpecError,
    },
    /// An empty output path.
    #[error("empty output path (give a file, serial:PATH@BAUD or -)")]
    EmptyPath,
    /// The output file cannot be created.
    #[error("cannot write the stream to {}", path.display())]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The serial port cannot be opened.
    #[error("cannot open serial port {path} at {baud} baud")]
    Serial {
        /// The port.
        path: String,
        /// Its rate.
        baud: u32,
        /// Why.
        #[source]
        source: serialport::Error,
    },
    /// The writer stopped: the port vanished, the disk filled, the reader went away.
    #[error("the link failed")]
    Failed(#[source] std::io::Error),
    /// The writer thread panicked.
    #[error("the link's writer panicked")]
    Panicked,
    /// The link was already closed.
    #[error("the link closed")]
    Closed,
}

/// Where the stream goes, parsed from `serial:PATH[@BAUD]`, `file:PATH` (or a path) and `-`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Destination {
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

impl std::str::FromStr for Destination {
    type Err = LinkError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "-" {
            return Ok(Destination::Stdout);
        }
        match SerialSpec::parse(s) {
            Ok(Some(spec)) => {
                return Ok(Destination::Serial {
                    path: spec.path.to_string(),
                    baud: spec.baud,
                });
            }
            Ok(None) => {}
            Err(why) => {
                return Err(LinkError::BadTarget {
                    text: s.chars().take(80).collect(),
                    why,
                });
            }
        }
        let path = s.strip_prefix("file:").unwrap_or(s);
        if path.is_empty() {
            return Err(LinkError::EmptyPath);
        }
        Ok(Destination::File(path.into()))
    }
}

impl Destination {
    /// Opens the target for writing.
    ///
    /// # Errors
    /// [`LinkError::File`] or [`LinkError::Serial`], naming the file or port.
    pub fn open(&self) -> Result<Box<dyn Write + Send>, LinkError> {
        Ok(match self {
            Destination::Stdout => Box::new(std::io::stdout()),
            Destination::File(p) => {
                Box::new(std::fs::File::create(p).map_err(|source| LinkError::File {
                    path: p.clone(),
                    source,
                })?)
            }
            Destination::Serial { path, baud } => Box::new(
                serialport::new(path, *baud)
                    .timeout(Duration::from_secs(2))
                    .open_native()
                    .map_err(|source| LinkError::Serial {
                        path: path.clone(),
                        baud: *baud,
                        source,
                    })?,
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

/// A link dropped unfinished (a session's error on the way out) still writes what was queued:
/// the host hears why the scan stopped before the process ends.
impl Drop for Link {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Most buffers between the pipeline and the writer (`--link-depth`): 64 packets of the largest
/// size are under 5 MB.
pub const MAX_DEPTH: usize = 64;

impl Link {
    /// Starts the writer on `out` with `depth` buffers of `capacity` bytes (allocated now, once).
    pub fn spawn(mut out: Box<dyn Write + Send>, depth: usize, capacity: usize) -> Link {
        let depth = depth.clamp(1, MAX_DEPTH);
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
    pub fn send(&mut self, buf: Vec<u8>, len: usize) -> Result<(), LinkError> {
        let tx = self.tx.as_ref().ok_or(LinkError::Closed)?;
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
    pub fn buffer_blocking(&mut self) -> Result<Vec<u8>, LinkError> {
        if let Some(b) = self.buffer() {
            return Ok(b);
        }
        match self.back.recv() {
            Ok(b) => Ok(b),
            Err(_) => Err(self.failure()),
        }
    }

    fn failure(&mut self) -> LinkError {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Err(e))) => LinkError::Failed(e),
            Some(Err(_)) => LinkError::Panicked,
            _ => LinkError::Closed,
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
    pub fn finish(mut self) -> Result<LinkStats, LinkError> {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(_))) | None => Ok(self.stats),
            Some(Ok(Err(e))) => Err(LinkError::Failed(e)),
            Some(Err(_)) => Err(LinkError::Panicked),
        }
    }
}
