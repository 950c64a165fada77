//! Where the refinement's hold applies (docs/method.md "Isometric refinement", unstretched
//! garments): on every edge, or only where the scan has no points for the fit — a hole, the
//! part of a garment inside the body — so that a garment whose schedule left it unstretched is
//! refined to the rest shape's metric wherever the scan sees it.

use crate::fit::support::{border_band, ring_mean};
use crate::rings::Neighborhoods;

/// A vertex has no scan support when the scan points whose nearest vertex lies in its ring
/// (itself and its one-ring), per vertex of the ring, number fewer than this share of the
/// typical (median) vertex's.
pub const UNSUPPORTED_CLAIMS: f64 = 0.25;

/// The unsupported region is grown by this many rings: the vertices beside a hole, matched to
/// its rim, slide along it as freely as those inside it.
pub const UNSUPPORTED_GROW: usize = 1;

/// Per vertex of `ring`, whether the scan has no points for it: `matched` is every scan
/// point's nearest vertex (`u32::MAX`: none), `weights` the points' weights (0: not the
/// garment's).
pub fn unsupported(
    ring: &Neighborhoods,
    matched: &[(u32, f64)],
    weights: Option<&[f64]>,
) -> Vec<bool> {
    let m = ring.len();
    let mut claims = vec![0.0f64; m];
    for (j, &(v, _)) in matched.iter().enumerate() {
        if v != u32::MAX && weights.is_none_or(|w| w[j] > 0.0) {
            claims[v as usize] += 1.0;
        }
    }
    let per_ring = ring_mean(ring, &claims);
    let mut positive: Vec<f64> = per_ring.iter().copied().filter(|&c| c > 0.0).collect();
    if positive.is_empty() {
        // No point claims a vertex: nothing to compare with (the refinement has no scan).
        return vec![false; m];
    }
    let typical = crate::metrics::upper_median(&mut positive);
    let core: Vec<bool> = per_ring
        .iter()
        .map(|&c| c < UNSUPPORTED_CLAIMS * typical)
        .collect();
    let band = border_band(ring, &core, UNSUPPORTED_GROW);
    core.iter().zip(&band).map(|(&c, &b)| c || b).collect()
}

/// Each ring slot's (edge i → k) hold, `hold` times the mean of its two ends' `unsupported`
/// (1 or 0), and each vertex's sum of its slots' holds.
pub fn edge_holds(ring: &Neighborhoods, unsupported: &[bool], hold: f64) -> (Vec<f64>, Vec<f64>) {
    let share = |i: usize| if unsupported[i] { 1.0 } else { 0.0 };
    let mut edge = vec![0.0; ring.members.len()];
    let mut vertex = vec![0.0; unsupported.len()];
    for (i, sum) in vertex.iter_mut().enumerate() {
        let lo = ring.offsets[i];
        for (e, &k) in ring.of(i).iter().enumerate() {
            let h = hold * 0.5 * (share(i) + share(k as usize));
            edge[lo + e] = h;
            *sum += h;
        }
    }
    (edge, vertex)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rings::adjacency;

    /// A strip of `n` × 2 vertices in a row of quads (two triangles each).
    fn strip(n: u32) -> Vec<[u32; 3]> {
        (0..n - 1)
            .flat_map(|i| {
                [
                    [2 * i, 2 * i + 2, 2 * i + 1],
                    [2 * i + 1, 2 * i + 2, 2 * i + 3],
                ]
            })
            .collect()
    }

    #[test]
    fn vertices_no_scan_point_is_nearest_to_are_unsupported_and_grown_by_a_ring() {
        let n = 20;
        let faces = strip(n);
        let m = 2 * n as usize;
        let ring = adjacency(&faces, m);
        // Four scan points per vertex, none for the vertices of columns 8..=11 (a hole).
        let matched: Vec<(u32, f64)> = (0..m as u32)
            .filter(|v| !(16..24).contains(v))
            .flat_map(|v| std::iter::repeat_n((v, 0.0), 4))
            .collect();
        let out = unsupported(&ring, &matched, None);
        // Columns 9 and 10 have no claim in their ring; 8 and 11, beside them, are grown into
        // if not marked already; the columns three and more away keep their support.
        for (v, &marked) in out.iter().enumerate() {
            let column = v / 2;
            if (8..=11).contains(&column) {
                assert!(marked, "vertex {v}");
            } else if !(5..=14).contains(&column) {
                assert!(!marked, "vertex {v}");
            }
        }
        // Points of weight 0 claim nothing; with none claiming, no vertex is marked.
        let weights = vec![0.0; matched.len()];
        assert!(unsupported(&ring, &matched, Some(&weights))
            .iter()
            .all(|&u| !u));
    }

    #[test]
    fn an_edge_holds_by_the_share_of_its_unsupported_ends() {
        let faces = strip(3);
        let ring = adjacency(&faces, 6);
        let unsupported = [true, true, false, false, false, false];
        let (edge, vertex) = edge_holds(&ring, &unsupported, 0.6);
        for i in 0..6 {
            let lo = ring.offsets[i];
            let mut sum = 0.0;
            for (e, &k) in ring.of(i).iter().enumerate() {
                let expected = 0.3 * (unsupported[i] as u8 + unsupported[k as usize] as u8) as f64;
                assert!((edge[lo + e] - expected).abs() < 1e-12);
                sum += expected;
            }
            assert!((vertex[i] - sum).abs() < 1e-12);
        }
    }
}
