//! The k-d tree with a tight bounding box per node ([`BoxTree`]): the k-NN queries over the
//! scan and the nearest-template-point queries of the two-way attraction.

use super::squared_distance;

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
/// [`BoxTree::update`]) and for the k-NN queries over the scan ([`PointIndex`](super::PointIndex)).
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
/// array. Ties go to the lower index, as in [`brute_force_nearest`](super::brute_force_nearest).
#[derive(Clone, Debug, Default)]
pub struct BoxTree {
    /// The points in tree order, with their indices.
    entries: Vec<([f64; 3], u32)>,
    nodes: Vec<BoxNode>,
    /// [`BoxTree::looseness`] right after the last rebuild.
    pub(super) built_looseness: f64,
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
    pub(super) fn looseness(&self) -> f64 {
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
    /// skipped (the two-way attraction's local certificate, [`ReverseNearest`](super::ReverseNearest)). With floors
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
    /// the lower index — [`brute_force_nearest`](super::brute_force_nearest)'s answer — with their squared distances in
    /// `dist2`; nothing is allocated (short lists are sorted in the outputs, long ones gathered
    /// in a per-thread buffer kept from call to call: `SORTED_LIST_MAX`).
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
