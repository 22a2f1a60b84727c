//! Why views could not be merged: each reason names the views, the figures and what to do.

/// Why views cannot be merged.
#[derive(Debug, Clone, thiserror::Error)]
pub enum MergeError {
    /// An option out of its range ([`crate::MergeOptions::check`]).
    #[error("--{option} must be {must_be}, found {found}")]
    Option {
        /// The option, as the command line names it.
        option: &'static str,
        /// Its range, in words.
        must_be: &'static str,
        /// The value given.
        found: f64,
    },
    /// Fewer than two views.
    #[error("merge needs at least two views (sweeps of the object turned between them), got {0}")]
    TooFewViews(usize),
    /// Views from different cameras or calibrations cannot share a frame.
    #[error(
        "view {view} ({name}) was scanned with another camera or image size than view 0: merge views of one calibrated set-up"
    )]
    OtherCamera {
        /// Which view (from 0).
        view: usize,
        /// Its name.
        name: String,
    },
    /// A flat base needs the object's up, which view 0's board gives.
    #[error(
        "--flat-base needs to know which way is up: view 0's scan carries no board calibration"
    )]
    NoUp,
    /// A view registers onto none of the others.
    #[error(
        "view {view} ({name}) overlaps no other view; best try: {best}. Scan the object on the turntable disc (`scanner-device board --turntable a4`, `scan --disc a4`), sweep slower for a denser view, or add views between"
    )]
    NoMatch {
        /// Which view.
        view: usize,
        /// Its name.
        name: String,
        /// The best attempt's reason.
        best: RegisterError,
    },
    /// Some views match one another but none of view 0's group.
    #[error(
        "views {apart:?} match one another but none of views {placed:?} (view 0's group): their shapes do not tell how the object was turned. Print the turntable disc (`scanner-device board --turntable a4`) and scan on it with `--disc a4`; or sweep slower for denser views; or add views between these"
    )]
    Apart {
        /// Views registered into view 0's frame.
        placed: Vec<usize>,
        /// Views that could not be.
        apart: Vec<usize>,
    },
    /// The loop of views does not close after the joint refinement: some view is registered
    /// wrongly (views of flat faces that share too little can fit one another turned the wrong
    /// way), and a model from them would be wrong however watertight.
    #[error(
        "the views do not close into one object: view {view} registered onto view {onto} directly lands {rotation_deg:.2}° and {translation_mm:.1} mm from where the other views put it (a merge accepts at most {max_deg}° and {max_mm:.1} mm): at least one view is registered wrongly, so no model was written; views.png and views.ply show each view in its colour, merge-report.txt each registration (a part of large flat faces registers wrongly so: docs/reports.md)"
    )]
    LoopOpen {
        /// The view that closes the loop.
        view: usize,
        /// The view it was registered onto directly.
        onto: usize,
        /// Its rotation error, degrees.
        rotation_deg: f64,
        /// Its translation error, mm.
        translation_mm: f64,
        /// The rotation allowed, degrees.
        max_deg: f64,
        /// The translation allowed, mm.
        max_mm: f64,
    },
    /// A view's points lie in the space another view saw empty: one of the two is registered
    /// wrongly (see [`crate::depth`]), even where the loops of views close.
    #[error(
        "view {view} ({name})'s points lie in front of what view {seen_by} ({seen_by_name}) saw: {in_front} of the {tested} that fall on its seen surface ({:.1} %) are more than {tol_mm:.1} mm nearer its camera than the surface it saw (a merge accepts at most {:.0} %): at least one of the two views is registered wrongly, so no model was written; views.png and views.ply show each view in its colour, merge-report.txt each registration",
        100.0 * *in_front as f64 / (*tested).max(1) as f64,
        100.0 * max_share
    )]
    SeenThrough {
        /// The view whose points were tested.
        view: usize,
        /// Its name.
        name: String,
        /// The view whose free space they lie in.
        seen_by: usize,
        /// Its name.
        seen_by_name: String,
        /// Points tested.
        tested: usize,
        /// Points in front.
        in_front: usize,
        /// The tolerance, mm.
        tol_mm: f64,
        /// The largest share in front a merge accepts.
        max_share: f64,
    },
    /// A view without the turntable disc's pose fits the disc-posed views only where its
    /// points would lie in front of what they saw.
    #[error(
        "view {view} ({name}) has no turntable disc pose, and its shape fits the views posed by the disc only where its points lie in front of what they saw (the best such fit {:.0} % of its points): stand the object on the disc for this view too, sweep slower for a denser view, or leave the view out; no model was written",
        100.0 * overlap
    )]
    ShapeNowhere {
        /// The view.
        view: usize,
        /// Its name.
        name: String,
        /// The best fit's overlap.
        overlap: f64,
    },
    /// A view without the turntable disc's pose fits the disc-posed views in two places.
    #[error(
        "view {view} ({name}) has no turntable disc pose, and its shape fits the views posed by the disc in two places ({:.0} % and {:.0} % of its points): stand the object on the disc for this view too, sweep slower for a denser view, or leave the view out; no model was written",
        100.0 * best,
        100.0 * rival
    )]
    ShapeAmbiguous {
        /// The view.
        view: usize,
        /// Its name.
        name: String,
        /// The best fit's overlap.
        best: f64,
        /// The other fit's.
        rival: f64,
    },
    /// Two views posed by the turntable disc contradict each other's free space: the object
    /// moved on the disc between sweeps, or a disc was misread.
    #[error(
        "view {view} ({name})'s points lie in front of what view {seen_by} saw ({:.1} %), both posed by the turntable disc: the object moved on the disc between the sweeps, or the disc was misread; keep the object still on the disc, or merge with --no-disc; no model was written",
        100.0 * share
    )]
    DiscMoved {
        /// The view.
        view: usize,
        /// Its name.
        name: String,
        /// The view whose free space its points lie in.
        seen_by: usize,
        /// The share of its points there in front.
        share: f64,
    },
    /// The laser measures the turntable disc at another size than the one its poses were
    /// computed for: the disc chosen is not the disc printed, and a model from these poses
    /// would come apart in pieces.
    #[error(
        "the laser measures the turntable disc at {:.1} % of the size it was posed as (views {views:?}): the disc chosen is not the one printed (A4's disc is 68.6 % of A3's); scan again with the disc size you printed, or merge with --no-disc; no model was written",
        100.0 * measured
    )]
    DiscSize {
        /// The disc's measured size, as a share of the size chosen (the views' median).
        measured: f64,
        /// The disc-posed views whose points measured it.
        views: Vec<usize>,
    },
    /// `--sheet auto` found no overlap to measure the views' agreement on.
    #[error(
        "--sheet auto: the views nowhere overlap within {agree_mm} mm of each other, so they tell no sheet thickness; give it with --sheet MM"
    )]
    NoThickness {
        /// How near points of two views must lie to count, mm.
        agree_mm: f64,
    },
    /// The views were read at other sheet thicknesses than the search tries.
    #[error(
        "--sheet auto: {views} sets of views given for {tries} thicknesses to try: one set per thickness"
    )]
    ThicknessTries {
        /// Sets given.
        views: usize,
        /// Thicknesses tried.
        tries: usize,
    },
    /// The fusion failed.
    #[error("fusing the views")]
    Fuse(#[source] FuseError),
}

impl MergeError {
    /// Whether this is a refusal of views registered wrongly (the plausibility checks), after
    /// which the registered views and the report are worth a look.
    pub fn is_implausible(&self) -> bool {
        matches!(
            self,
            MergeError::LoopOpen { .. }
                | MergeError::SeenThrough { .. }
                | MergeError::DiscMoved { .. }
                | MergeError::DiscSize { .. }
        )
    }
}

/// Why two views could not be registered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegisterError {
    /// A view has too few points to describe its shape.
    #[error(
        "a view has {points} points after thinning to {voxel_mm} mm: at least {min} are needed"
    )]
    TooFewPoints {
        /// Points left.
        points: usize,
        /// The voxel size.
        voxel_mm: f64,
        /// Needed.
        min: usize,
    },
    /// No rigid motion brings enough of one view onto the other.
    #[error(
        "the views do not overlap enough: the best match brings {overlap_percent:.0} % of the points within {tolerance_mm} mm (at least {min_percent:.0} % needed)"
    )]
    NoOverlap {
        /// The best match's overlap.
        overlap_percent: f64,
        /// The distance counted as overlapping.
        tolerance_mm: f64,
        /// The least overlap accepted.
        min_percent: f64,
    },
}

/// Why the fusion failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FuseError {
    /// Too few points to reconstruct from (after thinning to half a cell, those with a normal).
    #[error(
        "{0} points with a normal after thinning to half a cell: at least 100 are needed for a surface"
    )]
    TooFewPoints(usize),
    /// Points, normals and weights of different lengths (a caller's mistake).
    #[error("{points} points with {normals} normals and {weights} weights: one each per point")]
    Lengths {
        /// Points.
        points: usize,
        /// Normals.
        normals: usize,
        /// Weights (0 stands for all 1).
        weights: usize,
    },
    /// A weight that is not a number from 0 to 1.
    #[error("point {index} has weight {weight}: weights are 0 to 1")]
    Weight {
        /// Which point.
        index: usize,
        /// Its weight.
        weight: f64,
    },
    /// The grid would be too large: its cells along x, y and z, and the most it may have.
    #[error(
        "a {0}×{1}×{2} grid at this cell size (at most {3} cells): choose a larger --fuse-cell"
    )]
    TooLarge(usize, usize, usize, usize),
}
