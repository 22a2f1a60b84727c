//! The head's command decoder on any bytes in any chunks: no panic, and whatever it reads as a
//! command is one the encoder writes back to the same bytes, and whose check does not panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_wire::{CommandDecoder, MAX_COMMAND_ENCODED, encode_command};

fuzz_target!(|data: &[u8]| {
    let chunk = usize::from(data.first().copied().unwrap_or(1)).max(1);
    let mut d = CommandDecoder::new();
    for c in data.chunks(chunk) {
        d.feed(c, |r| {
            if let Ok(frame) = r {
                let _ = frame.command.check();
                let _ = frame.command.name();
                let mut out = [0u8; MAX_COMMAND_ENCODED];
                let n = encode_command(&frame, &mut out).expect("a read command fits its limit");
                let mut again = CommandDecoder::new();
                let mut back = None;
                again.feed(&out[..n], |r| back = Some(r));
                assert_eq!(back, Some(Ok(frame)));
            }
        });
    }
});
