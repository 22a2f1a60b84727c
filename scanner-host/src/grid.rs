//! The 2-D structured grid (paper section 4, done better): points binned into regular cells over
//! the camera's view, each cell a robust running mean with an outlier test and a count. Several
//! sweeps merge into one grid; memory is the grid's, whatever the scan's length.
//!
//! Cells are either image pixels (`Cell::Pixels(n)`: the point is projected with the header's
//! camera, cells of n×n pixels — a perspective grid, the paper's) or millimetres
//! (`Cell::Mm(s)`: cells of s×s mm in the camera's x–y plane — an orthographic grid).
//!
//! The robust mean: each cell keeps two running clusters (Welford, weighted) of its samples by
//! distance from the camera. A sample that carries its standard uncertainty `u` (the head sends
//! it) weighs `1/u²`, so a cell's mean leans on its better samples and its own uncertainty is
//! `1/√Σ(1/u²)` ([`CellState::uncertainty`]); samples without weigh alike; a sample joins a cluster within `max(3σ, outlier_mm)` of it (σ once it has three
//! samples), else it is rejected. The cluster with more samples is the cell's surface: a cell on
//! an object's outline, which sees the object and the board behind it, takes the better-supported
//! depth instead of averaging the two.

use scanner_core::Camera;
use scanner_core::nalgebra::{Point3, Vector2};

/// Cell size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cell {
    /// Square cells of this many image pixels.
    Pixels(f64),
    /// Square cells of this many millimetres in the camera's x–y plane.
    Mm(f64),
}

/// A `--cell` that is not a cell size.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("cell size {text:?}: {why}")]
pub struct CellError {
    /// What was given.
    pub text: String,
    /// What is wrong.
    pub why: &'static str,
}

/// Most cells a grid may have: 2048 × 2048, what the default 2-pixel cells give on the largest
/// image a head sends (4096 × 4096). With the mesh and the pictures built from it, the host's
/// peak memory stays under 1 GB (`cargo run --release -p scanner-host --example peak_memory`).
pub const MAX_CELLS: usize = 2048 * 2048;

/// Why a grid cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// The camera's image corners have no rays.
    #[error("the header's camera cannot cast rays")]
    Camera(#[source] scanner_core::GeomError),
    /// Too many cells.
    #[error(
        "--cell gives a grid of {cols}×{rows} cells (at most {MAX_CELLS}): choose a larger cell size"
    )]
    TooMany {
        /// Columns.
        cols: usize,
        /// Rows.
        rows: usize,
    },
    /// Fewer than 2 × 2 cells: the cell is about as large as the view.
    #[error(
        "--cell gives a grid of {cols}×{rows} cells (at least 2×2): the cell is as large as the view; choose a smaller cell size"
    )]
    TooFew {
        /// Columns.
        cols: usize,
        /// Rows.
        rows: usize,
    },
}

impl std::str::FromStr for Cell {
    type Err = CellError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        let err = |why| CellError {
            text: s.chars().take(40).collect(),
            why,
        };
        let (num, unit) = if let Some(n) = s.strip_suffix("px") {
            (n, "px")
        } else if let Some(n) = s.strip_suffix("mm") {
            (n, "mm")
        } else {
            return Err(err("give a number with px or mm, e.g. 2px or 0.5mm"));
        };
        let v: f64 = num.trim().parse().map_err(|_| err("not a number"))?;
        if !(v > 0.0 && v.is_finite()) {
            return Err(err("must be positive"));
        }
        Ok(if unit == "px" {
            Cell::Pixels(v)
        } else {
            Cell::Mm(v)
        })
    }
}

/// One cell's state.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CellState {
    /// Samples of the cell's surface (its main cluster).
    pub count: u32,
    /// Samples that fitted neither cluster.
    pub rejected: u32,
    /// Mean position, mm.
    pub mean: [f32; 3],
    /// Sum of squared deviations of the range (distance from the camera).
    m2: f32,
    /// Mean range.
    range: f32,
    /// Mean colour.
    pub rgb: [f32; 3],
    /// Sum of the samples' weights (`1/u²`, u in mm; 1 each for samples without uncertainty).
    weight: f32,
    /// The other cluster: samples at another depth (a cell on an object's outline sees the
    /// object and the board behind it). Whichever has more samples is the cell's surface.
    alt: Cluster,
}

/// A running cluster of samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Cluster {
    count: u32,
    mean: [f32; 3],
    m2: f32,
    range: f32,
    rgb: [f32; 3],
    weight: f32,
}

impl CellState {
    fn main(&self) -> Cluster {
        Cluster {
            count: self.count,
            mean: self.mean,
            m2: self.m2,
            range: self.range,
            rgb: self.rgb,
            weight: self.weight,
        }
    }

    fn set_main(&mut self, c: Cluster) {
        (
            self.count,
            self.mean,
            self.m2,
            self.range,
            self.rgb,
            self.weight,
        ) = (c.count, c.mean, c.m2, c.range, c.rgb, c.weight);
    }

    /// The standard uncertainty of the cell's mean, mm, when its samples carried theirs:
    /// `1/√Σ(1/u²)` (independent samples). Meaningless for samples without (then 1/√count).
    pub fn uncertainty(&self) -> f32 {
        if self.weight > 0.0 {
            1.0 / self.weight.sqrt()
        } else {
            f32::INFINITY
        }
    }
}

impl Cluster {
    /// Whether a sample at `range` belongs here: within 3σ of the cluster's samples (once it
    /// has three) and never closer than `floor`.
    fn accepts(&self, range: f32, floor: f32) -> bool {
        let tol = if self.count >= 3 {
            // the weighted variance, unbiased for equal weights
            let n = self.count as f32;
            let var = self.m2 / self.weight * n / (n - 1.0);
            (3.0 * var.sqrt()).max(floor)
        } else {
            floor
        };
        (range - self.range).abs() <= tol
    }

    /// Adds a sample of weight `w` (West's weighted Welford update).
    fn add(&mut self, p: &Point3<f32>, range: f32, rgb: Option<[u8; 3]>, w: f32) {
        self.count += 1;
        self.weight += w;
        let k = w / self.weight;
        let d = range - self.range;
        self.range += d * k;
        self.m2 += w * d * (range - self.range);
        for (m, v) in self.mean.iter_mut().zip(p.iter()) {
            *m += (v - *m) * k;
        }
        if let Some(c) = rgb {
            for (m, v) in self.rgb.iter_mut().zip(c) {
                *m += (f32::from(v) - *m) * k;
            }
        }
    }
}

/// The grid.
#[derive(Debug, Clone)]
pub struct Grid {
    cell: Cell,
    camera: Camera<f64>,
    /// Cells per row and rows.
    pub cols: usize,
    /// Rows.
    pub rows: usize,
    origin: Vector2<f64>,
    cells: Vec<CellState>,
    outlier_mm: f32,
    outside: u64,
}

impl Grid {
    /// A grid over a `width`×`height` view of `camera`. For millimetre cells the view is taken
    /// out to `depth` mm (the board's distance): the grid spans what the camera sees there.
    ///
    /// # Errors
    /// A cell size that would make more than 64 million cells.
    pub fn new(
        camera: Camera<f64>,
        width: u32,
        height: u32,
        cell: Cell,
        depth: f64,
        outlier_mm: f32,
    ) -> Result<Grid, GridError> {
        let (cols, rows, origin) = match cell {
            Cell::Pixels(p) => (
                (f64::from(width) / p).ceil() as usize,
                (f64::from(height) / p).ceil() as usize,
                Vector2::zeros(),
            ),
            Cell::Mm(s) => {
                // The view's extent at `depth`, from the image corners' rays.
                let mut lo = Vector2::new(f64::INFINITY, f64::INFINITY);
                let mut hi = -lo;
                for (u, v) in [
                    (0.0, 0.0),
                    (f64::from(width), 0.0),
                    (0.0, f64::from(height)),
                    (f64::from(width), f64::from(height)),
                ] {
                    let r = camera
                        .pixel_to_ray(&scanner_core::nalgebra::Point2::new(u, v))
                        .map_err(GridError::Camera)?;
                    let p = Vector2::new(r.x * depth, r.y * depth);
                    lo = lo.inf(&p);
                    hi = hi.sup(&p);
                }
                (
                    ((hi.x - lo.x) / s).ceil() as usize,
                    ((hi.y - lo.y) / s).ceil() as usize,
                    lo,
                )
            }
        };
        if cols < 2 || rows < 2 {
            return Err(GridError::TooFew { cols, rows });
        }
        if cols.saturating_mul(rows) > MAX_CELLS {
            return Err(GridError::TooMany { cols, rows });
        }
        Ok(Grid {
            cell,
            camera,
            cols,
            rows,
            origin,
            cells: vec![CellState::default(); cols * rows],
            outlier_mm,
            outside: 0,
        })
    }

    /// The cell size.
    pub fn cell(&self) -> Cell {
        self.cell
    }

    /// Cell index of a point, if inside.
    pub fn locate(&self, p: &Point3<f32>) -> Option<(usize, usize)> {
        let (fx, fy) = match self.cell {
            Cell::Pixels(s) => {
                let px = self.camera.project(&p.cast::<f64>()).ok()?;
                (px.x / s, px.y / s)
            }
            Cell::Mm(s) => (
                (f64::from(p.x) - self.origin.x) / s,
                (f64::from(p.y) - self.origin.y) / s,
            ),
        };
        (fx >= 0.0 && fy >= 0.0 && fx < self.cols as f64 && fy < self.rows as f64)
            .then_some((fx as usize, fy as usize))
    }

    /// Adds a point (with its colour and its standard uncertainty in mm, if any); returns
    /// `false` if it fell outside or was rejected as an outlier. An uncertainty that is not
    /// positive and finite counts as none.
    pub fn insert(
        &mut self,
        p: &Point3<f32>,
        rgb: Option<[u8; 3]>,
        uncertainty: Option<f32>,
    ) -> bool {
        let Some((c, r)) = self.locate(p) else {
            self.outside += 1;
            return false;
        };
        let w = match uncertainty {
            Some(u) if u > 0.0 && u.is_finite() => 1.0 / (u * u),
            _ => 1.0,
        };
        let cell = &mut self.cells[r * self.cols + c];
        let range = p.coords.norm();
        let mut main = cell.main();
        if main.count == 0 || main.accepts(range, self.outlier_mm) {
            main.add(p, range, rgb, w);
            cell.set_main(main);
            return true;
        }
        if cell.alt.count == 0 || cell.alt.accepts(range, self.outlier_mm) {
            cell.alt.add(p, range, rgb, w);
            if cell.alt.count > main.count {
                // The other depth has more support: it is the cell's surface.
                let alt = cell.alt;
                cell.alt = main;
                cell.set_main(alt);
                return true;
            }
            return false;
        }
        cell.rejected += 1;
        false
    }

    /// The cell at column `c`, row `r`.
    pub fn at(&self, c: usize, r: usize) -> &CellState {
        &self.cells[r * self.cols + c]
    }

    /// Cells with at least one sample.
    pub fn filled(&self) -> usize {
        self.cells.iter().filter(|c| c.count > 0).count()
    }

    /// Points that fell outside the grid.
    pub fn outside(&self) -> u64 {
        self.outside
    }

    /// Samples not in their cell's surface (outliers, and the other depth of a mixed cell).
    pub fn rejected(&self) -> u64 {
        self.cells
            .iter()
            .map(|c| u64::from(c.rejected) + u64::from(c.alt.count))
            .sum()
    }
}
