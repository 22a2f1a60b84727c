//! The bottom of the merge: clouds of oriented points, k-d trees over them (`kiddo`), voxel
//! thinning and normals from neighbours. It imports nothing else of the crate, and the host's
//! single-view code (the sheet's correction, the artefact check) uses it without reaching the
//! registration.

use kiddo::{ImmutableKdTree, KdTree, SquaredEuclidean};
use scanner_core::nalgebra::{Matrix3, Point3, SymmetricEigen, Unit, Vector3};

/// Points with unit normals (facing their camera).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cloud {
    /// Positions, mm.
    pub points: Vec<Point3<f64>>,
    /// Unit normals.
    pub normals: Vec<Vector3<f64>>,
}

/// Most threads [`par_map`] shares its work among.
pub(crate) const MAX_THREADS: usize = 8;

/// The threads [`par_map`] and the fusion's slices use: the machine's cores, at most
/// [`MAX_THREADS`].
pub(crate) fn threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().min(MAX_THREADS))
}

/// `f(i)` for every `i` in `0..n`, in order, shared among [`threads`] threads (the searches
/// over a cloud's points: each answer independent of the others).
pub(crate) fn par_map<U: Send>(n: usize, f: impl Fn(usize) -> U + Sync) -> Vec<U> {
    if n < 1024 {
        return (0..n).map(f).collect();
    }
    let block = (n / (threads() * RUNS_PER_THREAD)).max(64);
    par_runs(n, block, |run| run.map(&f).collect())
}

/// Runs a thread takes, about, in [`par_runs`] from [`par_map`]: enough that one thread's
/// dense part of a cloud does not keep the others waiting.
const RUNS_PER_THREAD: usize = 16;

/// `f` over `0..n` cut into runs of `block`, each run's answers in order, the runs handed to
/// [`threads`] threads as each finishes its last (a cloud's dense parts, a grid's slices
/// through the surface, take longer than the rest); all the answers in order.
pub(crate) fn par_runs<U: Send>(
    n: usize,
    block: usize,
    f: impl Fn(std::ops::Range<usize>) -> Vec<U> + Sync,
) -> Vec<U> {
    let block = block.max(1);
    let runs = n.div_ceil(block);
    let threads = threads().min(runs);
    if threads <= 1 {
        return f(0..n);
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let (f, next) = (&f, &next);
    let mut done: Vec<(usize, Vec<U>)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(move || {
                    let mut mine = Vec::new();
                    loop {
                        let r = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if r >= runs {
                            return mine;
                        }
                        mine.push((r, f(r * block..((r + 1) * block).min(n))));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    done.sort_unstable_by_key(|(r, _)| *r);
    let mut out = Vec::with_capacity(n);
    for (_, v) in done {
        out.extend(v);
    }
    out
}

/// `k` as the count a k-d tree's n-nearest search takes (at least one).
pub(crate) fn at_least_one(k: usize) -> std::num::NonZero<usize> {
    std::num::NonZero::new(k).unwrap_or(std::num::NonZero::<usize>::MIN)
}

/// A k-d tree of `points`, items their indices.
pub fn tree(points: &[Point3<f64>]) -> KdTree<f64, 3> {
    tree_of(points.iter().map(|p| [p.x, p.y, p.z]))
}

/// A balanced k-d tree of `points`, built once (items their indices): for the searches of a
/// large set that does not change. A tree grown point by point in the points' own order grows
/// deep where that order is spatial (a marching-cubes mesh's vertices come slice by slice, a
/// turntable's points frame by frame: depths of 40 to 56 seen), and its searches slow with it.
/// `None` for no points.
pub fn balanced(points: &[Point3<f64>]) -> Option<ImmutableKdTree<f64, 3>> {
    if points.is_empty() {
        return None;
    }
    let items: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    Some(ImmutableKdTree::new_from_slice(&items))
}

/// Copies of one exact point a k-d tree takes: kiddo's leaves hold 32 items and cannot split
/// identical ones (it panics at the 33rd), and a journal can hold any number of the same point.
/// A query then finds one of the copies kept, at the same distance.
const MAX_SAME: usize = 16;

/// A k-d tree of `items`, each under its index, with at most [`MAX_SAME`] copies of any one.
/// The items go in in a scrambled order: kiddo's tree grows by splitting the leaf a point falls
/// in, so points that come in their spatial order (a turntable's frame after frame, a grid's
/// slice after slice) grow it deep on one side (depths of 40 to 56 seen, every search walking
/// them); in a scrambled order it grows about balanced. The order is fixed (a hash of the
/// index), so every run builds the same tree.
pub(crate) fn tree_of<A: kiddo::float::kdtree::Axis + Into<f64>, const K: usize>(
    items: impl Iterator<Item = [A; K]>,
) -> KdTree<A, K> {
    let items: Vec<[A; K]> = items.collect();
    let mut order: Vec<u32> = (0..items.len() as u32).collect();
    order.sort_unstable_by_key(|&i| scramble(u64::from(i)));
    let mut t: KdTree<A, K> = KdTree::new();
    let mut copies: std::collections::HashMap<[u64; K], usize> = std::collections::HashMap::new();
    for i in order {
        let item = items[i as usize];
        let n = copies.entry(item.map(|a| a.into().to_bits())).or_default();
        if *n < MAX_SAME {
            *n += 1;
            t.add(&item, u64::from(i));
        }
    }
    t
}

/// SplitMix64's finaliser: a fixed, well-spread order of the indices.
fn scramble(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// The indices of `points` grouped by the `voxel` mm cube they lie in, cubes in a fixed order.
pub(crate) fn voxel_groups(points: &[Point3<f64>], voxel: f64) -> Vec<Vec<u32>> {
    let mut cells: std::collections::HashMap<[i64; 3], Vec<u32>> = std::collections::HashMap::new();
    for (i, p) in points.iter().enumerate() {
        let key = [p.x, p.y, p.z].map(|v| (v / voxel).floor() as i64);
        cells.entry(key).or_default().push(i as u32);
    }
    let mut keys: Vec<_> = cells.into_iter().collect();
    keys.sort_by_key(|(k, _)| *k);
    keys.into_iter().map(|(_, v)| v).collect()
}

/// Thins a cloud to one point per `voxel` mm cube (the mean of the points and normals in it).
pub fn thin(c: &Cloud, voxel: f64) -> Cloud {
    thin_with(c, &[], &[], voxel).0
}

/// [`thin`], with the mean of each cube's colours and of each kind of `values` (each kind a
/// list with one value per point; a list of another length is left out) beside it.
pub(crate) fn thin_with(
    c: &Cloud,
    colours: &[[u8; 3]],
    values: &[&[f64]],
    voxel: f64,
) -> (Cloud, Vec<[u8; 3]>, Vec<Vec<f64>>) {
    let coloured = colours.len() == c.points.len() && !colours.is_empty();
    let mut out = Cloud::default();
    let mut rgb = Vec::new();
    let mut means: Vec<Vec<f64>> = vec![Vec::new(); values.len()];
    for group in voxel_groups(&c.points, voxel) {
        let n: Vector3<f64> = group.iter().map(|&i| c.normals[i as usize]).sum();
        if n.norm() <= 1e-9 {
            continue;
        }
        let p: Vector3<f64> = group.iter().map(|&i| c.points[i as usize].coords).sum();
        out.points.push(Point3::from(p / group.len() as f64));
        out.normals.push(n.normalize());
        for (mean, v) in means.iter_mut().zip(values) {
            if v.len() == c.points.len() && !v.is_empty() {
                mean.push(group.iter().map(|&i| v[i as usize]).sum::<f64>() / group.len() as f64);
            }
        }
        if coloured {
            let mut sum = [0u32; 3];
            for &i in &group {
                for (s, v) in sum.iter_mut().zip(colours[i as usize]) {
                    *s += u32::from(v);
                }
            }
            let k = group.len() as u32;
            rgb.push(sum.map(|s| ((s + k / 2) / k) as u8));
        }
    }
    (out, rgb, means)
}

/// Unit normals from the `k` nearest neighbours (the direction of least spread), turned to face
/// the camera at the origin.
pub fn normals(points: &[Point3<f64>], k: usize) -> Vec<Vector3<f64>> {
    let Some(t) = balanced(points) else {
        return Vec::new();
    };
    let k = at_least_one(k.max(3));
    par_map(points.len(), |i| {
        let p = &points[i];
        let nn = t.nearest_n::<SquaredEuclidean>(&[p.x, p.y, p.z], k);
        let mean = nn
            .iter()
            .fold(Vector3::zeros(), |a, n| a + points[n.item as usize].coords)
            / nn.len() as f64;
        let cov = nn.iter().fold(Matrix3::zeros(), |a, n| {
            let d = points[n.item as usize].coords - mean;
            a + d * d.transpose()
        });
        let e = SymmetricEigen::new(cov);
        let i = e.eigenvalues.imin();
        let n: Vector3<f64> = e.eigenvectors.column(i).into_owned();
        if n.dot(&p.coords) > 0.0 { -n } else { n }
    })
}

/// The index of the nearest of `tree`'s items to `q` within `max_dist` mm (searched within the
/// distance only: an unbounded search from far away visits much of the tree), with its squared
/// distance.
pub fn nearest_within(
    tree: &KdTree<f64, 3>,
    q: &Point3<f64>,
    max_dist: f64,
) -> Option<(usize, f64)> {
    tree.nearest_n_within::<SquaredEuclidean>(
        &[q.x, q.y, q.z],
        max_dist * max_dist,
        std::num::NonZero::<usize>::MIN,
        false,
    )
    .first()
    .map(|n| (n.item as usize, n.distance))
}

/// The mean of a cloud's points (the origin for none).
pub fn centre(points: &[Point3<f64>]) -> Point3<f64> {
    Point3::from(
        points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / points.len().max(1) as f64,
    )
}

/// Two unit directions across `axis`, square to it and to each other.
pub fn across(axis: &Unit<Vector3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    let e1 = axis
        .cross(&Vector3::x())
        .try_normalize(1e-6)
        .unwrap_or_else(|| axis.cross(&Vector3::y()).normalize());
    (e1, axis.cross(&e1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn par_map_keeps_the_order_below_and_above_its_threshold() {
        for n in [0, 1, 1023, 1024, 10_007] {
            let got = par_map(n, |i| i * 3 + 1);
            assert_eq!(got.len(), n);
            assert!(
                got.iter().enumerate().all(|(i, &v)| v == i * 3 + 1),
                "n = {n}"
            );
        }
        // runs of every length, the last one short; answers of any number per run
        for (n, block) in [(0, 4), (1, 4), (10, 3), (10, 1), (10, 10), (1000, 7)] {
            let got = par_runs(n, block, |run| run.flat_map(|i| [i, i]).collect());
            let want: Vec<usize> = (0..n).flat_map(|i| [i, i]).collect();
            assert_eq!(got, want, "n = {n}, block = {block}");
        }
    }
}
