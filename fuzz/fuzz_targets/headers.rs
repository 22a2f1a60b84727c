//! Arbitrary session headers (any field values, framed with a valid CRC, as a crafted stream
//! would send them) and arbitrary calibration files, through the host's collector — with the
//! peak of live heap bytes checked against the host's stated limit for every input: nothing a
//! header or a file says may make the host allocate beyond it.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_alloc::{live_bytes, peak_bytes, reset_peak};
use scanner_host::collect::{CollectOptions, Collector};
use scanner_wire::{Header, MAX_ENCODED, MAX_MESSAGE, Message, PlaneMethod, encode};

/// The host's peak memory limit with default options (README, reliability), bytes.
const LIMIT: usize = 1 << 30;

#[global_allocator]
static A: scanner_alloc::Peak = scanner_alloc::Peak;

fn through_host(h: &Header, rest: &[u8]) {
    let (mut scratch, mut out) = (vec![0u8; MAX_MESSAGE], vec![0u8; MAX_ENCODED]);
    let Ok(n) = encode(&Message::Header(*h), &mut scratch, &mut out) else {
        return;
    };
    let mut c = Collector::new(CollectOptions::default(), None);
    let _ = c.feed(&out[..n]);
    let _ = c.feed(rest);
    c.finish();
    let _ = c.counts();
}

fuzz_target!(|data: &[u8]| {
    reset_peak();
    let start = live_bytes();
    // Any header postcard can read from the bytes, then the rest of the bytes as the stream.
    if let Ok((h, rest)) = postcard::take_from_bytes::<Header>(data) {
        through_host(&h, rest);
    }
    // Any calibration file the parser accepts, sent as the head would send it.
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(f) = scanner_calib::file::CalibrationFile::parse(text, "fuzz")
        && let (Ok(camera), Some(Ok(board))) = (f.camera(), f.board())
        && let (Ok(w), Ok(h)) = (u16::try_from(f.image.width), u16::try_from(f.image.height))
    {
        let header = Header::new(
            1,
            (w, h),
            (&camera).into(),
            (&board).into(),
            false,
            PlaneMethod::LeastSquares,
        );
        through_host(&header, &[]);
    }
    let peak = peak_bytes() - start;
    assert!(
        peak < LIMIT,
        "peak heap {peak} bytes for one input (limit {LIMIT})"
    );
});
