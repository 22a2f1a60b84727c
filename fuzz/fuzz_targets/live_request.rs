//! The live view's request heads (`scanner_host::live::route`) on any bytes: a route or a
//! refusal, never a panic; what it borrows lies in the head.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_host::live::{Route, route};

fuzz_target!(|data: &[u8]| {
    for token in [None, Some("0123456789abcdef")] {
        match route(data, token) {
            Route::Live { key } | Route::File(key) => {
                assert!(key.len() <= data.len());
            }
            Route::Refuse(code, why) => {
                assert!((400..600).contains(&code) && !why.is_empty());
            }
            _ => {}
        }
    }
});
