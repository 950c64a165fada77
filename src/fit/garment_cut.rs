//! The garment cut on a dressed-body scan (docs/method.md "Scans of dressed people"): the
//! garment's points separated from the skin at the seam where the scan's surface steps, by a
//! minimum cut (Boykov & Jolly 2001, "Interactive graph cuts").
//!
//! The garment refit's points ([`explain`]: what a fit explains) hold the skin next to
//! the hems, cuffs and collar that the fit reached and miss the garment's rows past its fitted
//! rim. Where a garment ends on a body, the scan's surface steps: the skin continues under the
//! cloth, a cloth thickness or a loose hem's gap below it, so the garment's local plane does not
//! hold the skin. Every scan point is a node, joined to its nearest neighbours by edges that
//! are cheap to cut where the two points leave each other's local plane (a step) or lie far apart
//! (a gap); the points of a refit explained by vertices three rings or more inside the rim are
//! the garment's seeds, the points far from every vertex the body's. The garment is the
//! seeds' side of the cheapest cut: past the fitted rim as far as the garment's surface runs on,
//! and not across the step onto the skin.

use super::garment_refit::{explain, garment_points, rim_rings};
use crate::curvature::neighbourhood_frame;
use crate::knn::PointIndex;
use crate::math::{vec3, Vec3};
use crate::metrics::upper_median;
use crate::min_cut::CutGraph;
use rayon::prelude::*;

/// At most this many cuts, each followed by a fit onto its garment's side: the next cut is
/// seeded by the last fit, and made only while the garment's points still change.
pub(super) const MAX_CUTS: usize = 2;
/// The garment's points have settled when at most this share of them changed side.
pub(super) const SETTLED: f64 = 0.01;
/// Neighbours whose plane gives a point's normal (and its residual, the noise's measure).
const PLANE_NEIGHBOURS: usize = 16;
/// Neighbours a point is joined to in the graph.
const GRAPH_NEIGHBOURS: usize = 10;
/// The seeds of the garment: points whose nearest fitted vertex is this many rings or more
/// from the template's boundary.
const SEED_RINGS: u32 = 3;
/// The seeds of the body: points not explained, farther from every fitted vertex than this
/// multiple of the explained points' median distance.
const BODY_DISTANCE: f64 = 8.0;
/// The least noise assumed, as a share of the scan's median nearest-neighbour distance: a scan
/// without noise (a mesh's vertices, a synthetic scan) still has steps of that order between
/// neighbours on its curved surface.
const STEP_FLOOR: f64 = 0.125;
/// Edge capacities are `exp(−step²/τ²) · exp(−gap²)` in units of 1 / this.
const CAPACITY_UNITS: f64 = 1000.0;

/// A scan point's role in the cut.
#[derive(Clone, Copy)]
enum Node {
    /// A seed of the garment (contracted into the source).
    Garment,
    /// A seed of the body (contracted into the sink).
    Body,
    /// Contested: its index among the graph's free nodes.
    Free(u32),
}

/// The refit's weights of the scan points by the garment cut: the given weight (1 when none)
/// on the garment's side of the cut, 0 elsewhere. `step_multiple` sets τ, the step at which an
/// edge is cheap to cut, in multiples of the scan's median distance from a point to its
/// neighbours' plane (its noise, in the scan's own units; at least [`STEP_FLOOR`] × the median
/// nearest-neighbour distance). Falls back to the explained points
/// ([`garment_weights`](super::garment_refit::garment_weights)) when the fit explains no seed of the garment or no point lies far enough to be the body's.
pub(super) fn garment_cut_weights(
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    fitted: &[[f64; 3]],
    faces: &[[u32; 3]],
    radius_multiple: f64,
    step_multiple: f64,
) -> Vec<f64> {
    let e = explain(target, weights, fitted, faces, radius_multiple);
    let explained = || e.weights(target.len(), weights, |p| e.explained[p]);
    let (scan, n) = (&e.scan, e.scan.len());
    let k = PLANE_NEIGHBOURS.min(n.saturating_sub(1));
    if k < 3 {
        return explained();
    }
    let index = PointIndex::new(scan);
    let row = k + 1;
    let (mut idx, mut d2) = (vec![0u32; n * row], vec![0.0; n * row]);
    index.nearest_all(scan, row, &mut idx, &mut d2);
    // Per point: its neighbours' plane normal and its own distance from that plane.
    let planes: Vec<(Vec3, f64)> = (0..n)
        .into_par_iter()
        .map(|p| {
            let (centroid, frame) = neighbourhood_frame(scan, &idx[p * row..(p + 1) * row]);
            let normal: Vec3 = frame.vectors.column(2).into();
            (normal, (vec3(&scan[p]) - centroid).dot(&normal).abs())
        })
        .collect();
    let median = |mut v: Vec<f64>| upper_median(&mut v);
    let spacing = median((0..n).map(|p| d2[p * row + 1].sqrt()).collect());
    let noise = median(planes.iter().map(|p| p.1).collect());
    // On a scan without noise, a fold's own curvature between neighbours sets the scale.
    let tau = step_multiple * noise.max(STEP_FLOOR * spacing);
    if !(tau > 0.0 && spacing > 0.0) {
        return explained();
    }
    // The seeds, by the fitted vertex nearest to each point.
    let rings = rim_rings(faces, fitted.len());
    let explained_distances: Vec<f64> = (0..n)
        .filter(|&p| e.explained[p])
        .map(|p| e.nearest[p].1.sqrt())
        .collect();
    if explained_distances.is_empty() {
        return explained();
    }
    let far = BODY_DISTANCE * median(explained_distances);
    // The seeds are contracted into the two terminals (an exact reduction: a seed is on its
    // side of every cut), so the maximum flow runs on the contested points alone.
    let (mut free, mut garment_seeds, mut body_seeds) = (0u32, 0usize, 0usize);
    let node: Vec<Node> = (0..n)
        .map(|p| {
            let (v, d2) = e.nearest[p];
            if e.explained[p] && rings[v as usize] >= SEED_RINGS {
                garment_seeds += 1;
                Node::Garment
            } else if !e.explained[p] && d2.sqrt() > far {
                body_seeds += 1;
                Node::Body
            } else {
                free += 1;
                Node::Free(free - 1)
            }
        })
        .collect();
    if garment_seeds == 0 || body_seeds == 0 {
        return explained();
    }
    let (source, sink) = (free, free + 1);
    let id = |p: usize| match node[p] {
        Node::Free(i) => i,
        Node::Garment => source,
        Node::Body => sink,
    };
    // Edge e joins point e / K to its (e % K + 1)-th nearest neighbour.
    let graph_k = GRAPH_NEIGHBOURS.min(k);
    let ends = |e: usize| {
        (
            e / graph_k,
            idx[(e / graph_k) * row + 1 + e % graph_k] as usize,
        )
    };
    let capacities: Vec<i64> = (0..n * graph_k)
        .into_par_iter()
        .map(|e| {
            let (p, q) = ends(e);
            let offset = vec3(&scan[q]) - vec3(&scan[p]);
            let step = offset
                .dot(&planes[p].0)
                .abs()
                .max(offset.dot(&planes[q].0).abs());
            let gap = ((offset.norm() - 2.0 * spacing) / (2.0 * spacing)).max(0.0);
            (CAPACITY_UNITS * (-(step / tau).powi(2) - gap * gap).exp()) as i64
        })
        .collect();
    let mut graph = CutGraph::new(free as usize + 2);
    for (e, &capacity) in capacities.iter().enumerate() {
        let (p, q) = ends(e);
        let (a, b) = (id(p), id(q));
        // Between two seeds of one side: inside a terminal; of both sides: cut in every cut.
        if a.min(b) < source {
            graph.add_edge(a, b, capacity);
        }
    }
    let side = graph.source_side(&[source], &[sink]);
    e.weights(target.len(), weights, |p| match node[p] {
        Node::Free(i) => side[i as usize],
        Node::Garment => true,
        Node::Body => false,
    })
}

/// Whether the garment's points of two cuts (their weights) are the same up to [`SETTLED`]: at
/// most that share of the first cut's points changed side.
pub(super) fn settled(before: &[f64], after: &[f64]) -> bool {
    let changed = before
        .iter()
        .zip(after)
        .filter(|(a, b)| (**a > 0.0) != (**b > 0.0))
        .count();
    changed as f64 <= SETTLED * garment_points(before) as f64
}

#[cfg(test)]
mod tests {
    use super::super::garment_refit::garment_weights;
    use super::*;
    use crate::synthetic::grid_sheet;

    /// A deterministic jitter in [−a, a] (the scanner's noise; a noiseless plane has no
    /// residual to measure a step against).
    fn jitter(i: usize, a: f64) -> f64 {
        let h = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 11;
        a * (2.0 * (h as f64 / (1u64 << 53) as f64) - 1.0)
    }

    /// A garment (the plane z = 0 over x ∈ [−0.5, 0.5]) whose fit ends short of its edge (at
    /// x = ±0.4), skin continuing past the edge x = 0.5 three centimetres under it (a step), and
    /// the rest of a body far away: the cut keeps the garment's rows past the fitted rim, which
    /// the explained points miss, and leaves the skin and the body out.
    #[test]
    fn the_garment_reaches_past_the_fitted_rim_and_stops_at_the_step() {
        let (template, faces) = grid_sheet(9, 9, 1.0, 1.0);
        let fitted: Vec<[f64; 3]> = template.iter().map(|p| [0.8 * p[0], p[1], 0.0]).collect();
        let mut scan = Vec::new();
        let mut kind = Vec::new(); // 0 garment inside the fit, 1 past its rim, 2 skin, 3 body
        for i in 0..66 {
            for j in 0..51 {
                let (x, y) = (-0.5 + 0.02 * i as f64, -0.5 + 0.02 * j as f64);
                let z = if x > 0.5 { -0.03 } else { 0.0 };
                scan.push([x, y, z + jitter(scan.len(), 0.002)]);
                kind.push(if x > 0.5 {
                    2
                } else if x > 0.49 {
                    4 // the garment's last row, on the step itself: either side
                } else if x.abs() > 0.42 {
                    1
                } else {
                    0
                });
            }
        }
        let (body, _) = grid_sheet(25, 25, 3.0, 3.0);
        for p in &body {
            scan.push([p[0], p[1], -1.5 + jitter(scan.len(), 0.002)]);
            kind.push(3);
        }
        let explained = garment_weights(&scan, None, &fitted, &faces, 1.0);
        let cut = garment_cut_weights(&scan, None, &fitted, &faces, 1.0, 2.0);
        let share = |w: &[f64], k: u8| {
            let of: Vec<f64> = (0..scan.len())
                .filter(|&i| kind[i] == k)
                .map(|i| w[i])
                .collect();
            of.iter().filter(|&&v| v > 0.0).count() as f64 / of.len() as f64
        };
        assert!(
            share(&explained, 1) < 0.6,
            "the explained points miss the rows past the rim"
        );
        assert!(
            share(&cut, 0) > 0.99 && share(&cut, 1) > 0.95,
            "{} {}",
            share(&cut, 0),
            share(&cut, 1)
        );
        assert!(
            share(&cut, 2) < 0.05,
            "the skin past the step: {}",
            share(&cut, 2)
        );
        assert_eq!(share(&cut, 3), 0.0);
        // Given weights carry over; weight-0 points stay out.
        let mut given = vec![1.0; scan.len()];
        given[0] = 0.0;
        given[1] = 0.5;
        let weighted = garment_cut_weights(&scan, Some(&given), &fitted, &faces, 1.0, 2.0);
        assert_eq!(weighted[0], 0.0);
        assert_eq!(weighted[1], 0.5);
    }
}
