//! The fit driver: ξ iterations of the N-body step (§2) followed by the FoldMatch deformation
//! model (§3) or the NRGa rigid-per-vertex update (docs/method.md,
//! "NRGa mode").
//!
//! One iteration, for every template vertex k (all from the same step's state, so the result
//! does not depend on the thread count):
//! 1. Γᵏ_X ← the K nearest scan points of Y_k ([`crate::knn`]);
//! 2. velocity and proposed position from Eq. 2–3 ([`crate::nbody`]);
//! 3. FoldMatch: H_k from the ring's old and proposed positions (Eq. 4), regularized (Eq. 5),
//!    ψ-modified stretch and wrinkle vector (Eq. 6–7), rotation by Procrustes (Eq. 8);
//!    NRGa: Kabsch rotation of the k-NN neighborhood;
//! 4. `Y_k ← R_k* Y_k + t_k*`; velocities re-synchronized with the applied motion.
//!
//! All per-vertex buffers are allocated once per fit ([`Workspace`]).

mod attraction;
mod coherent;
mod free_edges;
mod garment_cut;
mod garment_refit;
mod garments;
mod isometric;
mod landmark_pull;
mod model;
mod params;
mod phases;
mod placement;
mod presets;
mod refinement;
mod result;
mod rim_match;
mod schedule;
mod setup;
mod strain_limit;
mod support;
mod symmetry;
#[cfg(test)]
mod tests;
mod validate;

pub use attraction::{DRESSED_TRUST_FACTOR, GARMENT_FRAME_RATIO};
pub use coherent::{COHERENT_MARGIN, COHERENT_MAX_UNSUPPORTED};
pub use garments::GARMENT_MIN_SHARE;
pub use isometric::{HoldWhere, IsometricRefine, PlaneNormal, SpringScale, Springs};
pub use model::{deformation_model, TemplateTopology, Workspace};
pub use params::{
    Acceleration, FitParams, Method, ModelConstants, Prealign, Readings, RotationSource, Schedule,
    Selection, UnstretchedRefinement, ACCURATE_ITERATIONS, AUTO_COARSE_RINGS,
    AUTO_COARSE_RINGS_MAX, CARRIED_SPRING_FACTOR, CARRY_BAND, CARRY_FAR_EDGES, CARRY_MIN_BEHIND,
    CARRY_MIN_DEPTH, CARRY_MIN_SHARE, CARRY_SURPLUS, COARSE_RINGS_REFERENCE_VERTICES,
    COARSE_SCAN_MAX_AUTO_STRIDE, COARSE_SCAN_POINTS_PER_VERTEX, DEFAULT_CARRY_UNSUPPORTED,
    DEFAULT_COHERENT_GATE, DEFAULT_ISOMETRIC_HOLD, DEFAULT_ISOMETRIC_ITERATIONS,
    DEFAULT_ISOMETRIC_WEIGHT, DEFAULT_ITERATIONS, DEFAULT_KEEP_MARGIN, DEFAULT_KNN_SLACK,
    DEFAULT_K_MAX, DEFAULT_LANDMARK_WEIGHT, DEFAULT_RHO, DEFAULT_RIM_WEIGHT, DEFAULT_STRAIN_LIMIT,
    DEFAULT_TWO_WAY_RIM, DEFAULT_TWO_WAY_TRUST, FAR_AWAY, FAST_ITERATIONS, FAST_TWO_WAY,
    MAX_SCAN_SAMPLE, PAPER_ITERATIONS, PAPER_K_MAX, PAPER_RHO, RIGID_SCAN_POINTS_PER_VERTEX,
    SCHEDULE_NAMES, SIZE_MISMATCH, TRACKING_ISOMETRIC_ITERATIONS, TRACKING_ITERATIONS,
    TRACKING_REST_RIGIDITY, TRACKING_STRAIN_LIMIT, UNSTRETCHED_FLIPS, UNSTRETCHED_SMOOTHING,
    UNSTRETCHED_SPREAD, UNSTRETCHED_STEPS,
};
pub(crate) use placement::landmark_placement;
pub use placement::READING_MARGIN;
use placement::{fit_readings, prealigned, PlacedFit};
pub use refinement::{LANDMARK_ANCHOR, REFINE_POINTS_PER_VERTEX};
pub use result::{
    CoherentFigures, ComponentFigures, Diagnostics, FitResult, IterationRecord, PrealignFigures,
    Progress, StageTimes,
};
pub use schedule::{keeps_start, select_schedule};

use crate::error::{FoldMatchError, Result};
use crate::landmarks::Landmarks;
use crate::math::vec3;
use crate::quality::PoseSource;
use rayon::prelude::*;
use refinement::{isometric_refinement, Refinement};
use schedule::{drive, median_scan_distance, selection_distance, weighted_median, ScheduleRun};
use setup::Prepared;
use std::sync::atomic::{AtomicUsize, Ordering};

/// What may come with a scan besides its points, each `None` by default (docs/method.md).
#[derive(Clone, Copy, Debug, Default)]
pub struct ScanExtras<'a> {
    /// The scan's faces when it is a mesh: curvature from the mesh, rim matching onto its
    /// boundary (docs/method.md "Rim matching").
    pub faces: Option<&'a [[u32; 3]]>,
    /// A non-negative weight per scan point. A point's weight scales its pull in Eq. 2's
    /// neighbourhood mean (a weighted mean), in the two-way attraction and in schedule
    /// selection's scan distance; a point of weight 0 is removed before anything else (the
    /// normalized frame, K and the curvature are those of the points that remain), so a 0/1
    /// segmentation mask fits exactly as the masked scan would, and equal weights fit exactly
    /// as no weights. Weights of the wrong length, negative, not finite or all zero are refused
    /// ([`FoldMatchError::Parameter`] naming the first bad index).
    pub weights: Option<&'a [f64]>,
    /// The scan's own normals, one per scan point, as a scanner writes them (PLY `nx ny nz`):
    /// the planes of the isometric refinement's fit → scan term ([`Schedule::isometric_plane`]
    /// `"scan"`, the default), in place of each point's plane of its 12 nearest scan points;
    /// their sign does not matter. Normals of the wrong count, not finite or of zero length are
    /// refused ([`FoldMatchError::Parameter`] naming the first bad row). docs/method.md
    /// "Isometric refinement".
    pub normals: Option<&'a [[f64; 3]]>,
    /// Template vertices whose positions on the scan are known ([`Landmarks`], validated
    /// against the template by [`Landmarks::new`]). They decide the pre-alignment — three or
    /// more (not on a line): the rigid fit of the landmark vertices onto their targets moves
    /// the template first, in place of [`FitParams::prealign`]; fewer: they choose among the
    /// search's placements ([`crate::prealign::align_by_landmarks`]) — and pull their vertices
    /// toward the targets through every phase, with [`FitParams::landmark_weight`]
    /// (docs/method.md "Landmarks"). A landmark whose vertex is not in the template is refused
    /// ([`FoldMatchError::Landmark`]).
    pub landmarks: Option<&'a Landmarks>,
}

/// Fits the template to the target.
///
/// * `template_vertices` (M), `template_faces` (T) — the template mesh;
/// * `target` (N) — the scan points; `target_faces` — its faces when it is a mesh;
/// * `observer` — called after every iteration; returning `false` stops the fit, which then
///   returns what it has (with `diagnostics.stopped_by_callback`).
///
/// Under schedule selection ([`Selection::ScanDistance`], the default: the given and the sharp
/// schedule; [`Selection::ScanDistanceWide`]: also the gentle one) the candidates are fitted
/// side by side, in lockstep (each iteration of every run concurrently, then one progress
/// report, so progress counts ξ iterations and a stop applies to all), sharing the setup; the
/// fit closest to the scan is returned. [`fit_scan`] takes the scan's weights, normals and
/// landmarks as well.
pub fn fit(
    template_vertices: &[[f64; 3]],
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    let extras = ScanExtras {
        faces: target_faces,
        ..ScanExtras::default()
    };
    fit_scan(
        template_vertices,
        template_faces,
        target,
        &extras,
        params,
        observer,
    )
}

/// [`fit`] with whatever comes with the scan ([`ScanExtras`]: its faces, weights, normals and
/// landmarks).
pub fn fit_scan(
    template_vertices: &[[f64; 3]],
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    extras: &ScanExtras<'_>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    if let Some(n) = extras.normals {
        validate_normals(n, target.len())?;
    }
    garments::fit_garments(
        template_vertices,
        None,
        template_faces,
        target,
        extras.faces,
        extras.weights,
        extras.normals,
        extras.landmarks,
        params,
        observer,
    )
}

/// [`fit`] with scan weights ([`ScanExtras::weights`]) of a warm-started frame (docs/method.md
/// "Tracking"): the fit starts from `start` (the previous frame's fit, or a prediction from it)
/// while everything that refers to the template's metric refers to `rest`, the template as
/// given — the rest shape of the rest-shape rigidity ([`Schedule::rest_rigidity`]), the edge
/// spread of schedule selection and the quality verdict's edge distortion, flipped and
/// collapsed faces. So a sequence is
/// anchored to its template instead of to a previous fit, and a drifting frame is judged
/// against the template. `rest` must have `start`'s vertex count
/// ([`FoldMatchError::Shape`]) and finite coordinates.
#[allow(clippy::too_many_arguments)]
pub fn fit_anchored(
    start: &[[f64; 3]],
    rest: &[[f64; 3]],
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    target_weights: Option<&[f64]>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    crate::mesh::validate_points("rest", rest)?;
    if rest.len() != start.len() {
        return Err(FoldMatchError::shape(
            "rest",
            format!(
                "has {} vertices, the warm start {} (one rest position per template vertex)",
                rest.len(),
                start.len()
            ),
        ));
    }
    garments::fit_garments(
        start,
        Some(rest),
        template_faces,
        target,
        target_faces,
        target_weights,
        None,
        None,
        params,
        observer,
    )
}

/// What one [`fit_from`] is to the driver (docs/method.md "Scans of dressed people", "Several
/// garments").
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FitRole<'a> {
    /// The template is one garment of several, so the scan holds more than it whatever its
    /// size.
    pub(crate) several: bool,
    /// A garment refit's fit onto the garment's points of a larger scan (`target_weights`),
    /// whose isometric refinement is not pulled by the points beyond its rim.
    pub(crate) garment: bool,
    /// In a garment refit, the scan as the user gave it — the points of positive weight in the
    /// user's `target_weights` (`None`: every point) — on which its free edges are judged: a
    /// point of weight 0 is removed, unlike the skin that the refit's own weights leave out.
    pub(crate) user_scan: Option<&'a [[f64; 3]]>,
    /// The template the verdict measures the fit against when its rest shape is another (the
    /// coherent candidate's, [`coherent`]); `None`: the rest shape.
    pub(crate) judged_on: Option<&'a [[f64; 3]]>,
}

/// The fit of one garment ([`garments::fit_garments`] splits a template of several): from
/// `template_vertices`, with `rest` (`None`: the template itself) as the rest shape; `role`:
/// what the fit is to the driver ([`FitRole`]).
#[allow(clippy::too_many_arguments)]
fn fit_from(
    template_vertices: &[[f64; 3]],
    rest: Option<&[[f64; 3]]>,
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    target_weights: Option<&[f64]>,
    target_normals: Option<&[[f64; 3]]>,
    landmarks: Option<&Landmarks>,
    role: FitRole<'_>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    params.validate()?;
    if let Some(l) = landmarks {
        // Built against some template; checked again against this one.
        let vertices: Vec<i64> = l.vertices.iter().map(|&v| v as i64).collect();
        Landmarks::new(&vertices, &l.positions, template_vertices.len())?;
    }
    if let Some(w) = target_weights {
        validate_weights(w, target.len())?;
    }
    // Equal weights are no weights; zero weights remove their points.
    let target_weights = target_weights.filter(|w| w.iter().any(|&x| x != w[0]));
    let kept: Option<Vec<usize>> = target_weights
        .filter(|w| w.contains(&0.0))
        .map(|w| (0..w.len()).filter(|&j| w[j] > 0.0).collect());
    let mut schedules = params.candidate_schedules();
    let clock = std::time::Instant::now();
    // Landmarks, when given, decide the pre-alignment in its place (below).
    let (placed, mut prealign, other) = match landmarks {
        Some(_) => (None, None, None),
        None => prealigned(template_vertices, target, kept.as_deref(), params)?,
    };
    // A similarity's scale is that of the scan's shape, which folds and drapes shrink: the
    // fit from it says by how much its cloth had to stretch (docs/method.md "Global
    // pre-alignment"). After such a probe the fits that follow report the second half of the
    // progress.
    let placed_fit = PlacedFit {
        rest,
        template_faces,
        target,
        target_faces,
        target_weights,
        target_normals,
        role,
        params,
    };
    // A fit far from its rest shape gets a second candidate from a coherent start, once the
    // fit it follows is chosen (docs/method.md "Coherent candidate").
    let candidate = coherent::Candidate {
        eligible: !role.garment && !role.several && rest.is_none() && landmarks.is_none(),
        fit: &placed_fit,
        kept: kept.as_deref(),
    };
    let (placed, other, probed) = match (placed, params.prealign) {
        (Some(p), Prealign::Similarity) => {
            let probe = placed_fit.run(&p, 0, prealign, observer)?;
            let stretch = crate::prealign::fitted_stretch(&p, &probe.vertices, template_faces);
            let off = (stretch - 1.0).abs();
            let settled =
                off <= crate::prealign::SCALE_SETTLED || off > crate::prealign::SCALE_TRUSTED;
            if probe.diagnostics.stopped_by_callback || (other.is_none() && settled) {
                return candidate.after(probe, &p, observer);
            }
            if settled {
                (Some(p), other, true)
            } else {
                if let Some(figures) = prealign.as_mut() {
                    figures.scale_stretch = stretch;
                }
                let rescale =
                    |q: Vec<[f64; 3]>| crate::prealign::scaled_about_centroid(&q, stretch);
                (Some(rescale(p)), other.map(rescale), true)
            }
        }
        (placed, _) => (placed, other, false),
    };
    let mut outer = |q: &Progress| {
        if probed {
            observer(&q.of_parts(1, 2, params.iterations))
        } else {
            observer(q)
        }
    };
    let observer: &mut (dyn FnMut(&Progress) -> bool + Send) = &mut outer;
    if let (Some(placed), Some(other)) = (&placed, &other) {
        // Two readings of other shapes that rigid scores cannot tell apart (a garment turned
        // back to front): each fitted, the one closer to the scan kept.
        let (kept, reading) = fit_readings([placed, other], &placed_fit, prealign, observer)?;
        return candidate.after(kept, [placed, other][reading], observer);
    }
    // The pre-alignment's figures go into the result's diagnostics, whichever fit returns.
    let with_prealign = |mut result: FitResult| {
        result.diagnostics.prealign = prealign;
        result
    };
    // Landmarks place the template: the rigid fit of their vertices onto their targets, with a
    // similarity also its size (then in whatever unit the template was given). The template so
    // placed is the fit's template and, without a rest shape of its own, the one its metric is
    // measured on (docs/method.md "Landmarks").
    // (A garment pass starts where the first fit started; landmarks that fix no orientation
    // chose that start among the search's placements, and their centroid would move it.)
    let placed_by_landmarks: Option<Vec<[f64; 3]>> = landmarks
        .filter(|l| !role.garment || l.fix_orientation(template_vertices))
        .map(|l| {
            let scaled = params.prealign == Prealign::Similarity && rest.is_none();
            landmark_placement(
                template_vertices,
                target,
                kept.as_deref(),
                l,
                params,
                scaled,
            )
            .apply_all(template_vertices)
        });
    let template_vertices = placed
        .as_deref()
        .or(placed_by_landmarks.as_deref())
        .unwrap_or(template_vertices);
    // What the template's metric is measured on: the rest shape when one is given.
    let rest_shape = rest.unwrap_or(template_vertices);
    let prepared = Prepared::new(
        template_vertices,
        rest,
        template_faces,
        target,
        target_faces,
        target_weights,
        kept.as_deref(),
        landmarks,
        // A garment pass of one garment of several fits onto the points its earlier pass
        // explained or its cut kept (the other garment's too), not onto those the placed
        // template explains (docs/method.md "Several garments").
        role.several && !role.garment,
        &schedules,
    )?;
    // A scan that holds more than the garment is fitted more than once: the second fit onto
    // the points the first explains, the next onto the garment cut's points (docs/method.md
    // "Scans of dressed people"); each reports its share of the iterations to the observer.
    let refit = params.schedule.garment_refit > 0.0 && prepared.garment.is_some();
    let passes = if params.schedule.garment_cut > 0.0 {
        3
    } else {
        2
    };
    let total = params.iterations;
    let pass = AtomicUsize::new(0);
    let mut observed = |p: &Progress| {
        if refit {
            observer(&p.of_parts(pass.load(Ordering::Relaxed), passes, total))
        } else {
            observer(p)
        }
    };
    let observer: &mut (dyn FnMut(&Progress) -> bool + Send) = &mut observed;
    // The first of the two fits runs without the strain limit: the scan's skin pulls on it, and
    // an inextensible garment carries those pulls across itself (docs/method.md "Strain limiting").
    if refit {
        for s in &mut schedules {
            s.schedule.strain_limit = 0.0;
        }
    }
    let mut runs: Vec<ScheduleRun> = schedules
        .into_par_iter()
        .map(|p| ScheduleRun::new(&prepared, p))
        .collect();
    let setup = clock.elapsed().as_secs_f64();
    // Side by side up to the comparison (by default the last iteration; a single run: all).
    let compare_at = if runs.len() > 1 {
        ((params.schedule.selection_at * total as f64).ceil() as usize).clamp(1, total)
    } else {
        total
    };
    drive(&prepared, &mut runs, 1..=compare_at, total, observer)?;
    // The template's edges: schedule selection's spreads and the verdict's.
    let rest_edges = crate::metrics::EdgeLengths::new(rest_shape, &prepared.faces);
    // The candidates are compared on their fitted vertices alone.
    let mut selection = (runs.len() > 1).then(|| {
        let vertices: Vec<Vec<[f64; 3]>> =
            runs.iter().map(|r| r.user_vertices(&prepared)).collect();
        let (distances, nearest): (Vec<f64>, Vec<schedule::ScanNearest>) = vertices
            .par_iter()
            .map(|v| selection_distance(target, target_weights, prepared.garment.as_deref(), v))
            .unzip();
        let spreads: Vec<f64> = vertices.iter().map(|v| rest_edges.spread(v)).collect();
        let best = select_schedule(&distances, &spreads, params.schedule.selection_margin);
        Comparison {
            best,
            vertices,
            distances,
            spreads,
            nearest,
        }
    });
    let best = selection.as_ref().map_or(0, |s| s.best);
    let mut winner = runs.swap_remove(best);
    // The chosen run alone from the comparison on (nothing to do when it was the end).
    if compare_at < total && !winner.finished {
        drive(
            &prepared,
            std::slice::from_mut(&mut winner),
            compare_at + 1..=total,
            total,
            observer,
        )?;
    }
    let iterations = clock.elapsed().as_secs_f64() - setup;
    let vertices = match selection.as_mut() {
        Some(c) if compare_at == total => c.vertices.swap_remove(best),
        _ => winner.user_vertices(&prepared),
    };
    // Each scan point's nearest vertex of the chosen fit, when schedule selection compared
    // the finished fits (on the points of `prepared.garment`, else all).
    let compared_nearest = selection
        .as_ref()
        .filter(|_| compare_at == total)
        .map(|c| &c.nearest[best]);
    // Do no harm: a template already on its scan stays there (docs/method.md "Do no harm").
    // The template where the fit started (pre-aligned, by the landmarks too), in the user's frame.
    let mut start_vertices = prepared.start.clone();
    prepared.frame.inverse_in_place(&mut start_vertices);
    // Before a garment refit, the points compared are those the start explains by the refit's
    // rule (not past its rim): skin past a hem, which a fit drawn to it comes closer to, does
    // not count against a start that sits on its garment.
    let start_garment: Option<Vec<usize>> =
        (refit && params.schedule.keep_margin > 0.0).then(|| {
            let w = garment_refit::garment_weights(
                target,
                target_weights,
                &start_vertices,
                &prepared.faces,
                params.schedule.garment_refit,
            );
            (0..w.len()).filter(|&j| w[j] > 0.0).collect()
        });
    let garment = start_garment
        .as_deref()
        .filter(|g| !g.is_empty())
        .or(prepared.garment.as_deref());
    let kept_start = params.schedule.keep_margin > 0.0 && {
        // On the same points, the chosen fit's distances are schedule selection's.
        let same_points = start_garment.as_ref().is_none_or(|g| g.is_empty());
        let (fitted, start) = rayon::join(
            || match compared_nearest.filter(|_| same_points) {
                Some(n) => weighted_median(&n.distance, target_weights, garment),
                None => median_scan_distance(target, target_weights, garment, &vertices),
            },
            || median_scan_distance(target, target_weights, garment, &start_vertices),
        );
        keeps_start(start, fitted, params.schedule.keep_margin)
    };
    // The verdict against the points the fit was drawn to: those of positive weight, or on a
    // scan that holds more than the garment, those the template explains.
    let assessed = prepared.garment.as_deref().or(kept.as_deref());
    // On a scan that holds more than the garment the first fit's refinement sees the points the
    // template explains (`assessed`), which seed the garment's segmentation: a fit whose slides
    // are undone explains less skin (docs/method.md "Scans of dressed people").
    let refine = !kept_start && params.schedule.isometric_iterations > 0;
    let mut refinement = Refinement::None;
    let rim_matched = match &winner.rim {
        Some(r) if !kept_start => r.vertices.len(),
        _ => 0,
    };
    let vertices = if kept_start {
        winner.pos.clone_from(&prepared.start);
        start_vertices
    } else if refine {
        // A fit that left the template unstretched is refined to the rest shape's metric
        // (UNSTRETCHED_SPREAD): a garment pass, or with `every_fit` also a fit of a scan of
        // the garment alone that carried no region without scan support.
        let eligible = match params.schedule.unstretched_refinement {
            UnstretchedRefinement::Garments => role.garment,
            UnstretchedRefinement::EveryFit => {
                role.garment
                    || (prepared.garment.is_none()
                        && !role.several
                        && !winner.carried.contains(&true))
            }
            UnstretchedRefinement::Off => false,
        };
        let unstretched = eligible
            && rest_edges.stretch_field_spread(&vertices, UNSTRETCHED_SMOOTHING)
                < UNSTRETCHED_SPREAD;
        // The rim matching's targets from the schedule's result, held by the refinement.
        let rim = prepared
            .rim_match
            .as_ref()
            .filter(|_| params.schedule.rim_weight > 0.0 && winner.rim.is_some())
            .map(|rm| {
                let t = rm.targets(&winner.pos, prepared.edge_length);
                let mut positions: Vec<[f64; 3]> = t.targets.iter().map(|&q| q.into()).collect();
                prepared.frame.inverse_in_place(&mut positions);
                Landmarks {
                    vertices: t.vertices,
                    positions,
                }
            });
        let mut refined = vertices;
        // A tracked frame's rest shape is its sequence's own metric; a single fit's template
        // may be placed at any size.
        let scale = if rest.is_some() {
            SpringScale::Rest
        } else {
            SpringScale::Fit
        };
        refinement = isometric_refinement(
            &mut refined,
            rest_shape,
            scale,
            &prepared,
            target,
            target_weights,
            target_normals,
            assessed,
            landmarks,
            rim.as_ref(),
            role.garment.then(|| role.user_scan.unwrap_or(target)),
            &winner.carried,
            unstretched,
            params,
        );
        // The result's motion (its accumulated wrinkle field) ends at the refined fit.
        winner.pos = prepared.frame.forward(&refined);
        refined
    } else {
        vertices
    };
    // Schedule selection's nearest vertices, when the verdict's fit and points are its own.
    let scan_nearest = compared_nearest
        .filter(|_| !kept_start && !refine && (prepared.garment.is_some() || kept.is_none()))
        .map(|n| &n.vertex[..]);
    let two_rings =
        (params.method == Method::FoldMatch && params.model.rings == 2).then_some(&prepared.rings);
    // The verdict's pose figures: from the pre-alignment's best score and readings when it
    // scored the same template on the same points (no search of its own); left for later in a
    // fit that goes on to its garment passes, and in those passes (the driver sets the last
    // one's).
    let reference = prealign
        .filter(|_| params.prealign == Prealign::Rigid && rest.is_none())
        .filter(|_| prepared.garment.is_none())
        .map(|p| crate::quality::PoseReference {
            best_score: p.best_score,
            readings: p.readings_placed,
        });
    let pose = match &reference {
        _ if refit || role.garment || role.several => PoseSource::Deferred,
        Some(r) => PoseSource::Reference(r),
        None => PoseSource::Search,
    };
    // The template the verdict measures against, when it is not the rest shape.
    let judged_edges = role
        .judged_on
        .map(|j| crate::metrics::EdgeLengths::new(j, &prepared.faces));
    let (judged, judged_edges) = match (role.judged_on, &judged_edges) {
        (Some(j), Some(e)) => (j, e),
        _ => (rest_shape, &rest_edges),
    };
    let assessment = crate::quality::assess_points_with(
        &crate::quality::AssessInput {
            template_vertices: judged,
            faces: &prepared.faces,
            fitted_vertices: &vertices,
            scan: target,
        },
        assessed,
        &crate::quality::VerdictThresholds::default(),
        Some(crate::quality::KnownMesh {
            two_rings,
            edges: judged_edges,
            scan_nearest,
            pose,
            carried: (!kept_start && !winner.carried.is_empty()).then_some(&winner.carried[..]),
        }),
    )?;
    // Only the chosen run is finished (its wrinkle fields are a whole Eq. 4–8 pass).
    let mut chosen = winner.finish(&prepared, vertices, assessment);
    chosen.diagnostics.components = result::component_figures(
        &prepared.faces,
        &chosen.residuals,
        &chosen.support,
        chosen.quality.scan_diagonal,
    );
    if let Some(Comparison {
        distances, spreads, ..
    }) = selection
    {
        chosen.params = params.clone();
        let d = &mut chosen.diagnostics;
        d.schedule = SCHEDULE_NAMES[best].into();
        d.candidate_scan_distances = distances;
        d.candidate_edge_spreads = spreads;
        for other in &runs {
            d.knn_queries += other.diagnostics.knn_queries;
            d.two_way_queries += other.diagnostics.two_way_queries;
            d.stage_seconds.add(&other.ws.times);
        }
    }
    if refit {
        // The caller's parameters, not the first fit's (run without the strain limit).
        chosen.params = params.clone();
    }
    chosen.diagnostics.kept_start = kept_start;
    chosen.diagnostics.dressed = refit;
    chosen.diagnostics.refinement = refinement.name().to_owned();
    chosen.diagnostics.rim_matched = rim_matched;
    let finish = clock.elapsed().as_secs_f64() - setup - iterations;
    chosen.diagnostics.wall_seconds = [setup, iterations, finish];
    // A first fit that is final after all: its deferred pose figures, on the points it was judged on
    // (a garment of several is judged whole by its driver).
    let settled = |mut r: FitResult| {
        if refit && !role.several {
            r.quality = crate::quality::with_pose_figures(
                r.quality,
                rest_shape,
                &rest_edges,
                &r.vertices,
                target,
                assessed,
            );
        }
        r
    };
    if candidate.gated(&chosen) {
        // The template where this fit started, which is its rest shape.
        return candidate
            .after(chosen, rest_shape, observer)
            .map(with_prealign);
    }
    if !refit || kept_start || chosen.diagnostics.stopped_by_callback {
        return Ok(with_prealign(settled(chosen)));
    }
    let weights = garment_refit::garment_weights(
        target,
        target_weights,
        &chosen.vertices,
        &prepared.faces,
        params.schedule.garment_refit,
    );
    let live = kept.as_ref().map_or(target.len(), Vec::len);
    // Too little to be the garment, or nothing left out: no fit onto these points.
    let usable = |points: usize| points >= template_vertices.len() / 4 && points < live;
    if !usable(garment_refit::garment_points(&weights)) {
        // The first fit stands.
        return Ok(with_prealign(settled(chosen)));
    }
    let mut inner = params.clone();
    inner.schedule.garment_refit = 0.0;
    // The first fit was not worse than its start; the second is not compared with it again
    // (on its fewer points the start can look as close as a fit that is far better).
    inner.schedule.keep_margin = 0.0;
    // From where the first fit started (pre-aligned already, by the landmarks too).
    inner.prealign = Prealign::None;
    let mut start = prepared.start.clone();
    prepared.frame.inverse_in_place(&mut start);
    // The scan as the user gave it, where the user's weights removed points.
    let user_scan: Option<Vec<[f64; 3]>> = kept
        .as_ref()
        .map(|k| k.iter().map(|&j| target[j]).collect());
    // Each later fit from the same start, with the same rest shape (a tracked frame stays
    // anchored), onto the weights of its pass.
    let mut fit_onto = |weights: &[f64], part: usize| -> Result<FitResult> {
        pass.store(part, Ordering::Relaxed);
        let mut fitted = fit_from(
            &start,
            rest,
            template_faces,
            target,
            target_faces,
            Some(weights),
            target_normals,
            landmarks,
            FitRole {
                garment: true,
                user_scan: user_scan.as_deref(),
                ..role
            },
            &inner,
            &mut *observer,
        )?;
        fitted.params = params.clone();
        fitted.garment_points = (0..weights.len() as u32)
            .filter(|&j| weights[j as usize] > 0.0)
            .collect();
        fitted.diagnostics.garment_refit_points = fitted.garment_points.len();
        Ok(fitted)
    };
    let mut last = fit_onto(&weights, 1)?;
    // The garment cut: the garment's points by the seam where the scan steps onto the skin,
    // seeded by the last fit, and a fit onto them; cut again while the garment's points still
    // change (a cut seeded by a fit that was wrong over a region is wrong there too).
    let cuts = if params.schedule.garment_cut > 0.0 {
        garment_cut::MAX_CUTS
    } else {
        0
    };
    let mut previous: Option<Vec<f64>> = None;
    for round in 0..cuts {
        if last.diagnostics.stopped_by_callback {
            break;
        }
        let cut = garment_cut::garment_cut_weights(
            target,
            target_weights,
            &last.vertices,
            &prepared.faces,
            params.schedule.garment_refit,
            params.schedule.garment_cut,
        );
        if !usable(garment_refit::garment_points(&cut))
            || previous
                .as_deref()
                .is_some_and(|before| garment_cut::settled(before, &cut))
        {
            break;
        }
        last = fit_onto(&cut, 2 + round)?;
        previous = Some(cut);
    }
    // The last pass's verdict, with the pose figures its passes left out, on its garment's points.
    if !role.several {
        let points: Vec<usize> = last.garment_points.iter().map(|&j| j as usize).collect();
        last.quality = crate::quality::with_pose_figures(
            last.quality,
            rest_shape,
            &rest_edges,
            &last.vertices,
            target,
            Some(&points),
        );
    }
    last.diagnostics.dressed = true;
    Ok(with_prealign(last))
}

/// Schedule selection's comparison of the candidates' fits (in the user's frame).
struct Comparison {
    /// The chosen candidate.
    best: usize,
    /// Each candidate's fitted vertices.
    vertices: Vec<Vec<[f64; 3]>>,
    /// Each candidate's scan distance ([`selection_distance`]).
    distances: Vec<f64>,
    /// Each candidate's edge-length spread.
    spreads: Vec<f64>,
    /// Each candidate's nearest vertex of every compared scan point.
    nearest: Vec<schedule::ScanNearest>,
}

/// Checks scan weights: one per scan point, finite, non-negative, not all zero.
pub fn validate_weights(weights: &[f64], points: usize) -> Result<()> {
    let name = "target_weights";
    if weights.len() != points {
        return Err(FoldMatchError::parameter(
            name,
            format!("{} weights", weights.len()),
            &format!("need one weight per scan point ({points})"),
        ));
    }
    if let Some(j) = weights.iter().position(|w| !w.is_finite() || *w < 0.0) {
        return Err(FoldMatchError::parameter(
            &format!("{name}[{j}]"),
            weights[j],
            "weights must be finite and >= 0",
        ));
    }
    if !weights.iter().any(|&w| w > 0.0) {
        return Err(FoldMatchError::parameter(
            name,
            "all zero",
            "at least one scan point needs a positive weight",
        ));
    }
    Ok(())
}

/// The scan points that remain: those of `kept` (indices into `target`), else all of them.
pub(crate) fn kept_points<'a>(
    target: &'a [[f64; 3]],
    kept: Option<&[usize]>,
) -> std::borrow::Cow<'a, [[f64; 3]]> {
    match kept {
        Some(k) => k.iter().map(|&j| target[j]).collect(),
        None => std::borrow::Cow::Borrowed(target),
    }
}

/// Checks scan normals: one per scan point, finite, of non-zero length (their length and sign
/// are not used).
pub fn validate_normals(normals: &[[f64; 3]], points: usize) -> Result<()> {
    let name = "target_normals";
    if normals.len() != points {
        return Err(FoldMatchError::parameter(
            name,
            format!("{} normals", normals.len()),
            &format!("need one normal per scan point ({points})"),
        ));
    }
    let bad = |n: &[f64; 3]| {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        !(length.is_finite() && length > 0.0)
    };
    if let Some(j) = normals.iter().position(bad) {
        return Err(FoldMatchError::parameter(
            &format!("{name}[{j}]"),
            format!("{:?}", normals[j]),
            "a normal must be finite and of non-zero length",
        ));
    }
    Ok(())
}

/// Fits without an observer.
pub fn fit_simple(
    template_vertices: &[[f64; 3]],
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    params: &FitParams,
) -> Result<FitResult> {
    fit(
        template_vertices,
        template_faces,
        target,
        target_faces,
        params,
        &mut |_| true,
    )
}

/// Magnitudes of a vector field.
pub fn magnitudes(field: &[[f64; 3]]) -> Vec<f64> {
    field.iter().map(|v| vec3(v).norm()).collect()
}
