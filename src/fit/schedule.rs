//! Schedule selection and one schedule's run: the candidates fitted side by side, the rule
//! that chooses among them, and the iteration loop that drives the phases.

use super::attraction::Attraction;
use super::landmark_pull::LandmarkTargets;
use super::model::{deformation_model, TemplateTopology, Workspace};
use super::params::{FitParams, Method};
use super::phases::{self, Phase, PhaseSample};
use super::result::{Diagnostics, FitResult, IterationRecord, Progress};
use super::setup::Prepared;
use super::strain_limit::StrainLimit;
use super::support;
use crate::error::{FoldMatchError, Result};
use crate::math::vec3;
use crate::rings::n_rings;
use rayon::prelude::*;

/// Each scan point's (those of `garment`, else all, in that order) nearest vertex of a fit and
/// the distance to it.
pub(super) struct ScanNearest {
    pub vertex: Vec<u32>,
    pub distance: Vec<f64>,
}

/// Schedule selection's scan distance of the fit `fitted`: the mean distance from the scan
/// points to their nearest fitted vertex, weighted by the scan weights, over the points the
/// template explains (`garment`, user indices) where the scan holds more than the garment;
/// with those nearest vertices ([`nearest_vertices`]), which the do-no-harm median
/// ([`weighted_median`]) and the verdict of the chosen fit read again.
pub(super) fn selection_distance(
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    garment: Option<&[usize]>,
    fitted: &[[f64; 3]],
) -> (f64, ScanNearest) {
    let nearest = nearest_vertices(target, garment, fitted);
    let d = &nearest.distance;
    let w: Option<Vec<f64>> = match garment {
        Some(g) => weights.map(|w| g.iter().map(|&j| w[j]).collect()),
        None => weights.map(<[f64]>::to_vec),
    };
    let mean = match w {
        Some(w) => d.iter().zip(&w).map(|(d, w)| d * w).sum::<f64>() / w.iter().sum::<f64>(),
        None => d.iter().sum::<f64>() / d.len() as f64,
    };
    (mean, nearest)
}

/// The nearest vertex of `fitted` to each scan point (those of `garment`, else all), in that
/// order, and the distance to it: the fit's own k-d tree
/// ([`PointIndex`](crate::knn::PointIndex)), parallel queries.
pub(super) fn nearest_vertices(
    target: &[[f64; 3]],
    garment: Option<&[usize]>,
    fitted: &[[f64; 3]],
) -> ScanNearest {
    let count = garment.map_or(target.len(), <[usize]>::len);
    if fitted.is_empty() {
        return ScanNearest {
            vertex: vec![0; count],
            distance: vec![f64::INFINITY; count],
        };
    }
    let index = crate::knn::PointIndex::new(fitted);
    let query = |p: &[f64; 3]| {
        let (v, d2) = index.nearest_one(p);
        (v, d2.sqrt())
    };
    let (vertex, distance) = match garment {
        Some(g) => g.par_iter().map(|&j| query(&target[j])).unzip(),
        None => target.par_iter().map(query).unzip(),
    };
    ScanNearest { vertex, distance }
}

/// The do-no-harm rule's scan distance of the vertices `fitted`: the (weighted) median of the
/// distances from the scan points of [`selection_distance`] to their nearest vertex. The median
/// is the typical point's: unmoved by the share (under half) of those points that the garment
/// does not explain, skin next to a hem that a fit drawn to it comes closer to
/// (docs/method.md "Do no harm").
pub(super) fn median_scan_distance(
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    garment: Option<&[usize]>,
    fitted: &[[f64; 3]],
) -> f64 {
    weighted_median(
        &nearest_vertices(target, garment, fitted).distance,
        weights,
        garment,
    )
}

/// The weighted median of `d`, the distances of the scan points of `garment` (else all) in
/// that order, under the scan weights (0 when no point weighs).
pub(super) fn weighted_median(
    d: &[f64],
    weights: Option<&[f64]>,
    garment: Option<&[usize]>,
) -> f64 {
    let weight = |i: usize| weights.map_or(1.0, |w| w[garment.map_or(i, |g| g[i])]);
    let w: Vec<f64> = (0..d.len()).map(weight).collect();
    let mut order: Vec<usize> = (0..d.len()).filter(|&i| w[i] > 0.0).collect();
    order.par_sort_unstable_by(|&a, &b| d[a].total_cmp(&d[b]).then(a.cmp(&b)));
    let half = 0.5 * order.iter().map(|&i| w[i]).sum::<f64>();
    let mut acc = 0.0;
    for &i in &order {
        acc += w[i];
        if acc >= half {
            return d[i];
        }
    }
    0.0
}

/// Schedule selection's rule (docs/method.md, "Beyond the paper: the default configuration"): of
/// the candidates whose mean scan→fit distance is at most `(1 + margin) ×` the smallest, the one
/// with the least edge-length spread; ties keep the earlier candidate (the given schedule first).
/// With `margin = 0` the closest fit wins (among exact ties, the least spread).
///
/// Why a margin: the candidates differ mainly in the two-way weight, and the two-way pull
/// minimizes the very distance compared, so the stronger pull wins it by a few per cent even
/// where its fit slid along the scan; cloth barely stretches, so among fits that lie about as
/// close to the scan the one nearest to an isometry of the template is kept.
pub fn select_schedule(distances: &[f64], spreads: &[f64], margin: f64) -> usize {
    debug_assert_eq!(distances.len(), spreads.len());
    let closest = distances.iter().copied().fold(f64::INFINITY, f64::min);
    let bound = closest * (1.0 + margin);
    (0..distances.len())
        .filter(|&i| distances[i] <= bound)
        .fold(None, |best: Option<usize>, i| match best {
            Some(b) if spreads[b] <= spreads[i] => Some(b),
            _ => Some(i),
        })
        .unwrap_or(0)
}

/// The do-no-harm rule (docs/method.md "Do no harm"): whether the template as given, at mean
/// scan distance `start`, is kept in place of the fit at `fitted` — when it lies within
/// `(1 + margin) ×` the fit's distance (`margin = 0`: never).
pub fn keeps_start(start: f64, fitted: f64, margin: f64) -> bool {
    margin > 0.0 && start <= (1.0 + margin) * fitted
}

/// Steps every run in lockstep (concurrently when there are several) and reports each iteration
/// once, with the first still-running schedule's figures; a `false` from the observer stops
/// them all.
pub(super) fn drive(
    prepared: &Prepared,
    runs: &mut [ScheduleRun],
    steps: std::ops::RangeInclusive<usize>,
    iterations: usize,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<()> {
    for it in steps {
        let record = match runs {
            [one] => one.step(prepared)?,
            [a, b] => {
                let (ra, rb) = rayon::join(|| a.step(prepared), || b.step(prepared));
                ra?.or(rb?)
            }
            [a, b, c] => {
                let (ra, (rb, rc)) = rayon::join(
                    || a.step(prepared),
                    || rayon::join(|| b.step(prepared), || c.step(prepared)),
                );
                ra?.or(rb?).or(rc?)
            }
            _ => unreachable!("one to three schedules"),
        };
        let Some(record) = record else {
            break; // every run has converged
        };
        if !observer(&Progress {
            iteration: it,
            iterations,
            record,
        }) {
            for run in runs.iter_mut().filter(|r| !r.finished) {
                run.diagnostics.stopped_by_callback = true;
                run.finished = true;
            }
            break;
        }
    }
    Ok(())
}

/// One schedule's fit in progress: its state and every per-vertex buffer, allocated once.
pub(super) struct ScheduleRun {
    pub(super) params: FitParams,
    pub(super) pos: Vec<[f64; 3]>,
    pub(super) vel: Vec<[f64; 3]>,
    pub(super) next: Vec<[f64; 3]>,
    pub(super) disp: Vec<f64>,
    pub(super) attraction: Attraction,
    pub(super) ws: Workspace,
    /// The phases' vertex samples and their buffers (one per distinct stride).
    pub(super) samples: Vec<PhaseSample>,
    /// Which of `samples` the rigid and the coarse phase use (`None`: every vertex).
    pub(super) phase_sample: [Option<usize>; 2],
    pub(super) rigid_iterations: usize,
    pub(super) coarse_iterations: usize,
    pub(super) iteration: usize,
    pub(super) history: Vec<IterationRecord>,
    pub(super) snapshots: Vec<(usize, Vec<[f64; 3]>)>,
    pub(super) diagnostics: Diagnostics,
    /// Converged, or stopped by the observer.
    pub(super) finished: bool,
    /// The fine phase's strain limiting ([`strain_limit`](crate::fit::Schedule::strain_limit);
    /// `None` when off).
    pub(super) strain: Option<StrainLimit>,
    /// The vertices without scan support once the rigid phase has placed the template,
    /// carried by their rest rings instead of attracted in the coarse and fine phases
    /// ([`carry_unsupported`](crate::fit::Schedule::carry_unsupported); empty: none).
    pub(super) carried: Vec<bool>,
    /// The vertices near a carried region, which move along their normals only (empty when
    /// nothing is carried; docs/method.md "Partial scans").
    pub(super) band: Vec<bool>,
    /// The rim matching's targets in the fine phase, refreshed every [`RIM_REFRESH`]
    /// iterations (`None` before it, or without rim matching; docs/method.md "Rim matching").
    pub(super) rim: Option<LandmarkTargets>,
}

/// The fine phase lays the rim onto the mesh target's afresh every this many iterations.
pub const RIM_REFRESH: usize = 4;

impl ScheduleRun {
    pub(super) fn new(prepared: &Prepared, params: FitParams) -> Self {
        let m = prepared.start.len();
        let (rigid_iterations, coarse_iterations) = params.phase_iterations();
        let mut samples: Vec<PhaseSample> = Vec::new();
        let mut phase_sample = [None, None];
        let [rigid_scan, coarse_scan] = prepared.scan_strides;
        let wanted = [
            (
                params.acceleration.rigid_sample,
                rigid_scan,
                rigid_iterations,
            ),
            (
                params.acceleration.coarse_sample,
                coarse_scan,
                coarse_iterations,
            ),
        ];
        for (slot, (stride, scan_stride, iterations)) in phase_sample.iter_mut().zip(wanted) {
            if (stride > 1 || scan_stride > 1) && iterations > 0 {
                let same = samples
                    .iter()
                    .position(|s| (s.stride, s.scan_stride) == (stride, scan_stride));
                *slot = Some(same.unwrap_or_else(|| {
                    samples.push(PhaseSample::new(prepared, stride, scan_stride, &params));
                    samples.len() - 1
                }));
            }
        }
        Self {
            pos: prepared.start.clone(),
            vel: vec![[0.0; 3]; m],
            next: vec![[0.0; 3]; m],
            disp: vec![0.0; m],
            attraction: Attraction::new(
                m,
                prepared.scan_points(1),
                &params,
                prepared,
                !prepared.rim.vertices.is_empty(),
            ),
            ws: Workspace::new(m),
            samples,
            phase_sample,
            rigid_iterations,
            coarse_iterations,
            iteration: 0,
            history: Vec::with_capacity(params.iterations),
            snapshots: Vec::new(),
            diagnostics: prepared.diagnostics.clone(),
            finished: false,
            strain: (params.schedule.strain_limit > 0.0 || params.schedule.compression_limit > 0.0)
                .then(|| {
                    let pinned = prepared
                        .landmarks
                        .as_ref()
                        .map_or(&[][..], |l| &l.vertices[..]);
                    StrainLimit::new(&prepared.rest, &prepared.faces, pinned)
                }),
            carried: Vec::new(),
            band: Vec::new(),
            rim: None,
            params,
        }
    }

    /// One iteration (§2 then §3); `None` when the run has already finished.
    pub(super) fn step(&mut self, prepared: &Prepared) -> Result<Option<IterationRecord>> {
        if self.finished || self.iteration >= self.params.iterations {
            return Ok(None);
        }
        self.iteration += 1;
        let it = self.iteration;
        let params = &self.params;
        let m = self.pos.len();
        let t = &mut self.ws.times;
        let phase = Phase::at(it, self.rigid_iterations, self.coarse_iterations);
        let sampled = match phase {
            Phase::Rigid => self.phase_sample[0],
            Phase::Coarse => self.phase_sample[1],
            Phase::Fine => None,
        };
        // The phase's points: a sample's copies of its vertices, or every vertex.
        let (attraction, pos, vel, scan_stride) = match sampled.map(|i| &mut self.samples[i]) {
            Some(sample) => {
                for (i, &v) in sample.vertices.iter().enumerate() {
                    sample.pos[i] = self.pos[v as usize];
                    sample.vel[i] = self.vel[v as usize];
                }
                let stride = sample.scan_stride;
                (
                    &mut sample.attraction,
                    &sample.pos[..],
                    &mut sample.vel[..],
                    stride,
                )
            }
            None => (&mut self.attraction, &self.pos[..], &mut self.vel[..], 1),
        };
        let scan = prepared.scan_points(scan_stride);
        let diagnostics = &mut self.diagnostics;
        attraction.propose(scan, &prepared.rim, params, it, pos, vel, t, diagnostics);
        if let Some(sample) = sampled.map(|i| &self.samples[i]) {
            for (i, &v) in sample.vertices.iter().enumerate() {
                self.vel[v as usize] = sample.vel[i];
            }
        }
        let update_start = std::time::Instant::now();
        // The unsupported vertices, once the rigid phase has placed the template, and the
        // border band around them.
        if it == self.rigid_iterations + 1 && params.carries() {
            self.carried = support::carried_vertices(prepared, &self.pos, params);
            if self.carried.contains(&true) && params.internal.carry_band > 0 {
                self.band = support::border_band(
                    &prepared.rings,
                    &self.carried,
                    params.internal.carry_band,
                );
            }
        }
        if phase != Phase::Rigid && !self.carried.is_empty() {
            // A carried vertex's proposal is where it is; a border vertex's keeps only its
            // part along the vertex normal.
            let (carried, band, full) = (&self.carried, &self.band, &self.pos);
            let sample = sampled.map(|i| &mut self.samples[i]);
            rewrite_proposals(sample, &mut self.attraction, full, |v, pos, proposed| {
                if carried[v] {
                    Some(*pos)
                } else if band.get(v).copied().unwrap_or(false) {
                    let normal =
                        crate::mesh::vertex_normal(full, &prepared.faces, &prepared.incidence, v);
                    Some(support::along_normal(pos, proposed, &normal))
                } else {
                    None
                }
            });
        }
        // The rim matching's targets, from the fit as the fine phase finds it and afresh
        // every RIM_REFRESH iterations; not where the fit carries a region the target does
        // not show, whose boundary there is not the cloth's (docs/method.md "Rim matching").
        let fine_j = it.saturating_sub(self.rigid_iterations + self.coarse_iterations);
        if let (Phase::Fine, Some(rm)) = (phase, prepared.rim_match.as_ref()) {
            if params.schedule.rim_weight > 0.0
                && (fine_j - 1).is_multiple_of(RIM_REFRESH)
                && !self.carried.contains(&true)
            {
                self.rim = Some(rm.targets(&self.pos, prepared.edge_length));
            }
        }
        // The landmarks' spring on the proposal: the rings holding them see it (Eq. 4, 8).
        if let (Phase::Fine, Some(l)) = (phase, prepared.landmarks.as_ref()) {
            l.pull(params.landmark_weight, &mut self.attraction.proposed);
        }
        // The rim's spring on the proposal only: the rings see it (Eq. 4, 8), and the update
        // is not pulled vertex by vertex (that folds the faces along the rim).
        if let (Phase::Fine, Some(r)) = (phase, self.rim.as_ref()) {
            r.pull(params.schedule.rim_weight, &mut self.attraction.proposed);
        }
        let (old, new, next) = (&self.pos, &self.attraction.proposed, &mut self.next);
        let sample = sampled.map(|i| &self.samples[i]);
        let ws = &mut self.ws;
        let degenerate = match phase {
            Phase::Rigid => phases::rigid(prepared, params, old, new, sample, next),
            Phase::Coarse => {
                let levels = prepared.coarse_levels.len();
                let level = (it - self.rigid_iterations - 1) * levels / self.coarse_iterations;
                phases::coarse(prepared, params, level, old, new, sample, ws, next)
            }
            Phase::Fine => {
                let before = self.rigid_iterations + self.coarse_iterations;
                let step = phases::FineStep {
                    j: it - before,
                    total: params.iterations - before,
                    carried: &self.carried,
                };
                phases::fine(prepared, params, step, old, new, ws, next)
            }
        };
        if let (Phase::Fine, Some(strain)) = (phase, self.strain.as_mut()) {
            strain.apply(
                &mut self.next,
                params.schedule.strain_limit,
                params.schedule.compression_limit,
                params.schedule.strain_passes,
            );
        }
        if let (Phase::Fine, Some(l)) = (phase, prepared.landmarks.as_ref()) {
            l.pull(params.landmark_weight, &mut self.next);
        }
        self.ws.times.update += update_start.elapsed().as_secs_f64();
        // Velocities follow the applied motion (docs/method.md, "Integration, Eq. 3");
        // displacement figures.
        let (dt, sync) = (params.model.nbody.time_step, params.readings.velocity_sync);
        let (pos, next) = (&self.pos, &self.next);
        self.disp
            .par_iter_mut()
            .zip(self.vel.par_iter_mut())
            .enumerate()
            .for_each(|(v, (d, vl))| {
                let delta = vec3(&next[v]) - vec3(&pos[v]);
                *d = delta.norm();
                if sync {
                    *vl = (delta / dt).into();
                }
            });
        // A non-finite position makes its displacement non-finite: checked in parallel, the
        // vertex looked for only then.
        if self.disp.par_iter().any(|d| !d.is_finite()) {
            if let Some(bad) = next.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
                return Err(FoldMatchError::Numerical(format!(
                    "vertex {bad} became non-finite at iteration {it}"
                )));
            }
        }
        std::mem::swap(&mut self.pos, &mut self.next);
        // Sequential sum: identical for any thread count (a maximum is, in any order).
        let mean = self.disp.iter().sum::<f64>() / m as f64;
        let max = self.disp.par_iter().copied().reduce(|| 0.0, f64::max);
        let record = IterationRecord {
            iteration: it,
            mean_displacement: mean,
            max_displacement: max,
            degenerate_gradients: degenerate,
        };
        self.history.push(record);
        let every = self.params.snapshot_every;
        if every > 0 && it.is_multiple_of(every) {
            let mut snap = self.pos.clone();
            prepared.frame.inverse_in_place(&mut snap);
            self.snapshots.push((it, snap));
        }
        if self.params.tolerance > 0.0 && mean < self.params.tolerance {
            self.diagnostics.converged = true;
            self.finished = true;
        }
        Ok(Some(record))
    }

    /// The current vertices in the user's frame.
    pub(super) fn user_vertices(&self, prepared: &Prepared) -> Vec<[f64; 3]> {
        let mut v = self.pos.clone();
        prepared.frame.inverse_in_place(&mut v);
        v
    }

    /// The result (`vertices`: [`ScheduleRun::user_vertices`]), with the wrinkle-vector fields
    /// of the last step and of the whole motion, and the `assessment` of `vertices`.
    pub(super) fn finish(
        mut self,
        prepared: &Prepared,
        vertices: Vec<[f64; 3]>,
        assessment: crate::quality::Assessment,
    ) -> FitResult {
        let params = &self.params;
        let m = self.pos.len();
        self.diagnostics.stage_seconds = self.ws.times;
        // Per-step field of the last iteration, and the accumulated field of the total motion.
        let wvf = if params.method == Method::FoldMatch && !self.history.is_empty() {
            self.ws.fill_wrinkle_field(params);
            self.ws.wvf.clone()
        } else {
            vec![[0.0; 3]; m]
        };
        let acc_rings;
        let acc_topo = if params.method == Method::FoldMatch {
            prepared.topology()
        } else {
            acc_rings = n_rings(&prepared.faces, m, params.model.rings);
            TemplateTopology {
                faces: &prepared.faces,
                incidence: &prepared.incidence,
                rings: &acc_rings,
            }
        };
        deformation_model(&prepared.start, &self.pos, &acc_topo, params, &mut self.ws);
        let wvf_accumulated = self.ws.wvf;
        FitResult {
            vertices,
            wvf,
            wvf_accumulated,
            iterations: self.history.len(),
            history: self.history,
            snapshots: self.snapshots,
            params: self.params,
            diagnostics: self.diagnostics,
            quality: assessment.quality,
            correspondences: assessment.correspondences,
            residuals: assessment.residuals,
            support: assessment.support,
            garment_points: Vec::new(),
        }
    }
}

/// Rewrites the phase's proposals: `rewrite(v, position, proposal)` for each of its points (the
/// sample's, or every vertex's when `sample` is `None`), `v` the template vertex; `Some` replaces
/// the proposal.
fn rewrite_proposals(
    sample: Option<&mut PhaseSample>,
    attraction: &mut Attraction,
    pos: &[[f64; 3]],
    mut rewrite: impl FnMut(usize, &[f64; 3], &[f64; 3]) -> Option<[f64; 3]>,
) {
    match sample {
        Some(sample) => {
            for (i, &v) in sample.vertices.iter().enumerate() {
                let (p, q) = (&sample.pos[i], &sample.attraction.proposed[i]);
                if let Some(new) = rewrite(v as usize, p, q) {
                    sample.attraction.proposed[i] = new;
                }
            }
        }
        None => {
            for (v, (p, q)) in pos.iter().zip(attraction.proposed.iter_mut()).enumerate() {
                if let Some(new) = rewrite(v, p, q) {
                    *q = new;
                }
            }
        }
    }
}
