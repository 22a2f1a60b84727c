//! One view as the merge takes it: a sweep's surface points with their normals, colours,
//! uncertainties and how clear of the view's edges each lies, and the scan's header (its
//! camera, image and board). The caller reads it (the host from a journal); the merge thins it
//! to one point per `THIN_MM` cube when it is made.

use scanner_core::nalgebra::{Isometry3, Point3, Vector3};
use scanner_wire::Header;

use crate::depth::DepthMap;
use crate::spatial::{Cloud, thin_with};

/// Each view is thinned to one point per cube of this size, mm: finer than the fusion's cells,
/// so nothing the model could show is lost; denser views only slow the searches (eight views of
/// 49 000 points merge in 8 s instead of 21, `cargo bench -p scanner-merge --bench merge`).
const THIN_MM: f64 = 0.75;

/// Points at least this clear of their view's edges ([`View::clearance`]) register; the others
/// only fill in the fusion where nothing better saw the surface.
pub(crate) const MIN_CLEARANCE: f64 = 0.5;

/// One view: its points in its own camera frame (mm), thinned.
#[derive(Debug, Clone)]
pub struct View {
    /// What the report calls it (the path it was read from).
    pub name: String,
    /// Its session header: the camera, the image's size and the board.
    pub header: Header,
    /// Its points and unit normals (facing its camera).
    pub cloud: Cloud,
    /// The surface's colour at each point (empty: the scan carried no colour).
    pub colours: Vec<[u8; 3]>,
    /// How far each point is from the view's edges: the share of the grid cells averaged into
    /// it that lie away from an occluding edge, a shadow's border or the view's outline; 0 on an
    /// edge, 1 clear of it. The joint refinement pairs only points at least half clear; the
    /// fusion weighs them by it.
    pub clearance: Vec<f64>,
    /// Each point's standard uncertainty, mm (empty: the scan carried none).
    pub sigma: Vec<f64>,
    /// With the laser sheet's correction: the samples it moved, of all; `None`: not asked.
    pub sheet_moved: Option<(u64, u64)>,
    /// The turntable disc's pose in this view's camera frame (disc → camera), when its head
    /// found the disc: the merge then poses it by the disc ([`crate::pose`]).
    pub disc: Option<Isometry3<f64>>,
    /// The disc's size as the laser measured it, as a share of the size its pose was computed
    /// for (1: the disc chosen is the disc printed; a disc printed on A4 posed as A3's gives
    /// about 0.69): the laser's points on the disc's plane lie at this share of the pose's
    /// distance, since a pose from a disc of the wrong size is the true pose scaled.
    pub disc_scale: Option<f64>,
    /// What the view saw beyond the object, its camera frame (mm): the points on and under the
    /// disc's plane (the disc, the table it lies on), left out of the view's surface. Only the
    /// space it saw empty comes from them (`crate::fuse::hull`).
    pub backdrop: Vec<Point3<f64>>,
}

/// What a view is read from, before it is thinned ([`View::new`]).
#[derive(Debug, Clone, Default)]
pub struct ScanPoints {
    /// Points and unit normals, the view's camera frame.
    pub cloud: Cloud,
    /// Colours, one per point, or none.
    pub colours: Vec<[u8; 3]>,
    /// Each point's share clear of the view's edges ([`View::clearance`]), one per point, or none
    /// (all clear).
    pub clearance: Vec<f64>,
    /// Each point's standard uncertainty, mm, one per point, or none.
    pub sigma: Vec<f64>,
}

impl ScanPoints {
    /// The surface with only the points `keep` (indices, in order); a list of another length
    /// than the points (none given) stays empty.
    pub fn subset(&self, keep: &[usize]) -> ScanPoints {
        let n = self.cloud.points.len();
        let pick = |v: &[f64]| -> Vec<f64> {
            if v.len() == n {
                keep.iter().map(|&i| v[i]).collect()
            } else {
                Vec::new()
            }
        };
        ScanPoints {
            cloud: Cloud {
                points: keep.iter().map(|&i| self.cloud.points[i]).collect(),
                normals: keep.iter().map(|&i| self.cloud.normals[i]).collect(),
            },
            colours: if self.colours.len() == n {
                keep.iter().map(|&i| self.colours[i]).collect()
            } else {
                Vec::new()
            },
            clearance: pick(&self.clearance),
            sigma: pick(&self.sigma),
        }
    }
}

impl View {
    /// The view of `surface` seen by the camera of `header`, thinned to one point per 0.75 mm
    /// cube (the mean of the points, normals, colours, clear shares and uncertainties in it).
    pub fn new(
        name: impl Into<String>,
        header: Header,
        surface: &ScanPoints,
        sheet_moved: Option<(u64, u64)>,
    ) -> View {
        let (cloud, colours, mut values) = thin_with(
            &surface.cloud,
            &surface.colours,
            &[&surface.clearance, &surface.sigma],
            THIN_MM,
        );
        let sigma = values.pop().unwrap_or_default();
        let clearance = values.pop().unwrap_or_default();
        View {
            name: name.into(),
            header,
            cloud,
            colours,
            clearance,
            sigma,
            sheet_moved,
            disc: None,
            disc_scale: None,
            backdrop: Vec::new(),
        }
    }

    /// Whether point `i` lies at least half clear of the view's edges (a point without a share
    /// counts as clear).
    pub(crate) fn is_clear(&self, i: usize) -> bool {
        self.clearance.get(i).is_none_or(|&c| c >= MIN_CLEARANCE)
    }

    /// The view's points clear of its edges (`MIN_CLEARANCE`; all of them when fewer than half are:
    /// a view that is all edge registers as it is).
    pub fn clear_cloud(&self) -> Cloud {
        let keep: Vec<usize> = (0..self.cloud.points.len())
            .filter(|&i| self.is_clear(i))
            .collect();
        if 2 * keep.len() < self.cloud.points.len() {
            return self.cloud.clone();
        }
        Cloud {
            points: keep.iter().map(|&i| self.cloud.points[i]).collect(),
            normals: keep.iter().map(|&i| self.cloud.normals[i]).collect(),
        }
    }

    /// The view with only the points `keep` (indices, in order).
    pub(crate) fn subset(&self, keep: &[usize]) -> View {
        let s = ScanPoints {
            cloud: self.cloud.clone(),
            colours: self.colours.clone(),
            clearance: self.clearance.clone(),
            sigma: self.sigma.clone(),
        }
        .subset(keep);
        View {
            cloud: s.cloud,
            colours: s.colours,
            clearance: s.clearance,
            sigma: s.sigma,
            ..self.clone()
        }
    }

    /// What the view saw: its nearest depth per bin of its image ([`crate::depth`]).
    pub fn depth_map(&self) -> DepthMap {
        DepthMap::new(&self.cloud.points, &self.header)
    }

    /// Its points clear of its edges, counted.
    pub fn clear_points(&self) -> usize {
        (0..self.cloud.points.len())
            .filter(|&i| self.is_clear(i))
            .count()
    }

    /// Up in the view's camera frame (the board's crease, pointing up the image): `None` when
    /// its header carries no usable board.
    pub fn up(&self) -> Option<Vector3<f64>> {
        scanner_core::geometry::Board::<f32>::try_from(self.header.board)
            .ok()
            .map(|b| b.up().cast())
    }

    /// The mean of its points.
    pub fn centre(&self) -> Point3<f64> {
        crate::spatial::centre(&self.cloud.points)
    }
}

#[cfg(test)]
impl View {
    /// A view of `points` with `normals` (all clear), seen by a 640×480 camera of 560 px focal
    /// length in front of a right-angled board 1000 mm away: for the crate's tests.
    pub(crate) fn for_tests(points: &[Point3<f64>], normals: &[Vector3<f64>]) -> View {
        let camera = scanner_wire::CameraBlock {
            fx: 560.0,
            fy: 560.0,
            cx: 319.5,
            cy: 239.5,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        };
        // a right-angled board 1000 mm away, its crease vertical
        let half = |x: f32| scanner_wire::PlaneBlock {
            normal: [x, 0.0, -1.0],
            offset: 1000.0,
        };
        View {
            name: String::new(),
            cloud: Cloud {
                points: points.to_vec(),
                normals: normals.to_vec(),
            },
            header: Header {
                scan_id: 1,
                width: 640,
                height: 480,
                unit_um: 10,
                camera,
                board: [half(1.0), half(-1.0)],
                colour: false,
                method: scanner_wire::PlaneMethod::LeastSquares,
            },
            colours: Vec::new(),
            clearance: Vec::new(),
            sigma: Vec::new(),
            sheet_moved: None,
            disc: None,
            disc_scale: None,
            backdrop: Vec::new(),
        }
    }
}
