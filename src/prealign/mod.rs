//! Global pre-alignment (docs/method.md, "Global pre-alignment"): the rigid motion — or the
//! similarity, when the scale is free — that places the template on a scan given in any
//! orientation, position and (with scale) unit.
//!
//! 1. The placement as given (the identity) is scored first by the robust two-sided distance
//!    of [`matching`]; when it already lies within [`PLACED`] of the scan's RMS radius, it is
//!    kept and nothing else runs (a scan in the template's frame costs two k-d trees and one
//!    scoring).
//! 2. Otherwise the candidates are the 24 rotations between the two principal frames
//!    ([`axes`]: every axis order and sign), each with the centroids matched and — with scale —
//!    the RMS radii, plus the identity; all are scored.
//! 3. The [`REFINED`] best and the identity are refined by trimmed ICP ([`icp`]); the best
//!    refined transform is kept, unless the identity scores within [`IDENTITY_MARGIN`] of it
//!    (the placement as given wins ties: on a scan already in the template's frame the result
//!    never gets worse than today's).
//!
//! What this cannot see: a garment that is nearly symmetric (a T-shirt's front and back, the
//! left and right of a skirt) matches the scan about as well turned 180°, and the two-sided
//! distance may prefer the turned placement; landmarks decide it.

mod axes;
mod icp;
mod matching;
mod transform;

pub use axes::{cube_rotations, principal_axes, Axes};
pub use matching::{Clouds, KEPT_FRACTION, SAMPLE_SIZE};
pub use transform::{fit_pairs, Similarity};

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

/// How many of the best-scoring principal-axis candidates are refined by ICP.
pub const REFINED: usize = 6;

/// The identity is kept when its score is within this fraction of the best refined one's.
pub const IDENTITY_MARGIN: f64 = 0.1;

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
    let mut candidates: Vec<(Similarity, f64)> = axes::candidate_rotations(&ta, &sa)
        .into_iter()
        .map(|rotation| {
            let t = Similarity {
                rotation,
                scale,
                translation: sa.centroid - scale * (rotation * ta.centroid),
            };
            (t, clouds.score(&t))
        })
        .collect();
    candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
    candidates.truncate(REFINED);
    candidates.push((identity, identity_score));
    let best = candidates
        .into_iter()
        .map(|(start, _)| icp::refine(&clouds, start, scaled))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("at least the identity");
    if identity_score <= best.1 * (1.0 + IDENTITY_MARGIN) {
        return Alignment {
            searched: true,
            ..unchanged(identity_score)
        };
    }
    Alignment {
        transform: best.0,
        identity_score,
        score: best.1,
        searched: true,
    }
}

#[cfg(test)]
mod tests;
