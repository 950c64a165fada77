//! The pose gap of a fit (docs/method.md "Quality verdict"): how much closer to the scan the
//! template comes rigidly placed elsewhere than in the basin of the fit's own rigid pose.
//!
//! A fit that started turned (back to front, on its side, z-up taken for y-up) without a
//! search that turns it is pulled onto the scan's nearest surface and wraps it closely: its
//! distances say nothing. Its rigid part — the template moved by the rotation and translation
//! that best map it onto the fit (Kabsch), at the fit's own scale — is still turned, and the
//! pre-alignment's search ([`crate::prealign::pose_scores`]) finds a rigid placement of the
//! template that lies on the scan much better than any near that pose. On a right fit the two
//! agree: the fit's pose lies in the best rigid placement's basin (trimmed ICP from the pose
//! reaches it), or the search's best is another reading of a garment that is nearly its own
//! symmetric image (which no figure of this kind can tell apart).
//!
//! `pose_gap = d(basin of the pose) / d(best)`, `d` the trimmed two-sided distance of
//! `crate::prealign`: 1 when no rigid placement beats the pose's basin.

use crate::prealign::{fit_pairs, pose_scores, Similarity};

/// The fit's rigid pose: the rotation and translation that best map the template, scaled by
/// `scale` (the fit's median edge ratio), onto the fitted vertices (least squares over every
/// vertex); `None` for fewer than three vertices or a template with no spread.
pub fn fit_pose(template: &[[f64; 3]], fitted: &[[f64; 3]], scale: f64) -> Option<Similarity> {
    let pairs: Vec<([f64; 3], [f64; 3])> = template
        .iter()
        .zip(fitted)
        .map(|(y, f)| ([scale * y[0], scale * y[1], scale * y[2]], *f))
        .collect();
    let rigid = fit_pairs(&pairs, false)?;
    Some(Similarity { scale, ..rigid })
}

/// The pose gap (module docs) of the fit `fitted` of `template` onto `scan`, `scale` the fit's
/// median edge ratio. With `reference` (the best rigid placement's distance, known from the
/// fit's own pre-alignment of the same template onto the same points) no search runs. 1 when
/// the pose or the distances cannot be measured.
pub fn pose_gap(
    template: &[[f64; 3]],
    fitted: &[[f64; 3]],
    scan: &[[f64; 3]],
    scale: f64,
    reference: Option<f64>,
) -> f64 {
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let Some(pose) = fit_pose(template, fitted, scale) else {
        return 1.0;
    };
    let Some((basin, best)) = pose_scores(template, scan, &pose, reference.is_none()) else {
        return 1.0;
    };
    let best = best.min(reference.unwrap_or(f64::INFINITY));
    if basin > 0.0 && best > 0.0 && basin.is_finite() {
        (basin / best).max(1.0)
    } else {
        1.0
    }
}
