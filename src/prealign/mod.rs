//! Global pre-alignment (docs/method.md, "Global pre-alignment"): the rigid motion — or the
//! similarity, when the scale is free — that places the template on a scan given in any
//! orientation, position and (with scale) unit.
//!
//! 1. The placement as given (the identity) is scored first by the robust two-sided distance
//!    of `matching`; when it already lies within [`PLACED`] of the scan's RMS radius, it is
//!    kept and nothing else runs (a scan in the template's frame costs two k-d trees and one
//!    scoring).
//! 2. Otherwise the candidates are the 24 rotations between the two principal frames
//!    (`axes`: every axis order and sign), each with the centroids matched and — with scale —
//!    the RMS radii, plus the identity.
//! 3. Every candidate is refined by trimmed ICP (`icp`) — ranking them before refining
//!    misses the right one on folded cloth, whose principal axes are not the flat template's
//!    (measured on a folded sheet turned 60°: the right basin was not among the 6 best
//!    unrefined candidates). Of the
//!    refined placements that score within [`NEAR_TIE`] of the best, the one turned least
//!    from the placement as given is kept (a near-tie by angle, within [`SAME_ANGLE`], goes
//!    to the lower score): a garment that is nearly symmetric matches the scan about as well
//!    turned 180°, and the least turn is the likelier reading of a scan that came z-up, or
//!    turned, or already placed. When that is the identity's own basin and ICP moved it by
//!    less than [`SMALL_ANGLE`] and [`PLACED`] of the scan's RMS radius, the placement as given
//!    is kept exactly (the fit's rigid phase finishes it; on a scan already in the template's
//!    frame the result does not change).
//!
//! What this cannot see: a template that is symmetric (a flat square sheet, a tube skirt about
//! its axis, a T-shirt whose front and back differ only at the neckline) matches the scan
//! equally well in each of its symmetric placements, and only one of them has the right
//! correspondences; turned 90° about the vertical, a front/back-symmetric garment has two
//! equally short turns (±90°). Landmarks decide it.

mod axes;
mod icp;
mod matching;
mod transform;

pub use axes::{cube_rotations, principal_axes, Axes};
pub use matching::{Clouds, KEPT_FRACTION, SAMPLE_SIZE};
pub use transform::{fit_pairs, Similarity};

use crate::math::Mat3;

/// What the pre-alignment may change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Rotation and translation.
    Rigid,
    /// Rotation, translation and a uniform scale (also a scan in other units).
    Similarity,
}

/// The identity is kept without a search when its two-sided distance is at most this fraction
/// of the scan's RMS radius (a placed template: the distance is of the order of the fold
/// depth, a turned or displaced one of the order of the radius).
pub const PLACED: f64 = 0.1;

/// Refined placements within this fraction of the best score are near-ties.
pub const NEAR_TIE: f64 = 0.1;

/// Near-ties whose rotation angles differ by less than this (degrees) are decided by score.
pub const SAME_ANGLE: f64 = 10.0;

/// An identity-basin placement turned less than this (degrees), and moved less than
/// [`PLACED`] of the scan's RMS radius, leaves the placement as given unchanged.
pub const SMALL_ANGLE: f64 = 10.0;

/// The result of [`align`].
#[derive(Clone, Copy, Debug)]
pub struct Alignment {
    /// Maps template coordinates onto the scan.
    pub transform: Similarity,
    /// The two-sided trimmed distance of the placement as given (scan units).
    pub identity_score: f64,
    /// The same for [`Alignment::transform`].
    pub score: f64,
    /// Whether the candidates were searched (false: the identity was good enough).
    pub searched: bool,
}

/// The pre-alignment of `template` onto `scan` (see the module documentation). Either set with
/// fewer than three points, or a set with no spread, gives the identity.
pub fn align(template: &[[f64; 3]], scan: &[[f64; 3]], motion: Motion) -> Alignment {
    let identity = Similarity::identity();
    let unchanged = |score| Alignment {
        transform: identity,
        identity_score: score,
        score,
        searched: false,
    };
    if template.len() < 3 || scan.len() < 3 {
        return unchanged(f64::NAN);
    }
    let (ta, sa) = (principal_axes(template), principal_axes(scan));
    if !(ta.rms_radius > 0.0 && sa.rms_radius > 0.0) {
        return unchanged(f64::NAN);
    }
    let clouds = Clouds::new(template, scan);
    let identity_score = clouds.score(&identity);
    if identity_score <= PLACED * sa.rms_radius {
        return unchanged(identity_score);
    }
    let scaled = motion == Motion::Similarity;
    let scale = if scaled {
        sa.rms_radius / ta.rms_radius
    } else {
        1.0
    };
    let mut starts: Vec<Similarity> = axes::candidate_rotations(&ta, &sa)
        .into_iter()
        .map(|rotation| Similarity {
            rotation,
            scale,
            translation: sa.centroid - scale * (rotation * ta.centroid),
        })
        .collect();
    starts.push(identity);
    let refined: Vec<(Similarity, f64)> = starts
        .into_iter()
        .map(|start| icp::refine(&clouds, start, scaled))
        .collect();
    let (transform, score) = least_turned_near_tie(&refined);
    let moved = (transform.translation + (transform.rotation - Mat3::identity()) * sa.centroid)
        .norm()
        .max((transform.scale - 1.0).abs() * sa.rms_radius);
    if transform.angle_degrees() < SMALL_ANGLE && moved < PLACED * sa.rms_radius {
        return Alignment {
            searched: true,
            ..unchanged(identity_score)
        };
    }
    Alignment {
        transform,
        identity_score,
        score,
        searched: true,
    }
}

/// Of `refined` (non-empty), the placements within [`NEAR_TIE`] of the best score; of those,
/// the least turned (a difference under [`SAME_ANGLE`] decided by score).
fn least_turned_near_tie(refined: &[(Similarity, f64)]) -> (Similarity, f64) {
    let best = refined.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    let ties: Vec<&(Similarity, f64)> = refined
        .iter()
        .filter(|r| r.1 <= best * (1.0 + NEAR_TIE))
        .collect();
    let least = ties
        .iter()
        .map(|r| r.0.angle_degrees())
        .fold(f64::INFINITY, f64::min);
    *ties
        .into_iter()
        .filter(|r| r.0.angle_degrees() < least + SAME_ANGLE)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("the least-turned near-tie")
}

#[cfg(test)]
mod tests;
