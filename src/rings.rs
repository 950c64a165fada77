//! Template neighborhoods Γᵏ_Y (paper §3, Fig. 2; docs/method.md "Template neighborhoods Γᵏ_Y"):
//! the vertices within graph distance n (the "n-ring") of every template vertex, including the
//! vertex itself, in CSR form, computed once per fit. β_j = 1/|Γᵏ_Y| weighs each member equally.

use crate::math::vec3;
use rayon::prelude::*;

/// Neighborhoods in compressed sparse row form: members of vertex k are
/// `members[offsets[k]..offsets[k + 1]]`, the vertex itself first, then the others in
/// breadth-first order (ties by index).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Neighborhoods {
    /// Row offsets, length M + 1.
    pub offsets: Vec<usize>,
    /// Concatenated member lists.
    pub members: Vec<u32>,
}

impl Neighborhoods {
    /// Number of vertices (rows).
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Members of vertex `k` (k itself first).
    #[inline]
    pub fn of(&self, k: usize) -> &[u32] {
        &self.members[self.offsets[k]..self.offsets[k + 1]]
    }

    /// Builds `n` CSR rows from `(row, member)` pairs, each row's members in the order the
    /// pairs give them (a counting sort: no list per row). `pairs` is called twice (count, fill).
    pub fn from_pairs<I: Iterator<Item = (u32, u32)>>(n: usize, pairs: impl Fn() -> I) -> Self {
        let mut offsets = vec![0usize; n + 1];
        for (row, _) in pairs() {
            offsets[row as usize + 1] += 1;
        }
        for v in 0..n {
            offsets[v + 1] += offsets[v];
        }
        let mut filled = offsets.clone();
        let mut members = vec![0u32; offsets[n]];
        for (row, member) in pairs() {
            members[filled[row as usize]] = member;
            filled[row as usize] += 1;
        }
        Self { offsets, members }
    }

    /// Builds CSR rows from per-vertex lists.
    pub fn from_rows(rows: Vec<Vec<u32>>) -> Self {
        let mut offsets = Vec::with_capacity(rows.len() + 1);
        offsets.push(0);
        let mut members = Vec::with_capacity(rows.iter().map(Vec::len).sum());
        for r in rows {
            members.extend_from_slice(&r);
            offsets.push(members.len());
        }
        Self { offsets, members }
    }
}

/// The length in `points` of every edge of `ring`, in the order of `ring.members` (the edge
/// from vertex v to each member of its row).
pub fn ring_lengths(ring: &Neighborhoods, points: &[[f64; 3]]) -> Vec<f64> {
    (0..ring.len())
        .flat_map(|v| {
            ring.of(v)
                .iter()
                .map(move |&u| (vec3(&points[v]) - vec3(&points[u as usize])).norm())
        })
        .collect()
}

/// Vertex adjacency (one-ring) of a triangle mesh in CSR form, sorted, without duplicates.
/// Built in place (counted, filled, each row sorted and deduplicated, then compacted): no list
/// per vertex.
pub fn adjacency(faces: &[[u32; 3]], n_vertices: usize) -> Neighborhoods {
    let Neighborhoods {
        offsets: start,
        mut members,
    } = Neighborhoods::from_pairs(n_vertices, || {
        faces
            .iter()
            .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
            .filter(|(a, b)| a != b)
            .flat_map(|(a, b)| [(a, b), (b, a)])
    });
    // Sort and deduplicate every row where it lies, then move the rows down over the gaps.
    let mut offsets = Vec::with_capacity(n_vertices + 1);
    offsets.push(0);
    let mut end = 0;
    for v in 0..n_vertices {
        let row = &mut members[start[v]..start[v + 1]];
        row.sort_unstable();
        let mut kept = 0;
        for i in 0..row.len() {
            if i == 0 || row[i] != row[kept - 1] {
                row[kept] = row[i];
                kept += 1;
            }
        }
        members.copy_within(start[v]..start[v] + kept, end);
        end += kept;
        offsets.push(end);
    }
    members.truncate(end);
    Neighborhoods { offsets, members }
}

/// The n-ring neighborhoods of every vertex: all vertices at graph distance ≤ `rings`
/// (including the vertex itself), by a bounded breadth-first search from each vertex.
pub fn n_rings(faces: &[[u32; 3]], n_vertices: usize, rings: usize) -> Neighborhoods {
    n_rings_of(&adjacency(faces, n_vertices), rings)
}

/// Vertices per parallel task of [`n_rings_of`].
const RING_CHUNK: usize = 256;

/// [`n_rings`] from the one-rings `adjacency` ([`adjacency`]'s), so that a caller building
/// several ring sizes builds the adjacency once. Each task appends its vertices' rows to one
/// buffer (no list per vertex; the 8-rings of the paper-sized template, 2.7M members, were
/// 13,225 growing lists and a copy), and the buffers are concatenated in vertex order.
pub fn n_rings_of(adjacency: &Neighborhoods, rings: usize) -> Neighborhoods {
    let m = adjacency.len();
    let chunks: Vec<(Vec<u32>, Vec<usize>)> = (0..m.div_ceil(RING_CHUNK))
        .into_par_iter()
        .map_init(
            || Visited::new(m),
            |visited, c| {
                let (lo, hi) = (c * RING_CHUNK, ((c + 1) * RING_CHUNK).min(m));
                let mut members = Vec::new();
                let mut ends = Vec::with_capacity(hi - lo);
                for v in lo..hi {
                    bfs_ring(adjacency, v as u32, rings, visited, &mut members);
                    ends.push(members.len());
                }
                (members, ends)
            },
        )
        .collect();
    let mut offsets = Vec::with_capacity(m + 1);
    offsets.push(0);
    let mut base = 0;
    for (chunk, ends) in &chunks {
        offsets.extend(ends.iter().map(|e| base + e));
        base += chunk.len();
    }
    // The chunks copied into place in parallel (the 12-rings of the paper-sized template are
    // 5.6M members: a serial copy was a fifth of their build).
    let mut members = vec![0u32; base];
    let mut places: Vec<&mut [u32]> = Vec::with_capacity(chunks.len());
    let mut rest = &mut members[..];
    for (chunk, _) in &chunks {
        let (place, tail) = rest.split_at_mut(chunk.len());
        places.push(place);
        rest = tail;
    }
    places
        .into_par_iter()
        .zip(chunks.par_iter())
        .for_each(|(place, (chunk, _))| place.copy_from_slice(chunk));
    Neighborhoods { offsets, members }
}

/// Per-thread "seen" marks of a breadth-first search: vertex `v` was seen in the current search
/// when `stamp[v] == search`, so starting a search is O(1), not O(M).
struct Visited {
    stamp: Vec<u32>,
    search: u32,
}

impl Visited {
    fn new(n: usize) -> Self {
        Self {
            stamp: vec![0; n],
            search: 0,
        }
    }

    /// Starts a new search (clearing every mark).
    fn clear(&mut self) {
        self.search = self.search.wrapping_add(1);
        if self.search == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.search = 1;
        }
    }

    /// Starts a new search with exactly `members` marked.
    fn mark_all(&mut self, members: &[u32]) {
        self.clear();
        for &x in members {
            self.insert(x);
        }
    }

    /// Whether `v` is marked.
    #[inline]
    fn contains(&self, v: u32) -> bool {
        self.stamp[v as usize] == self.search
    }

    /// Marks `v`; returns whether it was unmarked.
    #[inline]
    fn insert(&mut self, v: u32) -> bool {
        let seen = &mut self.stamp[v as usize];
        let new = *seen != self.search;
        *seen = self.search;
        new
    }
}

/// Bounded BFS from `start`, appending the visited set to `out` in BFS order (each ring sorted
/// by index).
fn bfs_ring(
    adj: &Neighborhoods,
    start: u32,
    rings: usize,
    visited: &mut Visited,
    out: &mut Vec<u32>,
) {
    visited.clear();
    visited.insert(start);
    let base = out.len();
    out.push(start);
    let mut frontier_start = base;
    for _ in 0..rings {
        let frontier_end = out.len();
        if frontier_start == frontier_end {
            break;
        }
        for i in frontier_start..frontier_end {
            for &nb in adj.of(out[i] as usize) {
                if visited.insert(nb) {
                    out.push(nb);
                }
            }
        }
        out[frontier_end..].sort_unstable();
        frontier_start = frontier_end;
    }
}

/// Consecutive vertices whose neighborhood sums [`RingDeltas`] evaluates in order (one block
/// per parallel task; a row derives only from an earlier row of its own block).
pub const DELTA_BLOCK: usize = 512;

/// Longest chain of rows derived from rows derived from …: every such step adds the
/// round-off of its few terms, so a chain restarts from a direct sum after this many.
pub const MAX_DELTA_CHAIN: u8 = 32;

/// Sums over large neighborhoods by differences (the coarse phase's 8-rings, issue
/// "Performance"): the row of vertex v is the row of an adjacent earlier vertex p of its block
/// plus the members of v's row that p's lacks, minus those p's has and v's lacks. Adjacent
/// 8-rings share most of their members (about 35 of 145 differ on a grid), so
/// `Σ_{row v} x = Σ_{row p} x + Σ_{added} x − Σ_{removed} x` reads a quarter of the values.
/// A row with no such parent, or one that differs from it in half its members or more, is
/// summed directly; chains are at most [`MAX_DELTA_CHAIN`] long. The sums equal the direct
/// ones to round-off (a few ulps of the row's magnitude per step).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RingDeltas {
    /// Per vertex: the vertex its row derives from (`u32::MAX`: summed directly).
    parent: Vec<u32>,
    /// Per vertex: `members[offsets[v]..split[v]]` to add, `members[split[v]..offsets[v+1]]`
    /// to remove.
    offsets: Vec<usize>,
    split: Vec<usize>,
    members: Vec<u32>,
}

impl RingDeltas {
    /// The differences of `rings` (rows of any order, no member repeated) between
    /// mesh-adjacent vertices (`adjacency`, [`adjacency`]'s one-rings).
    ///
    /// Set operations by per-thread marks (`Visited`): a row's members are marked once and
    /// each candidate parent's row is counted against the marks, and only the chosen parent's
    /// two difference lists are sorted (sorting every row and merging it with each candidate's
    /// took 24 ms of the paper-sized fit's setup, 2 threads; the lists are the same).
    pub fn new(rings: &Neighborhoods, adjacency: &Neighborhoods) -> Self {
        let m = rings.len();
        // Per block, in order: each vertex's parent (the adjacent earlier vertex of the block,
        // below the chain limit, with the fewest differing members, ties to the lower index)
        // and its two lists, appended to the block's buffer.
        struct Block {
            parent: Vec<u32>,
            members: Vec<u32>,
            /// Per vertex: where its removals start and where its row ends in `members`.
            split_end: Vec<(usize, usize)>,
        }
        let blocks: Vec<Block> = (0..m.div_ceil(DELTA_BLOCK))
            .into_par_iter()
            .map_init(
                || (Visited::new(m), Visited::new(m)),
                |(in_row, in_parent), b| {
                    let start = b * DELTA_BLOCK;
                    let end = (start + DELTA_BLOCK).min(m);
                    let mut depth = vec![0u8; end - start];
                    let mut block = Block {
                        parent: Vec::with_capacity(end - start),
                        members: Vec::new(),
                        split_end: Vec::with_capacity(end - start),
                    };
                    for v in start..end {
                        let row = rings.of(v);
                        in_row.mark_all(row);
                        let best = adjacency
                            .of(v)
                            .iter()
                            .map(|&u| u as usize)
                            .filter(|&u| u >= start && u < v && depth[u - start] < MAX_DELTA_CHAIN)
                            .map(|u| {
                                let other = rings.of(u);
                                let common = other.iter().filter(|&&x| in_row.contains(x)).count();
                                (row.len() + other.len() - 2 * common, u)
                            })
                            .min();
                        match best {
                            Some((cost, u)) if 2 * cost < row.len() => {
                                depth[v - start] = depth[u - start] + 1;
                                let other = rings.of(u);
                                in_parent.mark_all(other);
                                let from = block.members.len();
                                block
                                    .members
                                    .extend(row.iter().filter(|&&x| !in_parent.contains(x)));
                                block.members[from..].sort_unstable();
                                let split = block.members.len();
                                block
                                    .members
                                    .extend(other.iter().filter(|&&x| !in_row.contains(x)));
                                block.members[split..].sort_unstable();
                                block.parent.push(u as u32);
                                block.split_end.push((split, block.members.len()));
                            }
                            _ => {
                                let at = block.members.len();
                                block.parent.push(u32::MAX);
                                block.split_end.push((at, at));
                            }
                        }
                    }
                    block
                },
            )
            .collect();
        let mut out = Self {
            parent: Vec::with_capacity(m),
            offsets: Vec::with_capacity(m + 1),
            split: Vec::with_capacity(m),
            members: Vec::with_capacity(blocks.iter().map(|b| b.members.len()).sum()),
        };
        out.offsets.push(0);
        for block in blocks {
            let base = out.members.len();
            out.members.extend_from_slice(&block.members);
            out.parent.extend_from_slice(&block.parent);
            for (split, end) in block.split_end {
                out.split.push(base + split);
                out.offsets.push(base + end);
            }
        }
        out
    }

    /// `sums[v] = Σ_{u ∈ rings.of(v)} values[u]` for every vertex (the rows these deltas were
    /// built from), block by block in parallel, each block in order.
    pub fn sums<const W: usize>(
        &self,
        rings: &Neighborhoods,
        values: &[[f64; W]],
        sums: &mut [[f64; W]],
    ) {
        assert_eq!(sums.len(), self.parent.len());
        let add = |s: &mut [f64; W], x: &[f64; W]| s.iter_mut().zip(x).for_each(|(a, b)| *a += b);
        let sub = |s: &mut [f64; W], x: &[f64; W]| s.iter_mut().zip(x).for_each(|(a, b)| *a -= b);
        sums.par_chunks_mut(DELTA_BLOCK)
            .enumerate()
            .for_each(|(b, block)| {
                let start = b * DELTA_BLOCK;
                for i in 0..block.len() {
                    let v = start + i;
                    let mut s = match self.parent[v] {
                        u32::MAX => {
                            let mut s = [0.0; W];
                            rings
                                .of(v)
                                .iter()
                                .for_each(|&u| add(&mut s, &values[u as usize]));
                            s
                        }
                        p => block[p as usize - start],
                    };
                    let (lo, mid, hi) = (self.offsets[v], self.split[v], self.offsets[v + 1]);
                    self.members[lo..mid]
                        .iter()
                        .for_each(|&u| add(&mut s, &values[u as usize]));
                    self.members[mid..hi]
                        .iter()
                        .for_each(|&u| sub(&mut s, &values[u as usize]));
                    block[i] = s;
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::{HashSet, VecDeque};

    /// Independent reference: the graph distances from every vertex, by a full BFS.
    fn distances(faces: &[[u32; 3]], n: usize) -> Vec<Vec<usize>> {
        let adj = adjacency(faces, n);
        (0..n)
            .map(|s| {
                let mut dist = vec![usize::MAX; n];
                dist[s] = 0;
                let mut q = VecDeque::from([s]);
                while let Some(u) = q.pop_front() {
                    for &v in adj.of(u) {
                        if dist[v as usize] == usize::MAX {
                            dist[v as usize] = dist[u] + 1;
                            q.push_back(v as usize);
                        }
                    }
                }
                dist
            })
            .collect()
    }

    fn grid(w: usize, h: usize) -> Vec<[u32; 3]> {
        let mut f = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let a = (y * w + x) as u32;
                let (b, c, d) = (a + 1, a + w as u32, a + w as u32 + 1);
                f.push([a, b, d]);
                f.push([a, d, c]);
            }
        }
        f
    }

    #[test]
    fn adjacency_is_every_mesh_neighbour_once_in_order() {
        // A grid, a face given twice (either winding), a degenerate face and an isolated vertex.
        let mut faces = grid(6, 5);
        faces.push(faces[3]);
        faces.push([faces[7][0], faces[7][2], faces[7][1]]);
        faces.push([4, 4, 9]);
        let n = 30 + 1;
        let adj = adjacency(&faces, n);
        for v in 0..n as u32 {
            let mut want: Vec<u32> = faces
                .iter()
                .filter(|f| f.contains(&v))
                .flat_map(|f| f.iter().copied())
                .filter(|&u| u != v)
                .collect();
            want.sort_unstable();
            want.dedup();
            assert_eq!(adj.of(v as usize), &want[..], "vertex {v}");
        }
        assert!(adj.of(30).is_empty());
        assert_eq!(adj.members.len(), *adj.offsets.last().unwrap());
    }

    #[test]
    fn rings_equal_bfs_reference() {
        let faces = grid(9, 7);
        let n = 63 + 1; // one isolated vertex
        let dist = distances(&faces, n);
        for rings in 1..=4 {
            let nb = n_rings(&faces, n, rings);
            for (k, d) in dist.iter().enumerate() {
                let want: HashSet<u32> =
                    (0..n as u32).filter(|&v| d[v as usize] <= rings).collect();
                let got: HashSet<u32> = nb.of(k).iter().copied().collect();
                assert_eq!(got.len(), nb.of(k).len(), "no duplicates");
                assert_eq!(got, want, "vertex {k}, {rings}-ring");
                // The documented order (sums over a ring depend on it): by graph distance,
                // then by index — so the vertex itself first.
                let key = |&v: &u32| (d[v as usize], v);
                assert!(
                    nb.of(k).windows(2).all(|w| key(&w[0]) < key(&w[1])),
                    "vertex {k}"
                );
                assert_eq!(nb.of(k)[0], k as u32);
            }
        }
        assert_eq!(n_rings(&faces, n, 2).of(63), &[63]);
    }

    /// The parents and lists of [`RingDeltas::new`] by the earlier method (every row sorted,
    /// each candidate merged with it): the reference its marks must reproduce exactly.
    fn reference_deltas(rings: &Neighborhoods, adjacency: &Neighborhoods) -> RingDeltas {
        let m = rings.len();
        let sorted: Vec<Vec<u32>> = (0..m)
            .map(|v| {
                let mut row = rings.of(v).to_vec();
                row.sort_unstable();
                row
            })
            .collect();
        let mut out = RingDeltas {
            offsets: vec![0],
            ..Default::default()
        };
        let mut depth = vec![0u8; m];
        for v in 0..m {
            let start = v / DELTA_BLOCK * DELTA_BLOCK;
            let row = &sorted[v];
            let best = adjacency
                .of(v)
                .iter()
                .map(|&u| u as usize)
                .filter(|&u| u >= start && u < v && depth[u] < MAX_DELTA_CHAIN)
                .map(|u| (symmetric_difference_len(row, &sorted[u]), u))
                .min();
            let (parent, add, remove) = match best {
                Some((cost, u)) if 2 * cost < row.len() => {
                    depth[v] = depth[u] + 1;
                    let (add, remove) = differences(row, &sorted[u]);
                    (u as u32, add, remove)
                }
                _ => (u32::MAX, Vec::new(), Vec::new()),
            };
            out.parent.push(parent);
            out.members.extend_from_slice(&add);
            out.split.push(out.members.len());
            out.members.extend_from_slice(&remove);
            out.offsets.push(out.members.len());
        }
        out
    }

    /// `|a Δ b|` of two sorted lists.
    fn symmetric_difference_len(a: &[u32], b: &[u32]) -> usize {
        let (mut i, mut j, mut common) = (0, 0, 0);
        while i < a.len() && j < b.len() {
            match a[i].cmp(&b[j]) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    common += 1;
                    i += 1;
                    j += 1;
                }
            }
        }
        a.len() + b.len() - 2 * common
    }

    /// `(a \ b, b \ a)` of two sorted lists.
    fn differences(a: &[u32], b: &[u32]) -> (Vec<u32>, Vec<u32>) {
        let (mut only_a, mut only_b) = (Vec::new(), Vec::new());
        let (mut i, mut j) = (0, 0);
        while i < a.len() || j < b.len() {
            match (a.get(i), b.get(j)) {
                (Some(x), Some(y)) if x == y => {
                    i += 1;
                    j += 1;
                }
                (Some(x), Some(y)) if x < y => {
                    only_a.push(*x);
                    i += 1;
                }
                (Some(x), None) => {
                    only_a.push(*x);
                    i += 1;
                }
                (_, Some(y)) => {
                    only_b.push(*y);
                    j += 1;
                }
                (None, None) => unreachable!(),
            }
        }
        (only_a, only_b)
    }

    /// Rows of `deltas` summed directly (no parent), and the values read per evaluation (the
    /// direct rows' members and every delta) as a fraction of direct sums' reads.
    fn direct_rows_and_read_ratio(deltas: &RingDeltas, rings: &Neighborhoods) -> (usize, f64) {
        let direct: Vec<usize> = (0..deltas.parent.len())
            .filter(|&v| deltas.parent[v] == u32::MAX)
            .collect();
        let reads: usize =
            direct.iter().map(|&v| rings.of(v).len()).sum::<usize>() + deltas.members.len();
        (direct.len(), reads as f64 / rings.members.len() as f64)
    }

    #[test]
    fn ring_deltas_sum_like_the_rows_and_read_less() {
        // 8-rings of a 60 × 40 grid (several blocks), and 3-rings of a shuffled-index mesh
        // (parents only where the new order keeps neighbours in one block).
        let (w, h) = (60, 40);
        let n = w * h;
        let values: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let x = i as f64;
                [0.3 + (0.37 * x).sin(), (0.11 * x).cos() - 0.2, 1e-3 * x]
            })
            .collect();
        let check = |faces: &[[u32; 3]], rings: usize| {
            let (nb, adj) = (n_rings(faces, n, rings), adjacency(faces, n));
            let deltas = RingDeltas::new(&nb, &adj);
            assert_eq!(deltas, reference_deltas(&nb, &adj));
            let mut sums = vec![[0.0; 3]; n];
            deltas.sums(&nb, &values, &mut sums);
            for (v, s) in sums.iter().enumerate() {
                let mut want = [0.0; 3];
                for &u in nb.of(v) {
                    (0..3).for_each(|a| want[a] += values[u as usize][a]);
                }
                for a in 0..3 {
                    assert!(
                        (s[a] - want[a]).abs() < 1e-12 * nb.of(v).len() as f64,
                        "{v}"
                    );
                }
            }
            let (direct, ratio) = direct_rows_and_read_ratio(&deltas, &nb);
            (ratio, direct)
        };
        let (ratio, direct) = check(&grid(w, h), 8);
        assert!(ratio < 0.4, "read {ratio} of the members");
        // Rows of any order: the same sets with their members reversed.
        let nb = n_rings(&grid(w, h), n, 8);
        let reversed = Neighborhoods::from_rows(
            (0..n)
                .map(|v| nb.of(v).iter().rev().copied().collect())
                .collect(),
        );
        let adj = adjacency(&grid(w, h), n);
        assert_eq!(
            RingDeltas::new(&reversed, &adj),
            reference_deltas(&reversed, &adj)
        );
        // Block starts, chain restarts and the boundary rows are the direct ones.
        assert!(direct < n / 8, "{direct} direct rows");
        // A random relabelling: most adjacent vertices fall in other blocks.
        let mut perm: Vec<u32> = (0..n as u32).collect();
        let mut state = 12345u64;
        for i in (1..n).rev() {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            perm.swap(i, (state >> 33) as usize % (i + 1));
        }
        let shuffled: Vec<[u32; 3]> = grid(w, h)
            .iter()
            .map(|f| f.map(|v| perm[v as usize]))
            .collect();
        let (ratio, _) = check(&shuffled, 3);
        assert!(ratio <= 1.0, "{ratio}");
    }

    #[test]
    fn interior_one_ring_of_a_grid_has_six_neighbours() {
        let nb = n_rings(&grid(5, 5), 25, 1);
        assert_eq!(nb.of(12).len(), 7);
    }
}
