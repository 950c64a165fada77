//! Template neighborhoods Γᵏ_Y (paper §3, Fig. 2; SPEC §2.5): the vertices within graph
//! distance n (the "n-ring") of every template vertex, including the vertex itself, in CSR
//! form, computed once per fit. β_j = 1/|Γᵏ_Y| weighs each member equally.

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

/// Vertex adjacency (one-ring) of a triangle mesh in CSR form, sorted, without duplicates.
pub fn adjacency(faces: &[[u32; 3]], n_vertices: usize) -> Neighborhoods {
    let mut rows: Vec<Vec<u32>> = vec![Vec::new(); n_vertices];
    for f in faces {
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            if a != b {
                rows[a as usize].push(b);
                rows[b as usize].push(a);
            }
        }
    }
    for r in &mut rows {
        r.sort_unstable();
        r.dedup();
    }
    Neighborhoods::from_rows(rows)
}

/// The n-ring neighborhoods of every vertex: all vertices at graph distance ≤ `rings`
/// (including the vertex itself), by a bounded breadth-first search from each vertex.
pub fn n_rings(faces: &[[u32; 3]], n_vertices: usize, rings: usize) -> Neighborhoods {
    let adj = adjacency(faces, n_vertices);
    let rows: Vec<Vec<u32>> = (0..n_vertices)
        .into_par_iter()
        .map_init(
            || Visited::new(n_vertices),
            |visited, k| bfs_ring(&adj, k as u32, rings, visited),
        )
        .collect();
    Neighborhoods::from_rows(rows)
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

    /// Marks `v`; returns whether it was unmarked.
    #[inline]
    fn insert(&mut self, v: u32) -> bool {
        let seen = &mut self.stamp[v as usize];
        let new = *seen != self.search;
        *seen = self.search;
        new
    }
}

/// Bounded BFS from `start`; returns the visited set in BFS order (each ring sorted by index).
fn bfs_ring(adj: &Neighborhoods, start: u32, rings: usize, visited: &mut Visited) -> Vec<u32> {
    visited.clear();
    visited.insert(start);
    let mut out = vec![start];
    let mut frontier_start = 0;
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
    out
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

    #[test]
    fn interior_one_ring_of_a_grid_has_six_neighbours() {
        let nb = n_rings(&grid(5, 5), 25, 1);
        assert_eq!(nb.of(12).len(), 7);
    }
}
