//! Target neighborhoods Γᵏ_X (paper §2, SPEC §2.1): the K nearest scan points of every template
//! vertex, from a k-d tree over the scan built once per fit. This is the only module that talks
//! to `kiddo`.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZero;

/// A k-d tree over a fixed point set (the scan, or the template for NRGa neighborhoods).
pub struct PointIndex {
    tree: ImmutableKdTree<f64, 3>,
    points: Vec<[f64; 3]>,
}

/// The neighborhood size `K = clamp(⌊ρN⌋, k_min, k_max)`, never more than `n` (SPEC §2.1).
pub fn neighborhood_size(rho: f64, n: usize, k_min: usize, k_max: usize) -> usize {
    let k = (rho * n as f64).floor() as usize;
    k.clamp(k_min, k_max.max(k_min)).min(n).max(1)
}

impl PointIndex {
    /// Builds the tree over `points` (must be non-empty).
    pub fn new(points: &[[f64; 3]]) -> Self {
        Self {
            tree: ImmutableKdTree::new_from_slice(points),
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

    /// The `k` nearest indexed points of `query`, nearest first, written to `indices` (and the
    /// squared distances to `dist2`); both slices have length `k`.
    pub fn nearest_into(&self, query: &[f64; 3], indices: &mut [u32], dist2: &mut [f64]) {
        let k = indices.len();
        let found = self
            .tree
            .nearest_n::<SquaredEuclidean>(query, NonZero::new(k).unwrap());
        for (slot, nn) in found.iter().enumerate() {
            indices[slot] = nn.item as u32;
            dist2[slot] = nn.distance;
        }
    }

    /// Like [`PointIndex::nearest_into`], searching only within squared distance `radius2`;
    /// returns `false` (and leaves the outputs untouched) when fewer than `indices.len()`
    /// points lie that close.
    ///
    /// Collects every point of the ball unsorted and selects the `k` nearest (ties by index),
    /// which is several times faster than kiddo's bounded-heap `nearest_n_within` when the
    /// ball holds not many more than `k` points, as in [`NeighborCache`] re-queries (2K
    /// candidates measured faster than 3K/2 or 3K on the paper-sized case: fewer re-queries
    /// against a longer re-ranking). kiddo 5 returns a fresh `Vec` per query, as its
    /// `nearest_n` does.
    pub fn nearest_within_into(
        &self,
        query: &[f64; 3],
        radius2: f64,
        indices: &mut [u32],
        dist2: &mut [f64],
    ) -> bool {
        let k = indices.len();
        let mut found = self
            .tree
            .within_unsorted::<SquaredEuclidean>(query, radius2);
        if found.len() < k {
            return false;
        }
        let by_distance = |a: &kiddo::NearestNeighbour<f64, u64>,
                           b: &kiddo::NearestNeighbour<f64, u64>| {
            a.distance.total_cmp(&b.distance).then(a.item.cmp(&b.item))
        };
        if found.len() > k {
            found.select_nth_unstable_by(k - 1, by_distance);
        }
        found[..k].sort_unstable_by(by_distance);
        for (slot, nn) in found[..k].iter().enumerate() {
            indices[slot] = nn.item as u32;
            dist2[slot] = nn.distance;
        }
        true
    }

    /// The nearest indexed point of `query`: (index, squared distance).
    pub fn nearest_one(&self, query: &[f64; 3]) -> (u32, f64) {
        let nn = self.tree.nearest_one::<SquaredEuclidean>(query);
        (nn.item as u32, nn.distance)
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

/// Largest candidate set a [`NeighborCache`] keeps per query point.
pub const MAX_CACHED: usize = 192;

/// Exact re-use of earlier k-NN queries for points that moved little (SPEC §7, issue
/// "Performance").
///
/// Each point keeps the `c = min(2K, N, 192)` nearest candidates found at its *anchor* position,
/// with the anchor distances of the K-th and the c-th. After the point moved by δ from its
/// anchor, every point outside the candidate set is at least `d_c − δ` away and the K-th
/// nearest candidate at most `d_K + δ`,
/// so while `d_c − δ > d_K + δ` the K nearest points are the K nearest candidates: re-ranking
/// the candidates by their new distances gives exactly the k-d tree's answer (up to the order
/// of exactly tied distances). Otherwise the point is queried afresh and re-anchored.
pub struct NeighborCache {
    k: usize,
    c: usize,
    anchors: Vec<[f64; 3]>,
    /// The c candidates of every point, in the order of their last known distance (so the
    /// next re-ranking starts nearly sorted).
    candidates: Vec<u32>,
    /// Per point, at its anchor: the distances of the k-th and of the c-th nearest candidate.
    anchor_bounds: Vec<[f64; 2]>,
    /// Per point: 0 = no candidates yet, 1 = candidates re-used, 2 = queried afresh.
    state: Vec<u8>,
}

impl NeighborCache {
    /// A cache for `m` query points, `k` neighbours each, over an index of `n` points.
    pub fn new(m: usize, k: usize, n: usize) -> Self {
        let c = (2 * k).min(n).min(MAX_CACHED).max(k);
        Self {
            k,
            c,
            anchors: vec![[0.0; 3]; m],
            candidates: vec![0; m * c],
            anchor_bounds: vec![[0.0; 2]; m],
            state: vec![0; m],
        }
    }

    /// The `k` nearest indexed points of every query (same layout and order as
    /// [`PointIndex::nearest_all`]), re-using candidates where that is provably exact.
    /// Returns the number of points queried afresh.
    pub fn query(
        &mut self,
        index: &PointIndex,
        queries: &[[f64; 3]],
        indices: &mut [u32],
        dist2: &mut [f64],
    ) -> usize {
        let (k, c) = (self.k, self.c);
        let whole_set = c == index.len();
        self.anchors
            .par_iter_mut()
            .zip(self.candidates.par_chunks_mut(c))
            .zip(self.anchor_bounds.par_iter_mut())
            .zip(self.state.par_iter_mut())
            .zip(indices.par_chunks_mut(k).zip(dist2.par_chunks_mut(k)))
            .zip(queries.par_iter())
            .for_each(|(((((anchor, cand), bounds), state), (idx, d2)), q)| {
                let moved = (0..3)
                    .map(|a| (q[a] - anchor[a]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let [d_k, d_c] = *bounds;
                let reusable = *state > 0 && (whole_set || d_c - moved > d_k + moved);
                if reusable {
                    *state = 1;
                } else {
                    // The old candidates are all within d_c + δ of the new position, so the c
                    // nearest points are too: a bounded search finds the same points, faster.
                    let bound = if *state > 0 {
                        (d_c + moved) * (1.0 + 1e-9)
                    } else {
                        f64::INFINITY
                    };
                    let mut found_d2 = [0.0f64; MAX_CACHED];
                    let found_d2 = &mut found_d2[..c];
                    if !(bound.is_finite()
                        && index.nearest_within_into(q, bound * bound, cand, found_d2))
                    {
                        index.nearest_into(q, cand, found_d2);
                    }
                    *bounds = [found_d2[k - 1].sqrt(), found_d2[c - 1].sqrt()];
                    *anchor = *q;
                    *state = 2;
                }
                // Re-rank the candidates by their distance to the query's current position:
                // an insertion sort, as the stored order is last iteration's ranking and the
                // points move little between iterations (nearly sorted input, ~c steps).
                let mut ranked = [(0.0f64, 0u32); MAX_CACHED];
                let ranked = &mut ranked[..c];
                for (slot, &j) in ranked.iter_mut().zip(cand.iter()) {
                    let p = index.point(j);
                    *slot = ((0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>(), j);
                }
                let before =
                    |a: &(f64, u32), b: &(f64, u32)| a.0 < b.0 || (a.0 == b.0 && a.1 < b.1);
                for i in 1..c {
                    let item = ranked[i];
                    let mut at = i;
                    while at > 0 && before(&item, &ranked[at - 1]) {
                        ranked[at] = ranked[at - 1];
                        at -= 1;
                    }
                    ranked[at] = item;
                }
                for (slot, &(_, j)) in cand.iter_mut().zip(ranked.iter()) {
                    *slot = j;
                }
                for (s, &(d, j)) in ranked[..k].iter().enumerate() {
                    idx[s] = j;
                    d2[s] = d;
                }
            });
        self.state.iter().filter(|&&s| s == 2).count()
    }
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
            let d2 = (0..3).map(|a| (p[a] - query[a]).powi(2)).sum::<f64>();
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn cache_equals_fresh_queries_as_points_move() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let pts: Vec<[f64; 3]> = (0..3000)
            .map(|_| [rng.random(), rng.random(), rng.random()])
            .collect();
        let mut queries: Vec<[f64; 3]> = (0..400)
            .map(|_| [rng.random(), rng.random(), rng.random()])
            .collect();
        let index = PointIndex::new(&pts);
        let k = 12;
        let mut cache = NeighborCache::new(queries.len(), k, pts.len());
        let (mut ci, mut cd) = (vec![0; 400 * k], vec![0.0; 400 * k]);
        let (mut fi, mut fd) = (vec![0; 400 * k], vec![0.0; 400 * k]);
        let mut reused = 0;
        for step in 0..30 {
            let fresh = cache.query(&index, &queries, &mut ci, &mut cd);
            index.nearest_all(&queries, k, &mut fi, &mut fd);
            assert_eq!(ci, fi, "step {step}");
            assert_eq!(cd, fd);
            reused += queries.len() - fresh;
            for q in &mut queries {
                for c in q.iter_mut() {
                    *c += 0.004 * (rng.random::<f64>() - 0.5);
                }
            }
        }
        assert!(
            reused > 5000,
            "the cache should re-use most queries, re-used {reused}"
        );
    }

    #[test]
    fn k_clamp() {
        assert_eq!(neighborhood_size(0.002, 14_000, 8, 64), 28);
        assert_eq!(neighborhood_size(0.002, 1_000_000, 8, 64), 64);
        assert_eq!(neighborhood_size(0.002, 100, 8, 64), 8);
        assert_eq!(neighborhood_size(0.002, 5, 8, 64), 5);
    }

    #[test]
    fn kdtree_equals_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let pts: Vec<[f64; 3]> = (0..2000)
            .map(|_| [rng.random(), rng.random(), rng.random()])
            .collect();
        let queries: Vec<[f64; 3]> = (0..300)
            .map(|_| [rng.random(), rng.random(), rng.random::<f64>() * 1.5])
            .collect();
        let index = PointIndex::new(&pts);
        let k = 17;
        let mut idx = vec![0; queries.len() * k];
        let mut d2 = vec![0.0; queries.len() * k];
        index.nearest_all(&queries, k, &mut idx, &mut d2);
        for (q, query) in queries.iter().enumerate() {
            let (bi, bd) = brute_force_nearest(&pts, query, k);
            // Random real coordinates have no ties: indices must agree exactly.
            assert_eq!(&idx[q * k..(q + 1) * k], &bi[..]);
            for s in 0..k {
                assert!((d2[q * k + s] - bd[s]).abs() < 1e-15);
            }
            assert_eq!(index.nearest_one(query).0, bi[0]);
        }
    }
}
