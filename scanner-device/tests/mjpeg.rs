//! The head's own JPEG decoder (`scanner_jpeg`, through `Converter`) on frames it was not
//! written against: a real crop encoded by OpenCV's libjpeg in every sampling a webcam uses
//! (`tests/data/mjpeg`, `scripts/make-mjpeg-fixtures.py`), compared with the lossless original
//! and with the `image` crate's decoder; the forms it refuses, refused by name; no panic and a
//! named error on every truncation and on corrupted bytes.

use std::path::{Path, PathBuf};

use scanner_core::stripe::PixelFormat;
use scanner_device::source::convert::{CameraFormat, ConvertError, Converter, convert};
use scanner_jpeg::JpegError;

const W: usize = 202;
const H: usize = 150;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/mjpeg")
        .join(name)
}

fn read(name: &str) -> Vec<u8> {
    std::fs::read(data(name)).unwrap()
}

/// RGB pixels as YUYV, by the head's one conversion.
fn yuyv_of_rgb(rgb: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    convert(
        CameraFormat::Rgb3,
        rgb,
        W,
        H,
        3 * W,
        PixelFormat::Yuyv,
        &mut out,
    )
    .unwrap();
    out
}

/// Mean and largest absolute difference of the bytes at `offset`, `offset + step`, … .
fn diff(a: &[u8], b: &[u8], offset: usize, step: usize) -> (f64, u8) {
    let d: Vec<u8> = a
        .iter()
        .zip(b)
        .skip(offset)
        .step_by(step)
        .map(|(x, y)| x.abs_diff(*y))
        .collect();
    let mean = d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len() as f64;
    (mean, d.iter().copied().max().unwrap_or(0))
}

fn decode(jpeg: &[u8], want: PixelFormat) -> Result<Vec<u8>, ConvertError> {
    let mut out = Vec::new();
    Converter::new()
        .convert(CameraFormat::Mjpeg, jpeg, W, H, 0, want, &mut out)
        .map(|()| out)
}

#[test]
fn every_sampling_decodes_as_close_to_the_original_as_the_image_crate() {
    let original = image::open(data("crop.png")).unwrap().to_rgb8();
    let truth = yuyv_of_rgb(original.as_raw());
    for file in [
        "crop-422-rst.jpg",
        "crop-420.jpg",
        "crop-444.jpg",
        "crop-gray.jpg",
    ] {
        let jpeg = read(file);
        let ours = decode(&jpeg, PixelFormat::Yuyv).unwrap();
        let theirs = yuyv_of_rgb(image::load_from_memory(&jpeg).unwrap().to_rgb8().as_raw());
        // Luma: every other byte; chroma: bytes 1 and 3 of each pair.
        let (our_y, _) = diff(&ours, &truth, 0, 2);
        let (their_y, _) = diff(&theirs, &truth, 0, 2);
        let (_, y_max) = diff(&ours, &theirs, 0, 2);
        let (our_c, _) = diff(&ours, &truth, 1, 2);
        let (their_c, _) = diff(&theirs, &truth, 1, 2);
        println!(
            "{file}: luma off the original {our_y:.3} DN (image crate {their_y:.3}), \
             {y_max} DN at most off the image crate; chroma {our_c:.3} DN ({their_c:.3})"
        );
        assert!(
            our_y <= their_y + 0.1,
            "{file}: luma {our_y} vs the image crate's {their_y}"
        );
        // The two decoders differ only by rounding (and how `image` converts through RGB).
        assert!(y_max <= 4, "{file}: luma {y_max} DN off the image crate");
        if file != "crop-gray.jpg" {
            // Chroma repeated rather than interpolated: at most a little worse.
            assert!(
                our_c <= their_c + 0.5,
                "{file}: chroma {our_c} vs the image crate's {their_c}"
            );
        } else {
            assert!(ours.iter().skip(1).step_by(2).all(|&c| c == 128));
        }
        // Gray output: the same luma, chroma not transformed.
        let gray = decode(&jpeg, PixelFormat::Gray8).unwrap();
        assert!(gray.iter().zip(ours.iter().step_by(2)).all(|(a, b)| a == b));
        // RGB output: through YUYV, by the head's one conversion.
        let rgb = decode(&jpeg, PixelFormat::Rgb24).unwrap();
        assert_eq!(rgb.len(), 3 * W * H);
    }
}

/// Many webcams leave the Huffman tables out of their frames and mean the standard ones.
#[test]
fn a_frame_without_huffman_tables_uses_the_standard_ones() {
    let jpeg = read("crop-422-rst.jpg");
    // Drop every DHT segment (FF C4) before the scan.
    let mut stripped = jpeg[..2].to_vec();
    let mut pos = 2;
    let mut dropped = 0;
    while jpeg[pos] == 0xFF && jpeg[pos + 1] != 0xDA {
        let len = usize::from(jpeg[pos + 2]) << 8 | usize::from(jpeg[pos + 3]);
        if jpeg[pos + 1] == 0xC4 {
            dropped += 1;
        } else {
            stripped.extend_from_slice(&jpeg[pos..pos + 2 + len]);
        }
        pos += 2 + len;
    }
    stripped.extend_from_slice(&jpeg[pos..]);
    assert!(dropped > 0);
    assert_eq!(
        decode(&stripped, PixelFormat::Yuyv).unwrap(),
        decode(&jpeg, PixelFormat::Yuyv).unwrap()
    );
}

#[test]
fn what_the_decoder_does_not_read_is_refused_by_name() {
    for (file, what) in [
        ("crop-411.jpg", "chroma sampling"),
        ("crop-progressive.jpg", "progressive"),
    ] {
        let e = decode(&read(file), PixelFormat::Yuyv).unwrap_err();
        assert!(
            matches!(e, ConvertError::Jpeg(JpegError::Unsupported { what: w, .. }) if w.contains(what)),
            "{file}: {e:?}"
        );
        println!("{file}: {e}");
    }
    // Another size than the stream's.
    let mut out = Vec::new();
    let e = Converter::new()
        .convert(
            CameraFormat::Mjpeg,
            &read("crop-420.jpg"),
            200,
            150,
            0,
            PixelFormat::Yuyv,
            &mut out,
        )
        .unwrap_err();
    assert!(matches!(
        e,
        ConvertError::Jpeg(JpegError::Size {
            width: 202,
            height: 150,
            ..
        })
    ));
    assert!(matches!(
        decode(b"not a jpeg", PixelFormat::Gray8),
        Err(ConvertError::Jpeg(JpegError::NotJpeg))
    ));
    // A stream size over the limit, refused before any buffer is sized for it.
    let e = Converter::new()
        .convert(
            CameraFormat::Mjpeg,
            &read("crop-420.jpg"),
            1 << 20,
            1 << 20,
            0,
            PixelFormat::Yuyv,
            &mut out,
        )
        .unwrap_err();
    assert!(matches!(e, ConvertError::TooLarge { .. }), "{e:?}");
    assert!(out.capacity() < 1 << 20);
}

/// Every prefix of a frame (a camera buffer cut short) is an error, never a panic and never a
/// frame; bytes flipped anywhere give an error or a frame, never a panic.
#[test]
fn cut_and_corrupted_frames_are_errors_not_panics() {
    let mut converter = Converter::new();
    let mut out = Vec::new();
    for file in ["crop-422-rst.jpg", "crop-420.jpg", "crop-gray.jpg"] {
        let jpeg = read(file);
        // The decoder stops at the end of the last block: the final EOI marker may go.
        for len in 0..jpeg.len() - 2 {
            let r = converter.convert(
                CameraFormat::Mjpeg,
                &jpeg[..len],
                W,
                H,
                0,
                PixelFormat::Yuyv,
                &mut out,
            );
            assert!(r.is_err(), "{file} cut at {len} of {} decoded", jpeg.len());
        }
        let mut state = 0x2545_f491_u32;
        for _ in 0..2000 {
            let mut bad = jpeg.clone();
            for _ in 0..3 {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                let at = state as usize % bad.len();
                bad[at] ^= (state >> 24) as u8 | 1;
            }
            let _ = converter.convert(
                CameraFormat::Mjpeg,
                &bad,
                W,
                H,
                0,
                PixelFormat::Yuyv,
                &mut out,
            );
        }
    }
}
