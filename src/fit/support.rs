//! Support during the schedule (docs/method.md "Partial scans"): which template vertices the
//! scan has nothing for — the back of a garment that a one-sided rig saw from the front — so
//! that the coarse and fine phases carry them with their template rings instead of pulling
//! them onto the scanned side.

use super::params::{
    FitParams, CARRY_FAR_EDGES, CARRY_MIN_BEHIND, CARRY_MIN_DEPTH, CARRY_MIN_SHARE, CARRY_SURPLUS,
};
use super::schedule::nearest_vertices;
use super::setup::Prepared;
use crate::math::{dist2, vec3};
use crate::metrics::upper_median;
use crate::prealign::{principal_axes, Axes};
use crate::rings::Neighborhoods;
use rayon::prelude::*;

/// Per vertex of `pos` (the fit's normalized frame), whether it has no scan support
/// ([`carry_unsupported`](crate::fit::Schedule::carry_unsupported)): it lies farther than the
/// radius `r = carry_unsupported × max(median vertex → scan distance, mean edge)` from the
/// scan, and its nearest scan point `x` is explained by another part of the template — `x`'s
/// nearest vertex `u` lies within `r` of it and more than [`CARRY_FAR_EDGES`] mean edges from
/// the vertex in the rest shape — without a surplus (the mean over `u` and its ring, the
/// model's n-ring, of the count of scan points whose nearest vertex each is, at most
/// [`CARRY_SURPLUS`] × the typical one; more means a second layer belongs there). Regions
/// smaller than [`CARRY_MIN_SHARE`] of the template, or whose vertices' depths behind the
/// scanned side, summed, fall short of [`CARRY_MIN_BEHIND`] × `unit` (the `unit` above) per
/// template vertex, are left attracted.
pub(super) fn carried_vertices(
    prepared: &Prepared,
    pos: &[[f64; 3]],
    params: &FitParams,
) -> Vec<bool> {
    let scan = prepared.scan_points(1);
    let m = pos.len();
    if scan.points.is_empty() || m == 0 {
        return vec![false; m];
    }
    let live = |j: u32| scan.weights.as_ref().is_none_or(|w| w[j as usize] > 0.0);
    let nearest: Vec<(u32, f64)> = pos.par_iter().map(|p| scan.index.nearest_one(p)).collect();
    let mut distances: Vec<f64> = nearest.iter().map(|n| n.1).collect();
    let unit = upper_median(&mut distances)
        .sqrt()
        .max(prepared.edge_length);
    let r = params.schedule.carry_unsupported * unit;
    // Only vertices farther than `r` can be carried: too few of them for one region of
    // CARRY_MIN_SHARE, and nothing is (a whole scan, decided without the scan's claims).
    let least = min_region(m, CARRY_MIN_SHARE);
    if nearest.iter().filter(|n| n.1.sqrt() > r).count() < least {
        return vec![false; m];
    }
    // A garment lying flat (a scan thinner than CARRY_MIN_DEPTH of its width) hides a lower
    // layer that lies under the scanned one: attracted, not carried.
    let axes = principal_axes(&scan.points);
    if axes.variances[2].max(0.0).sqrt() < CARRY_MIN_DEPTH * axes.variances[1].max(0.0).sqrt() {
        return vec![false; m];
    }
    let far = CARRY_FAR_EDGES * prepared.edge_length;
    let claimant = nearest_vertices(&scan.points, None, pos);
    let mut claims = vec![0.0f64; m];
    for (j, &u) in claimant.vertex.iter().enumerate() {
        if live(j as u32) {
            claims[u as usize] += 1.0;
        }
    }
    let ring_claims = ring_mean(&prepared.rings, &claims);
    let mut positive: Vec<f64> = ring_claims.iter().copied().filter(|&c| c > 0.0).collect();
    let typical = upper_median(&mut positive);
    let rest = &prepared.rest;
    let carried: Vec<bool> = nearest
        .par_iter()
        .enumerate()
        .map(|(v, &(j, d2))| {
            if d2.sqrt() <= r || !live(j) {
                return false;
            }
            let u = claimant.vertex[j as usize];
            claimant.distance[j as usize] <= r
                && ring_claims[u as usize] <= CARRY_SURPLUS * typical
                && dist2(&rest[u as usize], &rest[v]).sqrt() > far
        })
        .collect();
    if !carried.iter().any(|&c| c) {
        return carried;
    }
    let depth = ScanDepth::new(&scan.points, &axes, 2.0 * unit);
    // Behind the scan, not beside it.
    let mut carried = carried;
    for (v, c) in carried.iter_mut().enumerate() {
        *c = *c && depth.covers(&pos[v]);
    }
    // Each region by the depth behind the scanned side that carrying keeps it at, summed and
    // per template vertex (CARRY_MIN_BEHIND).
    for region in regions(&prepared.rings, &carried) {
        let behind = depth.total_behind(pos, &region) / m as f64;
        if region.len() < least || behind < CARRY_MIN_BEHIND * unit {
            for &v in &region {
                carried[v] = false;
            }
        }
    }
    carried
}

/// Per vertex, the mean of `values` over the vertex and its ring (`rings`).
pub(super) fn ring_mean(rings: &Neighborhoods, values: &[f64]) -> Vec<f64> {
    (0..values.len())
        .into_par_iter()
        .map(|u| {
            let ring = rings.of(u);
            let sum: f64 = ring.iter().map(|&k| values[k as usize]).sum();
            (values[u] + sum) / (ring.len() + 1) as f64
        })
        .collect()
}

/// The vertices not in `carried` within `steps` rings (`rings`, the model's n-rings) of one
/// that is: the border of the carried regions
/// ([`CARRY_BAND`](super::params::CARRY_BAND)).
pub(super) fn border_band(rings: &Neighborhoods, carried: &[bool], steps: usize) -> Vec<bool> {
    let mut band = vec![false; carried.len()];
    let mut front: Vec<usize> = (0..carried.len()).filter(|&v| carried[v]).collect();
    for _ in 0..steps {
        let mut next = Vec::new();
        for &v in &front {
            for &k in rings.of(v) {
                let k = k as usize;
                if !carried[k] && !band[k] {
                    band[k] = true;
                    next.push(k);
                }
            }
        }
        front = next;
    }
    band
}

/// `proposed` moved back onto the line through `pos` along the unit `normal`: the proposal's
/// tangential part dropped (a zero normal keeps `pos`).
pub(super) fn along_normal(pos: &[f64; 3], proposed: &[f64; 3], normal: &[f64; 3]) -> [f64; 3] {
    let (p, n) = (vec3(pos), vec3(normal));
    (p + n * n.dot(&(vec3(proposed) - p))).into()
}

/// The scan's footprint and depth along its thinnest principal axis (the direction a one-sided
/// rig looked from) over a grid of cells across the other two: each cell's nearest and farthest
/// scan point.
struct ScanDepth<'a> {
    axes: &'a Axes,
    cell: f64,
    range: std::collections::HashMap<(i64, i64), (f64, f64)>,
}

impl<'a> ScanDepth<'a> {
    fn new(scan: &[[f64; 3]], axes: &'a Axes, cell: f64) -> Self {
        let mut depth = Self {
            axes,
            cell,
            range: Default::default(),
        };
        for p in scan {
            let (key, z) = depth.locate(p);
            let r = depth.range.entry(key).or_insert((z, z));
            r.0 = r.0.min(z);
            r.1 = r.1.max(z);
        }
        depth
    }

    /// The cell of `p` and its depth.
    fn locate(&self, p: &[f64; 3]) -> ((i64, i64), f64) {
        let d = vec3(p) - self.axes.centroid;
        let f = &self.axes.frame;
        let key = (
            (f.column(0).dot(&d) / self.cell).floor() as i64,
            (f.column(1).dot(&d) / self.cell).floor() as i64,
        );
        (key, f.column(2).dot(&d))
    }

    /// Whether `p` lies in the scan's footprint: projected along the depth axis, in a cell next
    /// to (or in) one that holds scan points. The unseen back of a one-sided scan lies behind
    /// its front, inside it; a flap of a folded sheet that the rigid phase left spread out lies
    /// beside the scan. Every point does on a grid without extent (`cell` ≤ 0).
    fn covers(&self, p: &[f64; 3]) -> bool {
        if self.cell <= 0.0 {
            return true;
        }
        let ((i, j), _) = self.locate(p);
        (-1..=1).any(|di| (-1..=1).any(|dj| self.range.contains_key(&(i + di, j + dj))))
    }

    /// The sum over the vertices of `region` (of `pos`) of the distance along the depth axis
    /// by which each lies outside its cell's scan depth range: how far behind the scanned
    /// side they are. A vertex over a cell without scan points counts 0.
    fn total_behind(&self, pos: &[[f64; 3]], region: &[usize]) -> f64 {
        region
            .iter()
            .filter_map(|&v| {
                let (key, z) = self.locate(&pos[v]);
                let &(lo, hi) = self.range.get(&key)?;
                Some((lo - z).max(z - hi).max(0.0))
            })
            .sum()
    }
}

/// The connected regions (through `rings`) of the vertices set in `mask`.
fn regions(rings: &Neighborhoods, mask: &[bool]) -> Vec<Vec<usize>> {
    let m = mask.len();
    let mut seen = vec![false; m];
    let mut stack = Vec::new();
    let mut out = Vec::new();
    for s in 0..m {
        if !mask[s] || seen[s] {
            continue;
        }
        let mut members = Vec::new();
        stack.push(s);
        seen[s] = true;
        while let Some(v) = stack.pop() {
            members.push(v);
            for &k in rings.of(v) {
                let k = k as usize;
                if mask[k] && !seen[k] {
                    seen[k] = true;
                    stack.push(k);
                }
            }
        }
        out.push(members);
    }
    out
}

/// The fewest vertices of a region that [`carried_vertices`] carries.
fn min_region(m: usize, min_share: f64) -> usize {
    (min_share * m as f64).ceil() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_depth_measures_how_far_behind_the_scanned_side_a_region_lies() {
        // Two layers of scan points, z = 0 and z = 1, over the unit square in cells of 0.1
        // (wide and long enough that z is the thinnest axis).
        let mut scan = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = (-2.0 + 0.1 * i as f64 + 0.05, -2.0 + 0.1 * j as f64 + 0.05);
                scan.push([x, y, 0.0]);
                scan.push([x, y, 1.0]);
            }
        }
        let axes = principal_axes(&scan);
        let depth = ScanDepth::new(&scan, &axes, 0.1);
        let pos = [
            [0.05, 0.05, 3.5],  // 2.5 beyond the layer at 1
            [0.05, 0.05, -1.5], // 1.5 beyond the layer at 0
            [0.05, 0.05, 0.5],  // between the layers: 0
            [10.05, 0.05, 9.0], // over no scan point: left out
        ];
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
        assert!(close(depth.total_behind(&pos, &[0]), 2.5));
        assert!(close(depth.total_behind(&pos, &[1]), 1.5));
        assert!(close(depth.total_behind(&pos, &[2]), 0.0));
        assert!(close(depth.total_behind(&pos, &[0, 1, 2, 3]), 4.0));
        assert_eq!(depth.total_behind(&pos, &[3]), 0.0);
    }
}
