//! Target neighborhoods Γᵏ_X (paper §2; docs/method.md "Target neighborhoods Γᵏ_X"): the K nearest
//! scan points of every template vertex, from a k-d tree over the scan built once per fit
//! ([`BoxTree`]; kiddo's trees, whose split-plane pruning is slow for queries off the scan's
//! surface, serve the metrics' nearest queries in `metrics.rs`).

mod box_tree;
mod cache;
mod morton;
mod reverse;
#[cfg(test)]
mod tests;

pub use box_tree::{BoxTree, REBUILD_LOOSENESS};
pub use cache::{NeighborCache, TargetNeighbours, MAX_CACHED};
pub use morton::morton_order;
pub use reverse::ReverseNearest;

use rayon::prelude::*;

/// A k-d tree with node bounding boxes ([`BoxTree`]) over a fixed point set (the scan, or the
/// template for NRGa neighborhoods): the first queries and the [`NeighborCache`] re-queries.
pub struct PointIndex {
    boxes: BoxTree,
    points: Vec<[f64; 3]>,
}

/// The neighborhood size `K = clamp(⌊ρN⌋, k_min, k_max)`, never more than `n` (docs/method.md
/// "Target neighborhoods Γᵏ_X").
pub fn neighborhood_size(rho: f64, n: usize, k_min: usize, k_max: usize) -> usize {
    let k = (rho * n as f64).floor() as usize;
    k.clamp(k_min, k_max.max(k_min)).min(n).max(1)
}

impl PointIndex {
    /// Builds the tree over `points` (must be non-empty).
    pub fn new(points: &[[f64; 3]]) -> Self {
        let mut boxes = BoxTree::default();
        boxes.rebuild(points);
        Self {
            boxes,
            points: points.to_vec(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the index is empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The indexed point `j`.
    #[inline]
    pub fn point(&self, j: u32) -> &[f64; 3] {
        &self.points[j as usize]
    }

    /// The `k` nearest indexed points of `query`, nearest first (ties by index), written to
    /// `indices` (and the squared distances to `dist2`); both slices have length `k` ≤ the
    /// number of points. From the [`BoxTree`] ([`BoxTree::nearest_k_into`]).
    pub fn nearest_into(&self, query: &[f64; 3], indices: &mut [u32], dist2: &mut [f64]) {
        self.boxes.nearest_k_into(query, indices, dist2);
    }

    /// Like [`PointIndex::nearest_into`], searching only within squared distance `radius2`
    /// ([`BoxTree::nearest_k_within`]: nodes and points beyond it are never looked at);
    /// returns `false` (the outputs then hold only what was found) when fewer than
    /// `indices.len()` points lie that close.
    ///
    /// The box tree's box distances prune for a query far off the scan's surface, where
    /// kiddo's split planes do not (on the million-point case the re-queries of template
    /// points still far from the scan took ~20 µs each). For [`NeighborCache`] re-queries
    /// (2K candidates, measured faster than 3K/2 or 3K on the paper-sized case: fewer
    /// re-queries against a longer re-ranking; within ±3 % of both on the quarter-size large
    /// case), the ball through the old candidates holds about 1.7 × 2K points; a sorted
    /// insertion of the ones that come before the k-th so far replaced collecting the ball
    /// and two selections and a sort (callgrind, 2,500-vertex default: −2.1 % of the fit's
    /// instructions).
    pub fn nearest_within_into(
        &self,
        query: &[f64; 3],
        radius2: f64,
        indices: &mut [u32],
        dist2: &mut [f64],
    ) -> bool {
        self.boxes.nearest_k_within(query, radius2, indices, dist2) == indices.len()
    }

    /// Like [`PointIndex::nearest_one`], given one point `(index, squared distance)` known to
    /// be that close ([`BoxTree::nearest_one_from`]): the same answer, ties included.
    pub fn nearest_from(&self, query: &[f64; 3], known: (u32, f64)) -> (u32, f64) {
        self.boxes.nearest_one_from(query, known)
    }

    /// The nearest indexed point of `query`: (index, squared distance).
    pub fn nearest_one(&self, query: &[f64; 3]) -> (u32, f64) {
        self.boxes.nearest_one(query)
    }

    /// The `k` nearest points of every query, in parallel: row `q` of the (len(queries) × k)
    /// row-major outputs belongs to `queries[q]`.
    pub fn nearest_all(
        &self,
        queries: &[[f64; 3]],
        k: usize,
        indices: &mut [u32],
        dist2: &mut [f64],
    ) {
        assert!(
            k >= 1 && k <= self.len(),
            "k = {k} must be in 1..={}",
            self.len()
        );
        assert_eq!(indices.len(), queries.len() * k);
        assert_eq!(dist2.len(), queries.len() * k);
        indices
            .par_chunks_mut(k)
            .zip(dist2.par_chunks_mut(k))
            .zip(queries.par_iter())
            .for_each(|((idx, d2), q)| self.nearest_into(q, idx, d2));
    }
}

/// Squared Euclidean distance, summed over x, y, z in order (every query of this module uses it,
/// so equal distances compare equal wherever they are computed).
#[inline]
pub(super) fn squared_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum()
}

/// Brute-force k nearest neighbours (the exact reference the k-d tree is tested against):
/// returns (indices, squared distances) nearest first, ties broken by index.
pub fn brute_force_nearest(
    points: &[[f64; 3]],
    query: &[f64; 3],
    k: usize,
) -> (Vec<u32>, Vec<f64>) {
    let mut all: Vec<(f64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let d2 = squared_distance(p, query);
            (d2, i as u32)
        })
        .collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    all.truncate(k);
    (
        all.iter().map(|x| x.1).collect(),
        all.iter().map(|x| x.0).collect(),
    )
}
