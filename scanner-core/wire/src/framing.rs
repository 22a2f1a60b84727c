//! Framing: a message (head → host) or a command (host → head) as one delimited frame and
//! back, and streaming decoders for both ([`Decoder`], [`CommandDecoder`]) that resynchronise
//! after garbage.
//!
//! ```text
//! 0x00 ‖ COBS( version:u8 ‖ postcard(body) ‖ crc32(version ‖ postcard(body)):u32 LE ) ‖ 0x00
//! ```

use crate::command::{self, CommandError, CommandFrame, MAX_COMMAND, MAX_COMMAND_ENCODED};
use crate::{Message, VERSION, WireError};

const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Encodes `msg` as one delimited frame into `out`, using `scratch` for the unframed bytes;
/// returns the number of bytes written to `out`.
///
/// # Errors
/// [`WireError::BufferFull`] if `scratch` or `out` is too small.
pub fn encode(msg: &Message, scratch: &mut [u8], out: &mut [u8]) -> Result<usize, WireError> {
    encode_body(msg, scratch, out)
}

/// Encodes a command as one delimited frame into `out` (at least [`MAX_COMMAND_ENCODED`]
/// bytes); returns the number of bytes written.
///
/// # Errors
/// [`WireError::BufferFull`] if `out` is too small.
pub fn encode_command(cmd: &CommandFrame, out: &mut [u8]) -> Result<usize, WireError> {
    let mut scratch = [0u8; MAX_COMMAND];
    encode_body(cmd, &mut scratch, out)
}

/// A body as one frame: version, postcard, CRC, COBS, delimiters.
fn encode_body<T: serde::Serialize>(
    body: &T,
    scratch: &mut [u8],
    out: &mut [u8],
) -> Result<usize, WireError> {
    let first = scratch.first_mut().ok_or(WireError::BufferFull)?;
    *first = VERSION;
    let body = postcard::to_slice(body, &mut scratch[1..])
        .map_err(|_| WireError::BufferFull)?
        .len();
    let n = 1 + body;
    let crc = CRC.checksum(&scratch[..n]);
    scratch
        .get_mut(n..n + 4)
        .ok_or(WireError::BufferFull)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = &scratch[..n + 4];
    if out.len() < cobs::max_encoding_length(raw.len()) + 2 {
        return Err(WireError::BufferFull);
    }
    out[0] = 0;
    let len = cobs::encode(raw, &mut out[1..]);
    out[len + 1] = 0;
    Ok(len + 2)
}

/// Decodes one frame's bytes (between delimiters, without the `0x00`) in place.
///
/// # Errors
/// Every [`WireError`] but [`WireError::BufferFull`].
pub fn decode(frame: &mut [u8]) -> Result<Message<'_>, WireError> {
    let body_len = checked(frame)?;
    let message = match frame[0] {
        VERSION => &frame[1..body_len],
        // Version 1's messages are version 2's but for `Points`, which ended after `rgb`: an
        // empty `uncertainty` (one zero byte, written over the checked CRC) makes it one.
        1 if frame.get(1) == Some(&1) => {
            frame[body_len] = 0;
            &frame[1..=body_len]
        }
        1 => &frame[1..body_len],
        v => return Err(WireError::UnknownVersion(v)),
    };
    let (msg, rest): (Message, _) =
        postcard::take_from_bytes(message).map_err(|_| WireError::BadPayload)?;
    if !rest.is_empty() {
        return Err(WireError::BadPayload);
    }
    if let Message::Preview(p) = &msg
        && !p.is_consistent()
    {
        return Err(WireError::BadPayload);
    }
    if let Message::Picture(p) = &msg
        && !p.is_consistent()
    {
        return Err(WireError::BadPayload);
    }
    if let Message::Points(p) = &msg {
        if !(p.rgb.is_empty() || p.rgb.len() == 3 * p.count as usize) {
            return Err(WireError::BadPoints);
        }
        if !(p.uncertainty.is_empty() || p.uncertainty.len() == p.count as usize) {
            return Err(WireError::BadPoints);
        }
        // Every coordinate takes at least one byte.
        if p.xyz.len() < 3 * p.count as usize {
            return Err(WireError::BadPoints);
        }
    }
    Ok(msg)
}

/// COBS-decodes a frame in place and checks its CRC; the length of `version ‖ body`, which
/// now starts the frame.
fn checked(frame: &mut [u8]) -> Result<usize, WireError> {
    let n = cobs::decode_in_place(frame).map_err(|_| WireError::BadCobs)?;
    if n < 5 {
        return Err(WireError::Truncated);
    }
    let (body, crc) = frame[..n].split_at(n - 4);
    let want = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if CRC.checksum(body) != want {
        return Err(WireError::BadCrc);
    }
    Ok(body.len())
}

/// Why a command frame was not read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandFrameError {
    /// The frame itself: bad COBS, CRC, too short or too long, or an unknown version.
    Frame(WireError),
    /// A frame, but not a command of this version.
    Command(CommandError),
}

impl core::fmt::Display for CommandFrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Frame(e) => e.fmt(f),
            Self::Command(e) => e.fmt(f),
        }
    }
}

impl core::error::Error for CommandFrameError {}

/// Decodes one command frame's bytes (between delimiters, without the `0x00`) in place.
///
/// # Errors
/// [`CommandFrameError`]: the frame's own faults, or the command's.
pub fn decode_command(frame: &mut [u8]) -> Result<CommandFrame, CommandFrameError> {
    let n = checked(frame).map_err(CommandFrameError::Frame)?;
    if frame[0] != VERSION {
        return Err(CommandFrameError::Frame(WireError::UnknownVersion(
            frame[0],
        )));
    }
    command::parse(&frame[1..n]).map_err(CommandFrameError::Command)
}

/// Splits a byte stream at its delimiters into frames held in a fixed buffer of `N` bytes; a
/// frame longer than the buffer is reported as [`WireError::Oversize`] at its end.
struct Splitter<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Splitter<N> {
    const fn new() -> Self {
        Splitter {
            buf: [0; N],
            len: 0,
            overflow: false,
        }
    }

    /// Takes one byte; at a delimiter that ends a frame, the frame (or its oversize).
    fn push(&mut self, b: u8) -> Option<Result<&mut [u8], WireError>> {
        if b != 0 {
            if self.len < N {
                self.buf[self.len] = b;
                self.len += 1;
            } else {
                self.overflow = true;
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            return Some(Err(WireError::Oversize));
        }
        // empty frames between two delimiters are ignored
        (len > 0).then(|| Ok(&mut self.buf[..len]))
    }

    /// Drops an unfinished frame; whether there was one.
    fn cut(&mut self) -> bool {
        let cut = self.len > 0 || self.overflow;
        self.len = 0;
        self.overflow = false;
        cut
    }
}

/// A streaming decoder of commands (the head's side): any chunks, resynchronised at the next
/// delimiter after garbage, frames longer than [`MAX_COMMAND_ENCODED`] refused unread. Never
/// panics on any input.
pub struct CommandDecoder {
    split: Splitter<MAX_COMMAND_ENCODED>,
}

impl Default for CommandDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl CommandDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        CommandDecoder {
            split: Splitter::new(),
        }
    }

    /// Feeds bytes; `f` gets each complete frame in order.
    pub fn feed(
        &mut self,
        bytes: &[u8],
        mut f: impl FnMut(Result<CommandFrame, CommandFrameError>),
    ) {
        for &b in bytes {
            match self.split.push(b) {
                None => {}
                Some(Ok(frame)) => f(decode_command(frame)),
                Some(Err(e)) => f(Err(CommandFrameError::Frame(e))),
            }
        }
    }
}

/// Counts of what a [`Decoder`] saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecodeStats {
    /// Frames decoded.
    pub frames: u64,
    /// Bytes consumed.
    pub bytes: u64,
    /// Frames rejected: bad COBS.
    pub bad_cobs: u64,
    /// Frames rejected: CRC mismatch.
    pub bad_crc: u64,
    /// Frames rejected: unknown version.
    pub bad_version: u64,
    /// Frames rejected: payload not a message, or inconsistent points.
    pub bad_payload: u64,
    /// Frames rejected: longer than the buffer.
    pub oversize: u64,
    /// Frames rejected: too short.
    pub truncated: u64,
}

impl DecodeStats {
    /// All rejected frames.
    pub fn rejected(&self) -> u64 {
        self.bad_cobs
            + self.bad_crc
            + self.bad_version
            + self.bad_payload
            + self.oversize
            + self.truncated
    }
}

/// A streaming decoder with a fixed buffer of `N` bytes: feed it bytes in any chunks; it calls
/// back with every complete frame (decoded, or the reason it was rejected) and resynchronises at
/// the next delimiter after garbage. Never panics on any input.
pub struct Decoder<const N: usize> {
    split: Splitter<N>,
    stats: DecodeStats,
}

impl<const N: usize> Default for Decoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Decoder<N> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Decoder {
            split: Splitter::new(),
            stats: DecodeStats {
                frames: 0,
                bytes: 0,
                bad_cobs: 0,
                bad_crc: 0,
                bad_version: 0,
                bad_payload: 0,
                oversize: 0,
                truncated: 0,
            },
        }
    }

    /// What it has seen so far.
    pub fn stats(&self) -> DecodeStats {
        self.stats
    }

    /// Bytes of an unfinished frame held.
    pub fn pending(&self) -> usize {
        self.split.len
    }

    /// Ends the input: an unfinished frame (bytes after the last delimiter, a stream cut
    /// mid-frame) is counted as truncated and dropped. Returns whether there was one.
    pub fn finish(&mut self) -> bool {
        let cut = self.split.cut();
        if cut {
            self.stats.truncated += 1;
        }
        cut
    }

    /// Feeds bytes; `f` gets each complete frame in order.
    pub fn feed(&mut self, bytes: &[u8], mut f: impl FnMut(Result<Message<'_>, WireError>)) {
        for &b in bytes {
            self.stats.bytes += 1;
            let res = match self.split.push(b) {
                None => continue,
                Some(Ok(frame)) => decode(frame),
                Some(Err(e)) => Err(e),
            };
            match &res {
                Ok(_) => self.stats.frames += 1,
                Err(WireError::Oversize) => self.stats.oversize += 1,
                Err(WireError::BadCobs) => self.stats.bad_cobs += 1,
                Err(WireError::BadCrc) => self.stats.bad_crc += 1,
                Err(WireError::UnknownVersion(_)) => self.stats.bad_version += 1,
                Err(WireError::Truncated) => self.stats.truncated += 1,
                Err(_) => self.stats.bad_payload += 1,
            }
            f(res);
        }
    }
}
