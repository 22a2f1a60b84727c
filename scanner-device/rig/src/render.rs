//! The rig itself ([`Rig`]): one ray per pixel cast once into a geometry buffer, then each
//! frame rendered from it with its ground truth.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use scanner_core::Camera;
use scanner_core::geometry::Plane;
use scanner_core::nalgebra::{Isometry3, Point2, Point3, Rotation3, Vector3};
use scanner_core::stripe::PixelFormat;

use crate::error::RigError;
use crate::scene::*;
use crate::surface::{Hit, Shape, SurfaceId};

/// One pixel of the geometry buffer: the surface point its centre sees.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Texel {
    point: [f32; 3],
    /// Index into the albedo table: 0, 1 board halves, 2 + n object n; `u16::MAX` nothing.
    surface: u16,
}

/// A laser source and its light plane.
pub type Laser = (Point3<f64>, Plane<f64>);

/// Ground truth of one column of one laser frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColumnTruth {
    /// Row (subpixel, pixel centres at integers) where the laser plane meets the visible surface.
    pub row: f64,
    /// The 3-D point there, camera coordinates, mm.
    pub point: Point3<f64>,
    /// The surface it lies on.
    pub surface: SurfaceId,
    /// Cosine of the laser's angle of incidence there (1 head-on, near 0 at the terminator,
    /// where part of the stripe falls in the surface's own shadow).
    pub incidence: f64,
}

/// A rendered frame in RGB, 8 bits per channel, rows packed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rgb8 {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// `width × height × 3` bytes.
    pub data: Vec<u8>,
}

impl Rgb8 {
    /// The frame's luma as an `image` gray image (what calibration reads).
    pub fn to_gray_image(&self) -> image::GrayImage {
        image::GrayImage::from_raw(
            self.width as u32,
            self.height as u32,
            self.to_format(PixelFormat::Gray8),
        )
        .expect("width × height bytes")
    }

    /// The frame in another pixel format, rows packed: gray is the luma, YUYV carries the luma
    /// of each pixel and the chroma of each pair.
    pub fn to_format(&self, format: PixelFormat) -> Vec<u8> {
        use scanner_core::colour::{luma, rgb_pair_to_yuyv};
        match format {
            PixelFormat::Rgb24 => self.data.clone(),
            PixelFormat::Gray8 => self
                .data
                .chunks_exact(3)
                .map(|p| luma([p[0], p[1], p[2]]))
                .collect(),
            PixelFormat::Yuyv => self
                .data
                .chunks_exact(6)
                .flat_map(|p| rgb_pair_to_yuyv([p[0], p[1], p[2]], [p[3], p[4], p[5]]))
                .collect(),
        }
    }
}

/// The rig: a scene with its geometry buffer.
#[derive(Debug, Clone)]
pub struct Rig {
    pub(crate) scene: Scene,
    pub(crate) board: BoardGeometry,
    /// Undistorted normalised coordinates of each pixel centre (NaN where undefined), for
    /// interpolating sub-pixel rays.
    pub(crate) normalised: Vec<[f32; 2]>,
    pub(crate) texels: Vec<Texel>,
    /// The ambient image, blurred once.
    pub(crate) ambient: Vec<[f32; 3]>,
    /// A shadow sweep's lamp-lit image without the rod (supersampled, before the lens blur);
    /// empty without a shadow.
    pub(crate) lamp: Vec<[f64; 3]>,
    /// A shadow sweep's reference: the ambient image and the rod-free lamp-lit image, through
    /// the lens; empty without a shadow.
    pub(crate) lamp_lit: Vec<[f32; 3]>,
    /// Normalised 1-D lens-blur kernel (odd length; `[1]` without blur).
    pub(crate) kernel: Vec<f64>,
}

use scanner_calib::blur::{blur, gaussian_kernel};

/// Largest footprint of a pixel across the light plane the renderer expects, mm: beyond
/// `5σ +` this from the plane a pixel is not examined further.
const FOOTPRINT_BOUND_MM: f64 = 40.0;

/// Largest distance the light plane sweeps over a surface point during one exposure the
/// renderer expects, mm (beyond it pixels are not examined).
const MOTION_BOUND_MM: f64 = 40.0;
/// Light planes averaged over an exposure with motion blur.
const MOTION_SAMPLES: usize = 5;

/// Sub-samples per pixel side near a marker's rim.
const RIM_SUPERSAMPLE: usize = 6;

/// Sub-samples per pixel side near the stripe.
const SUPERSAMPLE: usize = 3;

impl Rig {
    /// Builds the rig: one ray per pixel, cast once.
    ///
    /// # Errors
    /// [`RigError::Scene`] for out-of-range values, [`RigError::Geometry`] for a degenerate board.
    pub fn new(scene: Scene) -> Result<Rig, RigError> {
        Scene::check_size(scene.width, scene.height)?;
        if scene.laser.frames == 0 {
            return Err(RigError::Scene(
                "the laser sweep needs at least one frame".into(),
            ));
        }
        if !(scene.laser.sigma_mm > 0.0) {
            return Err(RigError::Scene(
                "laser thickness sigma_mm must be positive".into(),
            ));
        }
        if !(0.0..=10.0).contains(&scene.blur_px) {
            return Err(RigError::Scene(format!(
                "lens blur {} px (need 0–10)",
                scene.blur_px
            )));
        }
        let board = BoardGeometry::new(&scene.board)?;
        let (w, h) = (scene.width as usize, scene.height as usize);
        let scene_blur = scene.blur_px;
        let mut rig = Rig {
            scene,
            board,
            texels: vec![
                Texel {
                    point: [0.0; 3],
                    surface: u16::MAX
                };
                w * h
            ],
            normalised: vec![[f32::NAN; 2]; w * h],
            ambient: Vec::new(),
            lamp: Vec::new(),
            lamp_lit: Vec::new(),
            kernel: gaussian_kernel(scene_blur),
        };
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                if let Ok(n) = rig.scene.camera.undistort(&Point2::new(u as f64, v as f64)) {
                    rig.normalised[i] = [n.x as f32, n.y as f32];
                }
                if let Some(hit) = rig.ray(u as f64, v as f64).and_then(|dir| rig.cast(&dir)) {
                    rig.texels[i] = Texel {
                        point: [hit.point.x as f32, hit.point.y as f32, hit.point.z as f32],
                        surface: surface_index(hit.surface),
                    };
                }
            }
        }
        let amb = rig.scene.ambient;
        let fx = rig.scene.camera.fx();
        let mut flat = vec![[0.0; 3]; w * h];
        for (i, t) in rig.texels.iter().enumerate() {
            if t.surface == u16::MAX {
                continue;
            }
            let p = texel_point(t);
            let surface = surface_id(t.surface);
            let k = usize::from(t.surface);
            // near a marker's rim or the turntable's ink: the pixel's coverage by sub-samples, so
            // that markers are rendered without aliasing (their centres are ground truth)
            let albedo = if rig.to_ink_edge(k, &p) < 6.0 * p.coords.norm() / fx {
                let n = RIM_SUPERSAMPLE * RIM_SUPERSAMPLE;
                let mut sum = [0.0; 3];
                for (su, sv) in subpixels(i % w, i / w, RIM_SUPERSAMPLE) {
                    let hit = rig.ray_fast(su, sv).and_then(|d| rig.cast(&d));
                    let a = hit.map_or([0.0; 3], |hit| rig.albedo_of(hit.surface, &hit.point));
                    for c in 0..3 {
                        sum[c] += a[c] / n as f64;
                    }
                }
                sum
            } else {
                rig.albedo_of(surface, &p)
            };
            flat[i] = albedo.map(|a| amb * a);
        }
        rig.ambient = blur(&flat, w, h, &rig.kernel)
            .into_iter()
            .map(|p| p.map(|v| v as f32))
            .collect();
        if let Some(shadow) = rig.scene.shadow {
            shadow.check()?;
            rig.lamp = rig.lamp_image(&shadow);
            let lit = blur(&rig.lamp, w, h, &rig.kernel);
            rig.lamp_lit = rig
                .ambient
                .iter()
                .zip(lit)
                .map(|(a, l)| core::array::from_fn(|c| a[c] + l[c] as f32))
                .collect();
        }
        Ok(rig)
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Sets the sensor's digital numbers per unit of radiance (a camera's exposure × gain):
    /// every frame rendered after it, the reference included, takes it.
    pub fn set_sensor_gain(&mut self, gain: f64) {
        self.scene.sensor.gain = gain;
    }

    /// The true board planes, left and right, normals towards the camera.
    pub fn board_planes(&self) -> [Plane<f64>; 2] {
        self.board.planes()
    }

    /// Unit ray through the (subpixel) image point `(u, v)`.
    pub(crate) fn ray(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        let r = self.scene.camera.pixel_to_ray(&Point2::new(u, v)).ok()?;
        Some(r.normalize())
    }

    /// The albedo at a surface point: the marker ink inside a marker of a board sheet.
    pub(crate) fn albedo_of(&self, surface: SurfaceId, p: &Point3<f64>) -> [f64; 3] {
        let k = match surface {
            SurfaceId::Left => 0,
            SurfaceId::Right => 1,
            SurfaceId::Object(n) => {
                let o = &self.scene.objects[usize::from(n)];
                // The checker is fixed to the object: evaluated where the point was before the
                // view moved it (a fixed object never moved).
                let p = if self.scene.fixed.contains(&usize::from(n)) {
                    *p
                } else {
                    self.scene.object_pose.inverse_transform_point(p)
                };
                if let Some(t) = &self.scene.turntable
                    && t.object == usize::from(n)
                {
                    let q = t.pose.inverse_transform_point(&p);
                    let (x, y) = t.disc.to_sheet(&Point2::new(q.x, q.y));
                    return if t.sheet.ink(x, y) { t.ink } else { o.albedo };
                }
                return match o.texture {
                    Some((cell, other)) if cell > 0.0 => {
                        let parity = (p.x / cell).floor() as i64
                            + (p.y / cell).floor() as i64
                            + (p.z / cell).floor() as i64;
                        if parity.rem_euclid(2) == 0 {
                            o.albedo
                        } else {
                            other
                        }
                    }
                    _ => o.albedo,
                };
            }
        };
        let m = &self.scene.board.markers;
        let uv = self.board.sheet(k, p);
        if let Some(c) = &m.chess[k] {
            return match c.ink(uv) {
                Some(true) => m.albedo,
                _ => self.scene.board.albedo,
            };
        }
        let r2 = (m.diameter / 2.0).powi(2);
        let list = if k == 0 { &m.left } else { &m.right };
        if list
            .iter()
            .any(|c| (uv[0] - c[0]).powi(2) + (uv[1] - c[1]).powi(2) <= r2)
        {
            m.albedo
        } else {
            self.scene.board.albedo
        }
    }

    /// Distance (mm) from `p` on surface `k` (its index in the geometry buffer) to the nearest
    /// edge of printed ink: a board marker's rim or the turntable's print.
    pub(crate) fn to_ink_edge(&self, k: usize, p: &Point3<f64>) -> f64 {
        if k < 2 {
            return self.to_rim(k, p);
        }
        match &self.scene.turntable {
            Some(t) if t.object + 2 == k => {
                let q = t
                    .pose
                    .inverse_transform_point(&self.scene.object_pose.inverse_transform_point(p));
                let (x, y) = t.disc.to_sheet(&Point2::new(q.x, q.y));
                t.sheet.ink_edge_distance(x, y)
            }
            _ => f64::INFINITY,
        }
    }

    /// The turntable disc's pose (disc frame → camera) in this scene's view: `None` without a
    /// disc or when the view took it away.
    pub fn disc_pose(&self) -> Option<Isometry3<f64>> {
        let t = self.scene.turntable.as_ref()?;
        match self.scene.objects.get(t.object)?.shape {
            Shape::Disc { radius, .. } if radius > 0.0 => Some(self.scene.object_pose * t.pose),
            _ => None,
        }
    }

    /// Distance (mm) from `p` on half `k` to the nearest marker's rim.
    pub(crate) fn to_rim(&self, k: usize, p: &Point3<f64>) -> f64 {
        let m = &self.scene.board.markers;
        let uv = self.board.sheet(k, p);
        if let Some(c) = &m.chess[k] {
            return c.edge_distance(uv);
        }
        let list = if k == 0 { &m.left } else { &m.right };
        list.iter()
            .map(|c| {
                (((uv[0] - c[0]).powi(2) + (uv[1] - c[1]).powi(2)).sqrt() - m.diameter / 2.0).abs()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The ground truth of every printed marker.
    pub fn markers(&self) -> Vec<MarkerTruth> {
        let m = &self.scene.board.markers;
        let cam = &self.scene.camera;
        let (w, h) = (f64::from(self.scene.width), f64::from(self.scene.height));
        let mut out = Vec::new();
        for (k, (surface, list)) in [(SurfaceId::Left, &m.left), (SurfaceId::Right, &m.right)]
            .into_iter()
            .enumerate()
        {
            if let Some(c) = &m.chess[k] {
                // Corners: seen when the camera sees the board at the corner and around it.
                for (index, sheet) in c.corners().into_iter().enumerate() {
                    let centre = self.board.point(k, sheet);
                    let Ok(centre_px) = cam.project(&centre) else {
                        continue;
                    };
                    let r = 0.3 * c.square;
                    let visible = (0..16).all(|i| {
                        let a = f64::from(i) / 16.0 * std::f64::consts::TAU;
                        let p = self
                            .board
                            .point(k, [sheet[0] + r * a.cos(), sheet[1] + r * a.sin()]);
                        cam.project(&p).is_ok_and(|px| {
                            px.x >= 0.0 && px.y >= 0.0 && px.x <= w - 1.0 && px.y <= h - 1.0
                        }) && self.cast(&p.coords.normalize()).is_some_and(|hit| {
                            hit.surface == surface
                                && (hit.point - p).norm() < 1e-6 * p.coords.norm() + 1e-9
                        })
                    });
                    out.push(MarkerTruth {
                        surface,
                        index,
                        sheet,
                        centre,
                        centre_px,
                        disc_px: centre_px,
                        visible,
                    });
                }
                continue;
            }
            for (index, &sheet) in list.iter().enumerate() {
                let centre = self.board.point(k, sheet);
                let Ok(centre_px) = cam.project(&centre) else {
                    continue;
                };
                // the rim, projected: polygon centroid (Green's theorem) of 720 points
                let rim: Vec<Option<Point2<f64>>> = (0..720)
                    .map(|i| {
                        let a = i as f64 / 720.0 * std::f64::consts::TAU;
                        let r = m.diameter / 2.0;
                        let p = self
                            .board
                            .point(k, [sheet[0] + r * a.cos(), sheet[1] + r * a.sin()]);
                        let px = cam.project(&p).ok()?;
                        // in view, and the board is what the camera sees there
                        let seen = self.cast(&p.coords.normalize()).is_some_and(|hit| {
                            hit.surface == surface
                                && (hit.point - p).norm() < 1e-6 * p.coords.norm() + 1e-9
                        });
                        (seen && px.x >= 0.0 && px.y >= 0.0 && px.x <= w - 1.0 && px.y <= h - 1.0)
                            .then_some(px)
                    })
                    .collect();
                let visible = rim.iter().all(Option::is_some);
                let pts: Vec<Point2<f64>> = rim.iter().map(|p| p.unwrap_or(centre_px)).collect();
                let disc_px = polygon_centroid(&pts).unwrap_or(centre_px);
                out.push(MarkerTruth {
                    surface,
                    index,
                    sheet,
                    centre,
                    centre_px,
                    disc_px,
                    visible,
                });
            }
        }
        out
    }

    /// Unit ray through `(u, v)` interpolated bilinearly between the stored pixel centres
    /// (distortion is smooth: the error is far below a thousandth of a pixel); for rendering.
    pub(crate) fn ray_fast(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let u = u.clamp(0.0, (w - 1) as f64);
        let v = v.clamp(0.0, (h - 1) as f64);
        let (u0, v0) = (
            (u.floor() as usize).min(w - 2),
            (v.floor() as usize).min(h - 2),
        );
        let (fu, fv) = (u - u0 as f64, v - v0 as f64);
        let at = |uu: usize, vv: usize| self.normalised[vv * w + uu];
        let (a, b, c, d) = (
            at(u0, v0),
            at(u0 + 1, v0),
            at(u0, v0 + 1),
            at(u0 + 1, v0 + 1),
        );
        let lerp = |k: usize| {
            let top = f64::from(a[k]) * (1.0 - fu) + f64::from(b[k]) * fu;
            let bottom = f64::from(c[k]) * (1.0 - fu) + f64::from(d[k]) * fu;
            top * (1.0 - fv) + bottom * fv
        };
        let r = Vector3::new(lerp(0), lerp(1), 1.0);
        r.iter().all(|x| x.is_finite()).then(|| r.normalize())
    }

    /// Distance from `p` to the nearest true surface (a board sheet or an object), mm: how far a
    /// measured point is from what it measured.
    pub fn surface_distance(&self, p: &Point3<f64>) -> f64 {
        let mut best = f64::INFINITY;
        for k in 0..2 {
            let (plane, h) = &self.board.halves[k];
            let u = (p - self.board.crease).dot(h);
            let d = if u >= 0.0 {
                plane.signed_distance(p).abs()
            } else {
                // Beyond the crease: the distance to the crease line.
                let r = p - self.board.crease;
                (r - self.board.along * r.dot(&self.board.along)).norm()
            };
            best = best.min(d);
        }
        for o in &self.scene.objects {
            if let Some(d) = o.shape.distance(p) {
                best = best.min(d);
            }
        }
        best
    }

    /// The nearest surface along a unit ray from the camera centre.
    pub fn cast(&self, dir: &Vector3<f64>) -> Option<Hit> {
        let mut best = self.board.hit(dir);
        for (k, o) in self.scene.objects.iter().enumerate() {
            if let Some(h) = o.shape.hit(&Point3::origin(), dir, 1e-9, k as u16)
                && best.is_none_or(|b| h.t < b.t)
            {
                best = Some(h);
            }
        }
        best
    }

    /// `true` if an object lies between `p` and the laser source `s`.
    pub(crate) fn shadowed(&self, p: &Point3<f64>, s: &Point3<f64>) -> bool {
        let to = s - p;
        let dist = to.norm();
        let dir = to / dist;
        self.scene.objects.iter().enumerate().any(|(k, o)| {
            o.shape
                .hit(p, &dir, 1e-6, k as u16)
                .is_some_and(|h| h.t < dist - 1e-6)
        })
    }

    /// The laser's source and light plane in frame `index` of the sweep (at the middle of its
    /// exposure).
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep.
    pub fn laser(&self, index: usize) -> Result<Laser, RigError> {
        let l = &self.scene.laser;
        if index >= l.frames {
            return Err(RigError::NoSuchFrame {
                index,
                frames: l.frames,
            });
        }
        self.laser_at(index as f64)
    }

    /// The laser at time `t` in frame periods: the aim moves linearly through the sweep, the hand's
    /// wobble and jitter are random per frame and move linearly between frames.
    pub(crate) fn laser_at(&self, t: f64) -> Result<Laser, RigError> {
        let l = &self.scene.laser;
        if let Some(normal) = l.fixed {
            let plane = Plane::from_point_normal(&l.source, &normal)
                .map_err(RigError::Geometry)?
                .facing_camera();
            return Ok((l.source, plane));
        }
        let (source, along, aim) = self.sweep_at(t);
        let plane = Plane::from_point_normal(&source, &along.cross(&(aim - source)))
            .map_err(RigError::Geometry)?
            .facing_camera();
        Ok((source, plane))
    }

    /// The hand at time `t` (frame periods): the source's position, the (rolled) horizontal
    /// direction the light plane holds, and the aim point on the crease line.
    fn sweep_at(&self, t: f64) -> (Point3<f64>, Vector3<f64>, Point3<f64>) {
        let l = &self.scene.laser;
        let t = t.clamp(0.0, (l.frames - 1) as f64);
        let shake = |k: usize| -> [f64; 4] {
            let mut rng =
                SmallRng::seed_from_u64(l.seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            core::array::from_fn(|_| rng.random_range(-1.0..=1.0))
        };
        let (k0, f) = (t.floor() as usize, t - t.floor());
        let (a, b) = (shake(k0), shake(k0 + 1));
        let j: [f64; 4] = core::array::from_fn(|i| a[i] * (1.0 - f) + b[i] * f);
        let frac = if l.frames > 1 {
            t / (l.frames - 1) as f64
        } else {
            0.5
        };
        let height = l.sweep.0 + (l.sweep.1 - l.sweep.0) * frac;
        let source = l.source + Vector3::new(j[0], j[1], j[2]) * l.jitter_mm;
        let roll = (j[3] * l.wobble_deg).to_radians();
        // the plane holds the (rolled) horizontal direction and the aim point on the crease line
        let along = Rotation3::from_axis_angle(&Vector3::z_axis(), roll) * Vector3::x();
        let aim = Point3::new(0.0, height, self.scene.board.distance);
        (source, along, aim)
    }

    /// The rod of a shadow sweep at time `t` (frame periods): a point of its axis and the axis's
    /// direction. It lies in the plane the laser would have at `t`, `rod_distance_mm` from the
    /// laser's source along the plane's aim (the hand's jitter and wobble move it; the lamp
    /// stays at the source).
    fn rod_at(&self, shadow: &ShadowSpec, t: f64) -> Result<(Point3<f64>, Vector3<f64>), RigError> {
        let (source, along, aim) = self.sweep_at(t);
        let towards = aim - source;
        if !(towards.norm() > shadow.rod_distance_mm) {
            return Err(RigError::Scene(
                "shadow: the rod must stand between the lamp and the board".into(),
            ));
        }
        Ok((source + towards.normalize() * shadow.rod_distance_mm, along))
    }

    /// The two planes of a shadow sweep's frame `index` (at the middle of its exposure): through
    /// the lamp's centre and tangent to the rod — where half the lamp is hidden, the edges'
    /// truth.
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep; [`RigError::Scene`] without a shadow.
    pub fn shadow_planes(&self, index: usize) -> Result<[Plane<f64>; 2], RigError> {
        let shadow = self
            .scene
            .shadow
            .ok_or_else(|| RigError::Scene("the scene has no shadow sweep".into()))?;
        self.laser(index)?;
        // the lamp stands still; the hand's jitter and wobble move the rod
        let lamp = self.scene.laser.source;
        let (a, u) = self.rod_at(&shadow, index as f64)?;
        let w = (a - lamp) - u * (a - lamp).dot(&u);
        let d = w.norm();
        let (wh, side) = (w / d, u.cross(&(w / d)));
        let g = (shadow.rod_radius_mm / d).asin();
        let plane = |sign: f64| {
            let dir = wh * g.cos() + side * (sign * g.sin());
            Plane::from_point_normal(&lamp, &u.cross(&dir)).map_err(RigError::Geometry)
        };
        Ok([plane(1.0)?, plane(-1.0)?])
    }

    /// The share of the lamp's light the rod hides from `p` (0 to 1): the lamp a disc of
    /// `lamp_radius_mm` seen from `p`, the rod a band across it (in the plane across the rod).
    fn occlusion(
        &self,
        shadow: &ShadowSpec,
        p: &Point3<f64>,
        lamp: &Point3<f64>,
        (a, u): (&Point3<f64>, &Vector3<f64>),
    ) -> f64 {
        let across = |v: Vector3<f64>| v - u * v.dot(u);
        let (l, r) = (across(lamp - p), across(a - p));
        let (dl, dr) = (l.norm(), r.norm());
        // the rod must lie between the point and the lamp
        if !(dr > shadow.rod_radius_mm && dr < dl && l.dot(&r) > 0.0) {
            return 0.0;
        }
        let e2 = u.cross(&(l / dl));
        let (x, sb, sa) = (
            (r / dr).dot(&e2),
            (shadow.rod_radius_mm / dr).min(1.0),
            (shadow.lamp_radius_mm / (lamp - p).norm()).min(1.0),
        );
        // the rod clear of the lamp's disc, told without an arcsine (most of the image):
        // asin is superadditive on [0, 1], so |x| ≥ sb + sa gives |δ| ≥ β + α, a share of 0
        if x.abs() >= sb + sa {
            return 0.0;
        }
        let delta = x.asin();
        let beta = sb.asin();
        let alpha = sa.asin();
        if alpha <= 1e-9 {
            return if delta.abs() < beta { 1.0 } else { 0.0 };
        }
        // the share of a unit disc left of x = s
        let left = |s: f64| {
            let s = s.clamp(-1.0, 1.0);
            (std::f64::consts::FRAC_PI_2 + s.asin() + s * (1.0 - s * s).sqrt())
                / std::f64::consts::PI
        };
        left((delta + beta) / alpha) - left((delta - beta) / alpha)
    }

    /// The lamp's irradiance at a surface point (per unit albedo), without the rod: in units of
    /// the ambient light, falling with the square of the distance, nothing where an object
    /// stands between.
    fn lamp_light(&self, shadow: &ShadowSpec, p: &Point3<f64>, n: &Vector3<f64>) -> f64 {
        let lamp = self.scene.laser.source;
        let to = lamp - p;
        let dist2 = to.norm_squared();
        let cos = n.dot(&to) / dist2.sqrt();
        if cos <= 0.0 || self.shadowed(p, &lamp) {
            return 0.0;
        }
        shadow.power * cos * 1e6 / dist2
    }

    /// The share of the lamp's light the rod hides at each pixel's surface point, averaged over
    /// the rod's places `rods` (the exposure's motion).
    fn occlusions(&self, shadow: &ShadowSpec, rods: &[(Point3<f64>, Vector3<f64>)]) -> Vec<f64> {
        self.texels
            .iter()
            .map(|t| {
                if t.surface == u16::MAX {
                    0.0
                } else {
                    self.occlusion_at(shadow, rods, &texel_point(t))
                }
            })
            .collect()
    }

    fn occlusion_at(
        &self,
        shadow: &ShadowSpec,
        rods: &[(Point3<f64>, Vector3<f64>)],
        p: &Point3<f64>,
    ) -> f64 {
        let lamp = self.scene.laser.source;
        rods.iter()
            .map(|(a, u)| self.occlusion(shadow, p, &lamp, (a, u)))
            .sum::<f64>()
            / rods.len().max(1) as f64
    }

    /// The lamp-lit image of a shadow sweep without the rod (RGB radiance before the lens blur),
    /// every pixel supersampled (the objects' outlines too): made once.
    fn lamp_image(&self, shadow: &ShadowSpec) -> Vec<[f64; 3]> {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        (0..w * h)
            .map(|i| self.lamp_pixel(shadow, &[], i % w, i / w, Some(0.0)))
            .collect()
    }

    /// How the rod at the places `rods` changes the rod-free lamp-lit image: the pixels it
    /// touches and their change (RGB radiance before the lens blur). Where the rod's share is
    /// the same all over a pixel, the rod-free image scaled; where it varies, per sub-sample.
    fn rod_change(
        &self,
        shadow: &ShadowSpec,
        rods: &[(Point3<f64>, Vector3<f64>)],
    ) -> Vec<(usize, [f64; 3])> {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let occ = self.occlusions(shadow, rods);
        let mut out = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let varies = (occ[i] > 1e-4 && occ[i] < 1.0 - 1e-4)
                    || [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                        .iter()
                        .any(|(du, dv)| {
                            let (uu, vv) = (u as i64 + du, v as i64 + dv);
                            uu >= 0
                                && vv >= 0
                                && (uu as usize) < w
                                && (vv as usize) < h
                                && (occ[vv as usize * w + uu as usize] - occ[i]).abs() > 1e-4
                        });
                if varies {
                    let lit = self.lamp_pixel(shadow, rods, u, v, None);
                    out.push((i, core::array::from_fn(|c| lit[c] - self.lamp[i][c])));
                } else if occ[i] > 0.0 {
                    out.push((i, self.lamp[i].map(|l| -l * occ[i])));
                }
            }
        }
        out
    }

    /// Pixel `(u, v)` of the lamp-lit image, supersampled: the rod's share per sub-sample, or
    /// `share` for all of them.
    fn lamp_pixel(
        &self,
        shadow: &ShadowSpec,
        rods: &[(Point3<f64>, Vector3<f64>)],
        u: usize,
        v: usize,
        share: Option<f64>,
    ) -> [f64; 3] {
        let n = SUPERSAMPLE * SUPERSAMPLE;
        let mut sum = [0.0; 3];
        for (su, sv) in subpixels(u, v, SUPERSAMPLE) {
            let Some(hit) = self.ray_fast(su, sv).and_then(|d| self.cast(&d)) else {
                continue;
            };
            let hidden = share.unwrap_or_else(|| self.occlusion_at(shadow, rods, &hit.point));
            let e = self.lamp_light(shadow, &hit.point, &hit.normal) * (1.0 - hidden);
            let a = self.albedo_of(hit.surface, &hit.point);
            for c in 0..3 {
                sum[c] += e * a[c] / n as f64;
            }
        }
        sum
    }

    /// Frame `index` of a shadow sweep, or its reference (`None`: the rod away): ambient light
    /// and the lamp's, through the lens.
    fn shadow_radiance(
        &self,
        shadow: &ShadowSpec,
        index: Option<usize>,
    ) -> Result<Vec<[f32; 3]>, RigError> {
        let rods = match index {
            None => Vec::new(),
            Some(k) => {
                self.laser(k)?;
                let e = self.scene.exposure;
                let times: Vec<f64> = if e == 0.0 {
                    vec![k as f64]
                } else {
                    (0..MOTION_SAMPLES)
                        .map(|i| k as f64 + e * ((i as f64 + 0.5) / MOTION_SAMPLES as f64 - 0.5))
                        .collect()
                };
                times
                    .iter()
                    .map(|&t| self.rod_at(shadow, t))
                    .collect::<Result<_, _>>()?
            }
        };
        // the rod-free image through the lens (made once), and the rod's change splatted
        let mut out = self.lamp_lit.clone();
        let w = self.scene.width as usize;
        for (i, change) in self.rod_change(shadow, &rods) {
            self.splat(&mut out, i % w, i / w, change);
        }
        Ok(out)
    }

    /// The light planes the exposure of frame `index` averages (one without motion blur).
    pub(crate) fn exposure_planes(&self, index: usize) -> Result<Vec<Laser>, RigError> {
        self.laser(index)?;
        let e = self.scene.exposure;
        if e == 0.0 {
            return Ok(vec![self.laser_at(index as f64)?]);
        }
        (0..MOTION_SAMPLES)
            .map(|i| {
                let s = (i as f64 + 0.5) / MOTION_SAMPLES as f64 - 0.5;
                self.laser_at(index as f64 + e * s)
            })
            .collect()
    }

    /// Laser irradiance (per unit albedo and colour) at a surface point.
    pub(crate) fn laser_light(
        &self,
        p: &Point3<f64>,
        n: &Vector3<f64>,
        source: &Point3<f64>,
        plane: &Plane<f64>,
    ) -> f64 {
        let l = &self.scene.laser;
        let d = plane.signed_distance(p);
        let across = (-(d * d) / (2.0 * l.sigma_mm * l.sigma_mm)).exp();
        if across < 1e-7 {
            return 0.0;
        }
        let to = source - p;
        let dist2 = to.norm_squared();
        let cos = n.dot(&to) / dist2.sqrt();
        if cos <= 0.0 || self.shadowed(p, source) {
            return 0.0;
        }
        l.power * across * cos * 1e6 / dist2 * speckle(p, l.speckle)
    }

    /// The radiance image (RGB, row-major) of the scene lit by ambient light and, if given, by the
    /// laser of frame `laser`.
    pub(crate) fn radiance(&self, time: f64, lasers: &[Laser]) -> Vec<[f32; 3]> {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        // mains flicker: light intensity follows |sin| of the mains, i.e. twice its frequency
        let phase = 2.0 * std::f64::consts::PI * 2.0 * self.scene.mains_hz * time / self.scene.fps;
        let level = (1.0 + self.scene.flicker * phase.sin()) as f32;
        let mut out: Vec<[f32; 3]> = self.ambient.iter().map(|p| p.map(|v| v * level)).collect();
        let Some(&(_, plane)) = lasers.get(lasers.len() / 2) else {
            return out;
        };
        // how far the plane moves during the exposure, at each pixel's surface point
        let (first, last) = (lasers[0].1, lasers[lasers.len() - 1].1);
        let colour = self.scene.laser.colour;
        let sigma = self.scene.laser.sigma_mm;
        // distance of each pixel's surface point from the light plane, and its change to the
        // neighbours (the pixel's footprint across the plane)
        let dist: Vec<f64> = self
            .texels
            .iter()
            .map(|t| {
                if t.surface == u16::MAX {
                    f64::INFINITY
                } else {
                    plane.signed_distance(&Point3::new(
                        f64::from(t.point[0]),
                        f64::from(t.point[1]),
                        f64::from(t.point[2]),
                    ))
                }
            })
            .collect();
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let d = dist[i];
                // far from the plane (or no surface): no laser light, without looking further
                if !(d.abs() <= 5.0 * sigma + FOOTPRINT_BOUND_MM + MOTION_BOUND_MM) {
                    continue;
                }
                let mut foot = 0.0f64;
                for (du, dv) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (uu, vv) = (u as i64 + du, v as i64 + dv);
                    if uu >= 0 && vv >= 0 && (uu as usize) < w && (vv as usize) < h {
                        let e = dist[vv as usize * w + uu as usize];
                        if e.is_finite() {
                            foot = foot.max((e - d).abs());
                        }
                    }
                }
                let p = texel_point(&self.texels[i]);
                let sweep = (first.signed_distance(&p) - last.signed_distance(&p)).abs();
                if d.abs() > 5.0 * sigma + foot + sweep {
                    continue;
                }
                // supersample the pixel (interpolated sub-pixel rays, each cast into the scene)
                let mut sum = [0.0; 3];
                let n = SUPERSAMPLE * SUPERSAMPLE;
                for (su, sv) in subpixels(u, v, SUPERSAMPLE) {
                    let Some(dir) = self.ray_fast(su, sv) else {
                        continue;
                    };
                    let Some(hit) = self.cast(&dir) else { continue };
                    let e = lasers
                        .iter()
                        .map(|(s, p)| self.laser_light(&hit.point, &hit.normal, s, p))
                        .sum::<f64>()
                        / lasers.len() as f64;
                    let a = self.albedo_of(hit.surface, &hit.point);
                    for c in 0..3 {
                        sum[c] += e * a[c] * colour[c];
                    }
                }
                self.splat(&mut out, u, v, sum.map(|s| s / n as f64));
            }
        }
        out
    }

    /// Adds light falling on pixel `(u, v)` to `out` through the lens: spread with the blur
    /// kernel (what falls outside the image is lost).
    fn splat(&self, out: &mut [[f32; 3]], u: usize, v: usize, light: [f64; 3]) {
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let r = self.kernel.len() / 2;
        for (jv, kv) in self.kernel.iter().enumerate() {
            let Some(vv) = (v + jv).checked_sub(r).filter(|&vv| vv < h) else {
                continue;
            };
            for (ju, ku) in self.kernel.iter().enumerate() {
                let Some(uu) = (u + ju).checked_sub(r).filter(|&uu| uu < w) else {
                    continue;
                };
                let k = kv * ku;
                for c in 0..3 {
                    out[vv * w + uu][c] += (k * light[c]) as f32;
                }
            }
        }
    }

    /// Radiance → 8-bit RGB through the sensor; `noise_seed` picks the noise realisation.
    pub(crate) fn expose(&self, radiance: &[[f32; 3]], noise_seed: u64) -> Rgb8 {
        let s = &self.scene.sensor;
        let mut rng = SmallRng::seed_from_u64(s.seed ^ noise_seed);
        let (gain, read2, shot) = (s.gain, s.read_noise * s.read_noise, s.shot_noise);
        let mut data = vec![0u8; radiance.len() * 3];
        // rounded to the nearest level: `as` saturates (below 0 and NaN give 0, above 255
        // gives 255) and truncates, without a call to `round`
        let levels = data.chunks_exact_mut(3).zip(radiance);
        if s.read_noise > 0.0 || s.shot_noise > 0.0 {
            for (out, px) in levels {
                for (o, &r) in out.iter_mut().zip(px) {
                    let v = gain * f64::from(r);
                    let sd = (read2 + shot * v.max(0.0)).sqrt();
                    *o = (v + sd * unit_normal(rng.random::<u64>()) + 0.5) as u8;
                }
            }
        } else {
            for (out, px) in levels {
                for (o, &r) in out.iter_mut().zip(px) {
                    *o = (gain * f64::from(r) + 0.5) as u8;
                }
            }
        }
        Rgb8 {
            width: self.scene.width as usize,
            height: self.scene.height as usize,
            data,
        }
    }

    /// The reference frame: ambient light only, laser off.
    pub fn reference(&self) -> Rgb8 {
        if let Some(shadow) = &self.scene.shadow
            && let Ok(r) = self.shadow_radiance(shadow, None)
        {
            return self.expose(&r, u64::MAX);
        }
        self.expose(&self.radiance(-1.0, &[]), u64::MAX)
    }

    /// Laser frame `index` of the sweep.
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep.
    pub fn frame(&self, index: usize) -> Result<Rgb8, RigError> {
        if let Some(shadow) = &self.scene.shadow {
            return Ok(self.expose(&self.shadow_radiance(shadow, Some(index))?, index as u64));
        }
        let lasers = self.exposure_planes(index)?;
        Ok(self.expose(&self.radiance(index as f64, &lasers), index as u64))
    }

    /// The ground truth of laser frame `index`: per column, where the light plane meets the
    /// visible, lit surface — `None` where it does not, or where it does at more than one place
    /// (the stripe broken by an occluding edge).
    ///
    /// # Errors
    /// [`RigError::NoSuchFrame`] past the sweep.
    pub fn truth(&self, index: usize) -> Result<Vec<Option<ColumnTruth>>, RigError> {
        let (source, plane) = self.laser(index)?;
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let signed = |u: f64, v: f64| -> Option<(f64, Hit)> {
            let hit = self.cast(&self.ray(u, v)?)?;
            Some((plane.signed_distance(&hit.point), hit))
        };
        let mut out = vec![None; w];
        for (u, slot) in out.iter_mut().enumerate() {
            let mut found = Vec::new();
            for v in 0..h - 1 {
                let (a, b) = (&self.texels[v * w + u], &self.texels[(v + 1) * w + u]);
                if a.surface == u16::MAX || a.surface != b.surface {
                    continue;
                }
                let da = plane.signed_distance(&texel_point(a));
                let db = plane.signed_distance(&texel_point(b));
                if da == 0.0 || da.signum() != db.signum() {
                    found.push(v);
                }
            }
            // refine each crossing by bisection on exact rays; keep the lit ones
            let mut lit = Vec::new();
            for &v0 in &found {
                let (mut lo, mut hi) = (v0 as f64, v0 as f64 + 1.0);
                let Some((dlo, _)) = signed(u as f64, lo) else {
                    continue;
                };
                for _ in 0..50 {
                    let mid = (lo + hi) / 2.0;
                    let Some((dm, _)) = signed(u as f64, mid) else {
                        break;
                    };
                    if dm.signum() == dlo.signum() {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let row = (lo + hi) / 2.0;
                let Some((_, hit)) = signed(u as f64, row) else {
                    continue;
                };
                // on the plane (d ≈ 0): lit unless shadowed or facing away from the source
                if self.laser_light(&hit.point, &hit.normal, &source, &plane) > 0.0 {
                    lit.push(ColumnTruth {
                        row,
                        point: hit.point,
                        surface: hit.surface,
                        incidence: hit.normal.dot(&(source - hit.point).normalize()),
                    });
                }
            }
            if let [only] = lit[..] {
                *slot = Some(only);
            }
        }
        Ok(out)
    }
}

/// An approximately standard-normal number from 64 random bits: the sum of four 16-bit
/// uniforms, centred and scaled to unit variance (Irwin–Hall; tails end at ±3.46σ, which is
/// immaterial for sensor noise and four times cheaper than an exact sampler).
#[inline]
fn unit_normal(bits: u64) -> f64 {
    let sum = (bits & 0xFFFF) + ((bits >> 16) & 0xFFFF) + ((bits >> 32) & 0xFFFF) + (bits >> 48);
    // four uniforms on [0, 1): mean 2, variance 4/12
    (sum as f64 / 65536.0 - 2.0) * 3f64.sqrt()
}

/// Speckle: a fixed grain of mean 1 on the lit surface, from a hash of the 0.25 mm cell that holds
/// `p`: `(1 − c) + c · E` with `E` exponential (fully developed speckle) and contrast `c`.
fn speckle(p: &Point3<f64>, contrast: f64) -> f64 {
    if contrast == 0.0 {
        return 1.0;
    }
    let cell = |v: f64| (v / 0.25).floor() as i64 as u64;
    let mut x = cell(p.x).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ cell(p.y).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ cell(p.z).wrapping_mul(0x1656_67B1_9E37_79F9);
    // splitmix64 finaliser
    x ^= x >> 30;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^= x >> 31;
    let u = ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    (1.0 - contrast) + contrast * -u.ln()
}

/// The centres of an `n × n` grid of sub-samples of pixel `(u, v)`, pixel centres at integers.
pub(crate) fn subpixels(u: usize, v: usize, n: usize) -> impl Iterator<Item = (f64, f64)> {
    let step = 1.0 / n as f64;
    (0..n * n).map(move |k| {
        let (sx, sy) = (k % n, k / n);
        (
            u as f64 + (sx as f64 + 0.5) * step - 0.5,
            v as f64 + (sy as f64 + 0.5) * step - 0.5,
        )
    })
}

/// Area centroid of a closed polygon (Green's theorem); `None` for a degenerate one.
pub(crate) fn polygon_centroid(pts: &[Point2<f64>]) -> Option<Point2<f64>> {
    let (mut a2, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..pts.len() {
        let (p, q) = (pts[i], pts[(i + 1) % pts.len()]);
        let cross = p.x * q.y - q.x * p.y;
        a2 += cross;
        cx += (p.x + q.x) * cross;
        cy += (p.y + q.y) * cross;
    }
    (a2.abs() > 1e-12).then(|| Point2::new(cx / (3.0 * a2), cy / (3.0 * a2)))
}

fn texel_point(t: &Texel) -> Point3<f64> {
    Point3::new(
        f64::from(t.point[0]),
        f64::from(t.point[1]),
        f64::from(t.point[2]),
    )
}

fn surface_id(index: u16) -> SurfaceId {
    match index {
        0 => SurfaceId::Left,
        1 => SurfaceId::Right,
        n => SurfaceId::Object(n - 2),
    }
}

fn surface_index(s: SurfaceId) -> u16 {
    match s {
        SurfaceId::Left => 0,
        SurfaceId::Right => 1,
        SurfaceId::Object(n) => 2 + n,
    }
}

impl Rig {
    /// The laser speckle's share of a stripe centre's uncertainty on this rig, pixels, as
    /// [`scanner_calib::speckle::stripe_scatter`] measures it with `camera` and `board` on frames
    /// of the scene's bare board (objects taken away) at a quarter, half and three quarters of
    /// the sweep; `None` when no frame shows the stripe across a sheet.
    pub fn speckle(
        &self,
        camera: &Camera<f64>,
        board: &scanner_core::geometry::Board<f64>,
    ) -> Option<f64> {
        use scanner_core::stripe::{Axis, Frame, Method, PixelFormat, StripeConfig};
        let mut bare = self.scene.clone();
        bare.objects.clear();
        let rig = Rig::new(bare).ok()?;
        let (w, h) = (self.scene.width as usize, self.scene.height as usize);
        let reference = rig.reference().to_format(PixelFormat::Gray8);
        let rf = Frame::packed(&reference, w, h, PixelFormat::Gray8).ok()?;
        let n = self.scene.laser.frames;
        let cfg = StripeConfig::new(Method::Dim, Axis::Columns);
        let sq: Vec<f64> = [n / 4, n / 2, 3 * n / 4]
            .into_iter()
            .filter_map(|k| {
                let data = rig.frame(k).ok()?.to_format(PixelFormat::Gray8);
                let f = Frame::packed(&data, w, h, PixelFormat::Gray8).ok()?;
                let s =
                    scanner_calib::speckle::stripe_scatter(&f, &rf, camera, board, &cfg).ok()?;
                Some(s.speckle_px * s.speckle_px)
            })
            .collect();
        (!sq.is_empty()).then(|| (sq.iter().sum::<f64>() / sq.len() as f64).sqrt())
    }

    /// The rig's true camera and board as a calibration file (what a perfect calibration
    /// would give; for tests and benches that want the truth, not an estimate), with the rig's
    /// speckle measured ([`Rig::speckle`]).
    ///
    /// # Panics
    /// Never for a rig built from a valid scene (its board's planes meet).
    pub fn truth_calibration(&self) -> scanner_calib::file::CalibrationFile {
        use scanner_calib::file::{BoardSection, CalibrationFile, SheetSection};
        let s = self.scene();
        let mut f = CalibrationFile::from_camera(
            &s.camera,
            (s.width, s.height),
            "the virtual rig's true camera".into(),
            None,
        );
        let [l, r] = self.board_planes();
        let board = scanner_core::geometry::Board::new(l, r).expect("the rig's board is valid");
        f.camera.speckle_px = self.speckle(&s.camera, &board);
        let [l, r] = self.board_planes();
        let sheet = |p: &Plane<f64>| SheetSection {
            normal: (*p.normal()).into(),
            offset: p.offset(),
            rms_px: 0.0,
            plane_covariance: None,
            plane_from_intrinsics: None,
            markers: Vec::new(),
        };
        let board = scanner_core::geometry::Board::new(l, r).expect("the rig's board is valid");
        f.board = Some(BoardSection {
            method: "rig-truth".into(),
            angle_deg: board.angle().to_degrees(),
            crease_point: board.crease().point().coords.into(),
            crease_direction: (*board.crease().direction()).into(),
            left: sheet(&l),
            right: sheet(&r),
            paper: None,
        });
        f
    }
}
