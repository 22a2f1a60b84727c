//! The merge's refusals in the page's terms: views numbered as the page's table numbers them
//! (from 1, the views left out skipped), advice in buttons and actions, not the command line's
//! options.

use scanner_merge::MergeError;

/// A merge's refusal as the page shows it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PageRefusal {
    /// The merge error's kind (its variant's name).
    pub kind: String,
    /// The views it names, as the table numbers them.
    pub views: Vec<usize>,
    /// What is wrong and what to do.
    pub words: String,
}

/// A view taken off the disc whose shape does not tell where it belongs.
fn off_disc(view: usize) -> String {
    format!(
        "view {view} was not taken on the disc, and its shape does not tell where it belongs among the others: take it again on the disc, or untick it"
    )
}

/// `e` in the page's terms; `numbers`: the table's number of each view the merge was given, in
/// the order given (the merge numbers them from 0).
pub fn merge_refusal(e: &MergeError, numbers: &[usize]) -> PageRefusal {
    let n = |k: &usize| numbers.get(*k).copied().unwrap_or(k + 1);
    let list = |ks: &[usize]| {
        ks.iter()
            .map(|k| n(k).to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let disc = "stand the object on the printed disc for every view (choose its size in Scanning)";
    let (kind, views, words) = match e {
        MergeError::Option { .. } => ("Option", vec![], e.to_string()),
        MergeError::TooFewViews(_) => (
            "TooFewViews",
            vec![],
            "a merge needs two views or more: turn the object and take another".to_string(),
        ),
        MergeError::OtherCamera { view, .. } => (
            "OtherCamera",
            vec![n(view)],
            format!(
                "view {} was taken with another camera or picture size than view {}: untick it and merge again",
                n(view),
                n(&0)
            ),
        ),
        MergeError::NoUp => ("NoUp", vec![], e.to_string()),
        MergeError::NoMatch { view, .. } => (
            "NoMatch",
            vec![n(view)],
            format!(
                "view {} overlaps no other view: {disc}, sweep it again more slowly, or take a view between it and the others",
                n(view)
            ),
        ),
        MergeError::Apart { placed, apart } => (
            "Apart",
            apart.iter().map(n).collect(),
            format!(
                "views {} match one another but none of views {}: their shapes do not tell how the object was turned; {disc}, or take views between these",
                list(apart),
                list(placed)
            ),
        ),
        MergeError::LoopOpen {
            view,
            onto,
            rotation_deg,
            translation_mm,
            ..
        } => (
            "LoopOpen",
            vec![n(view), n(onto)],
            format!(
                "the views do not close into one object: view {} fitted onto view {} lands {rotation_deg:.2}° and {translation_mm:.1} mm from where the others put it; one view is placed wrongly: untick one of them and merge again, or {disc}",
                n(view),
                n(onto)
            ),
        ),
        MergeError::SeenThrough { view, seen_by, .. } => (
            "SeenThrough",
            vec![n(view), n(seen_by)],
            format!(
                "view {}'s points lie in front of what view {} saw: one of the two is placed wrongly; untick one of them and merge again, or {disc}",
                n(view),
                n(seen_by)
            ),
        ),
        MergeError::ShapeNowhere { view, .. } => ("ShapeNowhere", vec![n(view)], off_disc(n(view))),
        MergeError::ShapeAmbiguous { view, .. } => {
            ("ShapeAmbiguous", vec![n(view)], off_disc(n(view)))
        }
        MergeError::DiscMoved { view, seen_by, .. } => (
            "DiscMoved",
            vec![n(view), n(seen_by)],
            format!(
                "views {} and {} disagree though both stood on the disc: the object moved on the disc between them, or the disc was misread; keep the object still, take them again, or untick one",
                n(view),
                n(seen_by)
            ),
        ),
        MergeError::DiscSize { views, .. } => (
            "DiscSize",
            views.iter().map(n).collect(),
            format!(
                "the laser measures the disc of views {} at another size than the one chosen: choose the disc size you printed in Scanning, sweep the views again and merge",
                list(views)
            ),
        ),
        MergeError::NoThickness { .. } => ("NoThickness", vec![], e.to_string()),
        MergeError::ThicknessTries { .. } => ("ThicknessTries", vec![], e.to_string()),
        MergeError::Fuse(_) => ("Fuse", vec![], e.to_string()),
    };
    PageRefusal {
        kind: kind.to_string(),
        views,
        words,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_are_named_as_the_table_numbers_them() {
        // the table's views 1, 2, 4 and 5 went to the merge (3 was left out)
        let numbers = [1, 2, 4, 5];
        let apart = MergeError::Apart {
            placed: vec![0, 1],
            apart: vec![2, 3],
        };
        let r = merge_refusal(&apart, &numbers);
        assert_eq!(
            (r.kind.as_str(), r.views.as_slice()),
            ("Apart", &[4, 5][..])
        );
        let open = MergeError::LoopOpen {
            view: 3,
            onto: 0,
            rotation_deg: 2.0,
            translation_mm: 9.0,
            max_deg: 1.0,
            max_mm: 3.0,
        };
        let r = merge_refusal(&open, &numbers);
        assert_eq!(
            (r.kind.as_str(), r.views.as_slice()),
            ("LoopOpen", &[5, 1][..])
        );
        // the page's words never name the command line's options
        for e in [apart, open, MergeError::TooFewViews(1)] {
            assert!(!merge_refusal(&e, &numbers).words.contains("--"), "{e}");
        }
    }
}
