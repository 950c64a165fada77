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
//!
//! `pose_turn`, the angle from the fit's pose to the placement the pre-alignment would start a
//! fit from (the nearest of its two readings when it fits both), counted when the gap is at
//! least 1 + [`TURN_GAIN`]: a garment that is nearly its own image turned (a folded T-shirt
//! back to front) lies on the scan almost as well in the wrong reading, so its gap stays small
//! (1.05–1.3, within a right fit's), but the search starts it half a turn away. A right fit
//! lies where the search starts it (docs/method.md "Quality verdict").

use crate::prealign::{align, fit_pairs, pose_scores, Motion, Similarity};

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

/// What the fit's own pre-alignment of the same template onto the same points found: with it
/// no search runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseReference {
    /// The trimmed two-sided distance of the best rigid placement it refined.
    pub best_score: f64,
    /// The placements it would start a fit from (template → scan): its choice
    /// ([`crate::prealign::Alignment::transform`]) and, when the template was moved, the other
    /// reading it fitted too ([`crate::prealign::Alignment::alternative`]).
    pub readings: [Option<Similarity>; 2],
}

/// The pose turn ([`PoseFigures::turn`]) counts only when some rigid placement lies at least
/// this much closer to the scan than the pose's basin (a pose gap of 1 + this): the exact
/// symmetric readings of a template (a square sheet turned a quarter) tie, and are not turned.
pub const TURN_GAIN: f64 = 0.02;

/// The figures of a fit's rigid pose (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseFigures {
    /// `d(basin of the pose) / d(best)`, ≥ 1.
    pub gap: f64,
    /// The angle in degrees from the fit's pose to the nearest of the placements the
    /// pre-alignment would start a fit from, when the gap is [`TURN_GAIN`] or more; else 0.
    pub turn: f64,
}

impl PoseFigures {
    /// No figure: the pose or the distances could not be measured.
    pub const NONE: Self = Self {
        gap: 1.0,
        turn: 0.0,
    };
}

/// The pose figures (module docs) of the fit `fitted` of `template` onto `scan`, `scale` the
/// fit's median edge ratio. With `reference` (the fit's own pre-alignment) no search runs;
/// without, the pre-alignment ([`crate::prealign::align`], rigid, of the template at the fit's
/// scale) runs beside the pose's search. [`PoseFigures::NONE`] when the pose or the distances
/// cannot be measured.
pub fn pose_figures(
    template: &[[f64; 3]],
    fitted: &[[f64; 3]],
    scan: &[[f64; 3]],
    scale: f64,
    reference: Option<&PoseReference>,
) -> PoseFigures {
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let Some(pose) = fit_pose(template, fitted, scale) else {
        return PoseFigures::NONE;
    };
    let Some((basin, best)) = pose_scores(template, scan, &pose, reference.is_none()) else {
        return PoseFigures::NONE;
    };
    let best = best.min(reference.map_or(f64::INFINITY, |r| r.best_score));
    if !(basin > 0.0 && best > 0.0 && basin.is_finite()) {
        return PoseFigures::NONE;
    }
    let gap = (basin / best).max(1.0);
    if gap < 1.0 + TURN_GAIN {
        return PoseFigures { gap, turn: 0.0 };
    }
    let readings = match reference {
        Some(r) => r.readings,
        None => {
            let sized: Vec<[f64; 3]> = template
                .iter()
                .map(|p| (scale * crate::math::vec3(p)).into())
                .collect();
            let a = align(&sized, scan, Motion::Rigid);
            [Some(a.transform), a.alternative]
        }
    };
    let turn = readings
        .iter()
        .flatten()
        .map(|r| pose.turned_from(r))
        .fold(f64::INFINITY, f64::min);
    PoseFigures {
        gap,
        turn: if turn.is_finite() { turn } else { 0.0 },
    }
}
