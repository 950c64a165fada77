//! Support during the schedule (docs/method.md "Partial scans"): which template vertices the
//! scan has nothing for — the back of a garment that a one-sided rig saw from the front — so
//! that the coarse and fine phases carry them with their template rings instead of pulling
//! them onto the scanned side.

use super::params::{FitParams, CARRY_FAR_EDGES, CARRY_MIN_DEPTH, CARRY_MIN_SHARE, CARRY_SURPLUS};
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
/// [`CARRY_SURPLUS`] × the typical one; more means a second layer belongs there). Regions smaller than [`CARRY_MIN_SHARE`] of the template are
/// left attracted.
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
    let rings = &prepared.rings;
    let ring_claims: Vec<f64> = (0..m)
        .into_par_iter()
        .map(|u| {
            let ring = rings.of(u);
            let sum: f64 = ring.iter().map(|&k| claims[k as usize]).sum();
            (claims[u] + sum) / (ring.len() + 1) as f64
        })
        .collect();
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
    let carried = within_footprint(&scan.points, &axes, pos, carried, 2.0 * unit);
    large_regions(rings, carried, CARRY_MIN_SHARE)
}

/// `mask` cleared where the vertex of `pos` lies outside the scan's footprint: the scan and
/// the vertices projected along the scan's thinnest principal axis (`axes`, the direction a
/// one-sided rig looked from) onto a grid of `cell`, the scan's cells grown by one. The unseen
/// back of a one-sided scan lies behind its front, inside it; a flap of a folded sheet that
/// the rigid phase left spread out lies beside the scan.
fn within_footprint(
    scan: &[[f64; 3]],
    axes: &Axes,
    pos: &[[f64; 3]],
    mut mask: Vec<bool>,
    cell: f64,
) -> Vec<bool> {
    use std::collections::HashSet;
    if !mask.iter().any(|&c| c) || cell <= 0.0 {
        return mask;
    }
    let centre = axes.centroid;
    let (a, b) = (axes.frame.column(0), axes.frame.column(1));
    let key = |p: &[f64; 3]| {
        let d = vec3(p) - centre;
        (
            (a.dot(&d) / cell).floor() as i64,
            (b.dot(&d) / cell).floor() as i64,
        )
    };
    let mut cells: HashSet<(i64, i64)> = HashSet::new();
    for p in scan {
        let (i, j) = key(p);
        for di in -1..=1 {
            for dj in -1..=1 {
                cells.insert((i + di, j + dj));
            }
        }
    }
    for (v, c) in mask.iter_mut().enumerate() {
        if *c && !cells.contains(&key(&pos[v])) {
            *c = false;
        }
    }
    mask
}

/// `mask` with its connected regions (through `rings`) of fewer than `min_share` of the
/// vertices cleared.
pub(super) fn large_regions(
    rings: &Neighborhoods,
    mut mask: Vec<bool>,
    min_share: f64,
) -> Vec<bool> {
    let m = mask.len();
    let least = min_region(m, min_share);
    let mut seen = vec![false; m];
    let mut stack = Vec::new();
    let mut members = Vec::new();
    for s in 0..m {
        if !mask[s] || seen[s] {
            continue;
        }
        members.clear();
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
        if members.len() < least {
            for &v in &members {
                mask[v] = false;
            }
        }
    }
    mask
}

/// The fewest vertices of a region that [`large_regions`] keeps.
fn min_region(m: usize, min_share: f64) -> usize {
    (min_share * m as f64).ceil() as usize
}
