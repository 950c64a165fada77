//! Rim matching on a mesh target (docs/method.md "Rim matching"): the template's boundary
//! loops laid onto the target mesh's boundary loops at their rest arc length.
//!
//! A target's points say where the cloth's surface is, not which cloth lies where: a fit can
//! lie on the surface and still be slid and swirled along it, and nothing in the distance
//! terms sees that. A mesh target says one more thing: where the cloth ends. Each boundary
//! loop of the template goes onto the target loop its fitted rim lies along, every rim vertex
//! at the share of the loop's length it has in the rest shape (a rim keeps its metric up to
//! one scale per loop: the target loop's length over the rest loop's), with the loop's
//! offset and direction those that agree best with where the fitted rim projects. A loop
//! whose fitted rim lies far from every target loop, whose length differs too much from the
//! target loop's, or whose projections do not follow the rest arc length (the fit is not yet
//! near that loop) gets no targets.

use super::landmark_pull::LandmarkTargets;
use crate::math::{vec3, Vec3};
use rayon::prelude::*;

/// A loop's fitted rim lies along a target loop when the median distance of its vertices to it
/// is at most this many mean template edge lengths.
pub const RIM_REACH: f64 = 8.0;

/// A target loop is taken for a template loop only when their lengths (the fitted loop's) agree
/// within this factor either way.
pub const RIM_LENGTH_RATIO: f64 = 2.5;

/// The largest RMS difference, as a share of the target loop's length, between where the
/// fitted rim projects on the loop and where the rest arc length puts it: above it the fit is
/// not yet near enough to that loop for the arc length to place its vertices.
pub const RIM_RESIDUAL: f64 = 0.1;

/// Loops of fewer vertices are not matched (a loop of a few edges has no arc length to speak
/// of: a small hole, a stray triangle).
pub const MIN_RIM_LOOP: usize = 8;

/// A closed polyline with its cumulative arc length at every point.
struct Polyline {
    points: Vec<Vec3>,
    /// The arc length from the first point to each point.
    arc: Vec<f64>,
    length: f64,
}

impl Polyline {
    fn new(points: Vec<Vec3>) -> Self {
        let n = points.len();
        let mut arc = Vec::with_capacity(n);
        let mut length = 0.0;
        for i in 0..n {
            arc.push(length);
            length += (points[(i + 1) % n] - points[i]).norm();
        }
        Self {
            points,
            arc,
            length,
        }
    }

    /// The arc length of `q`'s closest point on the loop, and the squared distance to it.
    fn project(&self, q: &Vec3) -> (f64, f64) {
        let n = self.points.len();
        let mut best = (0.0, f64::INFINITY);
        for i in 0..n {
            let (a, b) = (self.points[i], self.points[(i + 1) % n]);
            let ab = b - a;
            let len2 = ab.norm_squared();
            let t = if len2 > 0.0 {
                ((q - a).dot(&ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d2 = (a + t * ab - q).norm_squared();
            if d2 < best.1 {
                best = (self.arc[i] + t * len2.sqrt(), d2);
            }
        }
        best
    }

    /// The point at arc length `s` (taken modulo the loop's length).
    fn at(&self, s: f64) -> Vec3 {
        let n = self.points.len();
        let s = s.rem_euclid(self.length.max(f64::MIN_POSITIVE));
        let i = self.arc.partition_point(|&a| a <= s).saturating_sub(1);
        let (a, b) = (self.points[i], self.points[(i + 1) % n]);
        let seg = (b - a).norm();
        if seg > 0.0 {
            a + (s - self.arc[i]) / seg * (b - a)
        } else {
            a
        }
    }
}

/// One boundary loop of the template: its vertices in order and their rest arc lengths.
struct TemplateLoop {
    vertices: Vec<u32>,
    rest: Polyline,
}

/// The template's and the target's boundary loops (docs/method.md "Rim matching").
pub(super) struct RimMatch {
    template: Vec<TemplateLoop>,
    target: Vec<Polyline>,
}

impl RimMatch {
    /// The loops of the template (`rest`, its rest shape) and of the target mesh, both in the
    /// fit's frame; `None` when either has no boundary loop of [`MIN_RIM_LOOP`] vertices.
    pub(super) fn new(
        rest: &[[f64; 3]],
        faces: &[[u32; 3]],
        target: &[[f64; 3]],
        target_faces: &[[u32; 3]],
    ) -> Option<Self> {
        let template: Vec<TemplateLoop> = boundary_loops(faces, rest.len())
            .into_iter()
            .map(|vertices| TemplateLoop {
                rest: Polyline::new(vertices.iter().map(|&v| vec3(&rest[v as usize])).collect()),
                vertices,
            })
            .collect();
        let target: Vec<Polyline> = boundary_loops(target_faces, target.len())
            .into_iter()
            .map(|l| Polyline::new(l.iter().map(|&j| vec3(&target[j as usize])).collect()))
            .collect();
        (!template.is_empty() && !target.is_empty()).then_some(Self { template, target })
    }

    /// Where the template's rim goes, given the fit's positions `pos` and its mean edge length
    /// `edge` (module docs): each template loop, nearest first, takes the nearest target loop
    /// no other has taken, if it passes [`RIM_REACH`], [`RIM_LENGTH_RATIO`] and
    /// [`RIM_RESIDUAL`]. The targets are in `pos`'s frame, pulled as landmarks are.
    pub(super) fn targets(&self, pos: &[[f64; 3]], edge: f64) -> LandmarkTargets {
        // Every (template loop, target loop) pair: the fitted rim's projections.
        let pairs: Vec<(f64, usize, usize, Vec<f64>)> = (0..self.template.len())
            .flat_map(|i| (0..self.target.len()).map(move |j| (i, j)))
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(i, j)| {
                let lp = &self.template[i];
                let (mut arcs, mut d2) = (Vec::with_capacity(lp.vertices.len()), Vec::new());
                for &v in &lp.vertices {
                    let (s, d) = self.target[j].project(&vec3(&pos[v as usize]));
                    arcs.push(s);
                    d2.push(d);
                }
                d2.sort_unstable_by(f64::total_cmp);
                (d2[d2.len() / 2].sqrt(), i, j, arcs)
            })
            .collect();
        let mut order: Vec<usize> = (0..pairs.len()).collect();
        order.sort_by(|&a, &b| pairs[a].0.total_cmp(&pairs[b].0));
        let (mut done, mut taken) = (
            vec![false; self.template.len()],
            vec![false; self.target.len()],
        );
        let (mut vertices, mut targets) = (Vec::new(), Vec::new());
        for k in order {
            let (median, i, j, ref arcs) = pairs[k];
            if done[i] || taken[j] || median > RIM_REACH * edge {
                continue;
            }
            let (lp, tl) = (&self.template[i], &self.target[j]);
            let n = lp.vertices.len();
            let fitted: f64 = (0..n)
                .map(|k| {
                    let (a, b) = (lp.vertices[k], lp.vertices[(k + 1) % n]);
                    (vec3(&pos[b as usize]) - vec3(&pos[a as usize])).norm()
                })
                .sum();
            let ratio = tl.length / fitted.max(f64::MIN_POSITIVE);
            if !(1.0 / RIM_LENGTH_RATIO..=RIM_LENGTH_RATIO).contains(&ratio) {
                continue;
            }
            let Some((direction, offset)) = arc_alignment(&lp.rest, tl.length, arcs) else {
                continue;
            };
            done[i] = true;
            taken[j] = true;
            let sigma = tl.length / lp.rest.length;
            for (&v, &s) in lp.vertices.iter().zip(&lp.rest.arc) {
                vertices.push(v);
                targets.push(tl.at(offset + direction * sigma * s));
            }
        }
        LandmarkTargets::in_frame(vertices, targets)
    }
}

/// The direction (±1) and offset o that best map the rest arc lengths s_i of `rest`, scaled to
/// a loop of length `length`, onto the projections `arcs` (t_i ≈ o + d σ s_i on the circle of
/// that length; o their circular mean); `None` when the better direction's RMS difference
/// exceeds [`RIM_RESIDUAL`] of the length.
fn arc_alignment(rest: &Polyline, length: f64, arcs: &[f64]) -> Option<(f64, f64)> {
    let sigma = length / rest.length.max(f64::MIN_POSITIVE);
    let turn = std::f64::consts::TAU / length;
    let wrap = |x: f64| (x + 0.5 * length).rem_euclid(length) - 0.5 * length;
    let mut best: Option<(f64, f64, f64)> = None;
    for direction in [1.0, -1.0] {
        let (mut c, mut s) = (0.0, 0.0);
        for (&t, &a) in arcs.iter().zip(&rest.arc) {
            let phase = (t - direction * sigma * a) * turn;
            c += phase.cos();
            s += phase.sin();
        }
        let offset = s.atan2(c) / turn;
        let residual = (arcs
            .iter()
            .zip(&rest.arc)
            .map(|(&t, &a)| wrap(t - offset - direction * sigma * a).powi(2))
            .sum::<f64>()
            / arcs.len() as f64)
            .sqrt();
        if best.is_none_or(|b| residual < b.0) {
            best = Some((residual, direction, offset));
        }
    }
    best.filter(|b| b.0 <= RIM_RESIDUAL * length)
        .map(|(_, direction, offset)| (direction, offset))
}

/// The mesh's boundary loops, each a cycle of vertices in order along the boundary; a
/// boundary vertex with other than two boundary neighbours (where two loops touch) ends the
/// loops through it, which are left out, as are loops under [`MIN_RIM_LOOP`] vertices.
pub(super) fn boundary_loops(faces: &[[u32; 3]], n: usize) -> Vec<Vec<u32>> {
    let mut next: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (a, b) in crate::mesh::boundary_edges(faces) {
        next[a as usize].push(b);
        next[b as usize].push(a);
    }
    let mut seen = vec![false; n];
    let mut loops = Vec::new();
    for start in 0..n {
        if seen[start] || next[start].len() != 2 {
            continue;
        }
        let mut lp = vec![start as u32];
        seen[start] = true;
        let (mut prev, mut cur) = (start, next[start][0] as usize);
        let closed = loop {
            if cur == start {
                break true;
            }
            if seen[cur] || next[cur].len() != 2 {
                break false;
            }
            seen[cur] = true;
            lp.push(cur as u32);
            let step = if next[cur][0] as usize == prev {
                next[cur][1]
            } else {
                next[cur][0]
            };
            (prev, cur) = (cur, step as usize);
        };
        if closed && lp.len() >= MIN_RIM_LOOP {
            loops.push(lp);
        }
    }
    loops
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An nx × ny grid sheet in the xy plane, spacing 1.
    fn grid(nx: usize, ny: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        crate::synthetic::grid_sheet(nx, ny, (nx - 1) as f64, (ny - 1) as f64)
    }

    #[test]
    fn a_grid_has_one_loop_through_every_border_vertex_in_order() {
        let (v, f) = grid(6, 4);
        let loops = boundary_loops(&f, v.len());
        assert_eq!(loops.len(), 1);
        let lp = &loops[0];
        assert_eq!(lp.len(), 2 * (6 + 4) - 4);
        for k in 0..lp.len() {
            let (a, b) = (v[lp[k] as usize], v[lp[(k + 1) % lp.len()] as usize]);
            let step = (a[0] - b[0]).abs() + (a[1] - b[1]).abs();
            assert!(
                (step - 1.0).abs() < 1e-12,
                "consecutive loop vertices are neighbours"
            );
        }
    }

    #[test]
    fn a_rim_bunched_along_the_target_is_spread_back_to_its_arc_length() {
        // The target is the template itself; the fit is the template with its rim vertices
        // moved along the rim by a wave of zero mean (bunched in places, spread in others):
        // every rim vertex's target is its own rest position.
        let (v, f) = grid(9, 9);
        let m = RimMatch::new(&v, &f, &v, &f).expect("loops");
        let lp = &m.template[0];
        let length = lp.rest.length;
        let mut fit = v.clone();
        for (&u, &s) in lp.vertices.iter().zip(&lp.rest.arc) {
            let wave = 0.4 * (2.0 * std::f64::consts::TAU * s / length).sin();
            fit[u as usize] = lp.rest.at(s + wave).into();
        }
        let t = m.targets(&fit, 1.0);
        assert_eq!(t.vertices.len(), lp.vertices.len());
        let off = |p: &[[f64; 3]]| {
            t.vertices
                .iter()
                .zip(&t.targets)
                .map(|(&u, q)| (vec3(&p[u as usize]) - q).norm())
                .fold(0.0, f64::max)
        };
        assert!(
            off(&v) < 1e-9,
            "rim targets at the rest positions: worst {}",
            off(&v)
        );
        assert!(off(&fit) > 0.3, "the fit was moved: {}", off(&fit));
    }

    #[test]
    fn a_far_or_mismatched_target_loop_gives_no_targets() {
        let (v, f) = grid(9, 9);
        // Moved 20 edges away: beyond the reach.
        let far: Vec<[f64; 3]> = v.iter().map(|p| [p[0], p[1], p[2] + 20.0]).collect();
        let m = RimMatch::new(&v, &f, &far, &f).expect("loops");
        assert!(m.targets(&v, 1.0).vertices.is_empty());
        // A target loop three times as long: beyond the length ratio.
        let big: Vec<[f64; 3]> = v.iter().map(|p| [3.0 * p[0], 3.0 * p[1], 0.0]).collect();
        let m = RimMatch::new(&v, &f, &big, &f).expect("loops");
        assert!(m.targets(&v, 10.0).vertices.is_empty());
    }
}
