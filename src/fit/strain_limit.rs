//! Strain limiting (Provot 1995, "Deformation constraints in a mass-spring model to describe
//! rigid cloth behavior"): cloth barely stretches, so after each update of the fine phase every
//! edge longer than `(1 + s)` times its rest length (and, when a compression limit c is set,
//! every edge shorter than its rest length ÷ `(1 + c)`) is moved back towards that band by a few
//! Jacobi passes of position projections (docs/method.md "Strain limiting"). Where the scan pins
//! the surface this changes little; where it does not (tangential sliding along the scan, hems
//! pulled onto skin, surface the scanner did not see) it keeps the template's metric, which the
//! rest-shape rigidity — faded to 0 by the last iteration — no longer does.

use crate::math::vec3;
use crate::rings::{adjacency, ring_lengths, Neighborhoods};
use rayon::prelude::*;

/// Every vertex's one-ring ([`adjacency`]) with the rest length of each of its edges, and the
/// passes' buffers.
pub(super) struct StrainLimit {
    pinned: Vec<bool>,
    ring: Neighborhoods,
    /// `rest_length[e]`: the rest length of the edge to `ring.members[e]`.
    rest_length: Vec<f64>,
    /// A pass's new position of every vertex (`None`: unmoved).
    moves: Vec<Option<[f64; 3]>>,
    /// Whether the last pass moved the vertex: after the first pass only the vertices moved
    /// and their neighbours, whose edges changed, are looked at.
    moved: Vec<bool>,
}

impl StrainLimit {
    /// The edges of `faces` with their lengths in `rest`; the `pinned` vertices (landmarks,
    /// docs/method.md "Landmarks") are never moved, their neighbours take the corrections.
    pub(super) fn new(rest: &[[f64; 3]], faces: &[[u32; 3]], pinned: &[u32]) -> Self {
        let m = rest.len();
        let ring = adjacency(faces, m);
        let rest_length = ring_lengths(&ring, rest);
        let mut is_pinned = vec![false; m];
        for &v in pinned {
            is_pinned[v as usize] = true;
        }
        Self {
            pinned: is_pinned,
            ring,
            rest_length,
            moves: vec![None; m],
            moved: vec![false; m],
        }
    }

    /// Up to `passes` Jacobi passes over `pos` (stopping at the first that moves nothing):
    /// every vertex moves by the mean over its edges of the correction that brings the edge's
    /// length into `[ℓ⁰ / (1 + c), (1 + s) ℓ⁰]` (s = 0: no upper bound, c = 0: no lower bound),
    /// i.e. twice the usual half-correction per endpoint, an over-relaxed Jacobi step (ω = 2)
    /// that the averaging over the one-ring keeps stable. Every stage of a pass runs in
    /// parallel over the vertices, with no allocation.
    pub(super) fn apply(&mut self, pos: &mut [[f64; 3]], s: f64, c: f64, passes: usize) {
        let hi = if s > 0.0 { 1.0 + s } else { f64::INFINITY };
        let hi2 = hi * hi;
        let lo = if c > 0.0 { 1.0 / (1.0 + c) } else { 0.0 };
        let lo2 = lo * lo;
        for pass in 0..passes {
            let (offsets, neighbours, rest_length, pinned, moved) = (
                &self.ring.offsets,
                &self.ring.members,
                &self.rest_length,
                &self.pinned,
                &self.moved,
            );
            let current: &[[f64; 3]] = pos;
            self.moves.par_iter_mut().enumerate().for_each(|(v, out)| {
                *out = None;
                let (a, b) = (offsets[v], offsets[v + 1]);
                // After the first pass, an edge changed only where an end moved.
                if pinned[v]
                    || (pass > 0
                        && !moved[v]
                        && !neighbours[a..b].iter().any(|&u| moved[u as usize]))
                {
                    return;
                }
                let p = vec3(&current[v]);
                let mut corr = crate::math::Vec3::zeros();
                let mut any = false;
                for e in a..b {
                    let d = vec3(&current[neighbours[e] as usize]) - p;
                    let l2 = d.norm_squared();
                    let r2 = rest_length[e] * rest_length[e];
                    if (l2 > hi2 * r2 || l2 < lo2 * r2) && l2 > 0.0 {
                        let l = l2.sqrt();
                        let target = l.clamp(lo * rest_length[e], hi * rest_length[e]);
                        corr += (l - target) / l * d;
                        any = true;
                    }
                }
                if any {
                    *out = Some((p + corr / (b - a) as f64).into());
                }
            });
            let moves = &self.moves;
            let any = pos
                .par_iter_mut()
                .zip(self.moved.par_iter_mut())
                .zip(moves.par_iter())
                .map(|((p, flag), mv)| {
                    *flag = mv.is_some();
                    if let Some(q) = mv {
                        *p = *q;
                    }
                    *flag
                })
                .reduce(|| false, |a, b| a || b);
            if !any {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{fit_simple, FitParams};
    use crate::synthetic::grid_sheet;

    /// Every edge's length in `pos` ÷ its rest length.
    fn ratios(limit: &StrainLimit, pos: &[[f64; 3]]) -> Vec<f64> {
        let mut out = Vec::new();
        for v in 0..pos.len() {
            for e in limit.ring.offsets[v]..limit.ring.offsets[v + 1] {
                let u = limit.ring.members[e] as usize;
                out.push((vec3(&pos[u]) - vec3(&pos[v])).norm() / limit.rest_length[e]);
            }
        }
        out
    }

    #[test]
    fn stretched_edges_come_back_into_the_band_and_compressed_ones_only_when_limited() {
        let (rest, faces) = grid_sheet(9, 9, 1.0, 1.0);
        let mut limit = StrainLimit::new(&rest, &faces, &[]);
        // Stretched 1.5× along x, shrunk 0.7× along y.
        let deformed: Vec<[f64; 3]> = rest.iter().map(|p| [1.5 * p[0], 0.7 * p[1], 0.0]).collect();
        let mut pos = deformed.clone();
        limit.apply(&mut pos, 0.1, 0.0, 200);
        let r = ratios(&limit, &pos);
        let max = r.iter().copied().fold(0.0, f64::max);
        assert!(max <= 1.11, "longest edge {max}");
        // Compression is not limited: the y edges keep about their 0.7.
        let min = r.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min < 0.75, "shortest edge {min}");
        // With a compression limit they come back too.
        let mut pos = deformed;
        limit.apply(&mut pos, 0.1, 0.1, 200);
        let min = ratios(&limit, &pos)
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        assert!(min >= 1.0 / 1.11, "shortest edge {min}");
    }

    #[test]
    fn pinned_vertices_stay_and_their_neighbours_move() {
        let (rest, faces) = grid_sheet(5, 5, 1.0, 1.0);
        let mut limit = StrainLimit::new(&rest, &faces, &[12]);
        let mut pos = rest.clone();
        pos[12][0] += 0.2; // the centre, pulled by its landmark
        let before = pos.clone();
        limit.apply(&mut pos, 0.05, 0.0, 4);
        assert_eq!(pos[12], before[12]);
        // Its left neighbour's edge is stretched 1.8×: the neighbour follows it.
        assert!(pos[11][0] > before[11][0], "a neighbour follows");
    }

    #[test]
    fn a_shape_within_the_band_is_left_exactly_as_it_is() {
        let (rest, faces) = grid_sheet(9, 9, 1.0, 1.0);
        let mut limit = StrainLimit::new(&rest, &faces, &[]);
        // Bent and moved rigidly: no edge longer than 1.05× its rest length.
        let shape: Vec<[f64; 3]> = rest
            .iter()
            .map(|p| [p[0] + 3.0, p[1], 0.1 * (3.0 * p[0]).sin()])
            .collect();
        let mut pos = shape.clone();
        limit.apply(&mut pos, 0.1, 0.0, 4);
        assert_eq!(pos, shape);
    }

    #[test]
    fn a_fit_onto_a_stretched_scan_keeps_its_edges_within_the_limit() {
        let (template, faces) = grid_sheet(11, 11, 1.0, 1.0);
        // The scan: the sheet 1.4× as wide, slightly curved.
        let mut scan = Vec::new();
        for i in 0..57 {
            for j in 0..41 {
                let (x, y) = (-0.7 + 1.4 * i as f64 / 56.0, -0.5 + j as f64 / 40.0);
                scan.push([x, y, 0.05 * (2.0 * x).cos()]);
            }
        }
        let longest = |limit_value: f64| {
            let mut params = FitParams {
                iterations: 40,
                ..FitParams::default()
            };
            params.schedule.strain_limit = limit_value;
            // The schedule's limit alone (the refinement's springs hold lengths too).
            params.schedule.isometric_iterations = 0;
            let fit = fit_simple(&template, &faces, &scan, None, &params).unwrap();
            let limit = StrainLimit::new(&template, &faces, &[]);
            ratios(&limit, &fit.vertices)
                .into_iter()
                .fold(0.0, f64::max)
        };
        let free = longest(0.0);
        let limited = longest(0.1);
        // Four Jacobi passes per iteration do not reach the band exactly where the scan keeps
        // pulling, but hold the stretch to a fraction of the free fit's.
        assert!(free > 1.3, "the free fit stretches: {free}");
        assert!(
            limited - 1.0 < 0.6 * (free - 1.0),
            "the limited fit keeps its edges: {limited} (free: {free})"
        );
    }
}
