//! A minimum s–t cut of an undirected graph with integer capacities, by Dinic's maximum flow
//! (Dinic 1970; the segmentation use is Boykov & Jolly 2001, "Interactive graph cuts"): the
//! nodes on the source's side of the cheapest set of edges whose removal separates the source
//! seeds from the sink seeds. Used by the garment cut of dressed-body scans
//! (docs/method.md "Scans of dressed people").

use std::collections::VecDeque;

/// An undirected graph under construction: `add_edge` as often as needed, then
/// [`CutGraph::source_side`].
#[derive(Debug, Default)]
pub struct CutGraph {
    nodes: usize,
    edges: Vec<(u32, u32, i64)>,
}

/// Capacity of the seeds' links to the terminals: never the cheapest to cut.
const SEED: i64 = i64::MAX / 4;

impl CutGraph {
    /// A graph of `nodes` nodes and no edges.
    pub fn new(nodes: usize) -> Self {
        Self {
            nodes,
            edges: Vec::new(),
        }
    }

    /// An undirected edge of capacity `capacity` (≥ 0; 0 adds nothing) between `a` and `b`;
    /// parallel edges add up.
    pub fn add_edge(&mut self, a: u32, b: u32, capacity: i64) {
        assert!(
            (a as usize) < self.nodes && (b as usize) < self.nodes,
            "edge ({a}, {b}) of a graph of {} nodes",
            self.nodes
        );
        if capacity > 0 && a != b {
            self.edges.push((a, b, capacity));
        }
    }

    /// The nodes on the source's side of a minimum cut between the `sources` and the `sinks`
    /// (a node both is a source): `true` where a node is still reached from a source once a
    /// maximum flow saturates the cut. With no sink every node a source reaches is on its side.
    pub fn source_side(&self, sources: &[u32], sinks: &[u32]) -> Vec<bool> {
        let (s, t) = (self.nodes, self.nodes + 1);
        let mut links: Vec<(u32, u32, i64, i64)> =
            self.edges.iter().map(|&(a, b, c)| (a, b, c, c)).collect();
        links.extend(sources.iter().map(|&v| (s as u32, v, SEED, 0)));
        links.extend(sinks.iter().map(|&v| (v, t as u32, SEED, 0)));
        let mut net = Residual::new(self.nodes + 2, &links);
        while net.levels(s, t) {
            net.blocking_flow(s, t);
        }
        let reached = net.reached(s);
        reached[..self.nodes].to_vec()
    }
}

/// The residual network: arcs in compressed rows per tail, each with its reverse.
struct Residual {
    offsets: Vec<usize>,
    head: Vec<u32>,
    capacity: Vec<i64>,
    reverse: Vec<usize>,
    level: Vec<u32>,
    next_arc: Vec<usize>,
}

const UNREACHED: u32 = u32::MAX;

impl Residual {
    /// Arcs `a → b` of capacity `c_ab` and `b → a` of capacity `c_ba` for every link.
    fn new(nodes: usize, links: &[(u32, u32, i64, i64)]) -> Self {
        let mut offsets = vec![0usize; nodes + 1];
        for &(a, b, ..) in links {
            offsets[a as usize + 1] += 1;
            offsets[b as usize + 1] += 1;
        }
        for i in 1..=nodes {
            offsets[i] += offsets[i - 1];
        }
        let arcs = offsets[nodes];
        let mut fill = offsets.clone();
        let (mut head, mut capacity, mut reverse) =
            (vec![0u32; arcs], vec![0i64; arcs], vec![0usize; arcs]);
        for &(a, b, c_ab, c_ba) in links {
            let (i, j) = (fill[a as usize], fill[b as usize]);
            fill[a as usize] += 1;
            fill[b as usize] += 1;
            (head[i], capacity[i], reverse[i]) = (b, c_ab, j);
            (head[j], capacity[j], reverse[j]) = (a, c_ba, i);
        }
        Self {
            offsets,
            head,
            capacity,
            reverse,
            level: vec![UNREACHED; nodes],
            next_arc: vec![0; nodes],
        }
    }

    /// Breadth-first levels from `s` over arcs with capacity left; whether `t` is reached.
    fn levels(&mut self, s: usize, t: usize) -> bool {
        self.level.fill(UNREACHED);
        self.level[s] = 0;
        let mut queue = VecDeque::from([s]);
        while let Some(u) = queue.pop_front() {
            for a in self.offsets[u]..self.offsets[u + 1] {
                let v = self.head[a] as usize;
                if self.capacity[a] > 0 && self.level[v] == UNREACHED {
                    self.level[v] = self.level[u] + 1;
                    queue.push_back(v);
                }
            }
        }
        self.level[t] != UNREACHED
    }

    /// Augments along level-increasing paths from `s` to `t` until none is left (an iterative
    /// depth-first search that keeps its place in every node's arcs).
    fn blocking_flow(&mut self, s: usize, t: usize) {
        self.next_arc
            .copy_from_slice(&self.offsets[..self.level.len()]);
        let mut path: Vec<usize> = Vec::new();
        let mut u = s;
        loop {
            if u == t {
                let flow = path.iter().map(|&a| self.capacity[a]).min().unwrap_or(0);
                for &a in &path {
                    self.capacity[a] -= flow;
                    self.capacity[self.reverse[a]] += flow;
                }
                // Back to the tail of the first saturated arc.
                let k = path
                    .iter()
                    .position(|&a| self.capacity[a] == 0)
                    .unwrap_or(0);
                path.truncate(k);
                u = path.last().map_or(s, |&a| self.head[a] as usize);
                continue;
            }
            let end = self.offsets[u + 1];
            let mut advanced = false;
            while self.next_arc[u] < end {
                let a = self.next_arc[u];
                let v = self.head[a] as usize;
                if self.capacity[a] > 0
                    && self.level[v] != UNREACHED
                    && self.level[v] == self.level[u] + 1
                {
                    path.push(a);
                    u = v;
                    advanced = true;
                    break;
                }
                self.next_arc[u] += 1;
            }
            if !advanced {
                if u == s {
                    return;
                }
                // A dead end: no path to t through u in this phase.
                self.level[u] = UNREACHED;
                path.pop();
                u = path.last().map_or(s, |&a| self.head[a] as usize);
                self.next_arc[u] += 1;
            }
        }
    }

    /// The nodes reached from `s` over arcs with capacity left.
    fn reached(&self, s: usize) -> Vec<bool> {
        let mut seen = vec![false; self.level.len()];
        seen[s] = true;
        let mut stack = vec![s];
        while let Some(u) = stack.pop() {
            for a in self.offsets[u]..self.offsets[u + 1] {
                let v = self.head[a] as usize;
                if self.capacity[a] > 0 && !seen[v] {
                    seen[v] = true;
                    stack.push(v);
                }
            }
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two dense clusters joined by one weak edge: the cut is that edge.
    #[test]
    fn cuts_the_weakest_seam_between_two_clusters() {
        let mut g = CutGraph::new(8);
        for group in [[0u32, 1, 2, 3], [4, 5, 6, 7]] {
            for (i, &a) in group.iter().enumerate() {
                for &b in &group[i + 1..] {
                    g.add_edge(a, b, 10);
                }
            }
        }
        g.add_edge(3, 4, 1);
        let side = g.source_side(&[0], &[7]);
        assert_eq!(side, [true, true, true, true, false, false, false, false]);
        // Seeds on either side choose the other cut direction alike.
        let side = g.source_side(&[6], &[1]);
        assert_eq!(side, [false, false, false, false, true, true, true, true]);
    }

    /// A chain whose cheapest link decides where it is cut (and a minimum cut's value equals
    /// the maximum flow: here the smallest capacity).
    #[test]
    fn a_chain_is_cut_at_its_cheapest_link() {
        let caps = [5i64, 7, 2, 9, 3, 8];
        let mut g = CutGraph::new(caps.len() + 1);
        for (i, &c) in caps.iter().enumerate() {
            g.add_edge(i as u32, i as u32 + 1, c);
        }
        let side = g.source_side(&[0], &[caps.len() as u32]);
        let expected: Vec<bool> = (0..=caps.len()).map(|i| i <= 2).collect();
        assert_eq!(side, expected);
    }

    /// Parallel edges add up; a node disconnected from both seeds is on neither side's reach.
    #[test]
    fn parallel_edges_add_and_unreached_nodes_are_not_on_the_source_side() {
        let mut g = CutGraph::new(5);
        g.add_edge(0, 1, 2);
        g.add_edge(0, 1, 2); // 4 in all
        g.add_edge(1, 2, 3);
        g.add_edge(0, 2, 0); // nothing
        let side = g.source_side(&[0], &[2]);
        assert_eq!(side, [true, true, false, false, false]);
        let no_sink = g.source_side(&[0], &[]);
        assert_eq!(no_sink, [true, true, true, false, false]);
    }

    /// Against brute force on small random graphs: the cut found is a minimum one (its value
    /// equals the cheapest of all 2^(n−2) separations).
    #[test]
    fn the_cut_is_minimum_on_random_graphs() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..40 {
            let n = 8;
            let mut edges = Vec::new();
            let mut g = CutGraph::new(n);
            for a in 0..n as u32 {
                for b in a + 1..n as u32 {
                    if next() % 3 == 0 {
                        let c = (next() % 9 + 1) as i64;
                        g.add_edge(a, b, c);
                        edges.push((a, b, c));
                    }
                }
            }
            let value = |side: &[bool]| -> i64 {
                edges
                    .iter()
                    .filter(|&&(a, b, _)| side[a as usize] != side[b as usize])
                    .map(|e| e.2)
                    .sum()
            };
            let side = g.source_side(&[0], &[n as u32 - 1]);
            assert!(side[0] && !side[n - 1]);
            let best = (0..1u32 << (n - 2))
                .map(|mask| {
                    let side: Vec<bool> = (0..n)
                        .map(|v| v == 0 || (v < n - 1 && mask >> (v - 1) & 1 == 1))
                        .collect();
                    value(&side)
                })
                .min()
                .unwrap();
            assert_eq!(value(&side), best);
        }
    }
}
