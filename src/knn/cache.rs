//! Exact re-use of earlier k-NN queries for points that moved little ([`NeighborCache`]).

use rayon::prelude::*;

use super::{squared_distance, PointIndex};

/// Largest candidate set a [`NeighborCache`] keeps per query point.
pub const MAX_CACHED: usize = 192;

/// Exact re-use of earlier k-NN queries for points that moved little (docs/method.md "Target
/// neighborhoods Γᵏ_X").
///
/// Each point keeps the `c = min(2K, N, 192)` nearest candidates found at its *anchor* position,
/// with the anchor distance `d_c` of the c-th. After the point moved by δ from its anchor, every
/// point outside the candidate set is at least `d_c − δ` away (triangle inequality). The
/// candidates are re-ranked by their distances to the new position; while the K-th of them is
/// closer than `d_c − δ`, the K nearest points are the K nearest candidates: exactly the k-d
/// tree's answer (up to the order of exactly tied distances). Otherwise the point is queried
/// afresh and re-anchored. (Testing the re-ranked K-th distance, rather than its worst case
/// `d_K + δ`, lets a point travel about twice as far before its re-query: on the paper-sized
/// default fit, 58 % fewer fresh queries.)
pub struct NeighborCache {
    k: usize,
    c: usize,
    anchors: Vec<[f64; 3]>,
    /// The c candidates of every point, its last known k nearest first and in order (so the
    /// next re-ranking starts nearly sorted), then the others.
    candidates: Vec<u32>,
    /// Per point: the distance of the c-th nearest candidate at its anchor.
    anchor_radius: Vec<f64>,
    /// Per point: 0 = no candidates yet, 1 = candidates re-used, 2 = queried afresh.
    state: Vec<u8>,
    /// σ of the approximate re-use ([`NeighborCache::set_slack`]); 0: exact.
    slack: f64,
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
            anchor_radius: vec![0.0; m],
            state: vec![0; m],
            slack: 0.0,
        }
    }

    /// Sets σ ≥ 0 for the next queries: candidates are re-used while their re-ranked K-th is
    /// within `(1 + σ) ×` the distance beyond which every other point lies, so every returned
    /// neighbour is within `(1 + σ) ×` the true K-th nearest distance (a (1 + σ)-approximate
    /// K-NN); 0 (the default): exact.
    pub fn set_slack(&mut self, slack: f64) {
        self.slack = slack.max(0.0);
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
        let widen = 1.0 + self.slack;
        self.anchors
            .par_iter_mut()
            .zip(self.candidates.par_chunks_mut(c))
            .zip(self.anchor_radius.par_iter_mut())
            .zip(self.state.par_iter_mut())
            .zip(indices.par_chunks_mut(k).zip(dist2.par_chunks_mut(k)))
            .zip(queries.par_iter())
            .for_each_init(
                // Per-thread scratch: the ranking and the fresh distances (not per point: a
                // zeroed 3 KB array per point and iteration was a memset of gigabytes over a
                // fit).
                || (vec![(0.0f64, 0u32); c], vec![0.0f64; c]),
                |(ranked, found_d2), (((((anchor, cand), radius), state), (idx, d2)), q)| {
                    let ranked = &mut ranked[..];
                    let mut exact = false;
                    let mut farthest = f64::INFINITY;
                    if *state > 0 {
                        farthest = rerank(index, q, cand, k, ranked);
                        let moved = squared_distance(q, anchor).sqrt();
                        // Every non-candidate is at least `radius − moved` away; the margin
                        // keeps round-off from admitting a tie.
                        let outside = (*radius - moved) * (1.0 - 1e-9) * widen;
                        exact = whole_set || (outside > 0.0 && ranked[k - 1].0 < outside * outside);
                    }
                    if exact {
                        *state = 1;
                    } else {
                        // The old candidates all lie within the re-ranked c-th distance of the
                        // new position, so the c nearest points do too: a bounded search finds
                        // the same points, faster. Either way the k nearest come first, in
                        // order, as `rerank` leaves them.
                        let bound2 = farthest * (1.0 + 1e-9);
                        let found_d2 = &mut found_d2[..];
                        if !(bound2.is_finite()
                            && index.nearest_within_into(q, bound2, cand, found_d2))
                        {
                            index.nearest_into(q, cand, found_d2);
                        }
                        let reach2 = found_d2.iter().copied().fold(0.0, f64::max);
                        *radius = reach2.sqrt();
                        *anchor = *q;
                        *state = 2;
                        for (slot, (&d, &j)) in
                            ranked.iter_mut().zip(found_d2.iter().zip(cand.iter()))
                        {
                            *slot = (d, j);
                        }
                    }
                    for (slot, &(_, j)) in cand.iter_mut().zip(ranked.iter()) {
                        *slot = j;
                    }
                    for (s, &(d, j)) in ranked[..k].iter().enumerate() {
                        idx[s] = j;
                        d2[s] = d;
                    }
                },
            );
        self.state.iter().filter(|&&s| s == 2).count()
    }
}

/// Ranks the candidates `cand` by their squared distance to `q` (ties by index): on return
/// `ranked[..k]` holds the `k` nearest in order and `ranked[k..]` the others in no particular
/// order; returns the largest squared distance of all (the c-th in order).
///
/// The stored order starts with the last iteration's `k` nearest, in order, and the points move
/// little between iterations: an insertion sort of that head is ~k steps, and each tail
/// candidate costs one comparison with the k-th unless it enters the head. (Sorting all c
/// candidates cost ~c² moves where a point's far candidates reorder as it moves.)
#[inline]
fn rerank(
    index: &PointIndex,
    q: &[f64; 3],
    cand: &[u32],
    k: usize,
    ranked: &mut [(f64, u32)],
) -> f64 {
    let mut farthest = 0.0f64;
    for (slot, &j) in ranked.iter_mut().zip(cand.iter()) {
        let p = index.point(j);
        let d2 = squared_distance(q, p);
        if d2 > farthest {
            farthest = d2;
        }
        *slot = (d2, j);
    }
    let before = |a: &(f64, u32), b: &(f64, u32)| a.0 < b.0 || (a.0 == b.0 && a.1 < b.1);
    let (head, tail) = ranked.split_at_mut(k);
    let insert = |head: &mut [(f64, u32)], item: (f64, u32), from: usize| {
        let mut at = from;
        while at > 0 && before(&item, &head[at - 1]) {
            head[at] = head[at - 1];
            at -= 1;
        }
        head[at] = item;
    };
    for i in 1..k {
        insert(head, head[i], i);
    }
    for slot in tail.iter_mut() {
        if before(slot, &head[k - 1]) {
            let evicted = head[k - 1];
            insert(head, *slot, k - 1);
            *slot = evicted;
        }
    }
    farthest
}

/// The K nearest scan points of every template point (Γᵏ_X), as [`PointIndex::nearest_all`]
/// and [`NeighborCache::query`] write them: row v of `indices` / `dist2` (K entries, nearest
/// first) belongs to template point v.
#[derive(Clone, Copy, Debug)]
pub struct TargetNeighbours<'a> {
    /// Scan indices, M × K row-major.
    pub indices: &'a [u32],
    /// Their squared distances.
    pub dist2: &'a [f64],
    /// K.
    pub k: usize,
    /// Whether these are the exact K nearest (not the approximate lists of
    /// [`NeighborCache::set_slack`]): only then does [`ReverseNearest`](super::ReverseNearest) prune its tree
    /// searches by the lists' local radii (its global certificate applies either way).
    pub exact: bool,
}
