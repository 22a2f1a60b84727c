//! Test support for the golden frames beside each message's code: a message's exact bytes on
//! the wire, its round trip, and every truncation of its body refused (smoltcp's wire tests are
//! the model).

extern crate std;

use std::vec::Vec;

use crate::framing::{decode, encode};
use crate::{MAX_ENCODED, MAX_MESSAGE, Message, VERSION, WireError};

/// `msg` encodes to exactly `golden` (a whole frame, both delimiters included), decodes back to
/// itself, and every shorter body (its CRC made right, so that only the body is short) is
/// refused as [`WireError::BadPayload`] or [`WireError::BadPoints`], never read as a message.
pub fn check(msg: Message<'_>, golden: &[u8]) {
    let mut scratch = [0u8; MAX_MESSAGE + 8];
    let mut out = std::vec![0u8; MAX_ENCODED];
    let n = encode(&msg, &mut scratch, &mut out).expect("encodes");
    assert_eq!(
        &out[..n],
        golden,
        "the frame's bytes changed (a change of the wire: bump VERSION and docs/wire.md); now {:?}",
        &out[..n]
    );
    let mut frame = golden[1..golden.len() - 1].to_vec();
    assert_eq!(decode(&mut frame).expect("decodes"), msg);
    let body = postcard::to_slice(&msg, &mut scratch)
        .expect("postcard")
        .to_vec();
    for cut in 0..body.len() {
        let mut short = reframe(&body[..cut]);
        match decode(&mut short) {
            Err(WireError::BadPayload | WireError::BadPoints | WireError::Truncated) => {}
            other => panic!("a body cut to {cut} of {} bytes gave {other:?}", body.len()),
        }
    }
}

/// A body as a frame's inner bytes with the right version and CRC (COBS encoded, no
/// delimiters).
fn reframe(body: &[u8]) -> Vec<u8> {
    const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let mut raw = std::vec![VERSION];
    raw.extend_from_slice(body);
    let crc = CRC.checksum(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = std::vec![0u8; cobs::max_encoding_length(raw.len())];
    let n = cobs::encode(&raw, &mut out);
    out.truncate(n);
    out
}
