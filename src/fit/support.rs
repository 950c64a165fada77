//! Support during the schedule (docs/method.md "Partial scans"): which template vertices the
//! scan has nothing for — the back of a garment that a one-sided rig saw from the front — so
//! that the coarse and fine phases carry them with their template rings instead of pulling
//! them onto the scanned side.

use super::params::{FitParams, CARRY_FAR_EDGES, CARRY_MIN_SHARE, CARRY_SURPLUS};
use super::schedule::nearest_vertices;
use super::setup::Prepared;
use crate::math::dist2;
use crate::metrics::upper_median;
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
    large_regions(rings, carried, CARRY_MIN_SHARE)
}

/// `mask` with its connected regions (through `rings`) of fewer than `min_share` of the
/// vertices cleared.
pub(super) fn large_regions(
    rings: &Neighborhoods,
    mut mask: Vec<bool>,
    min_share: f64,
) -> Vec<bool> {
    let m = mask.len();
    let least = (min_share * m as f64).ceil() as usize;
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
