//! The per-frame calls allocate nothing: a counting global allocator watches the stripe extractor
//! (every format, both methods and axes, every estimator) and the f32 geometry of one frame; and
//! the intrinsics calibration (Zhang's closed form, poses, joint refinement).

use scanner_core::geometry::{Board, LaserFitConfig, Limits, Plane, laser, triangulate};
use scanner_core::nalgebra::{Point2, Point3, Vector3};
use scanner_core::stripe::{Axis, Estimator, Extractor, Frame, Method, PixelFormat, StripeConfig};
use scanner_core::{Camera, Distortion};

#[global_allocator]
static GLOBAL: scanner_alloc::Counting = scanner_alloc::Counting;

use scanner_alloc::allocations_during;

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

#[test]
fn intrinsics_calibration_does_not_allocate() {
    use scanner_core::calib::bundle::{initial_camera, initial_pose, refine};
    use scanner_core::calib::model::predict;
    use scanner_core::calib::{Free, TargetImage};
    use scanner_core::geometry::Pose;
    use scanner_core::nalgebra::{Point2, Rotation3, Vector3};
    use scanner_core::{Camera, Distortion};
    let truth = Camera::new(
        900.0,
        901.0,
        322.0,
        241.0,
        Distortion {
            k1: -0.1,
            ..Distortion::none()
        },
    )
    .unwrap();
    let layout: [Point2<f64>; 20] = core::array::from_fn(|i| {
        Point2::new((i % 5) as f64 * 20.0 - 40.0, (i / 5) as f64 * 20.0 - 30.0)
    });
    let poses: [Pose; 4] = core::array::from_fn(|k| Pose {
        rotation: Rotation3::from_euler_angles(
            0.4 * (k as f64 - 1.5),
            0.3 * ((k % 2) as f64 - 0.5),
            0.1,
        ),
        translation: Vector3::new(10.0 * k as f64, -5.0, 500.0 + 40.0 * k as f64),
    });
    let pixels: [[Point2<f64>; 20]; 4] = core::array::from_fn(|k| {
        core::array::from_fn(|i| predict(&truth, &poses[k], &layout[i], 3.0).unwrap())
    });
    let mut result = None;
    let n = allocations_during(|| {
        let views: [TargetImage; 4] = core::array::from_fn(|k| TargetImage {
            layout: &layout,
            pixels: &pixels[k],
        });
        let init = initial_camera(&views, 640, 480).unwrap();
        let mut p: [Pose; 4] = core::array::from_fn(|k| initial_pose(&init, &views[k]).unwrap());
        result = Some(refine(&init, Free::NO_K3, &views, &mut p, 3.0).unwrap());
    });
    assert_eq!(n, 0, "calibration allocated {n} times");
    let r = result.unwrap();
    assert!((r.camera.fx() - 900.0).abs() < 1e-6, "{:?}", r.camera);
}
