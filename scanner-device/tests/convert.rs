//! Camera buffer formats on recorded buffers (no camera needed): YUYV, GREY with padded rows,
//! RGB3 and MJPEG to the pipeline's gray, YUYV and RGB; and the image-folder source.

use scanner_core::stripe::PixelFormat;
use scanner_device::source::convert::{CameraFormat, ConvertError, convert};
use scanner_device::source::{SourceOptions, open_with};

/// A 6×4 test picture: a gradient with a bright pixel.
fn rgb() -> Vec<u8> {
    (0..4)
        .flat_map(|y| {
            (0..6).flat_map(move |x| {
                if (x, y) == (3, 2) {
                    [250, 250, 250]
                } else {
                    [20 * x as u8, 30 * y as u8, 40]
                }
            })
        })
        .collect()
}

#[test]
fn yuyv_buffers_give_their_luma_and_colour() {
    // A recorded YUYV buffer: Y = 16·x + y, neutral chroma, rows padded to 16 bytes.
    let (w, h, stride) = (6, 4, 16);
    let mut buf = vec![0xAAu8; stride * h];
    for y in 0..h {
        for x in 0..w {
            buf[y * stride + 2 * x] = (16 * x + y) as u8;
            buf[y * stride + 2 * x + 1] = 128;
        }
    }
    let mut out = Vec::new();
    convert(
        CameraFormat::Yuyv,
        &buf,
        w,
        h,
        stride,
        PixelFormat::Gray8,
        &mut out,
    )
    .unwrap();
    assert_eq!(
        out,
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (16 * x + y) as u8))
            .collect::<Vec<_>>()
    );
    convert(
        CameraFormat::Yuyv,
        &buf,
        w,
        h,
        stride,
        PixelFormat::Rgb24,
        &mut out,
    )
    .unwrap();
    assert_eq!(&out[..6], &[0, 0, 0, 16, 16, 16], "neutral chroma is gray");
    convert(
        CameraFormat::Yuyv,
        &buf,
        w,
        h,
        stride,
        PixelFormat::Yuyv,
        &mut out,
    )
    .unwrap();
    assert_eq!(out.len(), 2 * w * h);
    assert_eq!(&out[..2 * w], &buf[..2 * w]);
}

#[test]
fn grey_rgb3_and_mjpeg_buffers() {
    let (w, h) = (6, 4);
    let rgb = rgb();
    let mut out = Vec::new();
    convert(
        CameraFormat::Rgb3,
        &rgb,
        w,
        h,
        3 * w,
        PixelFormat::Gray8,
        &mut out,
    )
    .unwrap();
    assert_eq!(out[2 * w + 3], 250);
    let grey = out.clone();
    convert(
        CameraFormat::Grey,
        &grey,
        w,
        h,
        w,
        PixelFormat::Rgb24,
        &mut out,
    )
    .unwrap();
    assert_eq!(&out[3 * (2 * w + 3)..3 * (2 * w + 3) + 3], &[250, 250, 250]);
    // A MJPEG frame is a JPEG image.
    let img = image::RgbImage::from_raw(w as u32, h as u32, rgb.clone()).unwrap();
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 100)
        .encode_image(&img)
        .unwrap();
    convert(
        CameraFormat::Mjpeg,
        &jpeg,
        w,
        h,
        0,
        PixelFormat::Gray8,
        &mut out,
    )
    .unwrap();
    assert!(
        out.iter()
            .zip(&grey)
            .all(|(a, b)| (i32::from(*a) - i32::from(*b)).abs() <= 12),
        "{out:?} vs {grey:?}"
    );
}

#[test]
fn bad_buffers_are_named_errors() {
    let mut out = Vec::new();
    let e = convert(
        CameraFormat::Yuyv,
        &[0; 10],
        6,
        4,
        12,
        PixelFormat::Gray8,
        &mut out,
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            ConvertError::Short {
                got: 10,
                want: 48,
                ..
            }
        ),
        "{e}"
    );
    let e = convert(
        CameraFormat::Mjpeg,
        b"not a jpeg",
        6,
        4,
        0,
        PixelFormat::Gray8,
        &mut out,
    )
    .unwrap_err();
    assert!(
        matches!(e, ConvertError::Jpeg(scanner_jpeg::JpegError::NotJpeg)),
        "{e}"
    );
    let e = convert(
        CameraFormat::Yuyv,
        &[0; 40],
        5,
        4,
        10,
        PixelFormat::Gray8,
        &mut out,
    )
    .unwrap_err();
    assert_eq!(e, ConvertError::OddWidth(5));
    assert_eq!(
        CameraFormat::from_fourcc(*b"MJPG"),
        Some(CameraFormat::Mjpeg)
    );
    assert_eq!(CameraFormat::from_fourcc(*b"H264"), None);
}

#[test]
fn a_folder_of_rendered_frames_is_a_source() {
    let dir = tempfile::tempdir().unwrap();
    let job = scanner_device::cli::render::RenderJob {
        scene: None,
        out: dir.path().to_path_buf(),
        gray: true,
        frames: Some(5),
        view: None,
    };
    scanner_device::cli::render::render(&job, |_, _| {}).unwrap();
    let mut src = open_with(
        &format!("dir:{}", dir.path().display()),
        PixelFormat::Gray8,
        &SourceOptions::default(),
    )
    .unwrap();
    assert_eq!(src.size(), (640, 480));
    let r = src.reference().unwrap();
    let rig_ref = scanner_rig::Rig::new(scanner_rig::Scene::demo(640, 480))
        .unwrap()
        .reference()
        .to_format(PixelFormat::Gray8);
    assert_eq!(r.data, rig_ref, "reference.png is the reference");
    let mut n = 0;
    while let Some(f) = src.next_frame().unwrap() {
        assert_eq!(f.index, n);
        n += 1;
    }
    assert_eq!(n, 5);
    // Without reference.png: the first frames are averaged, once checked to be laser-off; these
    // are laser frames, so the reference is refused, naming the first frame that shows the laser.
    std::fs::remove_file(dir.path().join("reference.png")).unwrap();
    let opts = SourceOptions {
        reference_frames: 2,
        ..SourceOptions::default()
    };
    let mut src = open_with(dir.path().to_str().unwrap(), PixelFormat::Gray8, &opts).unwrap();
    match src.reference() {
        Err(scanner_device::source::SourceError::LaserInReference {
            frame: 1,
            frames: 2,
            ..
        }) => {}
        other => panic!("laser frames averaged into a reference: {:?}", other.err()),
    }
    // An empty folder.
    let empty = tempfile::tempdir().unwrap();
    let e = open_with(
        &format!("dir:{}", empty.path().display()),
        PixelFormat::Gray8,
        &SourceOptions::default(),
    )
    .err()
    .unwrap();
    assert!(
        matches!(e, scanner_device::source::SourceError::NoImages(_)),
        "{e}"
    );
}

#[test]
#[ignore = "needs a V4L2 camera at /dev/video0 (hardware)"]
fn a_real_camera_streams_frames() {
    let mut src = open_with(
        "/dev/video0",
        PixelFormat::Gray8,
        &SourceOptions {
            reference_frames: 2,
            ..SourceOptions::default()
        },
    )
    .unwrap();
    println!("{}", src.describe());
    let r = src.reference().unwrap();
    for _ in 0..3 {
        let f = src.next_frame().unwrap().unwrap();
        assert_eq!((f.width, f.height), (r.width, r.height));
    }
}
