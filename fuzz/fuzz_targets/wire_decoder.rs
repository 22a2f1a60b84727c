//! The stream decoder and resynchroniser (versions 1 and 2), and the point coding, on any bytes
//! in any chunks.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_wire::{Decoder, Message, points};

fuzz_target!(|data: &[u8]| {
    let chunk = usize::from(data.first().copied().unwrap_or(1)).max(1);
    let mut d = Decoder::<4096>::new();
    let mut frames = 0u64;
    for c in data.chunks(chunk) {
        d.feed(c, |m| {
            frames += 1;
            if let Ok(Message::Points(p)) = m {
                let _ = points::decode(p.xyz, p.count as usize, |_| {});
                // a decoded frame's uncertainty is empty or one byte per point
                assert!(p.uncertainty.is_empty() || p.uncertainty.len() == p.count as usize);
                for &c in p.uncertainty {
                    assert!(points::uncertainty_mm(c) > 0.0);
                }
            }
        });
    }
    assert_eq!(d.stats().bytes, data.len() as u64);
    assert!(d.stats().frames + d.stats().rejected() <= frames + 1);
});
