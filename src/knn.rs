//! Target neighborhoods Γᵏ_X (paper §2, SPEC §2.1): the K nearest scan points of every template
//! vertex, from a k-d tree over the scan built once per fit ([`BoxTree`]; kiddo's trees, whose
//! split-plane pruning is slow for queries off the scan's surface, serve the metrics' nearest
//! queries in `metrics.rs`).

use rayon::prelude::*;

/// A k-d tree with node bounding boxes ([`BoxTree`]) over a fixed point set (the scan, or the
/// template for NRGa neighborhoods): the first queries and the [`NeighborCache`] re-queries.
pub struct PointIndex {
    boxes: BoxTree,
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

/// Points per leaf of a [`BoxTree`]. Measured by callgrind on whole default fits, one thread:
/// 32 points 2.806G instructions on the 2,500-vertex case and 25.97G on the paper-sized one,
/// 16 points 2.748G and 25.62G, 12 points 25.72G (paper-sized), 8 points 2.754G (2,500
/// vertices); the wall times were equal within the machine's noise.
const BOX_LEAF: usize = 16;

/// The longest list [`BoxTree::nearest_k_within`] keeps by sorted insertion; longer ones are
/// gathered and selected. Measured by callgrind on whole fits, one thread, one schedule:
/// lists of 16 (the 2,025-vertex case, K = 8, both schedules) 2.693G instructions by insertion
/// against 2.743G gathered, 56 (paper-sized, K = 28) 11.683G against 11.688G, 128 (a 71×71
/// sheet on 50,000 points, K = 64, as on the million-point case) 10.316G against 9.490G: an
/// insertion shifts ~k/2 entries when the points arrive in no order (a query far off the
/// scan sees them all at about its height). Lowered from 64 to 32 once the default `k_max`
/// became 32 (lists of 64): the 71×71 sheet on 50,000 points, both schedules, 16.63G → 16.47G;
/// the million-point case's k-NN stage 26.6 s → 24.7 s of wall time (2 threads, one run each).
const SORTED_LIST_MAX: usize = 32;

/// [`BoxTree::update`] rebuilds once the leaves' looseness exceeds this multiple of its value
/// at the last rebuild.
pub const REBUILD_LOOSENESS: f64 = 1.5;

/// A k-d tree with a tight bounding box per node: for the nearest template point of scan
/// points (the two-way attraction's queries; refitted as the template moves,
/// [`BoxTree::update`]) and for the k-NN queries over the scan ([`PointIndex`]).
///
/// A k-d tree that prunes by its split planes alone (kiddo's) only sees how far a query lies
/// *along the split axes*: for a query at height h above a flat patch of template, every leaf
/// within lateral distance h of it looks close enough, and a query far from the template scans
/// O((h / spacing)²) points. Box distances count the height too, so a query visits the few
/// leaves around its foot point wherever it is (on the million-point case most of the reverse
/// queries are such far points: scan regions the template has not reached yet).
///
/// Median splits along each node's longest box side; the node layout depends only on the
/// number of points, so both halves are built in parallel into their own parts of the node
/// array. Ties go to the lower index, as in [`brute_force_nearest`].
#[derive(Clone, Debug, Default)]
pub struct BoxTree {
    /// The points in tree order, with their indices.
    entries: Vec<([f64; 3], u32)>,
    nodes: Vec<BoxNode>,
    /// [`BoxTree::looseness`] right after the last rebuild.
    built_looseness: f64,
}

#[derive(Clone, Copy, Debug, Default)]
struct BoxNode {
    lo: [f64; 3],
    hi: [f64; 3],
    /// The node's range of `entries`.
    start: u32,
    end: u32,
    /// Index of the right child (the left child is the next node); 0 for a leaf.
    right: u32,
}

/// Nodes of a [`BoxTree`] over `n` points.
fn box_nodes(n: usize) -> usize {
    if n <= BOX_LEAF {
        1
    } else {
        1 + box_nodes(n / 2) + box_nodes(n - n / 2)
    }
}

/// Squared Euclidean distance, summed over x, y, z in order (every query of this module uses it,
/// so equal distances compare equal wherever they are computed).
#[inline]
fn squared_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum()
}

/// Squared distance from `q` to the box `[lo, hi]` (0 inside).
#[inline]
fn box_distance2(q: &[f64; 3], lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
    (0..3)
        .map(|a| (lo[a] - q[a]).max(q[a] - hi[a]).max(0.0).powi(2))
        .sum()
}

impl BoxTree {
    /// Rebuilds the tree over `points` (non-empty), re-using its buffers.
    pub fn rebuild(&mut self, points: &[[f64; 3]]) {
        assert!(!points.is_empty() && points.len() < u32::MAX as usize);
        self.entries.clear();
        self.entries
            .extend(points.iter().enumerate().map(|(i, p)| (*p, i as u32)));
        self.nodes
            .resize(box_nodes(points.len()), BoxNode::default());
        build_box_node(&mut self.entries, 0, &mut self.nodes, 0);
        self.built_looseness = self.looseness();
    }

    /// Moves the points of the tree to `points` (the same points, moved: `points.len()` equal
    /// to the tree's) keeping its structure, and recomputes every node's box bottom-up, in
    /// O(n) instead of the rebuild's O(n log n) selections. Queries stay exact (every box
    /// bounds its points; [`BoxTree::nearest_one`]'s answer, ties included, does not depend
    /// on how the points are grouped), only slower if the motion pulled the leaves' points
    /// apart: see [`BoxTree::update`].
    pub fn refit(&mut self, points: &[[f64; 3]]) {
        assert_eq!(points.len(), self.entries.len());
        for (p, id) in &mut self.entries {
            *p = points[*id as usize];
        }
        // Children follow their parent in the node array: in reverse every child is done
        // before its parent.
        for at in (0..self.nodes.len()).rev() {
            let node = self.nodes[at];
            let (lo, hi) = if node.right == 0 {
                bounds(&self.entries[node.start as usize..node.end as usize])
            } else {
                let (l, r) = (&self.nodes[at + 1], &self.nodes[node.right as usize]);
                (
                    std::array::from_fn(|a| l.lo[a].min(r.lo[a])),
                    std::array::from_fn(|a| l.hi[a].max(r.hi[a])),
                )
            };
            self.nodes[at].lo = lo;
            self.nodes[at].hi = hi;
        }
    }

    /// Per node, the smallest of `values` (one per point, by the points' indices) over the
    /// node's points, written to `out`, in O(nodes) bottom-up.
    pub fn node_minima(&self, values: &[f64], out: &mut Vec<f64>) {
        out.resize(self.nodes.len(), 0.0);
        for at in (0..self.nodes.len()).rev() {
            let node = &self.nodes[at];
            out[at] = if node.right == 0 {
                self.entries[node.start as usize..node.end as usize]
                    .iter()
                    .map(|(_, id)| values[*id as usize])
                    .fold(f64::INFINITY, f64::min)
            } else {
                out[at + 1].min(out[node.right as usize])
            };
        }
    }

    /// The leaves' boxes against the root's: the sum over the leaves of their box's
    /// half-perimeter (`Δx + Δy + Δz`) ÷ the root box's. Unchanged by a translation or a
    /// uniform scaling of the points; it grows when a motion pulls the points of a leaf apart
    /// (stretching or tearing; a fold or a roll-up of cloth, an isometry, bends the leaves but
    /// keeps them compact — the test rolls a grid shut).
    fn looseness(&self) -> f64 {
        let half_perimeter = |n: &BoxNode| (0..3).map(|a| n.hi[a] - n.lo[a]).sum::<f64>();
        let leaves: f64 = self
            .nodes
            .iter()
            .filter(|n| n.right == 0)
            .map(half_perimeter)
            .sum();
        leaves / half_perimeter(&self.nodes[0]).max(f64::MIN_POSITIVE)
    }

    /// Brings the tree to `points`: a [`BoxTree::refit`] while the leaves stay within
    /// [`REBUILD_LOOSENESS`] × their looseness at the last rebuild, else (and for a new point
    /// count) a rebuild. The answers are the same either way; a moving template (the two-way
    /// attraction's tree) refits in O(n) most iterations.
    pub fn update(&mut self, points: &[[f64; 3]]) {
        if points.len() != self.entries.len() || self.nodes.is_empty() {
            self.rebuild(points);
            return;
        }
        self.refit(points);
        if self.looseness() > REBUILD_LOOSENESS * self.built_looseness {
            self.rebuild(points);
        }
    }

    /// The nearest point of `q`: (index, squared distance), ties to the lower index.
    pub fn nearest_one(&self, q: &[f64; 3]) -> (u32, f64) {
        self.nearest_one_from(q, (u32::MAX, f64::INFINITY))
    }

    /// Like [`BoxTree::nearest_one`], given one point `(index, squared distance)` known to be
    /// that close: the search prunes by it from the start (the nearest point of the last
    /// iteration, a few spacings off at most). The same answer, ties included.
    pub fn nearest_one_from(&self, q: &[f64; 3], known: (u32, f64)) -> (u32, f64) {
        self.nearest_one_floored(q, known, |_| 0.0)
    }

    /// Like [`BoxTree::nearest_one_from`] where, besides its box, each node `at` has a floor
    /// `floor(at)`: no point of the node that could answer lies closer (squared) than it
    /// unless farther than `known` — so a node whose floor exceeds the best distance found is
    /// skipped (the two-way attraction's local certificate, [`ReverseNearest`]). With floors
    /// that hold, the same answer as [`BoxTree::nearest_one_from`], ties included (a floor
    /// only skips nodes strictly beyond the bound).
    #[inline]
    pub fn nearest_one_floored(
        &self,
        q: &[f64; 3],
        known: (u32, f64),
        floor: impl Fn(u32) -> f64,
    ) -> (u32, f64) {
        let mut best = known;
        self.descend_floored(q, best.1, floor, |leaf| {
            for (p, id) in leaf {
                let d2 = squared_distance(p, q);
                if d2 < best.1 || (d2 == best.1 && *id < best.0) {
                    best = (*id, d2);
                }
            }
            best.1
        });
        best
    }

    /// Visits the leaves that may hold a point within squared distance `bound2` of `q`, depth
    /// first, the nearer child first; `leaf` sees a leaf's entries and returns the bound from
    /// then on (the search's current k-th distance). Nodes whose box lies farther than the
    /// bound are skipped; one at the bound is visited (it may hold a tie of lower index).
    #[inline(always)]
    fn descend(&self, q: &[f64; 3], bound2: f64, leaf: impl FnMut(&[([f64; 3], u32)]) -> f64) {
        self.descend_floored(q, bound2, |_| 0.0, leaf);
    }

    /// [`BoxTree::descend`] with a lower bound per node besides its box distance (see
    /// [`BoxTree::nearest_one_floored`]): a node is ordered and pruned by the larger of the two.
    #[inline(always)]
    fn descend_floored(
        &self,
        q: &[f64; 3],
        mut bound2: f64,
        floor: impl Fn(u32) -> f64,
        mut leaf: impl FnMut(&[([f64; 3], u32)]) -> f64,
    ) {
        // Depth ≤ log2(n / BOX_LEAF) + 1 and one pending sibling per level.
        let mut stack = [(0u32, 0.0f64); 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (at, d2) = stack[top];
            if d2 > bound2 {
                continue;
            }
            let node = &self.nodes[at as usize];
            if node.right == 0 {
                bound2 = leaf(&self.entries[node.start as usize..node.end as usize]);
                continue;
            }
            let (left, right) = (at + 1, node.right);
            let dl = box_distance2(
                q,
                &self.nodes[left as usize].lo,
                &self.nodes[left as usize].hi,
            )
            .max(floor(left));
            let dr = box_distance2(
                q,
                &self.nodes[right as usize].lo,
                &self.nodes[right as usize].hi,
            )
            .max(floor(right));
            // The nearer child on top, visited first.
            let (near, far) = if dl <= dr {
                ((left, dl), (right, dr))
            } else {
                ((right, dr), (left, dl))
            };
            stack[top] = far;
            stack[top + 1] = near;
            top += 2;
        }
    }
}

impl BoxTree {
    /// The `indices.len()` nearest points of `q` (at most the tree's), nearest first, ties to
    /// the lower index — [`brute_force_nearest`]'s answer — with their squared distances in
    /// `dist2`; nothing is allocated (short lists are sorted in the outputs, long ones gathered
    /// in a per-thread buffer kept from call to call: [`SORTED_LIST_MAX`]).
    ///
    /// Depth first, the nearer child first, pruned by box distance against the k-th found so
    /// far. It replaced kiddo's `nearest_n` for the first query of every template point: at
    /// the start of a fit those points lie off the scan, where split-plane pruning visits a
    /// wide slab of leaves (paper-sized default: ~40,000 instructions a query, 4.6 % of the
    /// fit's instructions).
    pub fn nearest_k_into(&self, q: &[f64; 3], indices: &mut [u32], dist2: &mut [f64]) {
        let filled = self.nearest_k_within(q, f64::INFINITY, indices, dist2);
        debug_assert_eq!(filled, indices.len());
    }

    /// Like [`BoxTree::nearest_k_into`] among the points within squared distance `radius2` of
    /// `q` (nodes and points beyond it are never looked at); returns how many it found (the
    /// first that many outputs are written), which is `indices.len()` whenever that many
    /// points lie within the radius.
    pub fn nearest_k_within(
        &self,
        q: &[f64; 3],
        radius2: f64,
        indices: &mut [u32],
        dist2: &mut [f64],
    ) -> usize {
        let k = indices.len();
        assert!(k >= 1 && k <= self.entries.len() && dist2.len() == k);
        if k <= SORTED_LIST_MAX {
            self.nearest_k_sorted(q, radius2, indices, dist2)
        } else {
            self.nearest_k_gathered(q, radius2, indices, dist2)
        }
    }

    /// Visits, nearest leaves first, every point within squared distance `radius2` of `q` that
    /// comes before the bound (ties to the lower index), offering it to `offer`, which returns
    /// the new bound (the k-th found so far) when it has one.
    #[inline(always)]
    fn offer_nearest(
        &self,
        q: &[f64; 3],
        radius2: f64,
        mut offer: impl FnMut(f64, u32) -> Option<(f64, u32)>,
    ) {
        let mut worst = (radius2, u32::MAX);
        self.descend(q, radius2, |leaf| {
            for (p, id) in leaf {
                let d2 = squared_distance(p, q);
                if d2 > worst.0 || (d2 == worst.0 && *id > worst.1) {
                    continue;
                }
                if let Some(bound) = offer(d2, *id) {
                    worst = bound;
                }
            }
            worst.0
        });
    }

    /// [`BoxTree::nearest_k_within`] for long lists: the points that may belong are gathered
    /// unsorted and cut back to the k nearest by a selection each time 2k have come (amortized
    /// O(1) a point), then sorted once. The bound is the radius until k points are found, then
    /// the k-th of them, re-tightened at each cut.
    fn nearest_k_gathered(
        &self,
        q: &[f64; 3],
        radius2: f64,
        indices: &mut [u32],
        dist2: &mut [f64],
    ) -> usize {
        let k = indices.len();
        FOUND.with_borrow_mut(|found| {
            found.clear();
            // (squared distance's bits, index): for non-negative floats the bits order as the
            // values, so the tuples' own order is the answer's, ties to the lower index.
            self.offer_nearest(q, radius2, |d2, id| {
                found.push((d2.to_bits(), id));
                let kth = if found.len() == k {
                    found.iter().copied().max()
                } else if found.len() == 2 * k {
                    found.select_nth_unstable(k - 1);
                    found.truncate(k);
                    Some(found[k - 1])
                } else {
                    None
                };
                kth.map(|(bits, j)| (f64::from_bits(bits), j))
            });
            if found.len() > k {
                found.select_nth_unstable(k - 1);
                found.truncate(k);
            }
            found.sort_unstable();
            for (s, &(bits, j)) in found.iter().enumerate() {
                dist2[s] = f64::from_bits(bits);
                indices[s] = j;
            }
            found.len()
        })
    }

    /// [`BoxTree::nearest_k_within`] for short lists: a sorted insertion into the outputs (the
    /// leaves come nearest first, so most points enter near the end or not at all), the bound
    /// the radius until k are found, then the k-th.
    fn nearest_k_sorted(
        &self,
        q: &[f64; 3],
        radius2: f64,
        indices: &mut [u32],
        dist2: &mut [f64],
    ) -> usize {
        let k = indices.len();
        let mut filled = 0;
        self.offer_nearest(q, radius2, |d2, id| {
            // Insert into the sorted list, dropping its last when full.
            let mut slot = filled.min(k - 1);
            filled = (filled + 1).min(k);
            while slot > 0
                && (dist2[slot - 1] > d2 || (dist2[slot - 1] == d2 && indices[slot - 1] > id))
            {
                dist2[slot] = dist2[slot - 1];
                indices[slot] = indices[slot - 1];
                slot -= 1;
            }
            dist2[slot] = d2;
            indices[slot] = id;
            (filled == k).then(|| (dist2[k - 1], indices[k - 1]))
        });
        filled
    }
}

thread_local! {
    /// [`BoxTree::nearest_k_within`]'s gathered points, per thread (its capacity, at most 2k,
    /// is kept from call to call, so a search allocates nothing once warm).
    static FOUND: std::cell::RefCell<Vec<(u64, u32)>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The bounding box `(lo, hi)` of a [`BoxTree`]'s entries.
fn bounds(entries: &[([f64; 3], u32)]) -> ([f64; 3], [f64; 3]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (p, _) in entries {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

/// Builds the node `nodes[0]` (number `base` of the tree) over `entries` (which start at
/// `offset` in the tree's order), its subtrees after it.
fn build_box_node(
    entries: &mut [([f64; 3], u32)],
    offset: usize,
    nodes: &mut [BoxNode],
    base: usize,
) {
    let (lo, hi) = bounds(entries);
    let n = entries.len();
    let mut node = BoxNode {
        lo,
        hi,
        start: offset as u32,
        end: (offset + n) as u32,
        right: 0,
    };
    if n <= BOX_LEAF {
        nodes[0] = node;
        return;
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let half = n / 2;
    entries.select_nth_unstable_by(half, |a, b| a.0[axis].total_cmp(&b.0[axis]));
    let left_nodes = box_nodes(half);
    let right = base + 1 + left_nodes;
    node.right = right as u32;
    nodes[0] = node;
    let (left_part, right_part) = nodes[1..].split_at_mut(left_nodes);
    let (left_entries, right_entries) = entries.split_at_mut(half);
    let mut left = || build_box_node(left_entries, offset, left_part, base + 1);
    let mut right = || build_box_node(right_entries, offset + half, right_part, right);
    if n > 4096 {
        rayon::join(left, right);
    } else {
        left();
        right();
    }
}

/// Largest candidate set a [`NeighborCache`] keeps per query point.
pub const MAX_CACHED: usize = 192;

/// Exact re-use of earlier k-NN queries for points that moved little (SPEC §7, issue
/// "Performance").
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
    /// [`NeighborCache::set_slack`]): only then does [`ReverseNearest`] prune its tree
    /// searches by the lists' local radii (its global certificate applies either way).
    pub exact: bool,
}

/// The nearest template point of every scan point (the two-way attraction's query), derived
/// from the forward k-NN lists where that is provably exact (issue "Performance").
///
/// The forward lists give, for every template point v, its K nearest scan points and the
/// distance ρ_v of the K-th. A scan point x absent from v's list is at least ρ_v from v, so at
/// least `ρ_min = min_v ρ_v` from every template point that did not list it. Among the template
/// points that did list x, the nearest one (ties by index) is therefore x's nearest template
/// point whenever it is closer than ρ_min — the k-d tree's answer up to exactly tied distances.
/// Scan points without that certificate (none listed them, as when the template is still far
/// from the scan, or the nearest listing point is not close enough) are queried against a
/// [`BoxTree`] over the template, brought up to date ([`BoxTree::update`]: refitted, or rebuilt
/// when loose) only in iterations that need one.
/// Inverting the lists is one pass over M·K entries instead of N tree queries.
///
/// The same argument prunes those tree searches locally when the lists are exact: a template
/// point w lies at least min(ρ_w, d*) from x (d* the distance of x's nearest listing point,
/// ∞ when none lists it), so a tree node whose smallest ρ exceeds the best distance found
/// holds no closer point and is skipped ([`BoxTree::nearest_one_floored`]). The answer is the
/// same; on the million-point case the FoldMatch iterations' two-way stage took 6 % less time
/// (9.3 s against 9.9 s, two runs each). Under [`NeighborCache::set_slack`] the lists are
/// approximate and only the global certificate is used, as before.
#[derive(Clone, Debug, Default)]
pub struct ReverseNearest {
    /// Per scan point: the smallest squared distance from a template point listing it.
    best_d2: Vec<f64>,
    /// Over the template, for the scan points without a certificate.
    tree: BoxTree,
    /// Per scan point: its nearest template point of the last call (`u32::MAX`: none yet), a
    /// known distance to start the tree search from.
    last: Vec<u32>,
    /// Per template point: ρ², the squared distance of the K-th of its forward list.
    rho2: Vec<f64>,
    /// Per node of `tree`: the smallest ρ² of its points, less the round-off margin.
    floors: Vec<f64>,
}

impl ReverseNearest {
    /// Scratch for `n` scan points.
    pub fn new(n: usize) -> Self {
        Self {
            best_d2: vec![0.0; n],
            tree: BoxTree::default(),
            last: vec![u32::MAX; n],
            rho2: Vec::new(),
            floors: Vec::new(),
        }
    }

    /// Writes to `nearest[j]` the index of the template point (of `template`) nearest to
    /// `scan[j]`: from `forward`, the exact forward lists of these template positions, where
    /// certified, else (and without `forward`, for every scan point) from a tree over the
    /// template. Returns the number of scan points queried against the tree.
    pub fn query(
        &mut self,
        template: &[[f64; 3]],
        scan: &[[f64; 3]],
        forward: Option<TargetNeighbours<'_>>,
        nearest: &mut [u32],
    ) -> usize {
        assert_eq!(nearest.len(), scan.len());
        let local_floors = forward.is_some_and(|lists| lists.exact);
        let rho2_min = match forward {
            Some(lists) => self.invert(template.len(), lists, nearest),
            None => {
                self.best_d2.fill(f64::INFINITY);
                nearest.fill(u32::MAX);
                0.0
            }
        };
        // The margin keeps round-off from certifying a tie.
        let certified = |d2: f64| d2 < rho2_min * (1.0 - 1e-12);
        let fresh = self.best_d2.iter().filter(|&&d2| !certified(d2)).count();
        if fresh > 0 {
            self.tree.update(template);
            // The local certificate: a template point w that does not list x lies at least
            // ρ_w from it, one that does at least as far as x's nearest listing point; so a
            // node whose smallest ρ exceeds the best distance found holds no closer point.
            // Without them the plain search (the floors' extra work per node cost 1.3 % of the
            // paper-sized fit's instructions when they were all 0).
            if local_floors {
                self.tree.node_minima(&self.rho2, &mut self.floors);
                self.floors.iter_mut().for_each(|f| *f *= 1.0 - 1e-12);
            }
            let (tree, floors) = (&self.tree, &self.floors);
            // The search starts from a template point known to be that close: the nearest
            // listing one, else the last call's answer.
            nearest
                .par_iter_mut()
                .zip(self.best_d2.par_iter())
                .zip(scan.par_iter().zip(self.last.par_iter()))
                .filter(|((_, &d2), _)| !certified(d2))
                .for_each(|((n, &d2), (x, &last))| {
                    let known = if *n != u32::MAX {
                        (*n, d2)
                    } else if let Some(p) = template.get(last as usize) {
                        (last, squared_distance(p, x))
                    } else {
                        (u32::MAX, f64::INFINITY)
                    };
                    *n = if local_floors {
                        tree.nearest_one_floored(x, known, |at| floors[at as usize])
                            .0
                    } else {
                        tree.nearest_one_from(x, known).0
                    };
                });
        }
        self.last.copy_from_slice(nearest);
        fresh
    }

    /// The nearest listing template point of every scan point (`nearest`, its squared distance
    /// in `best_d2`; `u32::MAX` and ∞ where none lists it), and the smallest ρ² of the lists.
    fn invert(&mut self, m: usize, forward: TargetNeighbours<'_>, nearest: &mut [u32]) -> f64 {
        let TargetNeighbours {
            indices: forward_idx,
            dist2: forward_d2,
            k,
            ..
        } = forward;
        assert_eq!(forward_idx.len(), m * k);
        self.best_d2.fill(f64::INFINITY);
        nearest.fill(u32::MAX);
        // Template points in increasing order and a strict `<`: ties go to the lower index.
        for (v, (row_idx, row_d2)) in forward_idx
            .chunks_exact(k)
            .zip(forward_d2.chunks_exact(k))
            .enumerate()
        {
            for (&j, &d2) in row_idx.iter().zip(row_d2) {
                if d2 < self.best_d2[j as usize] {
                    self.best_d2[j as usize] = d2;
                    nearest[j as usize] = v as u32;
                }
            }
        }
        self.rho2.clear();
        self.rho2
            .extend(forward_d2.chunks_exact(k).map(|row| row[k - 1]));
        self.rho2.iter().copied().fold(f64::INFINITY, f64::min)
    }
}

/// The points in Morton (Z-curve) order of their bounding box, 21 bits per axis, ties by
/// index: an order in which points close in space are mostly close in memory.
///
/// The fit keeps the scan in this order (issue "Performance"): every stage reads scan points
/// through neighbour lists (the k-NN re-ranking, the forces, the inversion of the lists), and
/// spatially ordered lists touch a few cache lines instead of one per point. On a
/// 250,000-point scan in random order the fit took 17 % less wall time; the scan's order
/// changes the fit only by round-off (the sums run in another order; a test bounds it).
pub fn morton_order(points: &[[f64; 3]]) -> Vec<u32> {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    let cells = ((1u64 << 21) - 1) as f64;
    let scale = if extent > 0.0 { cells / extent } else { 0.0 };
    // Spreads the low 21 bits of x to every third bit.
    let spread = |x: u64| {
        let mut x = x & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        (x | x << 2) & 0x1249_2492_4924_9249
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let cell = |a: usize| (((p[a] - lo[a]) * scale) as u64).min(cells as u64);
            (
                spread(cell(0)) | spread(cell(1)) << 1 | spread(cell(2)) << 2,
                i as u32,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
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
    fn slack_gives_approximate_neighbours_within_the_bound_and_fewer_queries() {
        // Queries descending onto a noisy plane of points from far above, as template
        // vertices do in the rigid and coarse phases.
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        let pts: Vec<[f64; 3]> = (0..4000)
            .map(|_| [rng.random(), rng.random(), 0.01 * rng.random::<f64>()])
            .collect();
        let start: Vec<[f64; 3]> = (0..300)
            .map(|_| [rng.random(), rng.random(), 0.3 + 0.1 * rng.random::<f64>()])
            .collect();
        let index = PointIndex::new(&pts);
        let (k, m) = (16, start.len());
        let mut fresh_total = [0usize; 2];
        for (run, slack) in [0.0, 0.3].into_iter().enumerate() {
            let mut queries = start.clone();
            let mut cache = NeighborCache::new(m, k, pts.len());
            cache.set_slack(slack);
            let (mut ci, mut cd) = (vec![0; m * k], vec![0.0; m * k]);
            let (mut fi, mut fd) = (vec![0; m * k], vec![0.0; m * k]);
            for step in 0..40 {
                fresh_total[run] += cache.query(&index, &queries, &mut ci, &mut cd);
                index.nearest_all(&queries, k, &mut fi, &mut fd);
                for (q, query) in queries.iter().enumerate() {
                    let row = q * k..(q + 1) * k;
                    let true_kth = fd[row.end - 1].sqrt();
                    for s in row.clone() {
                        // The distances reported are the returned points' own, nearest first.
                        let own = squared_distance(query, index.point(ci[s]));
                        assert_eq!(cd[s], own);
                        assert!(s == row.start || cd[s - 1] <= cd[s]);
                        assert!(
                            cd[s].sqrt() <= (1.0 + slack) * true_kth * (1.0 + 1e-12),
                            "step {step}, query {q}: {} beyond (1 + {slack}) × {true_kth}",
                            cd[s].sqrt()
                        );
                    }
                    if slack == 0.0 {
                        assert_eq!(ci[row.clone()], fi[row.clone()], "step {step}");
                    }
                }
                for q in &mut queries {
                    q[2] *= 0.93; // descend
                    q[0] += 0.003 * (rng.random::<f64>() - 0.5);
                }
            }
        }
        assert!(
            2 * fresh_total[1] < fresh_total[0],
            "slack should spare most far re-queries: {fresh_total:?}"
        );
    }

    #[test]
    fn reverse_nearest_equals_the_tree_and_inverts_most_queries() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        // A noisy scan of the unit square, and a template hovering over it, ever closer.
        let scan: Vec<[f64; 3]> = (0..6000)
            .map(|_| [rng.random(), rng.random(), 0.01 * rng.random::<f64>()])
            .collect();
        let side = 30;
        let index = PointIndex::new(&scan);
        // K covering a few template spacings of scan points, as ρ·N does in a fit.
        let k = 32;
        let mut reverse = ReverseNearest::new(scan.len());
        let mut got = vec![0; scan.len()];
        let mut certified = Vec::new();
        for height in [0.5, 0.05, 0.01, 0.0] {
            let template: Vec<[f64; 3]> = (0..side * side)
                .map(|i| {
                    let (x, y) = ((i % side) as f64, (i / side) as f64);
                    let jitter = 0.3 * (rng.random::<f64>() - 0.5);
                    [
                        (x + 0.5 + jitter) / side as f64,
                        (y + 0.5) / side as f64,
                        height,
                    ]
                })
                .collect();
            let mut idx = vec![0; template.len() * k];
            let mut d2 = vec![0.0; template.len() * k];
            index.nearest_all(&template, k, &mut idx, &mut d2);
            let lists = TargetNeighbours {
                indices: &idx,
                dist2: &d2,
                k,
                exact: true,
            };
            let fresh = reverse.query(&template, &scan, Some(lists), &mut got);
            let mut from_tree = vec![0; scan.len()];
            assert_eq!(
                reverse.query(&template, &scan, None, &mut from_tree),
                scan.len()
            );
            assert_eq!(from_tree, got, "height {height}: the tree alone");
            let tree = PointIndex::new(&template);
            for (j, x) in scan.iter().enumerate() {
                let (want, want_d2) = brute_force_nearest(&template, x, 1);
                assert_eq!(got[j], want[0], "height {height}, scan point {j}");
                assert_eq!(tree.nearest_one(x), (want[0], want_d2[0]));
            }
            certified.push(scan.len() - fresh);
        }
        // The exactness above covers both paths; on the scan most queries are certified.
        assert!(
            certified[0] < certified[3] && certified[3] > 3 * scan.len() / 4,
            "{certified:?}"
        );
    }

    #[test]
    fn box_tree_equals_brute_force_near_and_far() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        // A flat patch with duplicated points (ties go to the lower index), queried on it and
        // from far above it, as the two-way attraction's scan points query the template.
        let mut pts: Vec<[f64; 3]> = (0..1500)
            .map(|_| [rng.random(), rng.random(), 0.001 * rng.random::<f64>()])
            .collect();
        pts.extend_from_within(100..140);
        let mut tree = BoxTree::default();
        for round in 0..2 {
            tree.rebuild(&pts[..pts.len() - 300 * round]);
            let live = &pts[..pts.len() - 300 * round];
            for (i, height) in (0..400).map(|i| (i, [0.0, 0.01, 0.3, 5.0][i % 4])) {
                let q = if i % 7 == 0 {
                    live[i % 1200]
                } else {
                    [rng.random(), rng.random(), height]
                };
                let (want, want_d2) = brute_force_nearest(live, &q, 1);
                assert_eq!(tree.nearest_one(&q), (want[0], want_d2[0]), "query {q:?}");
                // Started from any point at its distance (here: one of the 40 duplicates).
                let p = live[120];
                let known = (120, squared_distance(&p, &q));
                assert_eq!(tree.nearest_one_from(&q, known), (want[0], want_d2[0]));
                // The k nearest, in order, ties (the 40 duplicates) to the lower index, by
                // sorted insertion (30) and by gathering (150 > SORTED_LIST_MAX).
                for k in [30, 150] {
                    let (near, near_d2) = brute_force_nearest(live, &q, k);
                    let (mut got, mut got_d2) = (vec![0; k], vec![0.0; k]);
                    tree.nearest_k_into(&q, &mut got, &mut got_d2);
                    assert_eq!((&got, &got_d2), (&near, &near_d2), "query {q:?}, k {k}");
                    // Within the k-th distance: the same k; within less, fewer than k.
                    let (mut ball, mut ball_d2) = (vec![0; k], vec![0.0; k]);
                    assert_eq!(
                        tree.nearest_k_within(&q, near_d2[k - 1], &mut ball, &mut ball_d2),
                        k
                    );
                    assert_eq!((&ball, &ball_d2), (&near, &near_d2), "query {q:?}, k {k}");
                    let less = near_d2[k - 1] * (1.0 - 1e-9);
                    let short = tree.nearest_k_within(&q, less, &mut ball, &mut ball_d2);
                    let closer = near_d2.iter().filter(|&&d| d <= less).count();
                    assert_eq!(short, closer);
                    assert_eq!(&ball[..short], &near[..short]);
                }
            }
        }
        // One point, and points in one spot (k = all of them: ties in index order).
        tree.rebuild(&[[1.0, 2.0, 3.0]]);
        assert_eq!(tree.nearest_one(&[0.0; 3]), (0, 14.0));
        for n in [20, 150] {
            tree.rebuild(&vec![[0.5; 3]; n]);
            assert_eq!(tree.nearest_one(&[0.0; 3]).0, 0);
            let (mut all, mut all_d2) = (vec![0; n], vec![0.0; n]);
            tree.nearest_k_into(&[0.0; 3], &mut all, &mut all_d2);
            assert_eq!(all, (0..n as u32).collect::<Vec<u32>>());
            assert!(all_d2.iter().all(|&d| d == 0.75));
        }
    }

    #[test]
    fn box_tree_refit_answers_like_brute_force_and_update_rebuilds_when_loose() {
        // A flat 40 × 40 grid, then the same points rolled up around the y axis (a fold that
        // brings x = 0 and x = 1 together), then scattered at random (the worst motion for a
        // kept grouping): a refitted tree keeps the flat grid's grouping and must still answer
        // exactly, ties to the lower index included.
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let flat: Vec<[f64; 3]> = (0..1600)
            .map(|i| [(i % 40) as f64 / 39.0, (i / 40) as f64 / 39.0, 0.0])
            .collect();
        let rolled = |t: f64| -> Vec<[f64; 3]> {
            let r = 1.0 / (t * std::f64::consts::TAU);
            flat.iter()
                .map(|p| {
                    let angle = t * std::f64::consts::TAU * p[0];
                    [r * angle.sin(), p[1], r * (1.0 - angle.cos())]
                })
                .collect()
        };
        let scattered: Vec<[f64; 3]> = (0..flat.len())
            .map(|_| [rng.random(), rng.random(), rng.random()])
            .collect();
        let mut refitted = BoxTree::default();
        refitted.rebuild(&flat);
        let mut updated = refitted.clone();
        let mut rebuilt = BoxTree::default();
        // Rolling bends the flat grid's leaves but keeps them compact (an isometry): refitted;
        // scattering pulls every leaf apart: rebuilt.
        for (moved, expect_loose) in [
            (rolled(0.5), false),
            (rolled(0.95), false),
            (scattered, true),
        ] {
            refitted.refit(&moved);
            let loose = refitted.looseness() > REBUILD_LOOSENESS * refitted.built_looseness;
            updated.update(&moved);
            rebuilt.rebuild(&moved);
            for i in 0..300 {
                let q = if i % 5 == 0 {
                    moved[(i * 7) % moved.len()]
                } else {
                    [
                        rng.random_range(-0.5..1.2),
                        rng.random(),
                        rng.random_range(-0.2..0.6),
                    ]
                };
                let (want, want_d2) = brute_force_nearest(&moved, &q, 1);
                for tree in [&refitted, &updated, &rebuilt] {
                    assert_eq!(tree.nearest_one(&q), (want[0], want_d2[0]), "{q:?}");
                }
            }
            assert_eq!(loose, expect_loose);
            assert!(updated.looseness() <= REBUILD_LOOSENESS * updated.built_looseness);
        }
        assert!(refitted.looseness() > 5.0 * refitted.built_looseness);
        // A translation and a uniform scale keep the looseness: no rebuild needed.
        let mut tree = BoxTree::default();
        tree.rebuild(&flat);
        let scaled: Vec<[f64; 3]> = flat
            .iter()
            .map(|p| [3.0 * p[0] + 1.0, 3.0 * p[1], 2.0])
            .collect();
        tree.refit(&scaled);
        assert!((tree.looseness() - tree.built_looseness).abs() < 1e-12 * tree.built_looseness);
    }

    #[test]
    fn morton_order_is_a_permutation_that_keeps_neighbours_close() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let pts: Vec<[f64; 3]> = (0..4000)
            .map(|_| [rng.random(), rng.random(), 0.1 * rng.random::<f64>()])
            .collect();
        let order = morton_order(&pts);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(i, &j)| i as u32 == j));
        // Consecutive points in the order are far closer than in the given (random) order.
        let step = |o: &[u32]| {
            o.windows(2)
                .map(|w| {
                    let (a, b) = (pts[w[0] as usize], pts[w[1] as usize]);
                    squared_distance(&a, &b).sqrt()
                })
                .sum::<f64>()
                / (o.len() - 1) as f64
        };
        let given: Vec<u32> = (0..pts.len() as u32).collect();
        assert!(
            step(&order) * 5.0 < step(&given),
            "{} vs {}",
            step(&order),
            step(&given)
        );
        // One point, and equal points (ties by index).
        assert_eq!(morton_order(&[[0.0; 3]]), vec![0]);
        assert_eq!(morton_order(&[[1.0; 3]; 3]), vec![0, 1, 2]);
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
