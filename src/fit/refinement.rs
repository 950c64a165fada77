//! The isometric refinement that ends a fit (docs/method.md "Isometric refinement"): which
//! scan points it sees, its springs, and whether a fit the schedule left unstretched is freed
//! (held only where the scan has no points for it) or held everywhere.

use super::free_edges;
use super::isometric::{HoldWhere, IsometricRefine, SpringScale, Springs};
use super::params::{FitParams, CARRIED_SPRING_FACTOR, UNSTRETCHED_FLIPS, UNSTRETCHED_STEPS};
use super::setup::Prepared;
use crate::landmarks::Landmarks;
use crate::math::vec3;
use crate::metrics::cross_of;
use rayon::prelude::*;
use std::borrow::Cow;

/// The [`IsometricRefine`] of `vertices` (in place) against the scan points the fit was drawn
/// to (`assessed`, else all), weighted by `weights`, the landmark vertices held at their
/// landmarks ([`LANDMARK_ANCHOR`] × the landmark weight) and the rim vertices at the rim
/// matching's targets (`rim`, the same × the rim weight; docs/method.md "Rim matching"),
/// with the scan's own normals as its planes where the user gave them (`normals`, indexed
/// as `target`), without the pull of the points beyond the rim on a garment pass
/// (`garment_pass`: the scan its free edges are judged on), its springs [`CARRIED_SPRING_FACTOR`] times as stiff and the
/// vertices of the region without a fit → scan match when the schedule carried a region
/// without scan support (`carried`, a flag per vertex or empty); `unstretched`
/// ([`UNSTRETCHED_SPREAD`](super::UNSTRETCHED_SPREAD)): [`UNSTRETCHED_STEPS`] steps at least,
/// the hold only where the scan has no points for the fit ([`HoldWhere::Unsupported`]), or —
/// outside a garment pass — with the hold everywhere where that turned over more than
/// [`UNSTRETCHED_FLIPS`] of the faces. Nothing when fewer than a plane's worth of points.
/// Returns how it ended.
#[allow(clippy::too_many_arguments)]
pub(super) fn isometric_refinement(
    vertices: &mut [[f64; 3]],
    rest: &[[f64; 3]],
    scale: SpringScale,
    prepared: &Prepared,
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    normals: Option<&[[f64; 3]]>,
    assessed: Option<&[usize]>,
    landmarks: Option<&Landmarks>,
    rim: Option<&Landmarks>,
    garment_pass: Option<&[[f64; 3]]>,
    carried: &[bool],
    unstretched: bool,
    params: &FitParams,
) -> Refinement {
    let carries = carried.contains(&true);
    // Every `stride`-th of the points: at most about REFINE_POINTS_PER_VERTEX per vertex.
    let live = assessed.map_or(target.len(), <[usize]>::len);
    let stride = live
        .div_ceil(REFINE_POINTS_PER_VERTEX * vertices.len().max(1))
        .max(1);
    // The scan as given when it is seen whole; else a copy of the points seen.
    let whole = assessed.is_none() && stride == 1;
    let points: Cow<[[f64; 3]]> = match assessed {
        _ if whole => Cow::Borrowed(target),
        Some(kept) => kept.iter().step_by(stride).map(|&j| target[j]).collect(),
        None => target.iter().step_by(stride).copied().collect(),
    };
    let point_weights: Option<Cow<[f64]>> = weights.map(|w| match assessed {
        _ if whole => Cow::Borrowed(w),
        Some(kept) => kept.iter().step_by(stride).map(|&j| w[j]).collect(),
        None => w.iter().step_by(stride).copied().collect(),
    });
    let point_weights = point_weights.filter(|w| w.iter().any(|&x| x > 0.0));
    let point_normals: Option<Cow<[[f64; 3]]>> = normals.map(|n| match assessed {
        _ if whole => Cow::Borrowed(n),
        Some(kept) => kept.iter().step_by(stride).map(|&j| n[j]).collect(),
        None => n.iter().step_by(stride).copied().collect(),
    });
    if points.len() < 12 {
        return Refinement::None;
    }
    let (faces, incidence) = (&prepared.faces, &prepared.incidence);
    let mut refine =
        IsometricRefine::new(rest, faces, incidence, &points, point_weights.as_deref())
            .with_plane_normal(params.schedule.isometric_plane);
    if let Some(n) = &point_normals {
        refine = refine.with_scan_normals(n);
    }
    if let Some(l) = landmarks {
        let weight = LANDMARK_ANCHOR * params.landmark_weight;
        refine = refine.with_anchors(&l.vertices, &l.positions, weight);
    }
    if let Some(r) = rim {
        let weight = LANDMARK_ANCHOR * params.schedule.rim_weight;
        refine = refine.with_anchors(&r.vertices, &r.positions, weight);
    }
    // The region carried without scan support has no fit → scan match either (its nearest
    // scan points lie on the seen side): docs/method.md "Partial scans".
    refine = refine.without_scan_under(carried);
    if let Some(scan) = garment_pass {
        // The scan past the rim is mostly skin the cut left in, but past a free edge it is
        // the garment's own (docs/method.md "Free edges"): judged on the whole scan (the
        // points the user kept).
        let free = free_edges::free_edge_faces(vertices, faces, scan);
        refine = refine.without_rim_pull().with_free_edges(free);
    }
    let springs = |hold_where| Springs {
        weight: params.schedule.isometric_weight
            * if carries { CARRIED_SPRING_FACTOR } else { 1.0 },
        hold: params.schedule.isometric_hold,
        scale,
        hold_where,
    };
    let held = springs(HoldWhere::Everywhere);
    if !unstretched {
        refine.run(vertices, params.schedule.isometric_iterations, held);
        return Refinement::Held;
    }
    // Freed where the scan has points for the fit; outside a garment pass, held everywhere
    // instead where that turned over more than UNSTRETCHED_FLIPS of the faces (a garment
    // pass's skin next to the garment and hidden parts turn faces that its freed springs
    // place right: bench.dressed, the penetrating skirt unplaced 24.4 mm freed, 29.8 guarded).
    let start = vertices.to_vec();
    let steps = params.schedule.isometric_iterations.max(UNSTRETCHED_STEPS);
    refine.run(vertices, steps, springs(HoldWhere::Unsupported));
    if garment_pass.is_some() || turned_over_share(&start, vertices, faces) <= UNSTRETCHED_FLIPS {
        return Refinement::Freed;
    }
    vertices.copy_from_slice(&start);
    refine.run(vertices, params.schedule.isometric_iterations, held);
    Refinement::HeldAfterFlips
}

/// The share of `faces` whose normal in `after` points against their normal in `before`.
pub(super) fn turned_over_share(
    before: &[[f64; 3]],
    after: &[[f64; 3]],
    faces: &[[u32; 3]],
) -> f64 {
    let normal = |p: &[[f64; 3]], f: &[u32; 3]| vec3(&cross_of(p, f));
    let turned = faces
        .par_iter()
        .filter(|f| normal(before, f).dot(&normal(after, f)) < 0.0)
        .count();
    turned as f64 / faces.len().max(1) as f64
}

/// How [`isometric_refinement`] ended a fit
/// ([`Diagnostics::refinement`](super::Diagnostics::refinement)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Refinement {
    None,
    Held,
    Freed,
    HeldAfterFlips,
}

impl Refinement {
    pub(super) fn name(self) -> &'static str {
        match self {
            Refinement::None => "",
            Refinement::Held => "held",
            Refinement::Freed => "freed",
            Refinement::HeldAfterFlips => "held_after_flips",
        }
    }
}

/// The isometric refinement sees at most about this many scan points per template vertex
/// (every k-th point of a denser scan): its scan → fit matches and the scan's normals cost in
/// proportion to the points, and four per vertex cover the fit as densely as it can be pulled
/// (a 100K-vertex template on a million points: the fit's finish 10.7 → 5.0 s).
pub const REFINE_POINTS_PER_VERTEX: usize = 4;

/// The weight of a landmark vertex's anchor in the isometric refinement, per unit of
/// [`FitParams::landmark_weight`], against a vertex's fit → scan weight of 1: it keeps the
/// landmark vertices at their landmarks, as the schedule's landmark pull left them.
pub const LANDMARK_ANCHOR: f64 = 100.0;
