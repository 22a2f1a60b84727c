//! What the rig's rays can hit: the two board planes (as half-planes meeting at the crease) and
//! analytic objects with exact ground truth.

use std::sync::Arc;

use scanner_core::nalgebra::{Isometry3, Point3, Unit, Vector3};

use super::mesh::SceneMesh;

/// Which surface a point lies on, as the ground truth reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SurfaceId {
    /// The left board plane.
    Left,
    /// The right board plane.
    Right,
    /// Object number `n` of the scene.
    Object(u16),
}

/// A ray hit: distance along the unit ray, point, unit normal facing the ray, surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance from the ray origin, mm.
    pub t: f64,
    /// The point hit.
    pub point: Point3<f64>,
    /// Unit normal, facing back along the ray.
    pub normal: Vector3<f64>,
    /// What was hit.
    pub surface: SurfaceId,
}

/// An analytic object.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A sphere.
    Sphere {
        /// Centre, mm.
        centre: Point3<f64>,
        /// Radius, mm.
        radius: f64,
    },
    /// A finite cylinder with caps.
    Cylinder {
        /// Centre of its base, mm.
        base: Point3<f64>,
        /// Unit axis.
        axis: Unit<Vector3<f64>>,
        /// Radius, mm.
        radius: f64,
        /// Height along the axis, mm.
        height: f64,
    },
    /// A box, axis-aligned in its own frame: centre, half sizes, and the frame's rotation.
    Cuboid {
        /// Centre, mm.
        centre: Point3<f64>,
        /// Half sizes along the box's own axes, mm.
        half: Vector3<f64>,
        /// The box's axes in camera coordinates (columns).
        axes: [Vector3<f64>; 3],
    },
    /// A placed triangle mesh.
    Mesh(Arc<SceneMesh>),
    /// A flat disc (a print lying on the table): centre, two unit in-plane axes (the print's
    /// `x` and `y`), radius.
    Disc {
        /// Centre, mm.
        centre: Point3<f64>,
        /// In-plane unit axes.
        axes: [Vector3<f64>; 2],
        /// Radius, mm (0: taken away, never hit).
        radius: f64,
    },
    /// A rectangle: centre, two unit in-plane axes, half sizes along them.
    Rectangle {
        /// Centre, mm.
        centre: Point3<f64>,
        /// In-plane unit axes.
        axes: [Vector3<f64>; 2],
        /// Half sizes along the axes, mm.
        half: [f64; 2],
    },
}

fn facing(n: Vector3<f64>, dir: &Vector3<f64>) -> Vector3<f64> {
    if n.dot(dir) > 0.0 { -n } else { n }
}

impl Shape {
    /// The shape moved rigidly by `pose` (`p ↦ pose · p`).
    pub fn moved(&self, pose: &Isometry3<f64>) -> Shape {
        let r = pose.rotation;
        match self {
            Shape::Sphere { centre, radius } => Shape::Sphere {
                centre: pose * centre,
                radius: *radius,
            },
            Shape::Cylinder {
                base,
                axis,
                radius,
                height,
            } => Shape::Cylinder {
                base: pose * base,
                axis: Unit::new_normalize(r * axis.into_inner()),
                radius: *radius,
                height: *height,
            },
            Shape::Cuboid { centre, half, axes } => Shape::Cuboid {
                centre: pose * centre,
                half: *half,
                axes: axes.map(|a| r * a),
            },
            Shape::Mesh(m) => Shape::Mesh(Arc::new(m.moved(pose))),
            Shape::Rectangle { centre, axes, half } => Shape::Rectangle {
                centre: pose * centre,
                axes: axes.map(|a| r * a),
                half: *half,
            },
            Shape::Disc {
                centre,
                axes,
                radius,
            } => Shape::Disc {
                centre: pose * centre,
                axes: axes.map(|a| r * a),
                radius: *radius,
            },
        }
    }

    /// A point at the shape's middle (centre, mid-axis, the mesh's vertex centroid).
    pub fn centre(&self) -> Point3<f64> {
        match self {
            Shape::Sphere { centre, .. }
            | Shape::Cuboid { centre, .. }
            | Shape::Rectangle { centre, .. }
            | Shape::Disc { centre, .. } => *centre,
            Shape::Cylinder {
                base, axis, height, ..
            } => base + axis.into_inner() * (height / 2.0),
            Shape::Mesh(m) => m.centroid(),
        }
    }

    /// Distance from `p` to the shape's surface, mm (meshes: every triangle is tried).
    pub fn distance(&self, p: &Point3<f64>) -> Option<f64> {
        match self {
            Shape::Sphere { centre, radius } => Some(((p - centre).norm() - radius).abs()),
            Shape::Cylinder {
                base,
                axis,
                radius,
                height,
            } => {
                let d = p - base;
                let t = d.dot(axis);
                let rho = (d - axis.as_ref() * t).norm();
                let (dt, dr) = (
                    if t < 0.0 {
                        -t
                    } else if t > *height {
                        t - height
                    } else {
                        0.0
                    },
                    (rho - radius).max(0.0),
                );
                Some(if dt > 0.0 || dr > 0.0 {
                    (dt * dt + dr * dr).sqrt()
                } else {
                    // Inside: the nearest of the side and the caps.
                    (radius - rho).min(t).min(height - t)
                })
            }
            Shape::Cuboid { centre, half, axes } => {
                let d = p - centre;
                let q: Vec<f64> = (0..3).map(|k| d.dot(&axes[k]).abs() - half[k]).collect();
                let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
                Some(if outside > 0.0 {
                    outside
                } else {
                    -q.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                })
            }
            Shape::Rectangle { centre, axes, half } => {
                let d = p - centre;
                let n = axes[0].cross(&axes[1]).normalize();
                let (a, b) = (
                    (d.dot(&axes[0]).abs() - half[0]).max(0.0),
                    (d.dot(&axes[1]).abs() - half[1]).max(0.0),
                );
                Some((d.dot(&n).powi(2) + a * a + b * b).sqrt())
            }
            Shape::Disc {
                centre,
                axes,
                radius,
            } => {
                let d = p - centre;
                let n = axes[0].cross(&axes[1]);
                let (a, b) = (d.dot(&axes[0]), d.dot(&axes[1]));
                let out = (a.hypot(b) - radius).max(0.0);
                Some(d.dot(&n).hypot(out))
            }
            Shape::Mesh(m) => Some(m.distance(p)),
        }
    }

    /// The nearest hit of the ray `origin + t·dir` (unit `dir`) with `t > t_min`.
    pub fn hit(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        t_min: f64,
        id: u16,
    ) -> Option<Hit> {
        let ray = Ray {
            origin: *origin,
            dir: *dir,
            t_min,
        };
        let (t, n) = match self {
            Shape::Sphere { centre, radius } => ray.sphere(centre, *radius),
            Shape::Cylinder {
                base,
                axis,
                radius,
                height,
            } => ray.cylinder(base, &axis.into_inner(), *radius, *height),
            Shape::Cuboid { centre, half, axes } => ray.cuboid(centre, half, axes),
            Shape::Mesh(mesh) => mesh.hit(origin, dir, t_min),
            Shape::Rectangle { centre, axes, half } => ray.rectangle(centre, axes, half),
            Shape::Disc {
                centre,
                axes,
                radius,
            } => ray
                .rectangle(centre, axes, &[*radius, *radius])
                .filter(|(t, _)| {
                    let r = ray.at(*t) - centre;
                    let (a, b) = (r.dot(&axes[0]), r.dot(&axes[1]));
                    a * a + b * b <= radius * radius
                }),
        }?;
        Some(Hit {
            t,
            point: origin + dir * t,
            normal: facing(n, dir),
            surface: SurfaceId::Object(id),
        })
    }
}

/// A ray `origin + t·dir` (unit `dir`) and the nearest distance that counts. Each shape's
/// intersection gives the distance of the nearest hit beyond `t_min` and the outward normal
/// there (not necessarily unit).
struct Ray {
    origin: Point3<f64>,
    dir: Vector3<f64>,
    t_min: f64,
}

impl Ray {
    fn at(&self, t: f64) -> Point3<f64> {
        self.origin + self.dir * t
    }

    fn sphere(&self, centre: &Point3<f64>, radius: f64) -> Option<(f64, Vector3<f64>)> {
        let oc = self.origin - centre;
        let b = oc.dot(&self.dir);
        let c = oc.norm_squared() - radius * radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        let t = [-b - s, -b + s].into_iter().find(|&t| t > self.t_min)?;
        Some((t, (self.at(t) - centre) / radius))
    }

    /// A closed cylinder from `base` along the unit `a` for `height`.
    fn cylinder(
        &self,
        base: &Point3<f64>,
        a: &Vector3<f64>,
        radius: f64,
        height: f64,
    ) -> Option<(f64, Vector3<f64>)> {
        let dir = &self.dir;
        let mut best: Option<(f64, Vector3<f64>)> = None;
        let mut consider = |t: f64, n: Vector3<f64>| {
            if t > self.t_min && best.is_none_or(|b| t < b.0) {
                best = Some((t, n));
            }
        };
        // side: |(p − base) − ((p − base)·a) a| = r
        let ob = self.origin - base;
        let d_perp = dir - a * dir.dot(a);
        let o_perp = ob - a * ob.dot(a);
        let qa = d_perp.norm_squared();
        let qb = 2.0 * d_perp.dot(&o_perp);
        let qc = o_perp.norm_squared() - radius * radius;
        let disc = qb * qb - 4.0 * qa * qc;
        if qa > 1e-12 && disc >= 0.0 {
            for t in [
                (-qb - disc.sqrt()) / (2.0 * qa),
                (-qb + disc.sqrt()) / (2.0 * qa),
            ] {
                let p = self.at(t);
                let h = (p - base).dot(a);
                if (0.0..=height).contains(&h) {
                    consider(t, ((p - base) - a * h) / radius);
                }
            }
        }
        // caps
        let den = dir.dot(a);
        if den.abs() > 1e-12 {
            for h in [0.0, height] {
                let t = (h - ob.dot(a)) / den;
                let r = (self.at(t) - base) - a * h;
                if r.norm() <= radius {
                    consider(t, *a);
                }
            }
        }
        best
    }

    /// A box: the slab test in its frame (`axes` unit, `half` its half sides).
    fn cuboid(
        &self,
        centre: &Point3<f64>,
        half: &Vector3<f64>,
        axes: &[Vector3<f64>; 3],
    ) -> Option<(f64, Vector3<f64>)> {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut n0, mut n1) = (Vector3::zeros(), Vector3::zeros());
        let oc = self.origin - centre;
        for k in 0..3 {
            let o = oc.dot(&axes[k]);
            let d = self.dir.dot(&axes[k]);
            if d.abs() < 1e-12 {
                if o.abs() > half[k] {
                    return None;
                }
                continue;
            }
            let (mut a, mut b) = ((-half[k] - o) / d, (half[k] - o) / d);
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            if a > t0 {
                t0 = a;
                n0 = axes[k];
            }
            if b < t1 {
                t1 = b;
                n1 = axes[k];
            }
        }
        if t0 > t1 {
            None
        } else if t0 > self.t_min {
            Some((t0, n0))
        } else if t1 > self.t_min {
            Some((t1, n1))
        } else {
            None
        }
    }

    fn rectangle(
        &self,
        centre: &Point3<f64>,
        axes: &[Vector3<f64>; 2],
        half: &[f64; 2],
    ) -> Option<(f64, Vector3<f64>)> {
        let n = axes[0].cross(&axes[1]);
        let den = self.dir.dot(&n);
        if den.abs() < 1e-12 {
            return None;
        }
        let t = (centre - self.origin).dot(&n) / den;
        if t <= self.t_min {
            return None;
        }
        let r = self.at(t) - centre;
        (r.dot(&axes[0]).abs() <= half[0] && r.dot(&axes[1]).abs() <= half[1]).then_some((t, n))
    }
}
