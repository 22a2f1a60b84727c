//! The stripe extractor on arbitrary frames: any size, stride, format, method, laser colour,
//! reference.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_core::stripe::{
    Axis, Extractor, Frame, LaserColour, Method, PixelFormat, StripeConfig,
};

fuzz_target!(|data: &[u8]| {
    if data.len() < 6 {
        return;
    }
    let w = usize::from(data[0] % 64) + 1;
    let h = usize::from(data[1] % 64) + 1;
    let format =
        [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb24][usize::from(data[2] % 3)];
    let pad = usize::from(data[3] % 8);
    let method = if data[4] % 2 == 0 {
        Method::Dim
    } else {
        Method::Lim
    };
    let colour = LaserColour::ALL[usize::from(data[4] / 2 % 4)];
    let axis = if data[5] % 2 == 0 {
        Axis::Columns
    } else {
        Axis::Rows
    };
    let stride = w * format.bytes_per_pixel() + pad;
    let body = &data[6..];
    let half = body.len() / 2;
    let (a, b) = body.split_at(half);
    let Ok(frame) = Frame::new(a, w, h, stride, format) else {
        return;
    };
    let reference = Frame::new(b, w, h, stride, format).ok();
    let mut ex = Box::new(Extractor::<64>::new());
    let cfg = StripeConfig {
        colour,
        ..StripeConfig::new(method, axis)
    };
    if let Ok(res) = ex.extract(&frame, reference.as_ref(), &cfg) {
        for p in res.points {
            assert!(p.centre.is_finite());
        }
    }
});
