//! The per-frame calls allocate nothing: a counting global allocator watches the stripe extractor
//! (every format, both methods and axes, every estimator) and the f32 geometry of one frame.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use scanner_core::geometry::{Board, LaserFitConfig, Limits, Plane, laser, triangulate};
use scanner_core::nalgebra::{Point2, Point3, Vector3};
use scanner_core::stripe::{Axis, Estimator, Extractor, Frame, Method, PixelFormat, StripeConfig};
use scanner_core::{Camera, Distortion};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged; only counts.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    f();
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

#[test]
fn per_frame_calls_do_not_allocate() {
    let (w, h) = (320usize, 240usize);
    // buffers and the extractor are set up before counting, as the device does once
    let mut ex = Box::new(Extractor::<512>::new());
    let mut frames = Vec::new();
    for format in [PixelFormat::Gray8, PixelFormat::Yuyv, PixelFormat::Rgb24] {
        let bpp = format.bytes_per_pixel();
        let mut f = vec![20u8; w * h * bpp];
        for x in 0..w {
            let y = 100 + x / 20;
            for dy in 0..3 {
                f[((y + dy) * w + x) * bpp] = 200;
            }
        }
        frames.push((format, f, vec![20u8; w * h * bpp]));
    }
    let camera = Camera::<f32>::new(
        1400.0,
        1400.0,
        159.5,
        119.5,
        Distortion {
            k1: -0.1,
            ..Distortion::none()
        },
    )
    .unwrap();
    let board = Board::new(
        Plane::new(Vector3::new(1.0f32, 0.0, -1.0), 700.0).unwrap(),
        Plane::new(Vector3::new(-1.0f32, 0.0, -1.0), 700.0).unwrap(),
    )
    .unwrap();
    let left: Vec<Point3<f32>> = (1..30)
        .map(|k| {
            let x = -10.0 * k as f32;
            let z = 700.0 - x.abs();
            Point3::new(x, 0.2 * z - 50.0, z)
        })
        .collect();
    let right: Vec<Point3<f32>> = (1..30)
        .map(|k| {
            let x = 10.0 * k as f32;
            let z = 700.0 - x.abs();
            Point3::new(x, 0.2 * z - 50.0, z)
        })
        .collect();

    let n = allocations_during(|| {
        for (format, f, r) in &frames {
            let fr = Frame::packed(f, w, h, *format).unwrap();
            let rf = Frame::packed(r, w, h, *format).unwrap();
            for method in [Method::Dim, Method::Lim] {
                for axis in [Axis::Columns, Axis::Rows] {
                    for estimator in [Estimator::Paper, Estimator::Centroid, Estimator::Gaussian] {
                        let cfg = StripeConfig {
                            estimator,
                            ..StripeConfig::new(method, axis)
                        };
                        let res = ex.extract(&fr, Some(&rf), &cfg).unwrap();
                        std::hint::black_box(res.valid().count());
                    }
                }
            }
        }
        let fit = laser::least_squares(&left, &right, &LaserFitConfig::default()).unwrap();
        let paper = laser::paper(&board, &left, &right, &LaserFitConfig::default()).unwrap();
        for x in 0..w {
            let px = Point2::new(x as f32, 150.0);
            std::hint::black_box(
                triangulate::triangulate(&camera, &board, &fit.plane, &px, &Limits::default()).ok(),
            );
            std::hint::black_box(
                triangulate::board_point(&camera, &board, &px, &Limits::default()).ok(),
            );
        }
        std::hint::black_box(paper);
    });
    assert_eq!(n, 0, "the per-frame path allocated {n} times");
    // the counter works: a Vec allocates
    assert!(
        allocations_during(|| {
            std::hint::black_box(vec![1u8; 10]);
        }) > 0
    );
}
