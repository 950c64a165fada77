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
//!    the RMS radii, plus the identity — with scale, where refining the identity rescales the
//!    template, the template's own orientation placed as those are, so that the search does
//!    not depend on the scan's unit. Rigidly, where a frame's two variances tie (a square
//!    sheet, a tube), the best coarse basin is also turned by ±30° and ±60° about that frame's
//!    third axis, and the best of those joins where it scores clearly below every other.
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
mod scale;
mod symmetry;
mod transform;

pub use axes::{cube_rotations, principal_axes, Axes};
pub use matching::{Clouds, Level, COARSE_SAMPLE_SIZE, KEPT_FRACTION, SAMPLE_SIZE};
pub use scale::{fitted_stretch, scaled_about_centroid, SCALE_SETTLED, SCALE_TRUSTED};
pub use transform::{fit_pairs, Similarity};

use crate::math::Mat3;
use crate::metrics::bbox_diagonal;
use rayon::prelude::*;

/// What the pre-alignment may change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Rotation and translation.
    Rigid,
    /// Rotation, translation and a uniform scale (also a scan in other units).
    Similarity,
}

/// A template whose two-sided distance as given is at most this fraction of the scan's RMS
/// radius, and whose principal axes agree with the scan's ([`Axes::agrees_with`]), is placed
/// already (the distance is of the order of the fold depth, a turned or
/// displaced one's of the order of the radius): only its own reading and its half turns are
/// searched ([`PLACED_TURN`]), and it is turned back by a half turn where that halves its score
/// ([`SEARCH_GAIN`]), else kept as given; in a scene ([`SCENE`]) it is kept without a search.
pub const PLACED: f64 = 0.1;

/// A template placed already ([`PLACED`]) is searched from the principal-frame candidates
/// turned at least this much (degrees) from it, or at most 180° less, only: its half turns
/// (back to front, upside down), the readings a garment that lies on its scan can be mistaken
/// for, and its own reading (without it, an exactly symmetric template's mirror reading can
/// win the least-turn tie-break); only a half turn moves it.
pub const PLACED_TURN: f64 = 150.0;

/// A scan whose bounding-box diagonal exceeds the template's this many times is a scene
/// larger than the garment (a dressed body; the same ratio as the dressed-scan rule of
/// docs/method.md "Scans of dressed people"): there a template placed is recognized by its
/// own distance to the scan alone.
pub const SCENE: f64 = 1.5;

/// Refined placements within this fraction of the best score are near-ties.
pub const NEAR_TIE: f64 = 0.1;

/// Near-ties whose rotation angles differ by less than this (degrees) are decided by score.
pub const SAME_ANGLE: f64 = 10.0;

/// An identity-basin placement turned less than this (degrees), and moved less than
/// [`PLACED`] of the scan's RMS radius, leaves the placement as given unchanged.
pub const SMALL_ANGLE: f64 = 10.0;

/// A template placed roughly right — the refinement of its placement as given ties with the
/// best — is moved only when the search's placement scores at most this fraction of the
/// placement as given: a flat sheet over its folded scan, or a garment over its wrinkled
/// frame, is otherwise left to the fit's rigid phase, which places it better than a rigid
/// match of the undeformed shape.
pub const SEARCH_GAIN: f64 = 0.5;

/// Coarse refinements scoring within this fraction above the best coarse score are refined
/// again on the full samples (the coarse score, on fewer points, is noisier).
pub const COARSE_MARGIN: f64 = 0.5;

/// At most this many distinct placements are refined on the full samples (a square sheet has
/// eight symmetric readings).
pub const FINALISTS: usize = 8;

/// Two coarse refinements turned less than this apart (degrees), and moved and scaled less
/// than [`SAME_PLACEMENT`] of the scan's RMS radius apart, are one placement.
pub const SAME_PLACEMENT_DEGREES: f64 = 2.0;

/// See [`SAME_PLACEMENT_DEGREES`].
pub const SAME_PLACEMENT: f64 = 0.02;

/// The result of [`align`].
#[derive(Clone, Copy, Debug)]
pub struct Alignment {
    /// Maps template coordinates onto the scan.
    pub transform: Similarity,
    /// The two-sided trimmed distance of the placement as given (scan units).
    pub identity_score: f64,
    /// The same for [`Alignment::transform`].
    pub score: f64,
    /// The lowest of every placement refined by the search (the placement as given's when
    /// nothing was searched): how close a rigid placement of the template comes to the scan.
    pub best_score: f64,
    /// Whether the candidates were searched (false: the identity was good enough).
    pub searched: bool,
    /// The distinct orientations (rotations [`SAME_ANGLE`] apart or more) among the refined
    /// placements within [`NEAR_TIE`] of the best score: more than one when the scan cannot
    /// tell the template's symmetric readings apart (a square sheet, a tube skirt, a T-shirt
    /// turned 90°), which the least turned then settles; 0 when nothing was searched.
    pub readings: usize,
    /// When the template was moved: the best-scoring other reading within [`NEAR_TIE`] of the
    /// best score (turned [`SAME_ANGLE`] or more from [`Alignment::transform`]) under which
    /// the template is another shape, not its own symmetric image — a T-shirt back to front.
    /// Rigid scores cannot decide between the two; the fit fits from both and keeps the one
    /// closer to the scan.
    pub alternative: Option<Similarity>,
}

/// The pre-alignment of `template` onto `scan` (see the module documentation). Either set with
/// fewer than three points, or a set with no spread, gives the identity.
pub fn align(template: &[[f64; 3]], scan: &[[f64; 3]], motion: Motion) -> Alignment {
    let identity = Similarity::identity();
    let unchanged = |score| Alignment {
        transform: identity,
        identity_score: score,
        score,
        best_score: score,
        searched: false,
        readings: 0,
        alternative: None,
    };
    let Some((ta, sa, clouds)) = searchable(template, scan) else {
        return unchanged(f64::NAN);
    };
    let (identity_score, identity_forward) = clouds.scores(&identity);
    // In a scene larger than the garment (a dressed body), most scan points are not the
    // garment's and the scan → template direction says nothing of the placement: a template
    // that lies on the scan is placed. (With the scale free, a larger scan is no scene: it may
    // be the garment in other units, which a template lies on a part of.)
    let scaled = motion == Motion::Similarity;
    let scene = !scaled && bbox_diagonal(scan) > SCENE * bbox_diagonal(template);
    if scene
        && (identity_score <= PLACED * sa.rms_radius || identity_forward <= PLACED * ta.rms_radius)
    {
        return unchanged(identity_score);
    }
    // A template that lies on the scan as given is searched too, from its own reading and its
    // half turns, and turned back by a half turn where that halves its score
    // ([`SEARCH_GAIN`]): a garment whose front and back differ a little can lie within
    // [`PLACED`] back to front.
    // A template turned a quarter turn from its scan can lie within [`PLACED`] of it by the
    // trimmed score alone (a round torso turned about its axis, the sleeves trimmed away): a
    // template whose principal axes disagree with the scan's is not placed.
    let placed = identity_score <= PLACED * sa.rms_radius && ta.agrees_with(&sa);
    let scale = start_scale(&ta, &sa, scaled);
    let (refined, given_index) =
        refined_placements(&clouds, &ta, &sa, scale, scaled, identity, placed);
    let (transform, score) = least_turned_near_tie(&refined);
    let readings = distinct_readings(&refined);
    let best = best_of(&refined);
    // Searched, and the placement as given kept.
    let kept = Alignment {
        searched: true,
        readings,
        best_score: best,
        ..unchanged(identity_score)
    };
    // A placed template is turned back by a half turn or kept: its own reading's basin is
    // left to the fit's rigid phase.
    if placed
        && (score > SEARCH_GAIN * identity_score || transform.turned_from(&identity) < PLACED_TURN)
    {
        return kept;
    }
    // A template placed roughly right — the basin of its placement as given ties with the
    // best — stays as given unless the search improves its score by [`SEARCH_GAIN`].
    let (basin, given_basin) = refined[given_index];
    // (With the scale free, a basin that rescales the template was not placed right: a scan in
    // other units.)
    let same_size = (basin.scale - 1.0).abs() < PLACED;
    if same_size && given_basin <= best * (1.0 + NEAR_TIE) && score > SEARCH_GAIN * identity_score {
        return kept;
    }
    // In a scene the two-sided score is mostly the body's: a placement elsewhere is taken only
    // when the template itself lies on the scan better there, by [`SEARCH_GAIN`].
    if scene && clouds.scores(&transform).1 > SEARCH_GAIN * identity_forward {
        return kept;
    }
    let moved = (transform.translation + (transform.rotation - Mat3::identity()) * sa.centroid)
        .norm()
        .max((transform.scale - 1.0).abs() * sa.rms_radius);
    if transform.angle_degrees() < SMALL_ANGLE && moved < PLACED * sa.rms_radius {
        return kept;
    }
    Alignment {
        transform,
        identity_score,
        score,
        best_score: best,
        searched: true,
        readings,
        alternative: other_reading(template, &clouds, &ta, &refined, &transform),
    }
}

/// The placement of `template` onto `scan` that a few landmarks choose (fewer than three, or
/// on a line: they fix no orientation themselves, docs/method.md "Landmarks"): of the placements
/// the search refines from the 24 principal-frame rotations and the placement as given
/// (searched whatever the scene or the placement as given): the search's own choice (the least
/// turned of the near-ties) unless another placement scoring within [`COARSE_MARGIN`] of the
/// best puts the landmark vertices `from` (template coordinates) nearer their targets `to` by
/// [`LANDMARK_GAIN`] (the sum of squared distances), then the nearest such. A scan turned back
/// to front fits a garment's two readings alike; a landmark off its symmetry plane says which
/// is right. `None` when the template or the scan cannot be searched (fewer than three points,
/// or no spread).
pub fn align_by_landmarks(
    template: &[[f64; 3]],
    scan: &[[f64; 3]],
    motion: Motion,
    from: &[[f64; 3]],
    to: &[[f64; 3]],
) -> Option<Similarity> {
    let (ta, sa, clouds) = searchable(template, scan)?;
    let scaled = motion == Motion::Similarity;
    let scale = start_scale(&ta, &sa, scaled);
    let identity = Similarity::identity();
    let (refined, _) = refined_placements(&clouds, &ta, &sa, scale, scaled, identity, false);
    let best = best_of(&refined);
    let miss = |t: &Similarity| -> f64 {
        from.iter()
            .zip(to)
            .map(|(p, q)| (crate::math::vec3(&t.apply(p)) - crate::math::vec3(q)).norm_squared())
            .sum()
    };
    let (chosen, _) = least_turned_near_tie(&refined);
    let nearest = refined
        .iter()
        .filter(|(_, score)| *score <= best * (1.0 + COARSE_MARGIN))
        .map(|(t, _)| (*t, miss(t)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    Some(match nearest {
        Some((t, m)) if m < LANDMARK_GAIN * miss(&chosen) => t,
        _ => chosen,
    })
}

/// The principal frames of `template` and `scan` and their matching samples, when both can be
/// searched: three points or more, with a spread.
fn searchable(template: &[[f64; 3]], scan: &[[f64; 3]]) -> Option<(Axes, Axes, Clouds)> {
    if template.len() < 3 || scan.len() < 3 {
        return None;
    }
    let (ta, sa) = (principal_axes(template), principal_axes(scan));
    (ta.rms_radius > 0.0 && sa.rms_radius > 0.0).then(|| (ta, sa, Clouds::new(template, scan)))
}

/// The scale the search's candidates start at: the RMS radii matched with the scale free, else 1.
fn start_scale(ta: &Axes, sa: &Axes, scaled: bool) -> f64 {
    if scaled {
        sa.rms_radius / ta.rms_radius
    } else {
        1.0
    }
}

/// Landmarks that fix no orientation move the search's choice to another of its placements
/// only when it puts them this much nearer their targets (sum of squared distances): the
/// other reading of a garment turned back to front misses them by its size, a nearby basin of
/// the same reading by little ([`align_by_landmarks`]).
pub const LANDMARK_GAIN: f64 = 0.5;

/// Every candidate placement of the template — the 24 rotations between the principal frames
/// `ta` and `sa` (centroids matched, the template scaled by `scale`) and `given`, and (rigidly)
/// the best of their coarse basins turned about a tied frame's axis ([`axes::tied_turns`]) where
/// that reaches a basin clearly below every other's — refined by
/// trimmed ICP on the coarse samples, side by side; the distinct placements that score near
/// the best there, and the basin of `given`, refined again on the full samples. Returns those
/// and the index of `given`'s basin among them. When `given` is `placed` (it lies on the scan),
/// only the candidates near it and its half turns are tried ([`PLACED_TURN`]).
///
/// With the scale free and `given` not placed, `given`'s orientation placed as the
/// principal-frame candidates are (centroids and RMS radii matched) is refined too, and stands
/// for `given` wherever `given`'s coarse basin rescales the template by [`PLACED`] or more (a
/// scan in other units): the search then does not depend on the unit. (Rigidly, only from
/// where it lies: from the centroids it would win the least-turn tie-break on turned scans
/// whose right reading scores no better.)
fn refined_placements(
    clouds: &Clouds,
    ta: &Axes,
    sa: &Axes,
    scale: f64,
    scaled: bool,
    given: Similarity,
    placed: bool,
) -> (Vec<(Similarity, f64)>, usize) {
    // A rotation with the centroids matched and the template scaled by `scale`.
    let centred = |rotation: Mat3| Similarity {
        rotation,
        scale,
        translation: sa.centroid - scale * (rotation * ta.centroid),
    };
    let cube = axes::candidate_rotations(ta, sa);
    // A template that lies on the scan: its own reading and its half turns (back to front,
    // upside down) only.
    let near_given_or_half_turn = |s: &Similarity| {
        let turn = s.turned_from(&given);
        !placed || turn >= PLACED_TURN || turn <= 180.0 - PLACED_TURN
    };
    let starts_of = |rotations: Vec<Mat3>| -> Vec<Similarity> {
        rotations
            .into_iter()
            .map(centred)
            .filter(near_given_or_half_turn)
            .collect()
    };
    let mut starts = starts_of(cube);
    let own = (scaled && !placed).then(|| centred(given.rotation));
    starts.extend(own);
    starts.push(given);
    let refine_coarse = |starts: Vec<Similarity>| -> Vec<(Similarity, f64)> {
        starts
            .into_par_iter()
            .map(|start| icp::refine(clouds, start, scaled, Level::Coarse))
            .collect()
    };
    let mut coarse = refine_coarse(starts);
    if own.is_some() {
        // The last two are the centred orientation's basin and `given`'s: one stands for it.
        let given_basin = coarse.pop().expect("the given's basin");
        if (given_basin.0.scale - 1.0).abs() < PLACED {
            *coarse.last_mut().expect("own's basin") = given_basin;
        }
    }
    // Where a frame's axes tie in a plane, the best basin turned about that frame's axis: the
    // cube candidates sample such a turn every 90° only. The best of those joins only where it
    // lies clearly below every other basin ([`NEAR_TIE`]): the turns are there to reach a basin
    // the cube candidates miss, not to add near-ties to the least-turned choice. Rigidly only:
    // with the scale free a lower trimmed score is no such sign (a drape's scan at half size
    // was placed 15× farther by it).
    if !scaled {
        let lowest = |c: &[(Similarity, f64)]| c.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1));
        let best = lowest(&coarse).expect("the given's basin at least");
        let turned = refine_coarse(starts_of(axes::tied_turns(ta, sa, &[best.0.rotation])));
        if let Some(reached) = lowest(&turned).filter(|t| t.1 < (1.0 - NEAR_TIE) * best.1) {
            coarse.insert(0, reached);
        }
    }
    let mut chosen = finalists(&coarse, sa.rms_radius);
    let given = coarse[coarse.len() - 1].0;
    let given_index = match chosen
        .iter()
        .position(|k| same_placement(k, &given, sa.rms_radius))
    {
        Some(i) => i,
        None => {
            chosen.push(given);
            chosen.len() - 1
        }
    };
    let refined: Vec<(Similarity, f64)> = chosen
        .into_par_iter()
        .map(|start| icp::refine(clouds, start, scaled, Level::Full))
        .collect();
    (refined, given_index)
}

/// The lowest score of `refined` (+∞ when empty).
fn best_of(refined: &[(Similarity, f64)]) -> f64 {
    refined.iter().map(|r| r.1).fold(f64::INFINITY, f64::min)
}

/// How a placement `pose` of `template` (a fit's rigid part, [`crate::quality`]'s pose gap)
/// lies on `scan`: the trimmed two-sided distance of the rigid placement that trimmed ICP
/// reaches from `pose` (its basin), and — with `search` — the lowest such distance of any
/// placement the search of [`align`] reaches from the 24 principal-frame rotations and
/// `pose` itself (without: the basin's again). The template moves rigidly at `pose.scale`.
/// `None` when either set has fewer than three points or no spread.
pub fn pose_scores(
    template: &[[f64; 3]],
    scan: &[[f64; 3]],
    pose: &Similarity,
    search: bool,
) -> Option<(f64, f64)> {
    if template.len() < 3 || scan.len() < 3 {
        return None;
    }
    // The scale is the pose's own; the search moves the template rigidly at that size.
    let sized: Vec<[f64; 3]> = template
        .iter()
        .map(|p| (pose.scale * crate::math::vec3(p)).into())
        .collect();
    let (ta, sa) = (principal_axes(&sized), principal_axes(scan));
    if !(ta.rms_radius > 0.0 && sa.rms_radius > 0.0) {
        return None;
    }
    let clouds = Clouds::new(&sized, scan);
    let rigid = Similarity {
        scale: 1.0,
        ..*pose
    };
    if !search {
        let (coarse, _) = icp::refine(&clouds, rigid, false, Level::Coarse);
        let basin = icp::refine(&clouds, coarse, false, Level::Full).1;
        return Some((basin, basin));
    }
    let (refined, given_index) = refined_placements(&clouds, &ta, &sa, 1.0, false, rigid, false);
    Some((refined[given_index].1, best_of(&refined)))
}

/// Of `refined` (non-empty), the best-scoring placement within [`NEAR_TIE`] of the best score
/// and turned [`SAME_ANGLE`] or more from `chosen`, unless the template turned from `chosen`
/// to it is its own symmetric image ([`symmetry::maps_onto_itself`]).
fn other_reading(
    template: &[[f64; 3]],
    clouds: &Clouds,
    axes: &Axes,
    refined: &[(Similarity, f64)],
    chosen: &Similarity,
) -> Option<Similarity> {
    let best = best_of(refined);
    let (other, _) = refined
        .iter()
        .filter(|r| r.1 <= best * (1.0 + NEAR_TIE) && r.0.turned_from(chosen) >= SAME_ANGLE)
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let turn = symmetry::relative(chosen, other);
    let symmetric = symmetry::maps_onto_itself(template, clouds.template_index(), axes, &turn);
    (!symmetric).then_some(*other)
}

/// Of the coarse refinements `coarse` (non-empty), those within [`COARSE_MARGIN`] of the best
/// coarse score, best first, each unless a better one is the same placement
/// ([`same_placement`]), at most [`FINALISTS`].
fn finalists(coarse: &[(Similarity, f64)], radius: f64) -> Vec<Similarity> {
    let best = coarse.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    let mut order: Vec<&(Similarity, f64)> = coarse
        .iter()
        .filter(|c| c.1 <= best * (1.0 + COARSE_MARGIN))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut kept: Vec<Similarity> = Vec::with_capacity(FINALISTS);
    for (t, _) in order {
        if !kept.iter().any(|k| same_placement(k, t, radius)) {
            kept.push(*t);
            if kept.len() == FINALISTS {
                break;
            }
        }
    }
    kept
}

/// Whether `a` and `b` are one placement: turned less than [`SAME_PLACEMENT_DEGREES`] apart,
/// translations and scales within [`SAME_PLACEMENT`] of the scan's RMS radius `radius`.
fn same_placement(a: &Similarity, b: &Similarity, radius: f64) -> bool {
    b.turned_from(a) < SAME_PLACEMENT_DEGREES
        && (a.translation - b.translation).norm() < SAME_PLACEMENT * radius
        && (a.scale - b.scale).abs() < SAME_PLACEMENT * a.scale
}

/// How many orientations the near-ties of `refined` (non-empty) hold: each placement within
/// [`NEAR_TIE`] of the best score counts unless one counted before is turned less than
/// [`SAME_ANGLE`] from it.
fn distinct_readings(refined: &[(Similarity, f64)]) -> usize {
    let best = refined.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    let mut kept: Vec<&Similarity> = Vec::new();
    for (t, score) in refined {
        if *score <= best * (1.0 + NEAR_TIE) && kept.iter().all(|k| t.turned_from(k) >= SAME_ANGLE)
        {
            kept.push(t);
        }
    }
    kept.len()
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
