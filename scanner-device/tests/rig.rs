//! The virtual rig against its own ground truth (issue 4, first slice): at zero noise the
//! intensity-weighted stripe centre of every lit column lies within 0.1 px of the projection of
//! the true stripe; what an object hides from the laser stays dark; the reference has no laser.

use scanner_core::stripe::PixelFormat;
use scanner_rig::{Rig, Scene, SurfaceId};

/// No noise, and a laser that does not clip (clipping is its own effect, tested elsewhere).
fn quiet(mut scene: Scene) -> Scene {
    scene.sensor.read_noise = 0.0;
    scene.sensor.shot_noise = 0.0;
    scene.laser.power = 1.2;
    scene.laser.speckle = 0.0;
    scene
}

/// Laser-only red channel (frame − reference) of one column of RGB frames, as f64.
fn column_signal(frame: &[u8], reference: &[u8], w: usize, h: usize, u: usize) -> Vec<f64> {
    (0..h)
        .map(|v| f64::from(frame[(v * w + u) * 3]) - f64::from(reference[(v * w + u) * 3]))
        .collect()
}

/// Checks the zero-noise stripe centroids of `frames` against the truth; returns the surfaces
/// checked and the number of columns.
fn check_centroids(
    scene: Scene,
    frames: &[usize],
) -> (std::collections::HashSet<SurfaceId>, usize) {
    let (w, h) = (scene.width as usize, scene.height as usize);
    let rig = Rig::new(quiet(scene)).unwrap();
    let reference = rig.reference().data;
    let mut checked = 0;
    let mut worst_at = (0, 0, SurfaceId::Left, 0.0);
    let mut kinked = 0;
    let mut grazing = 0;
    let mut faint = 0;
    let mut printed = 0;
    let mut steep = 0;
    let mut worst = 0.0f64;
    let mut surfaces = std::collections::HashSet::new();
    for &k in frames {
        let frame = rig.frame(k).unwrap().data;
        let truth = rig.truth(k).unwrap();
        for (u, t) in truth.iter().enumerate() {
            let Some(t) = t else { continue };
            // within the lens blur's radius of the border the point-spread function is cut
            if u < 4 || u + 4 >= w {
                continue;
            }
            // the blur mixes neighbouring columns: where the true stripe kinks within its radius
            // (the crease, an object's silhouette) the centroid moves with the optics, so the
            // check is for columns where the stripe has no kink over ±3 columns (a smooth curve
            // moves a blurred centroid by about σ²·curvature / 2: 0.01 px here)
            // an albedo edge (a marker's rim, a texture cell) across the stripe skews its profile: the
            // reference must be uniform over the stripe
            let band: Vec<u8> = ((t.row - 6.0).max(0.0) as usize
                ..=((t.row + 6.0) as usize).min(h - 1))
                .flat_map(|v| (u - 3..=u + 3).map(move |x| (v, x)))
                .map(|(v, x)| reference[(v * w + x) * 3])
                .collect();
            if band.iter().max().unwrap_or(&0) - band.iter().min().unwrap_or(&0) > 3 {
                printed += 1;
                continue;
            }
            // near the laser's terminator half the stripe is in the surface's own shadow
            if t.incidence < 0.25 {
                grazing += 1;
                continue;
            }
            // an occluding edge (another surface) within ±3 px along the column cuts the stripe
            let seen = |v: f64| {
                rig.scene()
                    .camera
                    .pixel_to_ray(&scanner_core::nalgebra::Point2::new(u as f64, v))
                    .ok()
                    .and_then(|r| rig.cast(&r.normalize()))
                    .map(|hit| hit.surface)
            };
            if seen(t.row - 3.0) != Some(t.surface) || seen(t.row + 3.0) != Some(t.surface) {
                kinked += 1;
                continue;
            }
            let (Some(a), Some(b)) = (truth[u - 3], truth[u + 3]) else {
                continue;
            };
            // columns measure roughly horizontal stripes (row mode is for steep ones): beyond 45°
            // the blur mixes neighbouring columns whose stripe lies rows away
            if (b.row - a.row).abs() > 6.0 {
                steep += 1;
                continue;
            }
            if a.surface != t.surface
                || b.surface != t.surface
                || (a.row - 2.0 * t.row + b.row).abs() > 0.5
            {
                kinked += 1;
                continue;
            }
            let s = column_signal(&frame, &reference, w, h, u);
            // centroid of the laser light within ±6 px of the truth
            let lo = (t.row - 6.0).max(0.0) as usize;
            let hi = ((t.row + 6.0) as usize).min(h - 1);
            let (mut m0, mut m1, mut peak) = (0.0, 0.0, 0.0f64);
            for (v, &x) in s.iter().enumerate().take(hi + 1).skip(lo) {
                let x = x.max(0.0);
                m0 += x;
                m1 += x * v as f64;
                peak = peak.max(x);
            }
            if peak < 40.0 {
                faint += 1; // 8-bit rounding alone would move a fainter stripe's centroid
                continue;
            }
            let err = (m1 / m0 - t.row).abs();
            if err > worst {
                worst_at = (k, u, t.surface, t.incidence);
            }
            worst = worst.max(err);
            assert!(
                err < 0.1,
                "frame {k} column {u}: centroid {} vs truth {} ({:?})",
                m1 / m0,
                t.row,
                t.surface
            );
            checked += 1;
            surfaces.insert(t.surface);
        }
    }
    println!(
        "{checked} columns, worst {worst:.4} px at (frame, column, surface, incidence) {worst_at:?}, {kinked} left out at kinks and edges, {grazing} at grazing incidence, {faint} faint, {printed} across marker rims, {steep} steeper than 45°, surfaces {surfaces:?}"
    );
    (surfaces, checked)
}

#[test]
fn stripe_centres_match_the_truth_at_zero_noise() {
    let (surfaces, checked) =
        check_centroids(Scene::demo(480, 360), &[5, 15, 20, 25, 30, 35, 40, 55]);
    assert!(checked > 1000, "only {checked} lit columns checked");
    assert!(surfaces.contains(&SurfaceId::Left) && surfaces.contains(&SurfaceId::Right));
    assert!(
        surfaces.contains(&SurfaceId::Object(0)) && surfaces.contains(&SurfaceId::Object(1)),
        "sphere and cylinder"
    );
}

#[test]
fn stripe_centres_on_the_bunny_mesh() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let text = std::fs::read_to_string(format!("{dir}/bunny.toml")).unwrap();
    let mut scene = Scene::from_toml_in(&text, std::path::Path::new(dir)).unwrap();
    scene.width = 480;
    scene.height = 360;
    scene.camera = Scene::demo(480, 360).camera;
    let (surfaces, checked) = check_centroids(scene, &[24, 27, 30, 33, 36]);
    assert!(
        surfaces.contains(&SurfaceId::Object(0)),
        "no bunny column checked ({checked} columns)"
    );
}

#[test]
fn mesh_hierarchy_agrees_with_brute_force() {
    use scanner_core::nalgebra::{Point3, Vector3};
    use scanner_rig::mesh::SceneMesh;
    let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj"));
    let mesh = SceneMesh::load(path, 120.0, 20.0, Point3::new(0.0, 0.0, 500.0)).unwrap();
    assert_eq!(mesh.len(), 3674);
    // the same triangles in one leaf-less list: a mesh of each triangle alone
    let tris = SceneMesh::triangles_of(path, 120.0, 20.0, Point3::new(0.0, 0.0, 500.0)).unwrap();
    let mut x = 12345u64;
    let mut rnd = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let (mut hits, mut n) = (0, 0);
    while n < 400 {
        let dir = Vector3::new(rnd() * 0.3, rnd() * 0.3, 1.0).normalize();
        let fast = mesh.hit(&Point3::origin(), &dir, 1e-9);
        let slow = tris
            .iter()
            .filter_map(|t| SceneMesh::new(vec![*t]).hit(&Point3::origin(), &dir, 1e-9))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        assert_eq!(fast.map(|h| h.0), slow.map(|h| h.0), "ray {dir:?}");
        hits += usize::from(fast.is_some());
        n += 1;
    }
    assert!(hits > 50, "only {hits} of 400 rays hit the bunny");
    let err = SceneMesh::load(
        std::path::Path::new("/no/such.obj"),
        1.0,
        0.0,
        Point3::origin(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("/no/such.obj"), "{err}");
}
#[test]
fn shadows_stay_dark_and_the_reference_has_no_laser() {
    let (w, h) = (320usize, 240usize);
    let rig = Rig::new(quiet(Scene::demo(w as u32, h as u32))).unwrap();
    let reference = rig.reference();
    let mut shadowed = 0;
    let camera = rig.scene().camera;
    for k in 0..rig.scene().laser.frames {
        let frame = rig.frame(k).unwrap();
        let (source, plane) = rig.laser(k).unwrap();
        // a pixel whose centre sees the board on the light plane with an object between it and
        // the source, and so do points 4.5 px around it (beyond the 3 px radius of the lens blur),
        // so that no light can reach it
        let in_shadow = |u: f64, v: f64| -> bool {
            let Ok(ray) = camera.pixel_to_ray(&scanner_core::nalgebra::Point2::new(u, v)) else {
                return false;
            };
            let Some(hit) = rig.cast(&ray.normalize()) else {
                return false;
            };
            if !matches!(hit.surface, SurfaceId::Left | SurfaceId::Right) {
                return false;
            }
            let to = source - hit.point;
            rig.scene().objects.iter().enumerate().any(|(n, o)| {
                o.shape
                    .hit(&hit.point, &to.normalize(), 1e-6, n as u16)
                    .is_some_and(|x| x.t < to.norm())
            })
        };
        for v in 1..h - 1 {
            for u in 1..w - 1 {
                let on_plane = camera
                    .pixel_to_ray(&scanner_core::nalgebra::Point2::new(u as f64, v as f64))
                    .ok()
                    .and_then(|r| rig.cast(&r.normalize()))
                    .is_some_and(|hit| plane.signed_distance(&hit.point).abs() < 0.3);
                if !on_plane {
                    continue;
                }
                let all = (-1..=1).all(|dv| {
                    (-1..=1).all(|du| {
                        in_shadow(
                            u as f64 + f64::from(du) * 4.5,
                            v as f64 + f64::from(dv) * 4.5,
                        )
                    })
                });
                if all {
                    let i = (v * w + u) * 3;
                    assert_eq!(
                        &frame.data[i..i + 3],
                        &reference.data[i..i + 3],
                        "frame {k} ({u}, {v}) is lit in a shadow"
                    );
                    shadowed += 1;
                }
            }
        }
        assert_ne!(frame.data, reference.data, "frame {k} shows no laser");
    }
    let shadow_columns = shadowed;
    assert!(
        shadow_columns > 20,
        "the demo scene must cast laser shadows on the board ({shadow_columns})"
    );
}

#[test]
fn formats_and_errors() {
    let rig = Rig::new(quiet(Scene::demo(64, 48))).unwrap();
    let f = rig.frame(0).unwrap();
    assert_eq!(f.to_format(PixelFormat::Gray8).len(), 64 * 48);
    assert_eq!(f.to_format(PixelFormat::Yuyv).len(), 64 * 48 * 2);
    assert_eq!(f.to_format(PixelFormat::Rgb24).len(), 64 * 48 * 3);
    let err = rig.frame(10_000).unwrap_err();
    assert!(err.to_string().contains("10000"), "{err}");
    let mut bad = Scene::demo(64, 48);
    bad.board.angle_deg = 180.0;
    assert!(Rig::new(bad).unwrap_err().to_string().contains("angle"));
}

#[test]
fn the_rig_is_a_frame_source_by_name() {
    use scanner_device::source::{SourceError, open};
    let mut src = open("rig:96x72", PixelFormat::Yuyv).unwrap();
    assert_eq!(src.size(), (96, 72));
    assert!(src.describe().contains("virtual rig"));
    let reference = src.reference().unwrap();
    assert_eq!(reference.data.len(), 96 * 72 * 2);
    reference.view().unwrap();
    let mut n = 0;
    while let Some(f) = src.next_frame().unwrap() {
        assert_eq!(f.index, n);
        assert_ne!(f.data, reference.data);
        n += 1;
    }
    assert_eq!(
        n,
        Scene::demo(96, 72).laser.frames as u64,
        "the stream ends after the sweep"
    );
    assert!(src.next_frame().unwrap().is_none());
    for (name, want) in [
        ("webcam", "no frame source"),
        ("rig:12", "WIDTHxHEIGHT"),
        ("rig:axb", "\"axb\": expected WIDTHxHEIGHT"),
        ("rig:95x72", "even width"),
    ] {
        let err = open(name, PixelFormat::Yuyv).err().expect(name);
        assert!(err.to_string().contains(want), "{name}: {err}");
        if name == "webcam" {
            assert!(matches!(err, SourceError::Unknown(_)));
        }
    }
}

/// Width (px above half its peak) and peak of the red laser light in one column.
fn stripe_in_column(frame: &[u8], reference: &[u8], w: usize, h: usize, u: usize) -> (usize, f64) {
    let s = column_signal(frame, reference, w, h, u);
    let peak = s.iter().copied().fold(0.0, f64::max);
    (s.iter().filter(|&&x| x > peak / 2.0).count(), peak)
}

#[test]
fn motion_blur_flicker_and_speckle_do_what_they_say() {
    let (w, h) = (160usize, 120usize);
    let base = quiet(Scene::demo(w as u32, h as u32));
    let still = Rig::new(base.clone()).unwrap();
    let moving = Rig::new(Scene {
        exposure: 1.0,
        ..base.clone()
    })
    .unwrap();
    let reference = still.reference().data;
    // motion blur: the stripe is wider on the board (column 20, left half)
    let k = 20;
    let (w0, _) = stripe_in_column(&still.frame(k).unwrap().data, &reference, w, h, 20);
    let (w1, _) = stripe_in_column(&moving.frame(k).unwrap().data, &reference, w, h, 20);
    assert!(w1 > w0, "motion blur: {w1} px vs {w0} px");
    // flicker: the ambient level differs from frame to frame
    let flicker = Rig::new(Scene {
        flicker: 0.3,
        ..base.clone()
    })
    .unwrap();
    let mean = |d: &[u8]| d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len() as f64;
    let levels: Vec<f64> = (0..4)
        .map(|k| mean(&flicker.frame(k).unwrap().data))
        .collect();
    let spread = levels.iter().copied().fold(f64::MIN, f64::max)
        - levels.iter().copied().fold(f64::MAX, f64::min);
    assert!(spread > 3.0, "flicker: frame means {levels:?}");
    // speckle: the peaks along the stripe vary more
    let rough = |scene: Scene| -> f64 {
        let rig = Rig::new(scene).unwrap();
        let (f, r) = (rig.frame(k).unwrap().data, rig.reference().data);
        let peaks: Vec<f64> = (5..40)
            .map(|u| stripe_in_column(&f, &r, w, h, u).1)
            .collect();
        let m = peaks.iter().sum::<f64>() / peaks.len() as f64;
        (peaks.iter().map(|p| (p - m).powi(2)).sum::<f64>() / peaks.len() as f64).sqrt() / m
    };
    let (smooth, grainy) = (
        rough(base.clone()),
        rough(Scene {
            laser: scanner_rig::LaserSpec {
                speckle: 1.0,
                ..base.laser.clone()
            },
            ..base
        }),
    );
    assert!(
        grainy > 2.0 * smooth,
        "speckle: relative spread of the peaks {grainy} vs {smooth}"
    );
}

#[test]
fn markers_render_at_their_projected_centres() {
    let (w, h) = (640usize, 480usize);
    let rig = Rig::new(quiet(Scene::demo(w as u32, h as u32))).unwrap();
    let img = rig.reference().to_format(PixelFormat::Gray8);
    let markers = rig.markers();
    assert_eq!(markers.len(), 12);
    let mut checked = 0;
    let mut near_objects = 0;
    let mut worst = 0.0f64;
    for m in markers.iter().filter(|m| m.visible) {
        // darkness below the board's level, over the disc's box plus the blur's reach
        let r = 0.5 * rig.scene().board.markers.diameter * rig.scene().camera.fx()
            / m.centre.coords.norm()
            + 5.0;
        let (x0, x1) = (
            (m.disc_px.x - r).floor() as usize,
            (m.disc_px.x + r).ceil() as usize,
        );
        let (y0, y1) = (
            (m.disc_px.y - r).floor() as usize,
            (m.disc_px.y + r).ceil() as usize,
        );
        // The board's level: the median of a ring just outside the window (a box corner may
        // fall on an object); the window itself is the disc plus the blur's reach.
        let dist = |x: usize, y: usize| {
            ((x as f64 - m.disc_px.x).powi(2) + (y as f64 - m.disc_px.y).powi(2)).sqrt()
        };
        let mut ring: Vec<f64> = Vec::new();
        for y in y0.saturating_sub(3)..=(y1 + 3).min(h - 1) {
            for x in x0.saturating_sub(3)..=(x1 + 3).min(w - 1) {
                let d = dist(x, y);
                if d > r && d <= r + 2.0 {
                    ring.push(f64::from(img[y * w + x]));
                }
            }
        }
        ring.sort_by(f64::total_cmp);
        let board = ring[ring.len() / 2];
        // An object next to the marker (in the ring) would bias this crude centroid: leave
        // such markers to the detector's test (tests/calib.rs), and count them.
        if ring[ring.len() * 9 / 10] - ring[ring.len() / 10] > 4.0 {
            near_objects += 1;
            continue;
        }
        let (mut m0, mut mx, mut my) = (0.0, 0.0, 0.0);
        for y in y0..=y1.min(h - 1) {
            for x in x0..=x1.min(w - 1) {
                if dist(x, y) > r {
                    continue;
                }
                let d = (board - f64::from(img[y * w + x])).max(0.0);
                m0 += d;
                mx += d * x as f64;
                my += d * y as f64;
            }
        }
        let err = ((mx / m0 - m.disc_px.x).powi(2) + (my / m0 - m.disc_px.y).powi(2)).sqrt();
        let bias = (m.disc_px - m.centre_px).norm();
        println!(
            "{:?} {}: error {err:.4} px (projected centre vs disc centroid {bias:.4} px)",
            m.surface, m.index
        );
        worst = worst.max(err);
        checked += 1;
    }
    println!("{checked} markers checked, {near_objects} left out next to an object");
    assert!(
        checked >= 6,
        "only {checked} markers fully visible and clear"
    );
    assert!(
        worst <= 0.05,
        "a marker renders {worst} px from its projected disc's centroid"
    );
}

#[test]
fn textured_objects_vary_in_colour() {
    let (w, h) = (320usize, 240usize);
    let rig = Rig::new(quiet(Scene::demo(w as u32, h as u32))).unwrap();
    let reference = rig.reference();
    // the sphere (textured) shows two colours, the cylinder (plain) one
    let mut sphere = std::collections::HashSet::new();
    let mut cylinder = std::collections::HashSet::new();
    for v in 0..h {
        for u in 0..w {
            let px = scanner_core::nalgebra::Point2::new(u as f64, v as f64);
            let Ok(ray) = rig.scene().camera.pixel_to_ray(&px) else {
                continue;
            };
            let i = (v * w + u) * 3;
            let rgb = (
                reference.data[i] / 8,
                reference.data[i + 1] / 8,
                reference.data[i + 2] / 8,
            );
            match rig.cast(&ray.normalize()).map(|hit| hit.surface) {
                Some(SurfaceId::Object(0)) => sphere.insert(rgb),
                Some(SurfaceId::Object(1)) => cylinder.insert(rgb),
                _ => false,
            };
        }
    }
    // coarse colour classes: the checker's two colours (plus blur at the edges) on the sphere
    assert!(sphere.len() >= 2, "sphere colours {sphere:?}");
    let greenish = sphere.iter().any(|c| c.1 > c.0);
    let reddish = sphere.iter().any(|c| c.0 > c.1);
    assert!(greenish && reddish, "sphere colours {sphere:?}");
    assert!(
        cylinder.iter().all(|c| c.2 >= c.0),
        "cylinder colours {cylinder:?}"
    );
}

#[test]
fn turntable_scene_errors_name_the_key() {
    let disc = "[[objects]]\nshape = \"turntable\"\npaper = \"a4\"\ncentre = [0.0, 60.0, 560.0]\n";
    let bad = [
        (format!("{disc}{disc}"), "turntables"),
        (disc.replace("\"a4\"", "\"a5\""), "a4 or a3"),
        (format!("tilt_deg = 100.0\n{disc}"), "tilt_deg"),
        (format!("tilt_deg = nan\n{disc}"), "tilt_deg"),
        ("[[views]]\ndisc = false\n".to_string(), "no turntable"),
    ];
    for (text, named) in bad {
        let err = Scene::from_toml(&text).unwrap_err().to_string();
        assert!(err.contains(named), "{text}: {err}");
    }
    // A view without the disc: the rig's truth has none there.
    let text = format!("{disc}[[views]]\n[[views]]\nangle_deg = 90.0\ndisc = false\n");
    let s = Scene::from_toml(&text).unwrap();
    assert!(Rig::new(s.view(0).unwrap()).unwrap().disc_pose().is_some());
    assert!(Rig::new(s.view(1).unwrap()).unwrap().disc_pose().is_none());
}

#[test]
fn shadow_scene_errors_name_the_key() {
    for (text, named) in [
        ("[shadow]\nlamp_radius_mm = nan\n", "lamp_radius_mm"),
        ("[shadow]\nlamp_radius_mm = -1.0\n", "lamp_radius_mm"),
        ("[shadow]\npower = 0.0\n", "power"),
        ("[shadow]\nrod_radius_mm = inf\n", "rod_radius_mm"),
        ("[shadow]\nrod_distance_mm = 2.0\n", "rod_distance_mm"),
        ("[shadow]\nbulb = 3.0\n", "bulb"),
    ] {
        let err = Scene::from_toml(text).unwrap_err().to_string();
        assert!(err.contains(named), "{text}: {err}");
    }
    let s = Scene::from_toml("[shadow]\nlamp_radius_mm = 1.5\n").unwrap();
    assert_eq!(s.shadow.map(|sh| sh.lamp_radius_mm), Some(1.5));
}

/// A scene's own calibration shots are read in order; a pose behind the camera, turned 80° or
/// more, or not a number is refused naming the shot, never rendered.
#[test]
fn a_scenes_calibration_shots_are_read_or_refused_by_number() {
    let s = Scene::from_toml(
        "[[shots]]\ncentre = [10.0, -5.0, 700.0]\nturn_deg = [20.0, 0.0, 0.0]\n\n[[shots]]\ncentre = [0.0, 0.0, 600.0]\n",
    )
    .unwrap();
    assert_eq!(s.shots.len(), 2);
    assert_eq!(s.shots[0].turn_deg, [20.0, 0.0, 0.0]);
    assert_eq!(s.shots[1].turn_deg, [0.0; 3]);
    for bad in [
        "centre = [0.0, 0.0, -5.0]",
        "centre = [0.0, 0.0, 600.0]\nturn_deg = [85.0, 0.0, 0.0]",
        "centre = [nan, 0.0, 600.0]",
    ] {
        let text = format!("[[shots]]\ncentre = [0.0, 0.0, 600.0]\n\n[[shots]]\n{bad}\n");
        match Scene::from_toml(&text) {
            Err(scanner_rig::RigError::Scene(why)) => {
                assert!(why.starts_with("shots[1]"), "{bad}: {why}")
            }
            other => panic!("{bad}: {other:?}"),
        }
    }
}
