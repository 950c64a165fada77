//! The phases of a FoldMatch schedule — rigid, coarse (piecewise rigid) and fine (the
//! deformation model, with the rest-shape rigidity) — and the softening annealing.

use super::attraction::Attraction;
use super::model::{deformation_rotations, Workspace};
use super::params::{FitParams, Method};
use super::setup::Prepared;
use crate::math::{nearest_rotation_with, vec3, Mat3, Vec3};
use crate::nbody::NBodyParams;
use crate::rings::{Neighborhoods, RingDeltas};
use crate::rotation::{
    kabsch, point_moments, ring_centroids, ring_fit_from_moments, ring_fit_from_sum,
    transform_vertex, PointMoments,
};
use rayon::prelude::*;

/// The phases of a FoldMatch schedule, in order: the first
/// [`rigid_fraction`](crate::fit::Schedule::rigid_fraction) of the ξ iterations moves the template
/// rigidly, the next [`coarse_fraction`](crate::fit::Schedule::coarse_fraction) piecewise rigidly,
/// and the rest by the deformation model (Eq. 4–8). NRGa runs its own update in every iteration, as
/// the fine phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Phase {
    /// One Kabsch fit of every vertex's (or a sample's) old → proposed positions moves the
    /// whole template ([`rigid`]).
    Rigid,
    /// Every vertex moves by the Kabsch fit of its coarse ring ([`coarse`]).
    Coarse,
    /// The deformation model with the rest-shape rigidity, or NRGa's update ([`fine`]).
    Fine,
}

impl Phase {
    /// The phase of iteration `it` (1-based) of a schedule whose rigid and coarse phases are
    /// `rigid` and `coarse` iterations long ([`FitParams::phase_iterations`]).
    pub(super) fn at(it: usize, rigid: usize, coarse: usize) -> Self {
        if it <= rigid {
            Phase::Rigid
        } else if it <= rigid + coarse {
            Phase::Coarse
        } else {
            Phase::Fine
        }
    }
}

/// The rigid phase's update: one Kabsch fit of every vertex's old → proposed positions (`old`
/// → `new`), or of the vertex sample's, moves every vertex of `old` into `next`.
pub(super) fn rigid(
    prepared: &Prepared,
    params: &FitParams,
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    sample: Option<&PhaseSample>,
    next: &mut [[f64; 3]],
) -> usize {
    let (all, fit_old, fit_new) = match sample {
        Some(sample) => (
            &sample.indices[..],
            &sample.pos[..],
            &sample.attraction.proposed[..],
        ),
        None => (&prepared.all_vertices[..], old, new),
    };
    let fast = params.internal.matrix_series;
    // Landmarks do not enter the rigid phase: they placed the template, and a rigid motion
    // cannot follow them onto a deformed garment; held to them (full-displacement pairs against
    // the scan's per-iteration steps) it stalls short of the scan (docs/method.md "Landmarks").
    if !prepared.rigid_parts.vertices.is_empty() {
        rigid_by_part(prepared, all, fit_old, fit_new, sample, old, fast, next);
        return 0;
    }
    let (c_old, c_new) = ring_centroids(all, fit_old, fit_new);
    let r = kabsch(all, fit_old, fit_new, &c_old, &c_new, fast);
    // No turn about the template's own symmetry axes (docs/method.md "Rigid phase").
    let r = match prepared.symmetry.as_ref() {
        Some(symmetry) => symmetry.hold(&r, old, &prepared.faces),
        None => r,
    };
    next.par_iter_mut().enumerate().for_each(|(v, out)| {
        *out = transform_vertex(&r, &vec3(&old[v]), &c_old, &c_new).into();
    });
    0
}

/// The rigid phase on a template of several garments ([`RigidParts`](super::setup::RigidParts)):
/// one Kabsch fit per part, of that part's members of `all` (`fit_old` → `fit_new`), moves that
/// part's vertices; a part with fewer than three fitted members moves with the whole template's
/// fit (docs/method.md "Rigid phase").
#[allow(clippy::too_many_arguments)] // the fit's points, the sample and the buffers
fn rigid_by_part(
    prepared: &Prepared,
    all: &[u32],
    fit_old: &[[f64; 3]],
    fit_new: &[[f64; 3]],
    sample: Option<&PhaseSample>,
    old: &[[f64; 3]],
    fast: bool,
    next: &mut [[f64; 3]],
) {
    let parts = &prepared.rigid_parts;
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); parts.vertices.len()];
    for &i in all {
        let v = sample.map_or(i, |s| s.vertices[i as usize]);
        members[parts.of[v as usize] as usize].push(i);
    }
    let fit = |ring: &[u32]| {
        let (c_old, c_new) = ring_centroids(ring, fit_old, fit_new);
        let r = kabsch(ring, fit_old, fit_new, &c_old, &c_new, fast);
        (r, c_old, c_new)
    };
    let whole = fit(all);
    let motions: Vec<(Mat3, Vec3, Vec3)> = members
        .iter()
        .map(|ring| if ring.len() >= 3 { fit(ring) } else { whole })
        .collect();
    next.par_iter_mut().enumerate().for_each(|(v, out)| {
        let (r, c_old, c_new) = &motions[parts.of[v] as usize];
        *out = transform_vertex(r, &vec3(&old[v]), c_old, c_new).into();
    });
}

/// The coarse phase's update at `level`: each vertex moves by the Kabsch fit of its coarse ring
/// (or of the ring's sampled members) from `old` to the proposal `new` (or the sample's).
#[allow(clippy::too_many_arguments)] // the level, the motion, the phase sample and the buffers
pub(super) fn coarse(
    prepared: &Prepared,
    params: &FitParams,
    level: usize,
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    sample: Option<&PhaseSample>,
    ws: &mut Workspace,
    next: &mut [[f64; 3]],
) -> usize {
    let levels = &prepared.coarse_levels;
    let (rings, deltas, ring_old, ring_new) = match sample {
        // Every vertex, on a scan sample: the whole rings, the sample's proposal.
        Some(sample) if sample.stride == 1 => (
            &levels[level],
            Some(&prepared.coarse_deltas[level]),
            old,
            &sample.attraction.proposed[..],
        ),
        Some(sample) => (
            &prepared.coarse_sampled[level],
            None,
            &sample.pos[..],
            &sample.attraction.proposed[..],
        ),
        None => (
            &levels[level],
            Some(&prepared.coarse_deltas[level]),
            old,
            new,
        ),
    };
    let fast = params.internal.matrix_series;
    let moments = fast.then_some((&mut ws.moments, deltas, &mut ws.ring_sums));
    kabsch_update(rings, ring_old, ring_new, old, fast, moments, next);
    if let Some(l) = prepared.landmarks.as_ref() {
        let eta = params.landmark_weight;
        if eta > 0.0 {
            l.coarse(level, rings, ring_old, ring_new, old, eta, fast, next);
        }
    }
    0
}

/// Where a fine-phase iteration stands: its `j`-th of `J` iterations, and the vertices the
/// schedule carries ([`carry_unsupported`](crate::fit::Schedule::carry_unsupported); empty:
/// none), which take the rest-shape placement alone (β = 1).
pub(super) struct FineStep<'a> {
    pub(super) j: usize,
    pub(super) total: usize,
    pub(super) carried: &'a [bool],
}

/// The fine phase's update in its `j`-th of `J` iterations (`step`): FoldMatch moves every
/// vertex by its Eq. 8 rotation of its n-ring's motion `old → new`, blended with the rest-shape
/// placement of that ring ([`rest_rigidity`](crate::fit::Schedule::rest_rigidity)); NRGa by the
/// Kabsch fit of its k-NN neighborhood. Returns the number of rank-deficient gradients.
pub(super) fn fine(
    prepared: &Prepared,
    params: &FitParams,
    step: FineStep<'_>,
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    ws: &mut Workspace,
    next: &mut [[f64; 3]],
) -> usize {
    let fast = params.internal.matrix_series;
    if params.method == Method::Nrga {
        kabsch_update(&prepared.rings, old, new, old, fast, None, next);
        return 0;
    }
    let before = ws.times.model();
    let d = deformation_rotations(old, new, &prepared.topology(), params, ws);
    ws.times.update -= ws.times.model() - before; // counted in their own stages
    let rot = &ws.rotation;
    let beta = rest_rigidity_at(params, step.j, step.total);
    let carried = step.carried;
    let rest = &prepared.rest;
    next.par_iter_mut().enumerate().for_each(|(v, out)| {
        let ring = prepared.rings.of(v);
        let (c_old, c_new) = ring_centroids(ring, old, new);
        let moved = transform_vertex(&rot[v], &vec3(&old[v]), &c_old, &c_new);
        let beta = if carried.get(v).copied().unwrap_or(false) {
            1.0
        } else {
            beta
        };
        *out = if beta > 0.0 {
            let c_rest = &prepared.rest_centroids[v];
            let placed = rest_ring_placement(ring, v, rest, c_rest, new, &c_new, fast);
            (1.0 - beta) * moved + beta * placed
        } else {
            moved
        }
        .into();
    });
    d
}

/// A phase run on a sample of the template
/// ([`rigid_sample`](crate::fit::Acceleration::rigid_sample),
/// [`coarse_sample`](crate::fit::Acceleration::coarse_sample)) or of the scan
/// ([`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample)): every s-th vertex, its
/// copied positions and velocities, and its own [`Attraction`].
pub(super) struct PhaseSample {
    pub(super) stride: usize,
    pub(super) scan_stride: usize,
    pub(super) vertices: Vec<u32>,
    /// `0..vertices.len()`: the sample's own indices, for the Kabsch fit.
    pub(super) indices: Vec<u32>,
    pub(super) pos: Vec<[f64; 3]>,
    pub(super) vel: Vec<[f64; 3]>,
    pub(super) attraction: Attraction,
}

impl PhaseSample {
    pub(super) fn new(
        prepared: &Prepared,
        stride: usize,
        scan_stride: usize,
        params: &FitParams,
    ) -> Self {
        let m = prepared.start.len();
        let vertices: Vec<u32> = (0..m as u32).step_by(stride).collect();
        let s = vertices.len();
        Self {
            stride,
            scan_stride,
            vertices,
            indices: (0..s as u32).collect(),
            pos: vec![[0.0; 3]; s],
            vel: vec![[0.0; 3]; s],
            attraction: Attraction::new(
                s,
                prepared.scan_points(scan_stride),
                params,
                prepared,
                stride == 1 && !prepared.rim.vertices.is_empty(),
            ),
        }
    }
}

/// The coarse phase's moment buffers for [`kabsch_update`]: the per-point moments, the rows'
/// differences (`None`: rows summed directly) and the per-vertex sums.
pub(super) type MomentBuffers<'a> = (
    &'a mut Vec<PointMoments>,
    Option<&'a RingDeltas>,
    &'a mut Vec<PointMoments>,
);

/// Moves every vertex `v` (at `old[v]`) by the Kabsch rigid fit of its neighborhood's motion
/// `ring_old → ring_new` (the NRGa update, and the coarse phase; the ring members index
/// `ring_old`/`ring_new`, which are `old` and the proposal, or a phase sample's); `fast` as in
/// [`kabsch`]. With `moments` (the coarse phase's large rings, under `matrix_series`) the
/// centroids and covariances come from per-point moments in one pass
/// ([`ring_fit_from_moments`]: half the flops, equal to round-off), summed over each ring from
/// an adjacent ring's sum where deltas are given ([`RingDeltas`]: a quarter of the reads on a
/// grid's 8-rings, equal to round-off), else from two passes.
pub(super) fn kabsch_update(
    rings: &Neighborhoods,
    ring_old: &[[f64; 3]],
    ring_new: &[[f64; 3]],
    old: &[[f64; 3]],
    fast: bool,
    moments: Option<MomentBuffers<'_>>,
    next: &mut [[f64; 3]],
) {
    if let Some((moments, deltas, sums)) = moments {
        // One pass of 15 sums per ring member from per-point moments (equal to round-off).
        let moments = &mut moments[..ring_old.len()];
        moments
            .par_iter_mut()
            .zip(ring_old.par_iter().zip(ring_new.par_iter()))
            .for_each(|(m, (o, n))| *m = point_moments(o, n));
        let moments = &*moments;
        let fit_vertex = |v: usize, out: &mut [f64; 3], (c_old, c_new, cov): (Vec3, Vec3, Mat3)| {
            let r = nearest_rotation_with(&cov, fast);
            *out = transform_vertex(&r, &vec3(&old[v]), &c_old, &c_new).into();
        };
        match deltas {
            Some(deltas) => {
                deltas.sums(rings, moments, sums);
                let sums = &*sums;
                next.par_iter_mut().enumerate().for_each(|(v, out)| {
                    fit_vertex(v, out, ring_fit_from_sum(&sums[v], rings.of(v).len()))
                });
            }
            None => next.par_iter_mut().enumerate().for_each(|(v, out)| {
                fit_vertex(v, out, ring_fit_from_moments(rings.of(v), moments))
            }),
        }
        return;
    }
    next.par_iter_mut().enumerate().for_each(|(v, out)| {
        let ring = rings.of(v);
        let (c_old, c_new) = ring_centroids(ring, ring_old, ring_new);
        let r = kabsch(ring, ring_old, ring_new, &c_old, &c_new, fast);
        *out = transform_vertex(&r, &vec3(&old[v]), &c_old, &c_new).into();
    });
}

/// The rest-shape rigidity β of the `fine`-th of the `total` FoldMatch iterations (1-based):
/// [`rest_rigidity`](crate::fit::Schedule::rest_rigidity) decreasing linearly to 0 at the last one.
pub(super) fn rest_rigidity_at(params: &FitParams, fine: usize, total: usize) -> f64 {
    params.schedule.rest_rigidity * (1.0 - fine as f64 / total.max(1) as f64)
}

/// Where the rest-shape rigidity ([`rest_rigidity`](crate::fit::Schedule::rest_rigidity)) puts
/// vertex `v`: its template ring `rest[ring]` (centroid `c_rest`), moved by the Kabsch rigid fit of
/// that ring onto the proposed positions `proposed[ring]` (centroid `c_proposed`), evaluated at
/// `rest[v]` — ARAP's local step with the proposal as the data.
pub(super) fn rest_ring_placement(
    ring: &[u32],
    v: usize,
    rest: &[[f64; 3]],
    c_rest: &Vec3,
    proposed: &[[f64; 3]],
    c_proposed: &Vec3,
    fast: bool,
) -> Vec3 {
    let r = kabsch(ring, rest, proposed, c_rest, c_proposed, fast);
    transform_vertex(&r, &vec3(&rest[v]), c_rest, c_proposed)
}

/// The N-body constants of iteration `it` (1-based): the softening annealed from
/// `anneal × ε` down to ε over the first `anneal_fraction × ξ` iterations.
pub(super) fn annealed(params: &FitParams, it: usize) -> NBodyParams {
    let mut p = params.model.nbody;
    let span = params.schedule.anneal_fraction * params.iterations as f64;
    if params.schedule.anneal > 1.0 && span > 0.0 {
        let remaining = 1.0 - ((it - 1) as f64 / span).min(1.0);
        p.softening *= 1.0 + (params.schedule.anneal - 1.0) * remaining;
    }
    p
}
