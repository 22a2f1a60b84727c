//! The link between the scanner head and the host: the messages and their framing. Both ends
//! use it; it is `no_std`, allocation-free and imports nothing of the scanner (encoding writes
//! into the caller's buffers, decoding borrows from them). The format is written down in
//! `docs/wire.md`; smoltcp's `wire` is the model, one message per module.
//!
//! A frame on the wire ([`framing`]):
//! ```text
//! 0x00 ‖ COBS( version:u8 ‖ postcard(Message) ‖ crc32(version ‖ postcard(Message)):u32 LE ) ‖ 0x00
//! ```
//! COBS removes every zero byte, so `0x00` delimits frames: a reader that joins mid-stream or
//! after garbage resynchronises at the next zero, and the leading zero cuts off any garbage just
//! before a frame (empty frames between two zeros are ignored). The CRC is CRC-32/ISO-HDLC (the
//! zlib one).
//!
//! # Messages
//! | message | module | when |
//! |---|---|---|
//! | [`Header`] | [`header`] | at the start, then periodically (a host that joins late can decode) |
//! | [`Controls`] | [`controls`] | after each header: the camera controls the head fixed |
//! | [`DiscPose`] | [`disc_pose`] | after each header, when asked: the turntable disc in the reference |
//! | [`FixedLaser`] | [`fixed_laser`] | after each header of a fixed-laser scan: the turning platform |
//! | [`Points`] | [`points`] | one per frame, self-contained (losing one loses only that frame) |
//! | [`Planes`] | [`planes`] | before each status: how well the laser planes fitted |
//! | [`Status`] | [`status`] | periodically and at the end: counters, skip reasons, why it ended |
//! | [`Notice`] | [`notice`] | as it happens: prompts and events for the operator |
//! | [`Preview`] | [`preview`] | about once a second while previewing: a thumbnail |
//! | [`Picture`] | [`picture`] | with a preview, when asked: the picture at up to full resolution |
//! | [`Reply`] | [`command`] | to every command of the host: accepted, or refused and why |
//! | [`ShotTaken`] | [`calibration`] | after a shot command: what the detector found |
//! | [`Calibrated`] | [`calibration`] | after a calibrate command: the calibration's figures |
//!
//! The host sends [`Command`]s the other way, framed alike ([`encode_command`],
//! [`CommandDecoder`]), each numbered so that its [`Reply`] names it.
//!
//! The words people read (prompts, control summaries, skip reasons) belong to the ends that
//! show them; the wire carries what happened, as numbers.
//!
//! # Layers
//! ```text
//! framing
//! message
//! preview  picture
//! header  points  status  controls  planes  disc_pose  fixed_laser  turn  notice  command  calibration
//! error
//! ```
#![no_std]
#![deny(missing_docs)]
#![deny(unsafe_code)]

/// A `u8` that names no variant of a wire enum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadEnum(pub u8);

impl core::fmt::Display for BadEnum {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{} names no value of this field", self.0)
    }
}

/// A wire enum as its `u8` and back (the value checked), for `#[serde(into = "u8", try_from =
/// "u8")]`.
macro_rules! wire_enum {
    ($t:ty, $($v:ident = $n:literal),+) => {
        impl From<$t> for u8 {
            fn from(v: $t) -> u8 {
                v as u8
            }
        }
        impl TryFrom<u8> for $t {
            type Error = $crate::BadEnum;
            fn try_from(n: u8) -> Result<Self, $crate::BadEnum> {
                match n {
                    $($n => Ok(<$t>::$v),)+
                    _ => Err($crate::BadEnum(n)),
                }
            }
        }
    };
}

pub mod calibration;
pub mod command;
pub mod controls;
pub mod disc_pose;
mod error;
pub mod fixed_laser;
pub mod framing;
#[cfg(test)]
mod golden;
pub mod header;
pub mod message;
pub mod notice;
pub mod picture;
pub mod planes;
pub mod points;
pub mod preview;
pub mod status;
pub mod turn;

pub use calibration::{Calibrated, ShotTaken};
pub use command::{
    Adjustable, ByHand, Command, CommandError, CommandFrame, HeadState, MAX_COMMAND,
    MAX_COMMAND_ENCODED, Outcome, PreviewRequest, Reply, SweepRequest, TURN_UNKNOWN,
};
pub use controls::{Control, Controls};
pub use disc_pose::{DiscFound, DiscPose};
pub use error::WireError;
pub use fixed_laser::FixedLaser;
pub use framing::{
    CommandDecoder, CommandFrameError, DecodeStats, Decoder, decode, decode_command, encode,
    encode_command,
};
pub use header::{CameraBlock, Header, PlaneBlock, PlaneMethod};
pub use message::Message;
pub use notice::{Notice, NoticeKind};
pub use picture::{PICTURE_MAX_JPEG, Picture};
pub use planes::Planes;
pub use points::Points;
pub use preview::{
    PREVIEW_MAX_MARKERS, PREVIEW_MAX_PIXELS, PREVIEW_MAX_SIDE, Preview, PreviewState,
};
pub use status::{EndReason, SKIP_REASONS, Skip, Status};
pub use turn::MeasuredTurn;

/// Protocol version, the first byte of every frame. Version 2 added
/// [`Points::uncertainty`]; frames of version 1 are still read (their points carry none).
pub const VERSION: u8 = 2;
/// Size of one wire unit of length, mm (0.01 mm).
pub const UNIT_MM: f32 = 0.01;
/// Most points one [`Points`] message carries: one per line (column or row) of a frame of at
/// most this many lines.
pub const MAX_POINTS: usize = 4096;
/// Most bytes a point's coordinates take: three zigzag varints of at most 5 bytes.
pub const MAX_XYZ_BYTES_PER_POINT: usize = 15;
/// Bytes a point's colour takes.
pub const RGB_BYTES_PER_POINT: usize = 3;
/// Bytes a point's standard uncertainty takes.
pub const UNCERTAINTY_BYTES_PER_POINT: usize = 1;
/// Room for a message's fields besides its points (ids, time, plane, counts, lengths), bytes.
pub const MESSAGE_OVERHEAD: usize = 256;
/// Largest message before COBS, bytes: [`MAX_POINTS`] points with colour and uncertainty fit.
pub const MAX_MESSAGE: usize = MAX_POINTS
    * (MAX_XYZ_BYTES_PER_POINT + RGB_BYTES_PER_POINT + UNCERTAINTY_BYTES_PER_POINT)
    + MESSAGE_OVERHEAD;
/// Largest encoded frame including COBS overhead and both delimiters.
pub const MAX_ENCODED: usize = cobs::max_encoding_length(MAX_MESSAGE) + 2;
