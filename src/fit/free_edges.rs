//! The garment's free edges on a dressed-body scan (docs/method.md "Scans of dressed people",
//! "Free edges"): the rims of a fit beyond which the scan ends within a short reach — a skirt's
//! hem hanging free, a loose sleeve's cuff — as against the rims the scan runs on past, onto
//! the skin (a tight waistband, a cuff tight on the arm).
//!
//! A garment pass's isometric refinement is not pulled by the scan beyond its rim, which is
//! mostly skin that the garment cut left in; but where the rim is a free edge, the scan points
//! past it are the garment's own, and they are what places the fit along a surface that the
//! rest of the scan does not pin (a skirt's tube slides up and down its own surface, and the
//! skin over a waistband continues it). There the pull stays on
//! ([`IsometricRefine::with_free_edges`](super::IsometricRefine::with_free_edges)).
//!
//! Each rim vertex walks out over the whole scan (garment and body; not the points the user
//! weighted 0) in the fit's outward direction, a scan spacing per step, snapping to the nearest
//! scan point while the surface runs on ahead: the rim is free when a step lands farther than
//! [`GAP`] spacings from every scan point within [`REACH`] of the fit's size.

use super::garment_refit::rim_outward;
use crate::knn::PointIndex;
use crate::math::vec3;
use crate::metrics::{bbox_diagonal, upper_median};
use rayon::prelude::*;

/// How far a rim vertex walks out, as a share of the fit's bounding-box diagonal (past a
/// fitted hem that stops short of the garment's edge, the garment's band runs on for a few
/// centimetres; the skin past a waistband for the whole torso).
pub const REACH: f64 = 0.05;

/// A step that lands farther than this many scan spacings from every scan point has left the
/// scan: the garment ends there.
pub const GAP: f64 = 3.0;

/// A walk snaps to the nearest scan point of its step when that point lies ahead by at least
/// this share of a step (the surface runs on, curved); otherwise it goes on straight (past the
/// scan's edge the nearest point is the edge behind it).
const AHEAD: f64 = 0.3;

/// Scan points sampled for the scan's spacing (the median distance to the nearest other point).
const SPACING_SAMPLE: usize = 2000;

/// Per face of `faces`: whether it holds a vertex of a free edge of the fit `fitted` on
/// `scan` (every scan point the user kept, the body's too). Empty when the scan has fewer than
/// two points.
pub(super) fn free_edge_faces(
    fitted: &[[f64; 3]],
    faces: &[[u32; 3]],
    scan: &[[f64; 3]],
) -> Vec<bool> {
    if scan.len() < 2 || fitted.is_empty() {
        return Vec::new();
    }
    let index = PointIndex::new(scan);
    let mut nearest: Vec<f64> = scan
        .par_iter()
        .step_by((scan.len() / SPACING_SAMPLE).max(1))
        .map(|p| {
            let (mut i, mut d2) = ([0u32; 2], [0.0; 2]);
            index.nearest_into(p, &mut i, &mut d2);
            d2[1].sqrt()
        })
        .collect();
    let spacing = upper_median(&mut nearest);
    let reach = REACH * bbox_diagonal(fitted);
    if !(spacing > 0.0 && reach > 0.0) {
        return vec![false; faces.len()];
    }
    let steps = (reach / spacing).floor() as usize;
    let outward = rim_outward(fitted, faces);
    let free: Vec<bool> = fitted
        .par_iter()
        .zip(outward.par_iter())
        .map(|(p, u)| {
            let u = vec3(u);
            if u.norm_squared() == 0.0 {
                return false;
            }
            let mut at = vec3(p);
            for _ in 0..steps {
                let step = at + spacing * u;
                let (j, d2) = index.nearest_one(&step.into());
                if d2.sqrt() > GAP * spacing {
                    return true;
                }
                let x = vec3(&scan[j as usize]);
                at = if (x - at).dot(&u) > AHEAD * spacing {
                    x
                } else {
                    step
                };
            }
            false
        })
        .collect();
    faces
        .iter()
        .map(|f| f.iter().any(|&v| free[v as usize]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::grid_sheet;

    /// A garment panel (a sheet over x ∈ [−0.5, 0.5]) on a scan that continues past its
    /// left edge (the skin, on for a metre) and ends a few centimetres past its right edge
    /// (the garment's band past a hem that the fit stopped short of): the right rim is free,
    /// the left one is not, and neither is the top or bottom edge, past which the scan also
    /// runs on.
    #[test]
    fn a_rim_is_free_where_the_scan_ends_and_not_where_it_runs_on() {
        let (fitted, faces) = grid_sheet(11, 11, 1.0, 1.0);
        let mut scan = Vec::new();
        for i in 0..=203 {
            for j in 0..=100 {
                // x from −1.5 to 0.53: the band 3 cm past the right rim at 0.5; y wide.
                let x = -1.5 + 0.01 * i as f64;
                let y = -1.0 + 0.02 * j as f64;
                if x <= 0.53 {
                    // A gentle bend of the skin, as a body's surface curves.
                    let z = if x < -0.5 {
                        0.2 * (x + 0.5) * (x + 0.5)
                    } else {
                        0.0
                    };
                    scan.push([x, y, z]);
                }
            }
        }
        let flags = free_edge_faces(&fitted, &faces, &scan);
        assert_eq!(flags.len(), faces.len());
        let near = |f: &[u32; 3], x: f64| {
            f.iter().all(|&v| {
                (fitted[v as usize][0] - x).abs() < 0.11 && fitted[v as usize][1].abs() < 0.35
            })
        };
        let right: Vec<bool> = faces
            .iter()
            .zip(&flags)
            .filter(|(f, _)| near(f, 0.45))
            .map(|p| *p.1)
            .collect();
        let left: Vec<bool> = faces
            .iter()
            .zip(&flags)
            .filter(|(f, _)| near(f, -0.45))
            .map(|p| *p.1)
            .collect();
        assert!(
            !right.is_empty() && right.iter().all(|&b| b),
            "the right rim is free"
        );
        assert!(
            !left.is_empty() && left.iter().all(|&b| !b),
            "the left rim runs on"
        );
        let middle = faces
            .iter()
            .zip(&flags)
            .filter(|(f, _)| f.iter().all(|&v| fitted[v as usize][0].abs() < 0.3))
            .any(|p| *p.1);
        assert!(!middle, "top and bottom: the scan runs on past them");
    }

    /// Too little scan: nothing is free.
    #[test]
    fn an_empty_scan_frees_nothing() {
        let (fitted, faces) = grid_sheet(3, 3, 1.0, 1.0);
        assert!(free_edge_faces(&fitted, &faces, &[[0.0; 3]]).is_empty());
    }
}
