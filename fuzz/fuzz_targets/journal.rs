//! The host's journal reader (the collector: decoder, journal replay, grid) on any bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_host::collect::{CollectOptions, Collector};

fuzz_target!(|data: &[u8]| {
    let mut c = Collector::new(CollectOptions::default(), None);
    let _ = c.feed(data);
    let _ = c.counts();
});
