//! What a fit returns and reports: the fitted vertices and wrinkle fields, per-iteration
//! figures, stage times and diagnostics.

use super::params::FitParams;
use crate::normalize::Frame;
use crate::quality::Quality;
use serde::{Deserialize, Serialize};

/// One iteration's figures.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Mean vertex displacement of the iteration, in normalized units (target diagonals).
    pub mean_displacement: f64,
    /// Largest vertex displacement of the iteration, in normalized units.
    pub max_displacement: f64,
    /// Vertices whose deformation gradient was rank-deficient (identity used in the missing
    /// directions).
    pub degenerate_gradients: usize,
}

/// What a progress observer sees after every iteration.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Iterations done.
    pub iteration: usize,
    /// Iterations planned (ξ).
    pub iterations: usize,
    /// The iteration's figures.
    pub record: IterationRecord,
}

impl Progress {
    /// This progress of one of two passes over `total` iterations each (`pass` 0 or 1), as
    /// progress over `total` iterations in all: each pass counts half.
    pub(super) fn of_passes(&self, pass: usize, total: usize) -> Progress {
        Progress {
            iteration: (pass * total + self.iteration).div_ceil(2),
            iterations: total,
            record: self.record,
        }
    }
}

/// Wall-clock seconds spent in each stage over the whole fit (for the benchmarks' breakdown).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct StageTimes {
    /// Target neighborhoods (k-d tree queries).
    pub knn: f64,
    /// Two-way attraction (template k-d tree, reverse queries and forces).
    pub two_way: f64,
    /// Force and integration (Eq. 2–3).
    pub nbody: f64,
    /// Vertex normals and deformation gradients (Eq. 4).
    pub gradient: f64,
    /// Regularization (Eq. 5), polar decompositions included.
    pub regularize: f64,
    /// ψ-modified stretch, wrinkle field and rotation solve (Eq. 6–8).
    pub rotation: f64,
    /// Per-vertex update (and the rigid / coarse phases' Kabsch fits).
    pub update: f64,
}

impl StageTimes {
    /// Seconds in the deformation model (Eq. 4–8).
    pub fn model(&self) -> f64 {
        self.gradient + self.regularize + self.rotation
    }

    /// Adds another run's seconds, stage by stage.
    pub fn add(&mut self, other: &Self) {
        self.knn += other.knn;
        self.two_way += other.two_way;
        self.nbody += other.nbody;
        self.gradient += other.gradient;
        self.regularize += other.regularize;
        self.rotation += other.rotation;
        self.update += other.update;
    }
}

/// Runs `f`, adding its wall time to `slot`.
#[inline]
pub(super) fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
    let start = std::time::Instant::now();
    let out = f();
    *slot += start.elapsed().as_secs_f64();
    out
}

/// Facts about the inputs and the run, for reports.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Diagnostics {
    /// K, the target neighborhood size used.
    pub target_neighbours: usize,
    /// The coarse phase's ring radius used ([`FitParams::coarse_radius`]; 0 when no schedule
    /// has a coarse phase).
    pub coarse_rings: usize,
    /// Mean size of the template neighborhoods (the vertex included).
    pub mean_ring_size: f64,
    /// Indices of template faces with a repeated vertex (ignored by the fit).
    pub degenerate_faces: Vec<usize>,
    /// Indices of template faces repeating an earlier face (ignored by the fit).
    pub duplicate_faces: Vec<usize>,
    /// Template vertices in no face (they follow their own particle; no gradient).
    pub isolated_vertices: usize,
    /// `(ω₀Δt)²` of the near-field spring ([`crate::nbody::NBodyParams::omega0_dt_squared`]; stable
    /// well below 1).
    pub omega0_dt_squared: f64,
    /// The curvature source: "mesh", "point_cloud" or "off".
    pub curvature: String,
    /// Whether the tolerance stopped the fit before ξ iterations.
    pub converged: bool,
    /// Whether the observer stopped the fit.
    pub stopped_by_callback: bool,
    /// Whether the do-no-harm rule returned the template as it started
    /// ([`keep_margin`](super::Schedule::keep_margin)).
    pub kept_start: bool,
    /// The scan points of the garment refit on a scan that holds more than the garment
    /// ([`garment_refit`](super::Schedule::garment_refit)); 0 when there was none.
    #[serde(default)]
    pub garment_refit_points: usize,
    /// The normalized frame used.
    pub frame: Option<Frame>,
    /// Seconds per stage of the iterations, summed over the schedules run (under schedule
    /// selection the runs overlap in time, so the stages add up to more than the wall time
    /// of the iterations; their shares are what they are).
    pub stage_seconds: StageTimes,
    /// Wall-clock seconds of the fit's three parts: `[setup, iterations, finish]` (validation,
    /// frame, scan tree, curvature and neighborhoods; the iterations of every schedule; the
    /// wrinkle fields, the return to the user's frame and the schedule selection).
    pub wall_seconds: [f64; 3],
    /// Fresh k-d tree queries of the target neighborhoods over the fit (M per iteration
    /// without the candidate cache).
    pub knn_queries: usize,
    /// k-d tree queries of the two-way attraction (a scan point's nearest template vertex; N
    /// per iteration with `knn_cache` off).
    pub two_way_queries: usize,
    /// Which schedule produced the result: `"given"` (the parameters as given), `"sharp"`
    /// ([`FitParams::sharp_schedule`]) or `"gentle"` ([`FitParams::gentle_schedule`]), the
    /// latter two chosen by schedule selection ([`Selection`](super::Selection)).
    pub schedule: String,
    /// Under schedule selection: the mean scan→fit distance (user units) of each candidate's
    /// fit, in [`SCHEDULE_NAMES`](super::SCHEDULE_NAMES) order; empty otherwise.
    pub candidate_scan_distances: Vec<f64>,
    /// Under schedule selection: each candidate's edge-length spread
    /// ([`crate::metrics::edge_length_spread`]), in [`SCHEDULE_NAMES`](super::SCHEDULE_NAMES)
    /// order; empty otherwise.
    pub candidate_edge_spreads: Vec<f64>,
}

/// The outcome of a fit, in the user's frame.
#[derive(Clone, Debug)]
pub struct FitResult {
    /// Fitted vertices (M).
    pub vertices: Vec<[f64; 3]>,
    /// Per-step wrinkle-vector field of the last iteration (M).
    pub wvf: Vec<[f64; 3]>,
    /// Wrinkle-vector field of the total motion from the input template to the fit (M).
    pub wvf_accumulated: Vec<[f64; 3]>,
    /// Iterations run.
    pub iterations: usize,
    /// Per-iteration figures.
    pub history: Vec<IterationRecord>,
    /// `(iteration, vertices)` snapshots, user frame, when requested.
    pub snapshots: Vec<(usize, Vec<[f64; 3]>)>,
    /// The parameters used.
    pub params: FitParams,
    /// Facts about the run.
    pub diagnostics: Diagnostics,
    /// Does the fit look right: figures without ground truth and the verdict
    /// ([`crate::quality`]), against the scan points of positive weight (on a scan that holds
    /// more than the garment, the points the template explains).
    pub quality: Quality,
    /// Per template vertex, the scan point (index into the target as given) it ends nearest
    /// to.
    pub correspondences: Vec<u32>,
    /// Per template vertex, the distance from the fitted vertex to that point (user units).
    pub residuals: Vec<f64>,
    /// Per template vertex, whether it has scan support ([`crate::quality`]).
    pub support: Vec<bool>,
}
