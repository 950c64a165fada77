//! The motion model's side of an iteration (§2): target neighborhoods, the two-way attraction
//! with its trust radius and rim rejection, and the Eq. 2–3 proposal; and the frame of a scan
//! that holds more than the garment.

use super::params::{FitParams, Method};
use super::phases::annealed;
use super::result::{timed, Diagnostics, StageTimes};
use super::setup::{mean_edge_length, Prepared};
use crate::knn::{NeighborCache, PointIndex, TargetNeighbours};
use crate::math::{vec3, Vec3};
use crate::metrics::upper_median;
use crate::nbody;
use crate::normalize::Frame;
use crate::rings::Neighborhoods;
use rayon::prelude::*;

/// The template's boundary vertices and their one-rings.
#[derive(Default)]
pub(super) struct Rim {
    pub(super) vertices: Vec<u32>,
    pub(super) rings: Neighborhoods,
}

impl Rim {
    /// Every vertex's outward direction in the surface at `pos` into `out`: on the boundary,
    /// the unit vector from the centroid of its one-ring to the vertex; zero elsewhere.
    pub(super) fn outward(&self, pos: &[[f64; 3]], out: &mut [[f64; 3]]) {
        for (r, &v) in self.vertices.iter().enumerate() {
            let ring = self.rings.of(r);
            let c = ring
                .iter()
                .fold(Vec3::zeros(), |a, &u| a + vec3(&pos[u as usize]))
                / ring.len().max(1) as f64;
            let d = vec3(&pos[v as usize]) - c;
            let n = d.norm();
            out[v as usize] = if n > 0.0 { (d / n).into() } else { [0.0; 3] };
        }
    }
}

/// The scan points an [`Attraction`] sees — the whole scan, or every `stride`-th point of it
/// ([`ScanPoints::sample`]) — with their curvatures, their k-d tree and K.
pub(super) struct ScanPoints {
    pub(super) stride: usize,
    pub(super) points: Vec<[f64; 3]>,
    pub(super) kappa: Vec<f64>,
    /// The scan weights of these points (`None`: all equal).
    pub(super) weights: Option<Vec<f64>>,
    pub(super) index: PointIndex,
    pub(super) k: usize,
}

impl ScanPoints {
    /// Every `stride`-th point (in the fit's Morton order, so spread evenly), with its own tree and
    /// `⌈K / stride⌉` neighbours per template point: about the same neighbourhood radius as K
    /// points of the whole scan
    /// ([`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample)).
    pub(super) fn sample(&self, stride: usize) -> Self {
        let points: Vec<[f64; 3]> = self.points.iter().step_by(stride).copied().collect();
        let kappa = self.kappa.iter().step_by(stride).copied().collect();
        let weights = self
            .weights
            .as_ref()
            .map(|w| w.iter().step_by(stride).copied().collect());
        let index = PointIndex::new(&points);
        let k = self.k.div_ceil(stride).clamp(1, points.len());
        Self {
            stride: stride * self.stride,
            points,
            kappa,
            weights,
            index,
            k,
        }
    }
}

/// The motion model's side of an iteration (§2) for a set of template points: their target
/// neighborhoods Γᵏ_X, the two-way attraction's pulls and the Eq. 2–3 proposal, with every
/// buffer allocated once.
pub(super) struct Attraction {
    pub(super) nn_idx: Vec<u32>,
    pub(super) nn_d2: Vec<f64>,
    pub(super) nn_cache: Option<NeighborCache>,
    /// The two-way attraction's state (`None`: one-way attraction).
    pub(super) reverse: Option<(nbody::ReverseAttraction, Vec<[f64; 3]>)>,
    /// The N-body proposal for every point.
    pub(super) proposed: Vec<[f64; 3]>,
    /// Scratch: every point's distance to its nearest scan point (the trust radius's median).
    pub(super) nearest: Vec<f64>,
    /// The floor of the two-way trust radius (the template's mean edge length).
    pub(super) edge_length: f64,
    /// The trust radius's multiple c ([`Prepared::trust`]).
    pub(super) trust: f64,
    /// Every point's outward direction on the rim
    /// ([`two_way_rim`](crate::fit::Schedule::two_way_rim); empty when off, or on a vertex sample).
    pub(super) outward: Vec<[f64; 3]>,
}

impl Attraction {
    /// Buffers for `m` template points over the scan points `scan`; `edge_length` is the
    /// template's mean edge length.
    pub(super) fn new(
        m: usize,
        scan: &ScanPoints,
        params: &FitParams,
        prepared: &Prepared,
        rim: bool,
    ) -> Self {
        let (n, k) = (scan.points.len(), scan.k);
        let reverse =
            (params.schedule.two_way > 0.0 && params.method == Method::FoldMatch).then(|| {
                (
                    nbody::ReverseAttraction::new(m, n, params.internal.knn_cache),
                    vec![[0.0; 3]; m],
                )
            });
        Self {
            nn_idx: vec![0u32; m * k],
            nn_d2: vec![0.0; m * k],
            nn_cache: params
                .internal
                .knn_cache
                .then(|| NeighborCache::new(m, k, n)),
            reverse,
            proposed: vec![[0.0; 3]; m],
            nearest: if prepared.trust(params) > 0.0 {
                vec![0.0; m]
            } else {
                Vec::new()
            },
            edge_length: prepared.edge_length,
            trust: prepared.trust(params),
            outward: if rim && params.schedule.two_way_rim > 0.0 && params.schedule.two_way > 0.0 {
                vec![[0.0; 3]; m]
            } else {
                Vec::new()
            },
        }
    }

    /// The two-way trust radius ([`two_way_trust`](crate::fit::Schedule::two_way_trust)) of the
    /// template whose neighbour lists are `nn_d2` (nearest first), with `nearest` as scratch.
    pub(super) fn trust_radius(
        nearest: &mut [f64],
        edge_length: f64,
        trust: f64,
        nn_d2: &[f64],
        k: usize,
    ) -> f64 {
        if trust <= 0.0 || nearest.is_empty() {
            return f64::INFINITY;
        }
        for (d, row) in nearest.iter_mut().zip(nn_d2.chunks_exact(k)) {
            *d = row[0];
        }
        trust * upper_median(nearest).sqrt().max(edge_length)
    }

    /// Γᵏ_X of the points `pos` among the scan points `scan`, the two-way pulls on them, and
    /// the Eq. 2–3 step: velocities `vel` updated, proposed positions in `self.proposed`.
    #[allow(clippy::too_many_arguments)] // the stage inputs, and the two accumulators
    pub(super) fn propose(
        &mut self,
        scan: &ScanPoints,
        rim: &Rim,
        params: &FitParams,
        it: usize,
        pos: &[[f64; 3]],
        vel: &mut [[f64; 3]],
        t: &mut StageTimes,
        diagnostics: &mut Diagnostics,
    ) {
        let (points, kappa, index, k) = (&scan.points, &scan.kappa, &scan.index, scan.k);
        let weights = scan.weights.as_deref();
        let (nn_idx, nn_d2) = (&mut self.nn_idx, &mut self.nn_d2);
        let slack = if self.nn_cache.is_some() {
            params.knn_slack_at(it)
        } else {
            0.0
        };
        diagnostics.knn_queries += timed(&mut t.knn, || match self.nn_cache.as_mut() {
            Some(cache) => {
                cache.set_slack(slack);
                cache.query(index, pos, nn_idx, nn_d2)
            }
            None => {
                index.nearest_all(pos, k, nn_idx, nn_d2);
                pos.len()
            }
        });
        let nbody_params = annealed(params, it);
        if !self.outward.is_empty() {
            rim.outward(pos, &mut self.outward);
        }
        let rim_margin = params.schedule.two_way_rim * self.edge_length;
        let forward_rim = (!self.outward.is_empty()).then(|| (&self.outward[..], rim_margin));
        let trust_radius = match self.reverse {
            Some(_) => {
                Self::trust_radius(&mut self.nearest, self.edge_length, self.trust, nn_d2, k)
            }
            None => f64::INFINITY,
        };
        let extra = match self.reverse.as_mut() {
            Some((reverse, force)) => {
                let forward = TargetNeighbours {
                    indices: nn_idx,
                    dist2: nn_d2,
                    k,
                    exact: slack == 0.0,
                };
                let two_way = nbody::TwoWay {
                    weight: params.schedule.two_way,
                    pull: params.schedule.two_way_pull,
                    trust_radius,
                    rim: forward_rim,
                    weights,
                };
                diagnostics.two_way_queries += timed(&mut t.two_way, || {
                    reverse.compute(pos, points, kappa, forward, &two_way, &nbody_params, force)
                });
                Some(force.as_slice())
            }
            None => None,
        };
        timed(&mut t.nbody, || {
            nbody::step(
                pos,
                vel,
                nn_idx,
                k,
                points,
                kappa,
                weights,
                forward_rim,
                &nbody_params,
                extra,
                &mut self.proposed,
            )
        });
    }
}

/// A scan whose bounding-box diagonal exceeds the template's by more than this factor holds
/// more than the garment (a dressed body, a scene): its normalized frame and K are then those
/// of the points the template explains (the pre-alignment's [`SCENE`](crate::prealign::SCENE)).
pub const GARMENT_FRAME_RATIO: f64 = crate::prealign::SCENE;

/// The trust radius on a scan that holds more than the garment, as a fraction of
/// [`two_way_trust`](crate::fit::Schedule::two_way_trust)'s: skin and hair adjoin the garment
/// (below a hem, out of a sleeve), where a garment alone has nothing, so the radius that is neutral
/// on garment scans (c = 4) lets them in; ¾ of it (c = 3) keeps them out (docs/method.md "Scans of
/// dressed people").
pub const DRESSED_TRUST_FACTOR: f64 = 0.75;

/// The scan points that the template as given explains, where the scan is much larger than the
/// template ([`GARMENT_FRAME_RATIO`]) or `several` says that it holds other garments too (the
/// template is one of several, docs/method.md "Several garments"); `None` otherwise, or when
/// the two-way trust radius is off:
/// those within the two-way trust radius ([`two_way_trust`](crate::fit::Schedule::two_way_trust))
/// of the template's nearest vertex. The paper's constants (ε, G, Δt, ρ) are set for a frame in
/// which the garment's scan has unit diagonal; a dressed body's skin and hair would stretch that
/// frame two- to threefold and soften every force (docs/method.md "Scans of dressed people").
pub(super) fn explained_points(
    scan: &[[f64; 3]],
    template: &[[f64; 3]],
    faces: &[[u32; 3]],
    params: &FitParams,
    several: bool,
) -> Option<Vec<u32>> {
    let diag = |p: &[[f64; 3]]| Frame::of_target(p).scale;
    if params.schedule.two_way_trust <= 0.0
        || (!several && diag(scan) <= GARMENT_FRAME_RATIO * diag(template))
    {
        return None;
    }
    let radius =
        DRESSED_TRUST_FACTOR * params.schedule.two_way_trust * trust_unit(template, faces, scan);
    let template_index = PointIndex::new(template);
    let explained: Vec<u32> = (0..scan.len() as u32)
        .into_par_iter()
        .filter(|&j| template_index.nearest_one(&scan[j as usize]).1 <= radius * radius)
        .collect();
    (!explained.is_empty() && explained.len() < scan.len()).then_some(explained)
}

/// The unit of the trust radius for `template` against `scan` (docs/method.md "Scans of dressed
/// people"): the larger of the median distance from a template vertex to its nearest scan point
/// and the template's mean edge length.
pub(super) fn trust_unit(template: &[[f64; 3]], faces: &[[u32; 3]], scan: &[[f64; 3]]) -> f64 {
    let scan_index = PointIndex::new(scan);
    let mut nearest: Vec<f64> = template
        .par_iter()
        .map(|v| scan_index.nearest_one(v).1)
        .collect();
    upper_median(&mut nearest)
        .sqrt()
        .max(mean_edge_length(template, faces))
}
