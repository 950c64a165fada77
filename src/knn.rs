//! Target neighborhoods Γᵏ_X (paper §2, SPEC §2.1): the K nearest scan points of every template
//! vertex, from a k-d tree over the scan built once per fit. This is the only module that talks
//! to `kiddo`.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZero;

/// A k-d tree over a fixed point set (the scan, or the template for NRGa neighborhoods).
pub struct PointIndex {
    tree: ImmutableKdTree<f64, 3>,
    len: usize,
}

/// The neighborhood size `K = clamp(⌊ρN⌋, k_min, k_max)`, never more than `n` (SPEC §2.1).
pub fn neighborhood_size(rho: f64, n: usize, k_min: usize, k_max: usize) -> usize {
    let k = (rho * n as f64).floor() as usize;
    k.clamp(k_min, k_max.max(k_min)).min(n).max(1)
}

impl PointIndex {
    /// Builds the tree over `points` (must be non-empty).
    pub fn new(points: &[[f64; 3]]) -> Self {
        Self { tree: ImmutableKdTree::new_from_slice(points), len: points.len() }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the index is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The `k` nearest indexed points of `query`, nearest first, written to `indices` (and the
    /// squared distances to `dist2`); both slices have length `k`.
    pub fn nearest_into(&self, query: &[f64; 3], indices: &mut [u32], dist2: &mut [f64]) {
        let k = indices.len();
        let found = self.tree.nearest_n::<SquaredEuclidean>(query, NonZero::new(k).unwrap());
        for (slot, nn) in found.iter().enumerate() {
            indices[slot] = nn.item as u32;
            dist2[slot] = nn.distance;
        }
    }

    /// The nearest indexed point of `query`: (index, squared distance).
    pub fn nearest_one(&self, query: &[f64; 3]) -> (u32, f64) {
        let nn = self.tree.nearest_one::<SquaredEuclidean>(query);
        (nn.item as u32, nn.distance)
    }

    /// The `k` nearest points of every query, in parallel: row `q` of the (len(queries) × k)
    /// row-major outputs belongs to `queries[q]`.
    pub fn nearest_all(&self, queries: &[[f64; 3]], k: usize, indices: &mut [u32], dist2: &mut [f64]) {
        assert!(k >= 1 && k <= self.len, "k = {k} must be in 1..={}", self.len);
        assert_eq!(indices.len(), queries.len() * k);
        assert_eq!(dist2.len(), queries.len() * k);
        indices
            .par_chunks_mut(k)
            .zip(dist2.par_chunks_mut(k))
            .zip(queries.par_iter())
            .for_each(|((idx, d2), q)| self.nearest_into(q, idx, d2));
    }
}

/// Brute-force k nearest neighbours (the exact reference the k-d tree is tested against):
/// returns (indices, squared distances) nearest first, ties broken by index.
pub fn brute_force_nearest(points: &[[f64; 3]], query: &[f64; 3], k: usize) -> (Vec<u32>, Vec<f64>) {
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
    (all.iter().map(|x| x.1).collect(), all.iter().map(|x| x.0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

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
        let pts: Vec<[f64; 3]> = (0..2000).map(|_| [rng.random(), rng.random(), rng.random()]).collect();
        let queries: Vec<[f64; 3]> = (0..300).map(|_| [rng.random(), rng.random(), rng.random::<f64>() * 1.5]).collect();
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
