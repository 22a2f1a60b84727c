//! The head's JPEG decoder on arbitrary camera buffers: any bytes, the size the first two bytes
//! ask (up to 64 × 64), YUYV or gray out. It may refuse; it must not panic or write past its
//! output. Seeded with real frames (fuzz/seeds/jpeg).
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_jpeg::{JpegDecoder, Output};

fuzz_target!(|data: &[u8]| {
    if data.len() < 3 {
        return;
    }
    let w = 2 * (usize::from(data[0] % 32) + 1);
    let h = usize::from(data[1] % 64) + 1;
    let output = if data[2] % 2 == 0 {
        Output::Yuyv
    } else {
        Output::Gray
    };
    let mut out = vec![0u8; 2 * w * h];
    let mut decoder = JpegDecoder::new();
    let _ = decoder.decode(&data[3..], w, h, output, &mut out);
    // The seeds' own size, whatever the first bytes say.
    let _ = decoder.decode(&data[3..], 202, 150, output, &mut vec![0u8; 2 * 202 * 150]);
});
