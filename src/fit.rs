//! The fit driver: ξ iterations of the N-body step (§2) followed by the FoldMatch deformation
//! model (§3) or the NRGa rigid-per-vertex update (SPEC §2.10–2.11).
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

use crate::curvature::{gaussian_curvature_mesh, gaussian_curvature_points};
use crate::deformation::deformation_gradient;
use crate::error::{FoldMatchError, Result};
use crate::knn::{morton_order, neighborhood_size, NeighborCache, PointIndex, TargetNeighbours};
use crate::limits::{MAX_ITERATIONS, MAX_K, MAX_PARAMETER};
use crate::math::{nearest_rotation_with, vec3, Mat3, Vec3};
use crate::mesh::{clean_faces, validate_faces, validate_points, vertex_normals, VertexFaces};
use crate::nbody::{self, NBodyParams, TwoWayPull};
use crate::normalize::Frame;
use crate::regularize::{regularize, Regularization, RegularizeBuffers};
use crate::rings::{adjacency, n_rings, n_rings_of, Neighborhoods, RingDeltas};
use crate::rotation::{
    kabsch, point_moments, ring_centroids, ring_fit_from_moments, ring_fit_from_sum,
    solve_rotation, transform_vertex, PointMoments,
};
use crate::wrinkle::{modified_stretch, stretch_stays_positive};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Which motion/deformation model updates the template.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's method: n-ring deformation gradients, Eq. 4–8.
    #[serde(rename = "foldmatch")]
    FoldMatch,
    /// The NRGa baseline: per-vertex rigid (Kabsch) fit of a k-NN neighborhood.
    Nrga,
}

/// Which gradient enters the rotation solve of Eq. 8.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationSource {
    /// The regularized gradient `R̄ Ū` (default). Û commutes with Ū, so R* = R̄ and ψ moves no
    /// vertex: it shapes only the wrinkle-vector field (SPEC §2.9).
    Regularized,
    /// The raw Eq. 4 gradient, in which ψ does act on the rotation.
    Raw,
}

/// What to do with a template placed far from the scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Prealign {
    /// Fit as given; a template whose centroid is more than [`FAR_AWAY`] target diagonals
    /// from the scan's centroid is rejected with [`FoldMatchError::FarAway`].
    None,
    /// Translate the template so its centroid lies on the scan's centroid first.
    Centroid,
}

/// Schedule selection (issue "Fidelity", docs/method.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// Run the schedule the parameters describe.
    Single,
    /// Also run the *sharp* schedule ([`FitParams::sharp_schedule`]: two-way 1, coarse 30 %,
    /// constant softening) and return the fit closer to the scan (the mean distance from every
    /// scan point to its nearest fitted vertex), a near-tie — within
    /// [`FitParams::selection_margin`] of the closest — going to the fit whose edge lengths
    /// spread least from the template's ([`crate::metrics::edge_length_spread`]; see
    /// [`select_schedule`]). FoldMatch only; twice the work, the two runs side by side
    /// (concurrently, sharing the setup).
    ScanDistance,
    /// Like [`Selection::ScanDistance`] with a third candidate, the *gentle* schedule
    /// ([`FitParams::gentle_schedule`]: the given one with ⅔ of the two-way weight and a
    /// longer annealing); three times the work of one schedule (docs/method.md).
    ScanDistanceWide,
}

/// The names of the candidate schedules, in [`FitParams::candidate_schedules`] order.
pub const SCHEDULE_NAMES: [&str; 3] = ["given", "sharp", "gentle"];

/// Scan points per rigid-phase vertex below which the automatic
/// [`FitParams::rigid_scan_sample`] does not sample the scan.
pub const RIGID_SCAN_POINTS_PER_VERTEX: usize = 8;

/// The largest scan-sample stride ([`FitParams::rigid_scan_sample`],
/// [`FitParams::coarse_scan_sample`]), given or automatic.
pub const MAX_SCAN_SAMPLE: usize = 64;

/// Scan points per coarse-phase vertex that the automatic [`FitParams::coarse_scan_sample`]
/// leaves at least: it samples only scans with twice as many points as that per vertex.
pub const COARSE_SCAN_POINTS_PER_VERTEX: usize = 4;

/// The largest stride the automatic [`FitParams::coarse_scan_sample`] takes. Measured on 19
/// held-out dense scans (`bench/heldout_density.py --points 60000`, 9–42 points per vertex):
/// stride 2 f_R ×1.002 in geometric mean (worst ×1.036), 4 ×1.006 (worst ×1.068), the
/// uncapped stride (up to 42) ×1.017 with one wind frame ×1.40 (docs/method.md,
/// "Fourteenth round").
pub const COARSE_SCAN_MAX_AUTO_STRIDE: usize = 2;

/// The automatic coarse ring radius ([`FitParams::coarse_rings`] = 0) at
/// [`COARSE_RINGS_REFERENCE_VERTICES`] template vertices and below.
pub const AUTO_COARSE_RINGS: usize = 8;

/// The template size at which the automatic coarse radius is [`AUTO_COARSE_RINGS`] (a 41 × 41
/// sheet, the size most harness cases were tuned at); above it the radius grows as the square
/// root of the vertex count, so each rigid piece keeps about the same share of the surface.
pub const COARSE_RINGS_REFERENCE_VERTICES: f64 = 1_700.0;

/// The largest automatic coarse radius: an 8-ring holds ~130 vertices of a grid, a 12-ring
/// ~290, and the ring rows and their sums grow with it (the paper-sized fit +8 % wall time).
/// Held out, caps of 10 or 11 fit 4–6 % farther from the truth than 12, and 12 rings fitted
/// the 81 × 81 sheets closer than 16 on 6 of 8 (docs/method.md "Seventeenth round").
pub const AUTO_COARSE_RINGS_MAX: usize = 12;

/// Two-way weight of the `"fast"` preset's one schedule ([`FitParams::fast`]): between the
/// sharp schedule's 1 and the default's 4.5 (measured 1.5, 2, 3 and 4.5 with a 30 % coarse
/// phase and constant softening: 3 had the lowest f_λ and the best worst group).
pub const FAST_TWO_WAY: f64 = 3.0;

/// The default [`FitParams::two_way_trust`].
pub const DEFAULT_TWO_WAY_TRUST: f64 = 4.0;

/// The default [`FitParams::two_way_rim`].
pub const DEFAULT_TWO_WAY_RIM: f64 = 1.0;

/// Iterations of the `"accurate"` preset ([`FitParams::accurate`]).
pub const ACCURATE_ITERATIONS: usize = 150;

/// The default [`FitParams::knn_slack`]: on the 91 harness cases σ = 0.1 leaves the fit's
/// accuracy unchanged (f_R × 1.000, f_λ × 0.998 in geometric mean against σ = 0; 0.2: × 0.997
/// / × 1.006; 0.3: × 1.017 / × 1.016) and spares a fifth of the fresh k-NN queries of the
/// million-point case (docs/performance.md, "Thirteenth round").
pub const DEFAULT_KNN_SLACK: f64 = 0.1;

/// Default ρ: K = 14 at the paper's 14,400 scan points, where 0.2 % gave 28; scans under
/// 8,000 points stay at `k_min` = 8 either way. On the paper-sized harness cases the smaller
/// neighbourhoods gave f_R ×0.960 and f_λ ×0.925 (5 of 6 closer to the truth), neutral
/// elsewhere (all 91 cases: f_R ×0.998, f_λ ×0.992), and a paper-sized fit in about a quarter
/// less time. Held out (`bench/heldout_density.py`: the real garments at 15,000 points, 8
/// unseen random sheets): f_R ×1.026, f_λ ×0.958, neutral on the garments; smooth sheets
/// under noise prefer 0.2 % (docs/method.md "Thirteenth round").
pub const DEFAULT_RHO: f64 = 0.001;

/// The paper's ρ = 0.2 % (SPEC §2), kept by [`FitParams::paper`].
pub const PAPER_RHO: f64 = 0.002;

/// Default upper clamp of K: reached from 32,000 scan points on (at ρ = 0.1 %). On the
/// 1M-point case (K 64 → 32) f_R 0.0228 → 0.0229, f_λ 0.0203 → 0.0196, flipped faces 0.86 % →
/// 0.53 %, and the fit 46.6 → 37.5 s (docs/method.md, "Thirteenth round").
pub const DEFAULT_K_MAX: usize = 32;

/// SPEC §2's upper clamp of K, kept by [`FitParams::paper`].
pub const PAPER_K_MAX: usize = 64;

/// Distance (in target bounding-box diagonals) beyond which an unaligned template is refused.
pub const FAR_AWAY: f64 = 1.0;

/// Every parameter of a fit. `Default` gives the paper's constants (§4) with the converging
/// readings of SPEC §2.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FitParams {
    /// FoldMatch or NRGa.
    pub method: Method,
    /// ξ, the number of iterations.
    pub iterations: usize,
    /// n of the n-ring template neighborhoods Γᵏ_Y.
    pub rings: usize,
    /// ρ, the target neighborhood size as a fraction of the scan's point count:
    /// `K = clamp(⌊ρN⌋, k_min, k_max)`. Default [`DEFAULT_RHO`] (0.1 %); the `"paper"` preset
    /// keeps [`PAPER_RHO`] (0.2 %), the upper end of the paper's "typically 0.02 – 0.2 %".
    pub rho: f64,
    /// Lower clamp of K.
    pub k_min: usize,
    /// Upper clamp of K. Default [`DEFAULT_K_MAX`] (32); the `"paper"` preset keeps SPEC §2's 64.
    pub k_max: usize,
    /// N-body constants and readings.
    #[serde(flatten)]
    pub nbody: NBodyParams,
    /// ψ, the wrinkle stretch coefficient.
    pub psi: f64,
    /// γ, weight of the normal completion of Eq. 4 (0 disables it).
    pub normal_completion: f64,
    /// Mean used by Eq. 5.
    pub regularization: Regularization,
    /// Gradient used by Eq. 8.
    pub rotation_source: RotationSource,
    /// Set velocities to the applied motion after each update (SPEC §2.4); `false` keeps the
    /// integrated velocity (literal reading).
    pub velocity_sync: bool,
    /// Work in the normalized frame (SPEC §1).
    pub normalize: bool,
    /// Stop early when the mean displacement of an iteration (normalized units) is below this
    /// (0 disables).
    pub tolerance: f64,
    /// Use the curvature term of Eq. 2 (`false` sets κ = 0, i.e. α = 1).
    pub use_curvature: bool,
    /// Handling of a template placed far from the scan.
    pub prealign: Prealign,
    /// Keep the vertex positions every this many iterations (0 keeps none).
    pub snapshot_every: usize,
    /// Two-way attraction: weight of the pull of every scan point on its nearest template
    /// vertex, added to Eq. 2 (0: the paper's one-way attraction).
    pub two_way: f64,
    /// Trust radius of the two-way attraction, as a multiple c of the fit's own current misfit:
    /// a scan point pulls its nearest template vertex only while it lies within
    /// `c · max(median over the template of the distance to the nearest scan point, mean
    /// template edge length)` of it. What the garment cannot explain — the skin beyond a hem, a
    /// cuff or a collar, the hair, another garment — lies farther and pulls nothing, while the
    /// median, taken from the template's side, is not moved by how much of the scan is body
    /// (Turk & Levoy's rejection of distant pairs; docs/method.md "Scans of dressed people").
    /// 0: every scan point pulls.
    pub two_way_trust: f64,
    /// Rim rejection of the two-way attraction, in mean template edge lengths: a scan point
    /// whose nearest template vertex lies on the template's boundary and that lies beyond that
    /// boundary (along its outward direction in the surface) by more than this margin pulls
    /// nothing — the skin below a hem or out of a sleeve continues the scan's surface past the
    /// garment's edge, and would drag it there (Turk & Levoy's rejection of boundary pairs;
    /// docs/method.md "Scans of dressed people"). 0: off. Applies where the attraction sees
    /// every template vertex (not on the rigid phase's vertex sample).
    pub two_way_rim: f64,
    /// How the two-way pulls on one vertex combine: their mean, or (the default) their sum in
    /// proportion to the template's share of the scan, so that a vertex standing for an
    /// uncovered scan region is pulled in proportion to it ([`TwoWayPull`]).
    pub two_way_pull: TwoWayPull,
    /// Rigid phase: this fraction of the ξ iterations comes first and moves the whole template
    /// rigidly (one Kabsch fit of all vertices' old to proposed positions). FoldMatch only.
    pub rigid_fraction: f64,
    /// Coarse phase: the next fraction of the iterations moves every vertex by the Kabsch rigid
    /// fit of its large geodesic neighborhood (`coarse_rings`), i.e. piecewise rigidly, before
    /// the FoldMatch n-ring model takes over. FoldMatch only.
    pub coarse_fraction: f64,
    /// Radius (graph distance) of the neighborhoods of the coarse phase; 0 (the default):
    /// automatic, scaled with the template's resolution ([`FitParams::coarse_radius`]):
    /// [`AUTO_COARSE_RINGS`] up to [`COARSE_RINGS_REFERENCE_VERTICES`] vertices, then growing
    /// as √M up to [`AUTO_COARSE_RINGS_MAX`]. A fixed radius covers a smaller share of a finer
    /// mesh, and the coarse phase's rigid pieces then no longer turn a sleeve or a panel as a
    /// unit (docs/method.md "Seventeenth round": held out, f_R ×0.88 against a fixed 8).
    pub coarse_rings: usize,
    /// Rigid phase on a sample: the N-body forces (and the two-way attraction's pulls) are
    /// computed for every `rigid_sample`-th template vertex only, and the one Kabsch fit of
    /// those vertices moves the whole template (1: every vertex). The rigid phase only needs
    /// the one rigid motion, so 4 (the default) costs no accuracy on the harness and cuts
    /// the phase's k-NN, two-way and force work by about 4× (docs/method.md).
    pub rigid_sample: usize,
    /// Rigid phase on a scan sample: the rigid phase sees every `rigid_scan_sample`-th scan
    /// point only (in the fit's space-filling-curve order, so the sample is spread evenly),
    /// with `⌈K / s⌉` target neighbours per vertex (about the same neighbourhood radius) and
    /// the two-way pulls of the sampled points. Eq. 2's force is a mean over the neighbours
    /// and the pulls on a vertex a mean over the scan points choosing it, which the sample
    /// estimates; the phase reduces them to one rigid motion. 0 (the default): automatic, the
    /// largest stride leaving [`RIGID_SCAN_POINTS_PER_VERTEX`] scan points per vertex of the
    /// rigid phase's sample (1 — the whole scan — unless the scan has more than that many times
    /// as many points, e.g. 4 for a 1M-point scan under a 100K-vertex template); 1: the whole
    /// scan.
    pub rigid_scan_sample: usize,
    /// Coarse phase on a scan sample, as [`FitParams::rigid_scan_sample`] for the rigid
    /// phase: the coarse phase sees every `coarse_scan_sample`-th scan point, with `⌈K / s⌉`
    /// target neighbours; each vertex there moves by the Kabsch fit of its coarse ring, which
    /// the sampled forces estimate. 0 (the default): automatic, the largest stride leaving
    /// [`COARSE_SCAN_POINTS_PER_VERTEX`] scan points per vertex of the coarse phase's sample,
    /// at most [`COARSE_SCAN_MAX_AUTO_STRIDE`] (so 2 where the scan has at least 8 points per
    /// vertex, as a 1M-point scan under a 100K-vertex template, else 1 — the whole scan; every
    /// harness case is at 1); 1: the whole scan. Measured on dense scans: the million-point
    /// case 32.4 s → 24.4 s at f_R ×0.999.
    pub coarse_scan_sample: usize,
    /// Coarse phase on a sample: the forces are computed for every `coarse_sample`-th vertex
    /// only, and every vertex moves by the Kabsch fit of the sampled members of its coarse
    /// ring (1: every vertex; more needs coarse rings of radius ≥ 3 at every level).
    pub coarse_sample: usize,
    /// Levels of the coarse phase: its iterations are split evenly into this many levels, level
    /// `l` using neighborhoods of radius `max(1, r / 2^l)`, r the coarse radius
    /// ([`FitParams::coarse_radius`]) (1: one radius throughout),
    /// so the pieces that move rigidly shrink as the fit proceeds, like the decreasing
    /// stiffness of non-rigid ICP.
    pub coarse_levels: usize,
    /// Fast 3×3 matrix functions, each agreeing with the eigen-decomposition to round-off:
    /// truncated series for the logarithms and exponentials of Eq. 5 near the identity, the
    /// unit-quaternion (Horn / QCP) solution for polar factors and nearest rotations (Eq. 5's
    /// rotation mean, Eq. 8, the Kabsch fits of the rigid and coarse phases, of the rest-shape
    /// rigidity and of NRGa), closed-form eigenvalues and a direct inverse for well-conditioned
    /// Eq. 4 systems. `false` always uses the Jacobi eigen-decomposition (the exact reference
    /// path).
    pub matrix_series: bool,
    /// Re-use earlier k-NN candidates when that is provably exact (see
    /// [`crate::knn::NeighborCache`]), and read the two-way attraction's nearest template
    /// vertices off the inverted k-NN lists where certified ([`crate::knn::ReverseNearest`]);
    /// `false` queries a k-d tree for every vertex and every scan point every iteration.
    /// Results are the same either way.
    pub knn_cache: bool,
    /// σ of the rigid and coarse phases' approximate target neighborhoods: there the k-NN
    /// cache ([`crate::knn::NeighborCache::set_slack`]) re-uses a vertex's candidates while
    /// every returned neighbour is within `(1 + σ) ×` the true K-th nearest distance, sparing
    /// the fresh queries of template points still far off the scan (their candidates all lie
    /// at about their height, so the exact test fails at nearly every move). The FoldMatch
    /// iterations stay exact. 0: exact throughout; without `knn_cache` every query is exact.
    /// Default [`DEFAULT_KNN_SLACK`]; docs/performance.md, "Thirteenth round".
    pub knn_slack: f64,
    /// Rest-shape rigidity β₀ of the FoldMatch iterations (as-rigid-as-possible blending): in
    /// the j-th of the J iterations after the rigid and coarse phases every vertex goes to
    /// `(1 − β) ·` its Eq. 8 update `+ β ·` the placement of its template n-ring, as given
    /// (the rest shape), by the Kabsch rigid fit of that ring onto the proposed positions,
    /// with `β = β₀ (1 − j / J)` (stiff first, the paper's update alone at the end, like
    /// non-rigid ICP's decreasing stiffness). Eq. 8 moves the *current* ring, so edge lengths
    /// drift where the scan does not pin them (tangential sliding, holes); the rest-shape term
    /// remembers the template's metric, as ARAP's local step does. 0: the paper's update
    /// alone. FoldMatch only; docs/method.md "Seventh round".
    pub rest_rigidity: f64,
    /// Softening annealing: ε starts at `anneal × ε` and decreases linearly to ε over the
    /// first `anneal_fraction` of the ξ iterations (1: constant ε, the paper's reading).
    pub anneal: f64,
    /// Fraction of the iterations over which the softening anneals.
    pub anneal_fraction: f64,
    /// Run one schedule, or two and keep the fit closer to the scan ([`Selection`]).
    pub selection: Selection,
    /// Schedule selection's near-tie margin: candidates whose mean scan→fit distance is within
    /// `(1 + selection_margin) ×` the closest one's are tied, and the tie goes to the least
    /// edge-length spread ([`select_schedule`]). 0: the closest fit alone (the rule before
    /// 2026-12-01). The given schedule's three-fold two-way pull minimizes exactly the
    /// distance compared, so it wins it by a few per cent even where its fit slid along the
    /// scan (docs/method.md "Eighth round").
    pub selection_margin: f64,
    /// When schedule selection compares its candidates, as a fraction of the ξ iterations: at
    /// iteration `⌈selection_at · ξ⌉` the candidates' fits are compared by the same rule
    /// ([`select_schedule`]) and only the chosen one runs on; the others' remaining iterations
    /// are spared. A case whose choice there is the one made at the end gets the same fit,
    /// bit for bit (the chosen run never sees the others). 1: at the end.
    pub selection_at: f64,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            method: Method::FoldMatch,
            iterations: 100,
            rings: 2,
            rho: DEFAULT_RHO,
            k_min: 8,
            k_max: DEFAULT_K_MAX,
            nbody: NBodyParams::default(),
            psi: 0.05,
            normal_completion: 0.3,
            regularization: Regularization::LogEuclidean,
            rotation_source: RotationSource::Regularized,
            velocity_sync: true,
            normalize: true,
            tolerance: 0.0,
            use_curvature: true,
            prealign: Prealign::None,
            snapshot_every: 0,
            two_way: 4.5,
            two_way_trust: DEFAULT_TWO_WAY_TRUST,
            two_way_rim: DEFAULT_TWO_WAY_RIM,
            two_way_pull: TwoWayPull::Coverage,
            rigid_fraction: 0.3,
            coarse_fraction: 0.5,
            coarse_rings: 0,
            coarse_levels: 1,
            rigid_sample: 4,
            rigid_scan_sample: 0,
            coarse_scan_sample: 0,
            coarse_sample: 1,
            knn_cache: true,
            knn_slack: DEFAULT_KNN_SLACK,
            matrix_series: true,
            rest_rigidity: 0.65,
            anneal: 3.0,
            anneal_fraction: 0.6,
            selection: Selection::ScanDistance,
            selection_margin: 0.06,
            selection_at: 1.0,
        }
    }
}

/// A real parameter's allowed range ([`FitParams::validate`]): the test and the rule it states.
#[derive(Clone, Copy)]
struct Range {
    contains: fn(f64) -> bool,
    rule: &'static str,
}

// The unbounded real parameters stop at `limits::MAX_PARAMETER` (10⁶): they act in the
// normalized frame, where larger values only throw the template out of the scan's range.
const POSITIVE: Range = Range {
    contains: |v| v > 0.0 && v <= MAX_PARAMETER,
    rule: "must be in (0, 1e6]",
};
const NON_NEGATIVE: Range = Range {
    contains: |v| (0.0..=MAX_PARAMETER).contains(&v),
    rule: "must be in [0, 1e6]",
};
const UNIT: Range = Range {
    contains: |v| (0.0..=1.0).contains(&v),
    rule: "must be in [0, 1]",
};
const OPEN_UNIT: Range = Range {
    contains: |v| v > 0.0 && v <= 1.0,
    rule: "must be in (0, 1]",
};
const PSI: Range = Range {
    contains: |v| v.is_finite() && v.abs() < 1.0,
    rule: "must be finite with |psi| < 1",
};
const AT_LEAST_ONE: Range = Range {
    contains: |v| (1.0..=MAX_PARAMETER).contains(&v),
    rule: "must be in [1, 1e6]",
};

impl FitParams {
    /// The paper's method as printed, with only the converging readings of SPEC §2: one-way
    /// attraction, no rigid or coarse phase, constant softening, Eq. 5 as the affine-invariant
    /// mean, ρ = 0.2 % and K ≤ 64 (the `"paper"` preset).
    pub fn paper() -> Self {
        Self {
            rho: PAPER_RHO,
            k_max: PAPER_K_MAX,
            two_way: 0.0,
            rigid_fraction: 0.0,
            coarse_fraction: 0.0,
            rest_rigidity: 0.0,
            anneal: 1.0,
            anneal_fraction: 0.0,
            selection: Selection::Single,
            regularization: Regularization::AffineInvariant,
            ..Self::default()
        }
    }

    /// The default without softening annealing, for a fit that starts close to its scan
    /// (warm-started frames of a sequence): annealing is a far-start device and, with few
    /// iterations per frame, leaves too little time at the final ε (docs/method.md). Its
    /// two-way weight (2), averaged pulls ([`TwoWayPull::Mean`]) and rigid phase on every
    /// vertex are the values it was measured with on sequences; it has no rest-shape rigidity
    /// (a warm-started frame's template is the previous fit, not a rest shape, and the option
    /// was not measured on sequences).
    pub fn tracking() -> Self {
        Self {
            two_way: 2.0,
            two_way_pull: TwoWayPull::Mean,
            rigid_sample: 1,
            rest_rigidity: 0.0,
            anneal: 1.0,
            anneal_fraction: 0.0,
            selection: Selection::Single,
            ..Self::default()
        }
    }

    /// The alternative schedule of [`Selection::ScanDistance`]: these parameters with the
    /// first-round schedule of docs/method.md — two-way weight 1, coarse phase 30 %, constant
    /// softening — which fits gently curved, misplaced cloth (the random sheets) best, where
    /// the annealed default fits large articulated motion best.
    pub fn sharp_schedule(&self) -> Self {
        Self {
            two_way: self.two_way.min(1.0),
            coarse_fraction: self.coarse_fraction.min(0.3),
            anneal: 1.0,
            anneal_fraction: 0.0,
            selection: Selection::Single,
            ..self.clone()
        }
    }

    /// The third candidate of [`Selection::ScanDistanceWide`]: these parameters with ⅔ of the
    /// two-way weight (4.5 → 3) and the softening annealed over at least 80 % of the iterations
    /// (60 % in the default): long-range pulls for longer, a gentler pull on scan regions the
    /// template does not cover yet (docs/method.md).
    pub fn gentle_schedule(&self) -> Self {
        Self {
            two_way: self.two_way / 1.5,
            anneal_fraction: self.anneal_fraction.max(0.8),
            selection: Selection::Single,
            ..self.clone()
        }
    }

    /// The schedules a fit runs: the given one alone ([`Selection::Single`], or NRGa), or the
    /// candidates of schedule selection, named by [`SCHEDULE_NAMES`].
    pub fn candidate_schedules(&self) -> Vec<Self> {
        let given = Self {
            selection: Selection::Single,
            ..self.clone()
        };
        match self.selection {
            _ if self.method != Method::FoldMatch => vec![given],
            Selection::Single => vec![given],
            Selection::ScanDistance => vec![given, self.sharp_schedule()],
            Selection::ScanDistanceWide => {
                vec![given, self.sharp_schedule(), self.gentle_schedule()]
            }
        }
    }

    /// The default with [`ACCURATE_ITERATIONS`] iterations instead of 100, every phase
    /// lengthened in proportion (the `"accurate"` preset): closer to the truth and to the scan
    /// on the harness at about 1.3× the time (the later iterations re-use more k-NN
    /// candidates); 200 iterations gain f_λ but lose f_R (docs/method.md "Eleventh round").
    /// Until 2026-12-02 this preset was the default with a third candidate schedule
    /// ([`Selection::ScanDistanceWide`], still an option) and the rigid phase on every vertex,
    /// which had become no closer to the truth than the default for twice its time.
    pub fn accurate() -> Self {
        Self {
            iterations: ACCURATE_ITERATIONS,
            ..Self::default()
        }
    }

    /// One schedule instead of schedule selection's two (the `"fast"` preset), between the
    /// given and the sharp one: the default's [`FitParams::sharp_schedule`] (a 30 % coarse
    /// phase, constant softening) with two-way weight [`FAST_TWO_WAY`]. About 0.6× the
    /// default's instructions (0.58× at the paper's size: the second run and the comparison
    /// are spared), at a higher error: on the harness f_R ÷ best peer 0.879 against the
    /// default's 0.761, f_λ ÷ best 0.969 against 0.964; held out f_R 4 % (15,000-point scans)
    /// to 22 % (5,000) above the default's. Either of the default's candidates alone is worse
    /// (the given one 0.985 / 0.999, the sharp one 0.892 / 1.054; docs/method.md "Eighteenth
    /// round"). For previews and large batches where time comes first.
    pub fn fast() -> Self {
        Self {
            two_way: FAST_TWO_WAY,
            ..Self::default().sharp_schedule()
        }
    }

    /// A named preset: `"default"` (the most accurate configuration for its cost, see
    /// docs/method.md), `"accurate"` ([`FitParams::accurate`]), `"fast"`
    /// ([`FitParams::fast`]), `"paper"` ([`FitParams::paper`]) or `"tracking"`
    /// ([`FitParams::tracking`]).
    pub fn preset(name: &str) -> Result<Self> {
        match name {
            "default" => Ok(Self::default()),
            "accurate" => Ok(Self::accurate()),
            "fast" => Ok(Self::fast()),
            "paper" => Ok(Self::paper()),
            "tracking" => Ok(Self::tracking()),
            other => Err(FoldMatchError::parameter(
                "preset",
                other,
                "one of default, accurate, fast, paper, tracking",
            )),
        }
    }

    /// The stride of the rigid phase's scan sample ([`FitParams::rigid_scan_sample`]) for a
    /// template of `m` vertices and a scan of `n` points.
    pub fn rigid_scan_stride(&self, m: usize, n: usize) -> usize {
        let (per_vertex, most) = (RIGID_SCAN_POINTS_PER_VERTEX, MAX_SCAN_SAMPLE);
        scan_stride(
            self.rigid_scan_sample,
            self.rigid_sample,
            per_vertex,
            most,
            m,
            n,
        )
    }

    /// The stride of the coarse phase's scan sample ([`FitParams::coarse_scan_sample`]).
    pub fn coarse_scan_stride(&self, m: usize, n: usize) -> usize {
        let (per_vertex, most) = (COARSE_SCAN_POINTS_PER_VERTEX, COARSE_SCAN_MAX_AUTO_STRIDE);
        scan_stride(
            self.coarse_scan_sample,
            self.coarse_sample,
            per_vertex,
            most,
            m,
            n,
        )
    }

    /// The coarse phase's ring radius for a template of `m` vertices: [`FitParams::coarse_rings`]
    /// when given, else `clamp(round(8 √(m / 1,700)), 8, 12)` ([`AUTO_COARSE_RINGS`],
    /// [`COARSE_RINGS_REFERENCE_VERTICES`], [`AUTO_COARSE_RINGS_MAX`]).
    pub fn coarse_radius(&self, m: usize) -> usize {
        if self.coarse_rings > 0 {
            return self.coarse_rings;
        }
        let scaled = AUTO_COARSE_RINGS as f64 * (m as f64 / COARSE_RINGS_REFERENCE_VERTICES).sqrt();
        (scaled.round() as usize).clamp(AUTO_COARSE_RINGS, AUTO_COARSE_RINGS_MAX)
    }

    /// Iterations of the rigid and coarse phases: `(rigid, coarse)`, both 0 for NRGa.
    pub fn phase_iterations(&self) -> (usize, usize) {
        if self.method == Method::Nrga {
            return (0, 0);
        }
        let rigid = (self.rigid_fraction * self.iterations as f64).round() as usize;
        let coarse = (self.coarse_fraction * self.iterations as f64).round() as usize;
        (rigid, coarse.min(self.iterations.saturating_sub(rigid)))
    }

    /// The k-NN slack σ in force at iteration `it` (1-based): [`FitParams::knn_slack`] in the
    /// rigid and coarse phases, 0 in the FoldMatch (or NRGa) iterations.
    pub fn knn_slack_at(&self, it: usize) -> f64 {
        let (rigid, coarse) = self.phase_iterations();
        if it <= rigid + coarse {
            self.knn_slack
        } else {
            0.0
        }
    }

    /// Parses parameters from a JSON object; missing keys take their defaults, unknown keys are
    /// an error naming the key.
    pub fn from_json(text: &str) -> Result<Self> {
        Self::from_json_over(text, Self::default())
    }

    /// Like [`FitParams::from_json`], with missing keys taken from `base` (a preset).
    pub fn from_json_over(text: &str, base: Self) -> Result<Self> {
        let mut given: serde_json::Map<String, serde_json::Value> = serde_json::from_str(text)
            .map_err(|e| {
                FoldMatchError::parameter("params", short(text), &format!("not a JSON object: {e}"))
            })?;
        let known = serde_json::to_value(Self::default()).expect("FitParams serializes");
        let known = known.as_object().expect("FitParams is an object");
        if let Some(bad) = given.keys().find(|k| !known.contains_key(*k)) {
            let names: Vec<&str> = known.keys().map(String::as_str).collect();
            return Err(FoldMatchError::parameter(
                bad,
                "?",
                &format!("unknown parameter; known: {}", names.join(", ")),
            ));
        }
        let base = serde_json::to_value(base).expect("FitParams serializes");
        for (key, value) in base.as_object().expect("object") {
            given.entry(key.clone()).or_insert_with(|| value.clone());
        }
        let params: Self = serde_json::from_value(serde_json::Value::Object(given.clone()))
            .map_err(|e| Self::blame(&given, &base, e))?;
        params.validate()?;
        Ok(params)
    }

    /// The error of a parameter object that does not deserialize, naming the first key whose
    /// value alone makes `base` fail (and only that key and value, not the whole object).
    fn blame(
        given: &serde_json::Map<String, serde_json::Value>,
        base: &serde_json::Value,
        whole: serde_json::Error,
    ) -> FoldMatchError {
        for (key, value) in given {
            let mut one = base.clone();
            one[key.as_str()] = value.clone();
            if let Err(e) = serde_json::from_value::<Self>(one) {
                let shown = match value {
                    serde_json::Value::String(s) => short(s),
                    other => short(&other.to_string()),
                };
                let non_finite = matches!(
                    shown.to_ascii_lowercase().trim_start_matches(['+', '-']),
                    "nan" | "inf" | "infinity" | "null"
                );
                let reason = if non_finite {
                    "must be a finite number".to_string()
                } else {
                    let e = e.to_string();
                    // serde's message ends with " at line L column C" of a text we made.
                    e.split(" at line ").next().unwrap_or(&e).to_string()
                };
                return FoldMatchError::parameter(key, shown, &reason);
            }
        }
        FoldMatchError::parameter("params", "?", &whole.to_string())
    }

    /// The parameters as a JSON object (every key, defaults included).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("FitParams serializes")
    }

    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<()> {
        let p = &self.nbody;
        if !(1..=MAX_ITERATIONS).contains(&self.iterations) {
            return Err(FoldMatchError::parameter(
                "iterations",
                self.iterations,
                &format!("must be in 1..={MAX_ITERATIONS}"),
            ));
        }
        // Every real-valued parameter's range.
        let rules = [
            ("rho", self.rho, POSITIVE),
            ("gravity", p.gravity, POSITIVE),
            ("softening", p.softening, POSITIVE),
            ("time_step", p.time_step, POSITIVE),
            ("template_mass", p.template_mass, POSITIVE),
            ("target_mass", p.target_mass, POSITIVE),
            ("alpha_floor", p.alpha_floor, OPEN_UNIT),
            ("psi", self.psi, PSI),
            ("selection_at", self.selection_at, OPEN_UNIT),
            ("normal_completion", self.normal_completion, NON_NEGATIVE),
            ("tolerance", self.tolerance, NON_NEGATIVE),
            ("selection_margin", self.selection_margin, NON_NEGATIVE),
            ("two_way", self.two_way, NON_NEGATIVE),
            ("two_way_trust", self.two_way_trust, NON_NEGATIVE),
            ("two_way_rim", self.two_way_rim, NON_NEGATIVE),
            ("damping", p.damping, UNIT),
            ("knn_slack", self.knn_slack, UNIT),
            ("rigid_fraction", self.rigid_fraction, UNIT),
            ("coarse_fraction", self.coarse_fraction, UNIT),
            ("anneal_fraction", self.anneal_fraction, UNIT),
            ("rest_rigidity", self.rest_rigidity, UNIT),
            ("anneal", self.anneal, AT_LEAST_ONE),
        ];
        for (name, v, range) in rules {
            if !(range.contains)(v) {
                return Err(FoldMatchError::parameter(name, shown(v), range.rule));
            }
        }
        if self.rigid_fraction + self.coarse_fraction > 1.0 {
            return Err(FoldMatchError::parameter(
                "rigid_fraction + coarse_fraction",
                self.rigid_fraction + self.coarse_fraction,
                "must be <= 1",
            ));
        }
        if !(1..=4).contains(&self.coarse_levels) {
            return Err(FoldMatchError::parameter(
                "coarse_levels",
                self.coarse_levels,
                "must be in 1..=4",
            ));
        }
        if !(1..=64).contains(&self.coarse_sample) {
            return Err(FoldMatchError::parameter(
                "coarse_sample",
                self.coarse_sample,
                "must be in 1..=64",
            ));
        }
        // The smallest radius any template gets (the automatic one grows with the size).
        let smallest_radius = self.coarse_radius(0);
        if self.coarse_sample > 1 && (smallest_radius >> (self.coarse_levels.max(1) - 1)) < 3 {
            return Err(FoldMatchError::parameter(
                "coarse_sample",
                self.coarse_sample,
                "needs coarse rings of radius >= 3 at every level (coarse_rings / 2^(coarse_levels-1))",
            ));
        }
        for (name, value) in [
            ("rigid_scan_sample", self.rigid_scan_sample),
            ("coarse_scan_sample", self.coarse_scan_sample),
        ] {
            if value > MAX_SCAN_SAMPLE {
                return Err(FoldMatchError::parameter(
                    name,
                    value,
                    &format!("must be in 0..={MAX_SCAN_SAMPLE} (0: automatic)"),
                ));
            }
        }
        if !(1..=64).contains(&self.rigid_sample) {
            return Err(FoldMatchError::parameter(
                "rigid_sample",
                self.rigid_sample,
                "must be in 1..=64",
            ));
        }
        if self.coarse_rings > 32 {
            return Err(FoldMatchError::parameter(
                "coarse_rings",
                self.coarse_rings,
                "must be in 0..=32 (0: automatic)",
            ));
        }
        if !(1..=8).contains(&self.rings) {
            return Err(FoldMatchError::parameter(
                "rings",
                self.rings,
                "must be in 1..=8",
            ));
        }
        if self.k_min == 0 || self.k_max < self.k_min || self.k_max > MAX_K {
            return Err(FoldMatchError::parameter(
                "k_min/k_max",
                format!("{}/{}", self.k_min, self.k_max),
                &format!("need 1 <= k_min <= k_max <= {MAX_K}"),
            ));
        }
        Ok(())
    }
}

/// A value for an error message: plain (`2`, `0.25`) in the usual range, else in the shortest
/// form that reads back (`1e300`, not 301 digits; `NaN`).
fn shown(v: f64) -> String {
    if v == 0.0 || (v.is_finite() && (1e-6..1e15).contains(&v.abs())) {
        format!("{v}")
    } else {
        format!("{v:?}")
    }
}

/// `text`, or its first 60 characters and an ellipsis (for error messages).
fn short(text: &str) -> String {
    match text.char_indices().nth(60) {
        Some((i, _)) => format!("{}…", &text[..i]),
        None => text.to_string(),
    }
}

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
fn timed<T>(slot: &mut f64, f: impl FnOnce() -> T) -> T {
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
    /// `(ω₀Δt)²` of the near-field spring (SPEC §2.4; stable well below 1).
    pub omega0_dt_squared: f64,
    /// The curvature source: "mesh", "point_cloud" or "off".
    pub curvature: String,
    /// Whether the tolerance stopped the fit before ξ iterations.
    pub converged: bool,
    /// Whether the observer stopped the fit.
    pub stopped_by_callback: bool,
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
    /// latter two chosen by schedule selection ([`Selection`]).
    pub schedule: String,
    /// Under schedule selection: the mean scan→fit distance (user units) of each candidate's
    /// fit, in [`SCHEDULE_NAMES`] order; empty otherwise.
    pub candidate_scan_distances: Vec<f64>,
    /// Under schedule selection: each candidate's edge-length spread
    /// ([`crate::metrics::edge_length_spread`]), in [`SCHEDULE_NAMES`] order; empty otherwise.
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
}

/// Per-vertex buffers of the FoldMatch deformation model, allocated once per fit.
pub struct Workspace {
    normals_old: Vec<[f64; 3]>,
    normals_new: Vec<[f64; 3]>,
    raw: Vec<Mat3>,
    degenerate: Vec<bool>,
    reg: RegularizeBuffers,
    reg_rotation: Vec<Mat3>,
    reg_stretch: Vec<Mat3>,
    /// Wrinkle vector of every vertex from the last [`deformation_model`] call (Eq. 6–7).
    pub wvf: Vec<[f64; 3]>,
    /// Whether the last deformation step left `wvf` to [`Workspace::fill_wrinkle_field`].
    wvf_stale: bool,
    /// Solved rotation R_k* of every vertex.
    pub rotation: Vec<Mat3>,
    /// Per-point moments of the coarse phase's Kabsch fits ([`ring_fit_from_moments`]), and
    /// their sums over every vertex's coarse ring ([`RingDeltas::sums`]).
    moments: Vec<PointMoments>,
    ring_sums: Vec<PointMoments>,
    /// Seconds spent per stage so far.
    pub times: StageTimes,
}

impl Workspace {
    /// Buffers for `m` vertices.
    pub fn new(m: usize) -> Self {
        Self {
            normals_old: vec![[0.0; 3]; m],
            normals_new: vec![[0.0; 3]; m],
            raw: vec![Mat3::identity(); m],
            degenerate: vec![false; m],
            reg: RegularizeBuffers::new(m),
            reg_rotation: vec![Mat3::identity(); m],
            reg_stretch: vec![Mat3::identity(); m],
            wvf: vec![[0.0; 3]; m],
            wvf_stale: false,
            rotation: vec![Mat3::identity(); m],
            moments: vec![[0.0; 15]; m],
            ring_sums: vec![[0.0; 15]; m],
            times: StageTimes::default(),
        }
    }

    /// The wrinkle-vector field (Eq. 6–7) of the last deformation step, from its regularized
    /// stretches, if that step left it stale.
    pub fn fill_wrinkle_field(&mut self, params: &FitParams) {
        if !std::mem::take(&mut self.wvf_stale) {
            return;
        }
        let start = std::time::Instant::now();
        let stretch = &self.reg_stretch;
        self.wvf.par_iter_mut().enumerate().for_each(|(k, w)| {
            *w = modified_stretch(&stretch[k], params.psi).wrinkle.into();
        });
        self.times.rotation += start.elapsed().as_secs_f64();
    }
}

/// The mesh-side inputs of the deformation model.
pub struct TemplateTopology<'a> {
    /// Template faces (cleaned).
    pub faces: &'a [[u32; 3]],
    /// Vertex → faces incidence.
    pub incidence: &'a VertexFaces,
    /// Γᵏ_Y.
    pub rings: &'a Neighborhoods,
}

/// Runs Eq. 4–8 on the motion `old → new`: fills `ws.rotation` (R_k*) and `ws.wvf`, and returns
/// the number of rank-deficient gradients.
pub fn deformation_model(
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    topo: &TemplateTopology<'_>,
    params: &FitParams,
    ws: &mut Workspace,
) -> usize {
    let degenerate = deformation_rotations(old, new, topo, params, ws);
    ws.fill_wrinkle_field(params);
    degenerate
}

/// [`deformation_model`] without the wrinkle-vector field, which only the last iteration's
/// state needs (the fit computes it once from `ws`'s regularized stretches when it finishes,
/// [`Workspace::fill_wrinkle_field`]): fills `ws.rotation` and marks `ws.wvf` stale.
///
/// Eq. 8's rotation is the polar factor of `H̄ Ûᵀ = R̄ Ū Û`. With the regularized gradient as
/// its source (the default), Ū and Û share their eigenvectors, so `Ū Û` is symmetric and,
/// where every ψ-modified eigenvalue stays positive ([`stretch_stays_positive`]), positive
/// definite: the polar factor is then `R̄` itself, and the Procrustes solve and the
/// ψ-stretch's eigen-decomposition are skipped (under `matrix_series`; equal to round-off, the
/// solve's own error). Elsewhere, and with `matrix_series` off, both are computed.
fn deformation_rotations(
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    topo: &TemplateTopology<'_>,
    params: &FitParams,
    ws: &mut Workspace,
) -> usize {
    let mut times = ws.times;
    timed(&mut times.gradient, || {
        vertex_normals(old, topo.faces, topo.incidence, &mut ws.normals_old);
        vertex_normals(new, topo.faces, topo.incidence, &mut ws.normals_new);
        let (n_old, n_new) = (&ws.normals_old, &ws.normals_new);
        ws.raw
            .par_iter_mut()
            .zip(ws.degenerate.par_iter_mut())
            .enumerate()
            .for_each(|(k, (h, deg))| {
                let (g, d) = deformation_gradient(
                    k,
                    topo.rings.of(k),
                    old,
                    new,
                    &n_old[k],
                    &n_new[k],
                    params.normal_completion,
                    params.matrix_series,
                );
                *h = g;
                *deg = d;
            });
    });
    timed(&mut times.regularize, || {
        regularize(
            &ws.raw,
            topo.rings,
            params.regularization,
            params.matrix_series,
            &mut ws.reg,
            &mut ws.reg_rotation,
            &mut ws.reg_stretch,
        )
    });
    timed(&mut times.rotation, || {
        let (raw, reg_r, reg_u) = (&ws.raw, &ws.reg_rotation, &ws.reg_stretch);
        let shortcut =
            params.matrix_series && params.rotation_source == RotationSource::Regularized;
        ws.rotation.par_iter_mut().enumerate().for_each(|(k, rot)| {
            if shortcut && stretch_stays_positive(&reg_u[k], params.psi) {
                *rot = reg_r[k];
                return;
            }
            let m = modified_stretch(&reg_u[k], params.psi);
            let h = match params.rotation_source {
                RotationSource::Regularized => reg_r[k] * reg_u[k],
                RotationSource::Raw => raw[k],
            };
            *rot = solve_rotation(&h, &m.stretch, params.matrix_series);
        });
    });
    ws.times = times;
    ws.wvf_stale = true;
    ws.degenerate.iter().filter(|&&d| d).count()
}

/// Fits the template to the target.
///
/// * `template_vertices` (M), `template_faces` (T) — the template mesh;
/// * `target` (N) — the scan points; `target_faces` — its faces when it is a mesh (used for
///   curvature only);
/// * `observer` — called after every iteration; returning `false` stops the fit, which then
///   returns what it has (with `diagnostics.stopped_by_callback`).
///
/// Under schedule selection ([`Selection::ScanDistance`], the default: the given and the sharp
/// schedule; [`Selection::ScanDistanceWide`]: also the gentle one) the candidates are fitted
/// side by side, in lockstep (each iteration of every run concurrently, then one progress
/// report, so progress counts ξ iterations and a stop applies to all), sharing the setup; the
/// fit closest to the scan is returned.
pub fn fit(
    template_vertices: &[[f64; 3]],
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    fit_weighted(
        template_vertices,
        template_faces,
        target,
        target_faces,
        None,
        params,
        observer,
    )
}

/// [`fit`] with a non-negative weight per scan point (`target_weights`, `None`: every weight
/// 1). A point's weight scales its pull in Eq. 2's neighbourhood mean (a weighted mean), in
/// the two-way attraction and in schedule selection's scan distance; a point of weight 0 is
/// removed before anything else (the normalized frame, K and the curvature are those of the
/// points that remain), so a 0/1 segmentation mask fits exactly as the masked scan would, and
/// equal weights fit exactly as no weights. Weights of the wrong length, negative, not
/// finite or all zero are refused ([`FoldMatchError::Parameter`] naming the first bad index).
#[allow(clippy::too_many_arguments)]
pub fn fit_weighted(
    template_vertices: &[[f64; 3]],
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    target_weights: Option<&[f64]>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    params.validate()?;
    if let Some(w) = target_weights {
        validate_weights(w, target.len())?;
    }
    // Equal weights are no weights; zero weights remove their points.
    let target_weights = target_weights.filter(|w| w.iter().any(|&x| x != w[0]));
    let kept: Option<Vec<usize>> = target_weights
        .filter(|w| w.contains(&0.0))
        .map(|w| (0..w.len()).filter(|&j| w[j] > 0.0).collect());
    let schedules = params.candidate_schedules();
    let clock = std::time::Instant::now();
    let prepared = Prepared::new(
        template_vertices,
        template_faces,
        target,
        target_faces,
        target_weights,
        kept.as_deref(),
        &schedules,
    )?;
    let mut runs: Vec<ScheduleRun> = schedules
        .into_iter()
        .map(|p| ScheduleRun::new(&prepared, p))
        .collect();
    let setup = clock.elapsed().as_secs_f64();
    let total = params.iterations;
    // Side by side up to the comparison (by default the last iteration; a single run: all).
    let compare_at = if runs.len() > 1 {
        ((params.selection_at * total as f64).ceil() as usize).clamp(1, total)
    } else {
        total
    };
    drive(&prepared, &mut runs, 1..=compare_at, total, observer)?;
    // The candidates are compared on their fitted vertices alone.
    let mut selection = (runs.len() > 1).then(|| {
        let vertices: Vec<Vec<[f64; 3]>> =
            runs.iter().map(|r| r.user_vertices(&prepared)).collect();
        let distances: Vec<f64> = vertices
            .iter()
            .map(|v| selection_distance(target, target_weights, prepared.garment.as_deref(), v))
            .collect();
        let rest_edges = crate::metrics::EdgeLengths::new(template_vertices, &prepared.faces);
        let spreads: Vec<f64> = vertices.iter().map(|v| rest_edges.spread(v)).collect();
        let best = select_schedule(&distances, &spreads, params.selection_margin);
        (best, vertices, distances, spreads)
    });
    let best = selection.as_ref().map_or(0, |s| s.0);
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
        Some((_, compared, ..)) if compare_at == total => compared.swap_remove(best),
        _ => winner.user_vertices(&prepared),
    };
    // Only the chosen run is finished (its wrinkle fields are a whole Eq. 4–8 pass).
    let mut chosen = winner.finish(&prepared, vertices);
    if let Some((_, _, distances, spreads)) = selection {
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
    let finish = clock.elapsed().as_secs_f64() - setup - iterations;
    chosen.diagnostics.wall_seconds = [setup, iterations, finish];
    Ok(chosen)
}

/// Schedule selection's scan distance of the fit `fitted`: the mean distance from the scan
/// points to their nearest fitted vertex, weighted by the scan weights, over the points the
/// template explains (`garment`, user indices) where the scan holds more than the garment.
fn selection_distance(
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    garment: Option<&[usize]>,
    fitted: &[[f64; 3]],
) -> f64 {
    let chosen: Vec<[f64; 3]>;
    let (points, w): (&[[f64; 3]], Option<Vec<f64>>) = match garment {
        Some(g) => {
            chosen = g.iter().map(|&j| target[j]).collect();
            (&chosen, weights.map(|w| g.iter().map(|&j| w[j]).collect()))
        }
        None => (target, weights.map(<[f64]>::to_vec)),
    };
    let d = crate::metrics::nearest_distances(points, fitted);
    match w {
        Some(w) => d.iter().zip(&w).map(|(d, w)| d * w).sum::<f64>() / w.iter().sum::<f64>(),
        None => d.iter().sum::<f64>() / d.len() as f64,
    }
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

/// Schedule selection's rule (docs/method.md "Eighth round"): of the candidates whose mean
/// scan→fit distance is at most `(1 + margin) ×` the smallest, the one with the least
/// edge-length spread; ties keep the earlier candidate (the given schedule first). With
/// `margin = 0` the closest fit wins (among exact ties, the least spread).
///
/// Why a margin: the candidates differ mainly in the two-way weight, and the two-way pull
/// minimizes the very distance compared, so the stronger pull wins it by a few per cent even
/// where its fit slid along the scan (measured on the random sheets: distances within ±3 %,
/// ground-truth error 2× apart); cloth barely stretches, so among fits that lie about as
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

/// Steps every run in lockstep (concurrently when there are several) and reports each iteration
/// once, with the first still-running schedule's figures; a `false` from the observer stops
/// them all.
fn drive(
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

/// What every schedule of a fit reads and none writes: the inputs validated and in the
/// normalized frame (SPEC §1), the scan's k-d tree and curvature, the template's topology.
/// Built once per [`fit`], shared by both runs of schedule selection.
struct Prepared {
    faces: Vec<[u32; 3]>,
    frame: Frame,
    /// The scan in the normalized frame, in [`morton_order`], with its curvature, tree and K.
    target: ScanPoints,
    /// The template in the normalized frame, after any pre-alignment.
    start: Vec<[f64; 3]>,
    incidence: VertexFaces,
    /// Γᵏ_Y: n-rings (FoldMatch) or k-NN neighborhoods (NRGa).
    rings: Neighborhoods,
    /// The centroid of every vertex's ring of `start` (the rest shape), for
    /// [`FitParams::rest_rigidity`]; empty when no schedule uses it.
    rest_centroids: Vec<Vec3>,
    /// The coarse phase's neighborhoods, one per level (empty when no schedule has one).
    coarse_levels: Vec<Neighborhoods>,
    /// Their rows as differences of adjacent rows, for the sums over them.
    coarse_deltas: Vec<RingDeltas>,
    /// Under `coarse_sample` = s > 1: per level, the sampled members of every vertex's coarse
    /// ring, as indices into the sample (vertex u ≡ 0 mod s is sample u / s).
    coarse_sampled: Vec<Neighborhoods>,
    /// Every vertex index (the rigid phase's "ring"; empty when no schedule has one).
    all_vertices: Vec<u32>,
    /// The phases' scan samples ([`FitParams::rigid_scan_sample`],
    /// [`FitParams::coarse_scan_sample`]), one per stride > 1 in use.
    scan_samples: Vec<ScanPoints>,
    /// The strides of the rigid and the coarse phase's scan samples (1: the whole scan).
    scan_strides: [usize; 2],
    /// The template's mean edge length in the normalized frame (the floor of the two-way
    /// trust radius, [`FitParams::two_way_trust`]).
    edge_length: f64,
    /// The template's boundary vertices and their one-rings (for [`FitParams::two_way_rim`];
    /// empty when no schedule uses it).
    rim: Rim,
    /// The scan points (user indices) that schedule selection's scan distance averages over:
    /// those the template explains where the scan holds more than the garment
    /// ([`explained_points`]); `None`: every point of positive weight.
    garment: Option<Vec<usize>>,
    /// The diagnostics every run starts from.
    diagnostics: Diagnostics,
}

impl Prepared {
    /// Validates the inputs and builds the shared state; `schedules` differ at most in their
    /// schedule fields ([`FitParams::sharp_schedule`]), the first one's structure is used.
    fn new(
        template_vertices: &[[f64; 3]],
        template_faces: &[[u32; 3]],
        target: &[[f64; 3]],
        target_faces: Option<&[[u32; 3]]>,
        weights: Option<&[f64]>,
        kept: Option<&[usize]>,
        schedules: &[FitParams],
    ) -> Result<Self> {
        let params = &schedules[0];
        validate_points("template_vertices", template_vertices)?;
        validate_points("target", target)?;
        validate_faces("template_faces", template_faces, template_vertices.len())?;
        if let Some(tf) = target_faces {
            validate_faces("target_faces", tf, target.len())?;
        }
        let m = template_vertices.len();
        let cleaned = clean_faces(template_faces);
        let faces = cleaned.faces;

        // The scan points that remain (weight > 0), with their weights.
        let remaining: Option<Vec<[f64; 3]>> = kept.map(|k| k.iter().map(|&j| target[j]).collect());
        let fitted = remaining.as_deref().unwrap_or(target);
        let weights: Option<Vec<f64>> =
            weights.map(|w| kept.map_or_else(|| w.to_vec(), |k| k.iter().map(|&j| w[j]).collect()));

        // Normalized frame (SPEC §1), of the points that remain, or of those the template
        // explains where the scan holds far more than the garment (a dressed body).
        let garment = explained_points(fitted, template_vertices, template_faces, params);
        let garment_points: Option<Vec<[f64; 3]>> = garment
            .as_ref()
            .map(|g| g.iter().map(|&j| fitted[j as usize]).collect());
        let frame_points = garment_points.as_deref().unwrap_or(fitted);
        let frame = if params.normalize {
            Frame::of_target(frame_points)
        } else {
            Frame::identity()
        };
        let all_scan = frame.forward(target);
        let mut start = frame.forward(template_vertices);
        let centroid = start.iter().fold(Vec3::zeros(), |acc, p| acc + vec3(p)) / m as f64;
        let scan_centroid = (fitted.iter().fold(Vec3::zeros(), |acc, p| acc + vec3(p))
            / fitted.len() as f64
            - vec3(&frame.center))
            / frame.scale;
        let scan_diag = if params.normalize {
            1.0
        } else {
            Frame::of_target(fitted).scale
        };
        let offset = centroid - scan_centroid;
        match params.prealign {
            Prealign::Centroid => {
                for p in &mut start {
                    *p = (vec3(p) - offset).into();
                }
            }
            Prealign::None if offset.norm() > FAR_AWAY * scan_diag => {
                return Err(FoldMatchError::FarAway {
                    distance: offset.norm() / scan_diag,
                });
            }
            Prealign::None => {}
        }

        // Target side, in space-filling-curve order ([`morton_order`]; only round-off depends
        // on the scan's order): k-d tree, K, curvature (a mesh's, of the given order).
        // A mesh's curvature is of the whole mesh; only the remaining points are fitted.
        let mesh_kappa = target_faces
            .filter(|f| params.use_curvature && !f.is_empty())
            .map(|tf| gaussian_curvature_mesh(&all_scan, tf))
            .map(|kappa| match kept {
                Some(k) => k.iter().map(|&j| kappa[j]).collect(),
                None => kappa,
            });
        let scan = match kept {
            Some(k) => k.iter().map(|&j| all_scan[j]).collect(),
            None => all_scan,
        };
        let order = morton_order(&scan);
        let scan: Vec<[f64; 3]> = order.iter().map(|&j| scan[j as usize]).collect();
        let weights: Option<Vec<f64>> =
            weights.map(|w| order.iter().map(|&j| w[j as usize]).collect());
        let index = PointIndex::new(&scan);
        let k = neighborhood_size(params.rho, frame_points.len(), params.k_min, params.k_max);
        let (kappa, curvature_source) = match mesh_kappa {
            _ if !params.use_curvature => (vec![0.0; scan.len()], "off"),
            Some(kappa) => (order.iter().map(|&j| kappa[j as usize]).collect(), "mesh"),
            None => (gaussian_curvature_points(&scan, &index), "point_cloud"),
        };

        // Template side: incidence, neighborhoods, the phases' neighborhoods.
        let incidence = VertexFaces::new(&faces, m);
        let isolated = (0..m)
            .filter(|&v| incidence.offsets[v] == incidence.offsets[v + 1])
            .count();
        // The one-rings, for the n-rings and the ring deltas (built once, and only if used:
        // NRGa's neighbourhoods are k-nearest, and it has no coarse phase).
        let one_rings = std::cell::LazyCell::new(|| adjacency(&faces, m));
        let rings = match params.method {
            Method::FoldMatch => n_rings_of(&one_rings, params.rings),
            Method::Nrga => knn_neighborhoods(&start, params),
        };
        let phases: Vec<(usize, usize)> =
            schedules.iter().map(FitParams::phase_iterations).collect();
        let target = ScanPoints {
            stride: 1,
            points: scan,
            kappa,
            weights,
            index,
            k,
        };
        let n = target.points.len();
        let scan_strides = [
            if phases.iter().any(|p| p.0 > 0) {
                params.rigid_scan_stride(m, n)
            } else {
                1
            },
            if phases.iter().any(|p| p.1 > 0) {
                params.coarse_scan_stride(m, n)
            } else {
                1
            },
        ];
        let mut scan_samples: Vec<ScanPoints> = Vec::new();
        for &stride in &scan_strides {
            if stride > 1 && !scan_samples.iter().any(|s| s.stride == stride) {
                scan_samples.push(target.sample(stride));
            }
        }
        let all_vertices = if phases.iter().any(|p| p.0 > 0) {
            (0..m as u32).collect()
        } else {
            Vec::new()
        };
        let coarse_radius = if phases.iter().any(|p| p.1 > 0) {
            params.coarse_radius(m)
        } else {
            0
        };
        let coarse_levels = if coarse_radius > 0 {
            (0..params.coarse_levels)
                .map(|l| n_rings_of(&one_rings, (coarse_radius >> l).max(1)))
                .collect()
        } else {
            Vec::new()
        };
        let rest_centroids = if schedules
            .iter()
            .any(|p| p.method == Method::FoldMatch && p.rest_rigidity > 0.0)
        {
            (0..m)
                .into_par_iter()
                .map(|v| ring_centroids(rings.of(v), &start, &start).0)
                .collect()
        } else {
            Vec::new()
        };
        let coarse_deltas = if coarse_levels.is_empty() {
            Vec::new()
        } else {
            coarse_levels
                .iter()
                .map(|rings| RingDeltas::new(rings, &one_rings))
                .collect()
        };
        let stride = params.coarse_sample;
        let coarse_sampled = if stride > 1 {
            coarse_levels
                .iter()
                .map(|rings: &Neighborhoods| {
                    Neighborhoods::from_rows(
                        (0..m)
                            .map(|v| {
                                let ring = rings.of(v).iter();
                                ring.filter(|&&u| (u as usize).is_multiple_of(stride))
                                    .map(|&u| u / stride as u32)
                                    .collect()
                            })
                            .collect(),
                    )
                })
                .collect()
        } else {
            Vec::new()
        };

        let edge_length = mean_edge_length(&start, &faces);
        // The rim rule is for scans that hold more than the garment: on a garment alone, the
        // scan beyond a boundary is garment the template has yet to cover.
        let rim = if garment.is_some()
            && schedules
                .iter()
                .any(|p| p.two_way_rim > 0.0 && p.two_way > 0.0)
        {
            let vertices = crate::mesh::boundary_vertices(&faces, m);
            let rings = Neighborhoods::from_rows(
                vertices
                    .iter()
                    .map(|&v| one_rings.of(v as usize).to_vec())
                    .collect(),
            );
            Rim { vertices, rings }
        } else {
            Rim::default()
        };
        let diagnostics = Diagnostics {
            target_neighbours: k,
            coarse_rings: coarse_radius,
            mean_ring_size: rings.members.len() as f64 / m as f64,
            degenerate_faces: cleaned.degenerate,
            duplicate_faces: cleaned.duplicate,
            isolated_vertices: isolated,
            omega0_dt_squared: params.nbody.omega0_dt_squared(k),
            curvature: curvature_source.into(),
            frame: Some(frame),
            schedule: "given".into(),
            ..Default::default()
        };
        Ok(Self {
            faces,
            frame,
            target,
            start,
            incidence,
            rings,
            rest_centroids,
            coarse_levels,
            coarse_deltas,
            coarse_sampled,
            all_vertices,
            scan_samples,
            scan_strides,
            edge_length,
            rim,
            garment: garment.map(|g| {
                g.iter()
                    .map(|&j| kept.map_or(j as usize, |k| k[j as usize]))
                    .collect()
            }),
            diagnostics,
        })
    }

    /// The two-way trust radius's multiple c of a schedule: [`FitParams::two_way_trust`], or
    /// [`DRESSED_TRUST_FACTOR`] of it on a scan that holds more than the garment.
    fn trust(&self, params: &FitParams) -> f64 {
        match self.garment {
            Some(_) => DRESSED_TRUST_FACTOR * params.two_way_trust,
            None => params.two_way_trust,
        }
    }

    /// The scan points a phase sees: the whole scan (`stride` 1), or the scan sample of that
    /// stride.
    fn scan_points(&self, stride: usize) -> &ScanPoints {
        self.scan_samples
            .iter()
            .find(|s| s.stride == stride)
            .unwrap_or(&self.target)
    }

    fn topology(&self) -> TemplateTopology<'_> {
        TemplateTopology {
            faces: &self.faces,
            incidence: &self.incidence,
            rings: &self.rings,
        }
    }
}

/// The template's boundary vertices and their one-rings.
#[derive(Default)]
struct Rim {
    vertices: Vec<u32>,
    rings: Neighborhoods,
}

impl Rim {
    /// Every vertex's outward direction in the surface at `pos` into `out`: on the boundary,
    /// the unit vector from the centroid of its one-ring to the vertex; zero elsewhere.
    fn outward(&self, pos: &[[f64; 3]], out: &mut [[f64; 3]]) {
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
struct ScanPoints {
    stride: usize,
    points: Vec<[f64; 3]>,
    kappa: Vec<f64>,
    /// The scan weights of these points (`None`: all equal).
    weights: Option<Vec<f64>>,
    index: PointIndex,
    k: usize,
}

impl ScanPoints {
    /// Every `stride`-th point (in the fit's Morton order, so spread evenly), with its own
    /// tree and `⌈K / stride⌉` neighbours per template point: about the same neighbourhood
    /// radius as K points of the whole scan ([`FitParams::rigid_scan_sample`]).
    fn sample(&self, stride: usize) -> Self {
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
struct Attraction {
    nn_idx: Vec<u32>,
    nn_d2: Vec<f64>,
    nn_cache: Option<NeighborCache>,
    /// The two-way attraction's state (`None`: one-way attraction).
    reverse: Option<(nbody::ReverseAttraction, Vec<[f64; 3]>)>,
    /// The N-body proposal for every point.
    proposed: Vec<[f64; 3]>,
    /// Scratch: every point's distance to its nearest scan point (the trust radius's median).
    nearest: Vec<f64>,
    /// The floor of the two-way trust radius (the template's mean edge length).
    edge_length: f64,
    /// The trust radius's multiple c ([`Prepared::trust`]).
    trust: f64,
    /// Every point's outward direction on the rim ([`FitParams::two_way_rim`]; empty when
    /// off, or on a vertex sample).
    outward: Vec<[f64; 3]>,
}

impl Attraction {
    /// Buffers for `m` template points over the scan points `scan`; `edge_length` is the
    /// template's mean edge length.
    fn new(
        m: usize,
        scan: &ScanPoints,
        params: &FitParams,
        prepared: &Prepared,
        rim: bool,
    ) -> Self {
        let (n, k) = (scan.points.len(), scan.k);
        let reverse = (params.two_way > 0.0 && params.method == Method::FoldMatch).then(|| {
            (
                nbody::ReverseAttraction::new(m, n, params.knn_cache),
                vec![[0.0; 3]; m],
            )
        });
        Self {
            nn_idx: vec![0u32; m * k],
            nn_d2: vec![0.0; m * k],
            nn_cache: params.knn_cache.then(|| NeighborCache::new(m, k, n)),
            reverse,
            proposed: vec![[0.0; 3]; m],
            nearest: if prepared.trust(params) > 0.0 {
                vec![0.0; m]
            } else {
                Vec::new()
            },
            edge_length: prepared.edge_length,
            trust: prepared.trust(params),
            outward: if rim && params.two_way_rim > 0.0 && params.two_way > 0.0 {
                vec![[0.0; 3]; m]
            } else {
                Vec::new()
            },
        }
    }

    /// The two-way trust radius ([`FitParams::two_way_trust`]) of the template whose
    /// neighbour lists are `nn_d2` (nearest first), with `nearest` as scratch.
    fn trust_radius(
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
        let mid = nearest.len() / 2;
        let (_, median2, _) = nearest.select_nth_unstable_by(mid, f64::total_cmp);
        trust * median2.sqrt().max(edge_length)
    }

    /// Γᵏ_X of the points `pos` among the scan points `scan`, the two-way pulls on them, and
    /// the Eq. 2–3 step: velocities `vel` updated, proposed positions in `self.proposed`.
    #[allow(clippy::too_many_arguments)] // the stage inputs, and the two accumulators
    fn propose(
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
        let rim_margin = params.two_way_rim * self.edge_length;
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
                    weight: params.two_way,
                    pull: params.two_way_pull,
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

/// A phase run on a sample of the template ([`FitParams::rigid_sample`],
/// [`FitParams::coarse_sample`]) or of the scan ([`FitParams::rigid_scan_sample`]): every s-th
/// vertex, its copied positions and velocities, and its own [`Attraction`].
struct PhaseSample {
    stride: usize,
    scan_stride: usize,
    vertices: Vec<u32>,
    /// `0..vertices.len()`: the sample's own indices, for the Kabsch fit.
    indices: Vec<u32>,
    pos: Vec<[f64; 3]>,
    vel: Vec<[f64; 3]>,
    attraction: Attraction,
}

impl PhaseSample {
    fn new(prepared: &Prepared, stride: usize, scan_stride: usize, params: &FitParams) -> Self {
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

/// One schedule's fit in progress: its state and every per-vertex buffer, allocated once.
struct ScheduleRun {
    params: FitParams,
    pos: Vec<[f64; 3]>,
    vel: Vec<[f64; 3]>,
    next: Vec<[f64; 3]>,
    disp: Vec<f64>,
    attraction: Attraction,
    ws: Workspace,
    /// The phases' vertex samples and their buffers (one per distinct stride).
    samples: Vec<PhaseSample>,
    /// Which of `samples` the rigid and the coarse phase use (`None`: every vertex).
    phase_sample: [Option<usize>; 2],
    rigid_iterations: usize,
    coarse_iterations: usize,
    iteration: usize,
    history: Vec<IterationRecord>,
    snapshots: Vec<(usize, Vec<[f64; 3]>)>,
    diagnostics: Diagnostics,
    /// Converged, or stopped by the observer.
    finished: bool,
}

impl ScheduleRun {
    fn new(prepared: &Prepared, params: FitParams) -> Self {
        let m = prepared.start.len();
        let (rigid_iterations, coarse_iterations) = params.phase_iterations();
        let mut samples: Vec<PhaseSample> = Vec::new();
        let mut phase_sample = [None, None];
        let [rigid_scan, coarse_scan] = prepared.scan_strides;
        let wanted = [
            (params.rigid_sample, rigid_scan, rigid_iterations),
            (params.coarse_sample, coarse_scan, coarse_iterations),
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
            params,
        }
    }

    /// One iteration (§2 then §3); `None` when the run has already finished.
    fn step(&mut self, prepared: &Prepared) -> Result<Option<IterationRecord>> {
        if self.finished || self.iteration >= self.params.iterations {
            return Ok(None);
        }
        self.iteration += 1;
        let it = self.iteration;
        let params = &self.params;
        let m = self.pos.len();
        let t = &mut self.ws.times;
        let rigid = it <= self.rigid_iterations;
        let coarse = !rigid && it <= self.rigid_iterations + self.coarse_iterations;
        let sampled = match (rigid, coarse) {
            (true, _) => self.phase_sample[0],
            (_, true) => self.phase_sample[1],
            _ => None,
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
        let (old, new, next) = (&self.pos, &self.attraction.proposed, &mut self.next);
        let degenerate = match params.method {
            _ if rigid => {
                // One Kabsch fit of every vertex's (or the sample's) old → proposed positions.
                let (all, fit_old, fit_new) = match sampled.map(|i| &self.samples[i]) {
                    Some(sample) => (
                        &sample.indices[..],
                        &sample.pos[..],
                        &sample.attraction.proposed[..],
                    ),
                    None => (&prepared.all_vertices[..], &old[..], &new[..]),
                };
                let (c_old, c_new) = ring_centroids(all, fit_old, fit_new);
                let r = kabsch(all, fit_old, fit_new, &c_old, &c_new, params.matrix_series);
                next.par_iter_mut().enumerate().for_each(|(v, out)| {
                    *out = transform_vertex(&r, &vec3(&old[v]), &c_old, &c_new).into();
                });
                0
            }
            _ if coarse => {
                let levels = &prepared.coarse_levels;
                let level =
                    (it - self.rigid_iterations - 1) * levels.len() / self.coarse_iterations;
                // Each vertex moves by the fit of its ring (or of the ring's sampled members).
                let (rings, deltas, ring_old, ring_new) = match sampled.map(|i| &self.samples[i]) {
                    // Every vertex, on a scan sample: the whole rings, the sample's proposal.
                    Some(sample) if sample.stride == 1 => (
                        &levels[level],
                        Some(&prepared.coarse_deltas[level]),
                        &old[..],
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
                        &old[..],
                        &new[..],
                    ),
                };
                let fast = params.matrix_series;
                let ws = &mut self.ws;
                let moments = fast.then_some((&mut ws.moments, deltas, &mut ws.ring_sums));
                kabsch_update(rings, ring_old, ring_new, old, fast, moments, next);
                0
            }
            Method::FoldMatch => {
                let ws = &mut self.ws;
                let before = ws.times.model();
                let d = deformation_rotations(old, new, &prepared.topology(), params, ws);
                ws.times.update -= ws.times.model() - before; // counted in their own stages
                let rot = &ws.rotation;
                let phases = self.rigid_iterations + self.coarse_iterations;
                let beta = rest_rigidity_at(params, it - phases, params.iterations - phases);
                let (rest, fast) = (&prepared.start, params.matrix_series);
                next.par_iter_mut().enumerate().for_each(|(v, out)| {
                    let ring = prepared.rings.of(v);
                    let (c_old, c_new) = ring_centroids(ring, old, new);
                    let moved = transform_vertex(&rot[v], &vec3(&old[v]), &c_old, &c_new);
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
            Method::Nrga => {
                let fast = params.matrix_series;
                kabsch_update(&prepared.rings, old, new, old, fast, None, next);
                0
            }
        };
        self.ws.times.update += update_start.elapsed().as_secs_f64();
        // Velocities follow the applied motion (SPEC §2.4); displacement figures.
        let (dt, sync) = (params.nbody.time_step, params.velocity_sync);
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
        if let Some(bad) = next.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(FoldMatchError::Numerical(format!(
                "vertex {bad} became non-finite at iteration {it}"
            )));
        }
        std::mem::swap(&mut self.pos, &mut self.next);
        // Sequential reduction: identical for any thread count.
        let mean = self.disp.iter().sum::<f64>() / m as f64;
        let max = self.disp.iter().copied().fold(0.0, f64::max);
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
    fn user_vertices(&self, prepared: &Prepared) -> Vec<[f64; 3]> {
        let mut v = self.pos.clone();
        prepared.frame.inverse_in_place(&mut v);
        v
    }

    /// The result (`vertices`: [`ScheduleRun::user_vertices`]), with the wrinkle-vector fields
    /// of the last step and of the whole motion.
    fn finish(mut self, prepared: &Prepared, vertices: Vec<[f64; 3]>) -> FitResult {
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
            acc_rings = n_rings(&prepared.faces, m, params.rings);
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
        }
    }
}

/// The coarse phase's moment buffers for [`kabsch_update`]: the per-point moments, the rows'
/// differences (`None`: rows summed directly) and the per-vertex sums.
type MomentBuffers<'a> = (
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
fn kabsch_update(
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

/// The stride of a phase's scan sample: `sample` when set, else (0, automatic) the largest
/// stride that leaves `per_vertex` scan points for each of the phase's `⌈m / vertex_stride⌉`
/// vertices, within `1..=most`.
fn scan_stride(
    sample: usize,
    vertex_stride: usize,
    per_vertex: usize,
    most: usize,
    m: usize,
    n: usize,
) -> usize {
    match sample {
        0 => {
            let vertices = m.div_ceil(vertex_stride.max(1)).max(1);
            (n / (per_vertex * vertices)).clamp(1, most)
        }
        s => s,
    }
}

/// The rest-shape rigidity β of the `fine`-th of the `total` FoldMatch iterations (1-based):
/// [`FitParams::rest_rigidity`] decreasing linearly to 0 at the last one.
fn rest_rigidity_at(params: &FitParams, fine: usize, total: usize) -> f64 {
    params.rest_rigidity * (1.0 - fine as f64 / total.max(1) as f64)
}

/// Where the rest-shape rigidity ([`FitParams::rest_rigidity`]) puts vertex `v`: its template
/// ring `rest[ring]` (centroid `c_rest`), moved by the Kabsch rigid fit of that ring onto the
/// proposed positions `proposed[ring]` (centroid `c_proposed`), evaluated at `rest[v]` —
/// ARAP's local step with the proposal as the data.
fn rest_ring_placement(
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
fn annealed(params: &FitParams, it: usize) -> NBodyParams {
    let mut p = params.nbody;
    let span = params.anneal_fraction * params.iterations as f64;
    if params.anneal > 1.0 && span > 0.0 {
        let remaining = 1.0 - ((it - 1) as f64 / span).min(1.0);
        p.softening *= 1.0 + (params.anneal - 1.0) * remaining;
    }
    p
}

/// A scan whose bounding-box diagonal exceeds the template's by more than this factor holds
/// more than the garment (a dressed body, a scene): its normalized frame and K are then those
/// of the points the template explains ([`explained_points`]).
pub const GARMENT_FRAME_RATIO: f64 = 1.5;

/// The trust radius on a scan that holds more than the garment, as a fraction of
/// [`FitParams::two_way_trust`]'s: skin and hair adjoin the garment (below a hem, out of a
/// sleeve), where a garment alone has nothing, so the radius that is neutral on garment scans
/// (c = 4) lets them in; ¾ of it (c = 3) keeps them out (docs/method.md "Scans of dressed
/// people").
pub const DRESSED_TRUST_FACTOR: f64 = 0.75;

/// The scan points that the template as given explains, where the scan is much larger than
/// the template ([`GARMENT_FRAME_RATIO`]; `None` otherwise, or when the two-way trust radius is
/// off): those within the two-way trust radius ([`FitParams::two_way_trust`]) of the
/// template's nearest vertex. The paper's constants (ε, G, Δt, ρ) are set for a frame in
/// which the garment's scan has unit diagonal; a dressed body's skin and hair would stretch
/// that frame two- to threefold and soften every force (docs/method.md "Scans of dressed
/// people").
fn explained_points(
    scan: &[[f64; 3]],
    template: &[[f64; 3]],
    faces: &[[u32; 3]],
    params: &FitParams,
) -> Option<Vec<u32>> {
    let diag = |p: &[[f64; 3]]| Frame::of_target(p).scale;
    if params.two_way_trust <= 0.0 || diag(scan) <= GARMENT_FRAME_RATIO * diag(template) {
        return None;
    }
    let scan_index = PointIndex::new(scan);
    let mut nearest: Vec<f64> = template
        .par_iter()
        .map(|v| scan_index.nearest_one(v).1)
        .collect();
    let mid = nearest.len() / 2;
    let median = nearest.select_nth_unstable_by(mid, f64::total_cmp).1.sqrt();
    let radius =
        DRESSED_TRUST_FACTOR * params.two_way_trust * median.max(mean_edge_length(template, faces));
    let template_index = PointIndex::new(template);
    let explained: Vec<u32> = (0..scan.len() as u32)
        .into_par_iter()
        .filter(|&j| template_index.nearest_one(&scan[j as usize]).1 <= radius * radius)
        .collect();
    (!explained.is_empty() && explained.len() < scan.len()).then_some(explained)
}

/// The mean length of the template's edges (each face's three, shared edges counted twice).
fn mean_edge_length(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    let sum: f64 = faces
        .iter()
        .map(|f| {
            let p = f.map(|v| &vertices[v as usize]);
            (0..3)
                .map(|i| crate::math::dist2(p[i], p[(i + 1) % 3]).sqrt())
                .sum::<f64>()
        })
        .sum();
    sum / (3 * faces.len()).max(1) as f64
}

/// NRGa neighborhoods: the K_Y nearest template points of every template vertex (itself
/// included), `K_Y = clamp(⌊ρM⌋, k_min, k_max)`, on the initial template.
fn knn_neighborhoods(start: &[[f64; 3]], params: &FitParams) -> Neighborhoods {
    let m = start.len();
    let k = neighborhood_size(params.rho, m, params.k_min, params.k_max);
    let index = PointIndex::new(start);
    let mut idx = vec![0u32; m * k];
    let mut d2 = vec![0.0; m * k];
    index.nearest_all(start, k, &mut idx, &mut d2);
    Neighborhoods {
        offsets: (0..=m).map(|i| i * k).collect(),
        members: idx,
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn softening_anneals_linearly_over_its_fraction_of_the_iterations() {
        let mut p = FitParams {
            anneal: 3.0,
            anneal_fraction: 0.5,
            iterations: 10,
            ..FitParams::default()
        };
        let eps = p.nbody.softening;
        let at = |p: &FitParams, it| annealed(p, it).softening / eps;
        assert!((at(&p, 1) - 3.0).abs() < 1e-15);
        // Span 5 iterations: at iteration 3, 2/5 of the way from 3 down to 1.
        assert!((at(&p, 3) - 2.2).abs() < 1e-15);
        for it in 6..=10 {
            assert_eq!(at(&p, it), 1.0, "iteration {it}");
        }
        // Same schedule, in fractions, whatever ξ is.
        p.iterations = 100;
        assert!((at(&p, 21) - 2.2).abs() < 1e-15);
        for off in [
            FitParams {
                anneal: 1.0,
                ..p.clone()
            },
            FitParams {
                anneal_fraction: 0.0,
                ..p.clone()
            },
            FitParams::paper(),
        ] {
            assert!((1..=100).all(|it| at(&off, it) == 1.0));
        }
    }

    /// A sheet (vertices, faces) and a wavy copy of its vertices lifted by `lift` as the scan.
    type Case = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 3]>);

    fn wavy_grid_case(side: usize, lift: f64) -> Case {
        let (v, f) = crate::synthetic::grid_sheet(side, side, 1.0, 1.0);
        let target = v
            .iter()
            .map(|p| [p[0], p[1], 0.05 * (4.0 * p[0]).sin() + lift])
            .collect();
        (v, f, target)
    }

    /// Schedule selection's first figure for a fit: the mean distance from every scan point
    /// to its nearest fitted vertex.
    fn mean_scan_distance(x: &[[f64; 3]], r: &FitResult) -> f64 {
        let d = crate::metrics::nearest_distances(x, &r.vertices);
        d.iter().sum::<f64>() / d.len() as f64
    }

    /// Schedule selection's tie-break for each fit: its edge-length spread.
    fn edge_spreads(v: &[[f64; 3]], f: &[[u32; 3]], runs: &[FitResult]) -> Vec<f64> {
        runs.iter()
            .map(|r| crate::metrics::edge_length_spread(v, &r.vertices, f))
            .collect()
    }

    /// A 13 × 13 sheet and its scan.
    fn grid_case() -> Case {
        wavy_grid_case(13, 0.02)
    }

    /// An 8×8 grid (64 vertices, graph diameter 14) and a scan above it.
    fn small_grid_case() -> Case {
        wavy_grid_case(8, 0.1)
    }

    /// The default with only a rigid phase, `iterations` long, one schedule.
    fn rigid_only(iterations: usize) -> FitParams {
        FitParams {
            iterations,
            rigid_fraction: 1.0,
            coarse_fraction: 0.0,
            selection: Selection::Single,
            ..FitParams::default()
        }
    }

    fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
        (vec3(a) - vec3(b)).norm()
    }

    /// The largest distance between corresponding points.
    fn max_apart(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        (0..a.len()).map(|i| dist(&a[i], &b[i])).fold(0.0, f64::max)
    }

    /// `moved` keeps every pairwise distance of `start`: one rigid motion.
    fn assert_rigidly_moved(start: &[[f64; 3]], moved: &[[f64; 3]]) {
        for i in 0..start.len() {
            for j in 0..i {
                assert!((dist(&moved[i], &moved[j]) - dist(&start[i], &start[j])).abs() < 1e-12);
            }
        }
    }

    /// `params` fail validation with an error naming `field`.
    fn assert_refused(params: &FitParams, field: &str) {
        let err = params.validate().unwrap_err().to_string();
        assert!(err.contains(field), "{err}");
    }

    #[test]
    fn automatic_coarse_radius_grows_with_the_square_root_of_the_template_and_is_clamped() {
        let auto = FitParams::default();
        assert_eq!(auto.coarse_rings, 0);
        // 8 rings up to the reference size, √M above it, at most 12.
        for (m, want) in [
            (10, 8),
            (1_700, 8),
            (1_921, 9),  // 8 √(1921 / 1700) = 8.50
            (3_845, 12), // 12.03
            (3_509, 11), // 11.49
            (6_561, 12), // 15.7, clamped
            (100_489, 12),
        ] {
            assert_eq!(auto.coarse_radius(m), want, "M = {m}");
        }
        // A given radius is used as given, whatever the size.
        let given = FitParams {
            coarse_rings: 5,
            ..FitParams::default()
        };
        assert_eq!(given.coarse_radius(100_489), 5);
        assert_refused(
            &FitParams {
                coarse_rings: 33,
                ..FitParams::default()
            },
            "coarse_rings",
        );
        // The automatic radius is the given one for that size: the same fit, bit for bit, and
        // the diagnostics report it (a 50 × 50 grid: 2,500 vertices, radius 10).
        let (v, f) = crate::synthetic::grid_sheet(50, 50, 1.0, 1.0);
        let x: Vec<[f64; 3]> = v
            .iter()
            .map(|p| [p[0], p[1], 0.1 * (3.0 * p[0]).sin() + 0.05])
            .collect();
        let base = FitParams {
            iterations: 10,
            selection: Selection::Single,
            ..FitParams::default()
        };
        let auto_fit = fit_simple(&v, &f, &x, None, &base).unwrap();
        let given = |coarse_rings| {
            let params = FitParams {
                coarse_rings,
                ..base.clone()
            };
            fit_simple(&v, &f, &x, None, &params).unwrap().vertices
        };
        assert_eq!(auto_fit.diagnostics.coarse_rings, 10);
        assert_eq!(auto_fit.vertices, given(10));
        assert_ne!(auto_fit.vertices, given(8));
    }

    #[test]
    fn coarse_levels_shrink_the_radius_and_stop_at_one_ring() {
        let (v, f, x) = grid_case();
        let base = FitParams {
            iterations: 12,
            selection: Selection::Single,
            coarse_rings: 1,
            ..FitParams::default()
        };
        let one = fit_simple(&v, &f, &x, None, &base).unwrap();
        // Radius max(1, 1 >> l) = 1 at every level: the same fit, bit for bit.
        let three = fit_simple(
            &v,
            &f,
            &x,
            None,
            &FitParams {
                coarse_levels: 3,
                ..base.clone()
            },
        );
        assert_eq!(one.vertices, three.unwrap().vertices);
        // From 4 rings, a second level (2 rings) changes the coarse phase.
        let wide = FitParams {
            coarse_rings: 4,
            ..base.clone()
        };
        let a = fit_simple(&v, &f, &x, None, &wide).unwrap();
        let b = fit_simple(
            &v,
            &f,
            &x,
            None,
            &FitParams {
                coarse_levels: 2,
                ..wide
            },
        )
        .unwrap();
        assert_ne!(a.vertices, b.vertices);
        for bad in [0, 5] {
            assert_refused(
                &FitParams {
                    coarse_levels: bad,
                    ..base.clone()
                },
                "coarse_levels",
            );
        }
    }

    #[test]
    fn rigid_sample_moves_the_template_rigidly_by_the_sample_fit() {
        let (v, f, x) = small_grid_case();
        let rigid_only = rigid_only(6);
        let with = |rigid_sample| {
            fit_simple(
                &v,
                &f,
                &x,
                None,
                &FitParams {
                    rigid_sample,
                    ..rigid_only.clone()
                },
            )
            .unwrap()
            .vertices
        };
        // A quarter of the vertices drives the fit: the template still moves rigidly (every
        // pairwise distance kept), but not as the fit driven by every vertex does.
        let (quarter, full) = (with(4), with(1));
        assert_rigidly_moved(&v, &quarter);
        let apart = max_apart(&quarter, &full);
        assert!(apart > 1e-9, "{apart}");
        // 64 ≥ M: the sample is vertex 0 alone, whose Kabsch fit has no rotation, so every
        // vertex moves by the same translation, the one the N-body step proposes for vertex 0.
        let one = with(64);
        let shift = vec3(&one[0]) - vec3(&v[0]);
        assert!(shift.norm() > 1e-6);
        for i in 0..v.len() {
            assert!((vec3(&one[i]) - vec3(&v[i]) - shift).norm() < 1e-12);
        }
        for bad in [0, 65] {
            assert_refused(
                &FitParams {
                    rigid_sample: bad,
                    ..rigid_only.clone()
                },
                "rigid_sample",
            );
        }
    }

    #[test]
    fn rigid_scan_sample_strides_only_dense_scans() {
        let default = FitParams::default();
        // Paper-sized: 14,400 points under 3,307 rigid-phase vertices: every point pulls.
        assert_eq!(default.rigid_scan_stride(13_225, 14_400), 1);
        // The large case: 1M points under 25,123 vertices, 8 per vertex → every 4th.
        assert_eq!(default.rigid_scan_stride(100_489, 1_000_000), 4);
        let every_vertex = FitParams {
            rigid_sample: 1,
            ..default.clone()
        };
        assert_eq!(every_vertex.rigid_scan_stride(100_489, 1_000_000), 1);
        let given = FitParams {
            rigid_scan_sample: 3,
            ..default.clone()
        };
        assert_eq!(given.rigid_scan_stride(100_489, 14_400), 3);
        assert_refused(
            &FitParams {
                rigid_scan_sample: 65,
                ..default
            },
            "rigid_scan_sample",
        );

        // An 8×8 template over a 40×40-point scan: 16 rigid-phase vertices, stride 12.
        let (v, f, _) = small_grid_case();
        let (_, _, x) = wavy_grid_case(40, 0.1);
        let rigid_only = rigid_only(6);
        assert_eq!(rigid_only.rigid_scan_stride(v.len(), x.len()), 12);
        let with = |rigid_scan_sample| {
            let params = FitParams {
                rigid_scan_sample,
                ..rigid_only.clone()
            };
            fit_simple(&v, &f, &x, None, &params).unwrap().vertices
        };
        let (auto, twelve, every) = (with(0), with(12), with(1));
        assert_eq!(auto, twelve);
        // Still one rigid motion, not the one every scan point drives, but close to it.
        assert_rigidly_moved(&v, &auto);
        let (apart, moved) = (max_apart(&auto, &every), max_apart(&every, &v));
        assert!(apart > 1e-9 && apart < 0.2 * moved, "{apart} vs {moved}");
    }

    #[test]
    fn coarse_scan_sample_halves_only_scans_of_eight_points_a_vertex() {
        let default = FitParams::default();
        // Paper-sized (1.1 points a vertex) and the harness's densest (3.5): the whole scan.
        assert_eq!(default.coarse_scan_stride(13_225, 14_400), 1);
        assert_eq!(default.coarse_scan_stride(1_426, 5_000), 1);
        // From 8 points a vertex every 2nd, and never more by itself.
        assert_eq!(default.coarse_scan_stride(1_000, 7_999), 1);
        assert_eq!(default.coarse_scan_stride(1_000, 8_000), 2);
        assert_eq!(default.coarse_scan_stride(100_489, 1_000_000), 2);
        assert_eq!(default.coarse_scan_stride(1_426, 60_000), 2);
        // The rigid phase's automatic stride keeps its own rule.
        assert_eq!(default.rigid_scan_stride(100_489, 1_000_000), 4);
        for given in [1, 3, 64] {
            let params = FitParams {
                coarse_scan_sample: given,
                ..default.clone()
            };
            assert_eq!(params.coarse_scan_stride(1_000, 1_000_000), given);
        }
        assert_refused(
            &FitParams {
                coarse_scan_sample: 65,
                ..default.clone()
            },
            "coarse_scan_sample",
        );

        // A coarse-only fit of an 8×8 template on a 40×40-point scan (25 points a vertex):
        // the automatic stride is the explicit 2, and it changes the fit by a fraction of the
        // motion.
        let (v, f, _) = small_grid_case();
        let (_, _, x) = wavy_grid_case(40, 0.1);
        let coarse_only = FitParams {
            iterations: 6,
            rigid_fraction: 0.0,
            coarse_fraction: 1.0,
            selection: Selection::Single,
            ..default
        };
        assert_eq!(coarse_only.coarse_scan_stride(v.len(), x.len()), 2);
        let with = |coarse_scan_sample| {
            let params = FitParams {
                coarse_scan_sample,
                ..coarse_only.clone()
            };
            fit_simple(&v, &f, &x, None, &params).unwrap().vertices
        };
        let (auto, two, every) = (with(0), with(2), with(1));
        assert_eq!(auto, two);
        let (apart, moved) = (max_apart(&auto, &every), max_apart(&every, &v));
        assert!(apart > 1e-9 && apart < 0.2 * moved, "{apart} vs {moved}");
    }

    #[test]
    fn coarse_sample_with_whole_mesh_rings_is_the_rigid_sample() {
        // Coarse rings reaching the whole 8×8 grid (graph diameter 14 < 32): every vertex's
        // sampled ring is the whole sample, so a coarse-only fit on every 4th vertex is the
        // rigid-only fit on every 4th vertex, up to the order of the sums.
        let (v, f, x) = small_grid_case();
        let base = FitParams {
            iterations: 6,
            coarse_rings: 32,
            selection: Selection::Single,
            ..FitParams::default()
        };
        let run = |p: FitParams| fit_simple(&v, &f, &x, None, &p).unwrap().vertices;
        let coarse = run(FitParams {
            rigid_fraction: 0.0,
            coarse_fraction: 1.0,
            coarse_sample: 4,
            ..base.clone()
        });
        let rigid = run(FitParams {
            rigid_fraction: 1.0,
            coarse_fraction: 0.0,
            rigid_sample: 4,
            ..base.clone()
        });
        let every = run(FitParams {
            rigid_fraction: 0.0,
            coarse_fraction: 1.0,
            ..base.clone()
        });
        let gap = |a: &[[f64; 3]], b: &[[f64; 3]]| {
            a.iter()
                .zip(b)
                .map(|(p, q)| (vec3(p) - vec3(q)).norm())
                .fold(0.0, f64::max)
        };
        assert!(gap(&coarse, &rigid) < 1e-12, "{}", gap(&coarse, &rigid));
        assert!(gap(&coarse, &every) > 1e-9, "the sample changed nothing");
        for (bad, rings, levels) in [(0, 8, 1), (65, 8, 1), (2, 4, 2), (2, 2, 1)] {
            assert_refused(
                &FitParams {
                    coarse_sample: bad,
                    coarse_rings: rings,
                    coarse_levels: levels,
                    ..base.clone()
                },
                "coarse_sample",
            );
        }
    }

    #[test]
    fn fast_preset_is_one_schedule_between_the_given_and_the_sharp() {
        let fast = FitParams::preset("fast").unwrap();
        assert_eq!(fast, FitParams::fast());
        let default = FitParams::default();
        let sharp = default.sharp_schedule();
        // The sharp schedule's phases and constant softening, a two-way weight between the two.
        assert_eq!(
            fast,
            FitParams {
                two_way: FAST_TWO_WAY,
                ..sharp.clone()
            }
        );
        assert!(sharp.two_way < fast.two_way && fast.two_way < default.two_way);
        assert_eq!(fast.candidate_schedules(), vec![fast.clone()]);
        // One run: no candidate figures, and a fit unlike either of the default's candidates.
        let (v, f, x) = small_grid_case();
        let run = |p: &FitParams| fit_simple(&v, &f, &x, None, p).unwrap();
        let alone = run(&fast);
        assert!(alone.diagnostics.candidate_scan_distances.is_empty());
        let d = mean_scan_distance(&x, &alone);
        let both = run(&default);
        for other in &both.diagnostics.candidate_scan_distances {
            assert!((other - d).abs() > 1e-9 * d, "{other} vs {d}");
        }
    }

    #[test]
    fn accurate_preset_is_the_default_lengthened() {
        let accurate = FitParams::preset("accurate").unwrap();
        assert_eq!(accurate, FitParams::accurate());
        assert_eq!(
            FitParams {
                iterations: 100,
                ..accurate.clone()
            },
            FitParams::default()
        );
        // Every phase keeps its share of the iterations: 45 rigid, 75 coarse, 30 FoldMatch.
        assert_eq!(accurate.iterations, ACCURATE_ITERATIONS);
        assert_eq!(accurate.phase_iterations(), (45, 75));
        assert_eq!(FitParams::default().phase_iterations(), (30, 50));
    }

    #[test]
    fn wide_selection_chooses_among_three_candidates() {
        let (v, f, x) = grid_case();
        let wide = FitParams {
            iterations: 20,
            selection: Selection::ScanDistanceWide,
            rigid_sample: 1,
            ..FitParams::default()
        };
        let candidates = wide.candidate_schedules();
        assert_eq!(candidates.len(), SCHEDULE_NAMES.len());
        // Given, sharp, gentle: the gentle one differs from the given only in its weight and
        // its annealing's length.
        assert_eq!(candidates[1], wide.sharp_schedule());
        assert_eq!(candidates[2].two_way, wide.two_way / 1.5);
        assert_eq!(candidates[2].anneal_fraction, 0.8);
        assert_eq!(
            FitParams {
                two_way: wide.two_way,
                anneal_fraction: wide.anneal_fraction,
                ..candidates[2].clone()
            },
            candidates[0]
        );
        let chosen = fit_simple(&v, &f, &x, None, &wide).unwrap();
        let alone: Vec<FitResult> = candidates
            .iter()
            .map(|p| fit_simple(&v, &f, &x, None, p).unwrap())
            .collect();
        let dist = |r: &FitResult| mean_scan_distance(&x, r);
        let d: Vec<f64> = alone.iter().map(dist).collect();
        assert_eq!(chosen.diagnostics.candidate_scan_distances, d);
        let spreads = edge_spreads(&v, &f, &alone);
        assert_eq!(chosen.diagnostics.candidate_edge_spreads, spreads);
        let best = select_schedule(&d, &spreads, wide.selection_margin);
        assert_eq!(chosen.vertices, alone[best].vertices);
        assert_eq!(chosen.diagnostics.schedule, SCHEDULE_NAMES[best]);
        // One schedule for NRGa and for a single selection.
        for p in [
            FitParams {
                method: Method::Nrga,
                ..wide.clone()
            },
            FitParams::tracking(),
        ] {
            assert_eq!(p.candidate_schedules().len(), 1);
        }
    }

    #[test]
    fn the_scan_order_changes_the_fit_only_by_round_off() {
        // The fit keeps the scan in Morton order; given in any other order, only the order of
        // the sums differs. The scan is a mesh (the folded vertices with noise, which breaks
        // the exact distance ties of a grid: those go to the lower index of the internal order),
        // fitted with its faces re-indexed (the mesh curvature follows its points) and without.
        let case = crate::synthetic::folded_sheet(&crate::synthetic::SheetSpec {
            nx: 24,
            ny: 24,
            noise: 0.002,
            ..Default::default()
        });
        let x = &case.scan;
        let n = x.len();
        // A scrambled order: position i holds point (i · 7919) mod n (7919 is prime to n).
        let perm: Vec<usize> = (0..n).map(|i| i * 7919 % n).collect();
        let mut inverse = vec![0u32; n];
        for (i, &j) in perm.iter().enumerate() {
            inverse[j] = i as u32;
        }
        let shuffled: Vec<[f64; 3]> = perm.iter().map(|&j| x[j]).collect();
        let faces = &case.faces;
        let shuffled_faces: Vec<[u32; 3]> = faces
            .iter()
            .map(|f| f.map(|j| inverse[j as usize]))
            .collect();
        let t = &case.template_vertices;
        for params in [FitParams::default(), FitParams::paper()] {
            let params = FitParams {
                iterations: 40,
                ..params
            };
            for mesh in [false, true] {
                let (a, b) = if mesh {
                    (
                        fit_simple(t, faces, x, Some(faces), &params).unwrap(),
                        fit_simple(t, faces, &shuffled, Some(&shuffled_faces), &params).unwrap(),
                    )
                } else {
                    (
                        fit_simple(t, faces, x, None, &params).unwrap(),
                        fit_simple(t, faces, &shuffled, None, &params).unwrap(),
                    )
                };
                let moved = a
                    .vertices
                    .iter()
                    .zip(t)
                    .map(|(p, q)| (vec3(p) - vec3(q)).norm())
                    .fold(0.0, f64::max);
                let apart = a
                    .vertices
                    .iter()
                    .zip(&b.vertices)
                    .map(|(p, q)| (vec3(p) - vec3(q)).norm())
                    .fold(0.0, f64::max);
                assert!(moved > 0.01 && apart < 1e-9 * moved, "{apart} of {moved}");
            }
        }
    }

    #[test]
    fn select_schedule_breaks_near_ties_by_the_edge_length_spread() {
        // Outside the margin the closest fit wins, whatever its spread.
        assert_eq!(select_schedule(&[1.0, 1.2], &[0.5, 0.1], 0.06), 0);
        assert_eq!(select_schedule(&[1.2, 1.0], &[0.1, 0.5], 0.06), 1);
        // Within it, the least spread.
        assert_eq!(select_schedule(&[1.0, 1.05], &[0.5, 0.1], 0.06), 1);
        assert_eq!(
            select_schedule(&[1.05, 1.0, 1.03], &[0.3, 0.5, 0.2], 0.06),
            2
        );
        // Margin 0: the closest alone (the earlier rule); equal spreads keep the earlier.
        assert_eq!(select_schedule(&[1.0, 1.05], &[0.5, 0.1], 0.0), 0);
        assert_eq!(select_schedule(&[1.0, 1.0], &[0.2, 0.2], 0.06), 0);
        assert_eq!(select_schedule(&[1.0, 1.0], &[0.2, 0.1], 0.0), 1);
        for bad in [-0.01, f64::NAN, f64::INFINITY] {
            assert_refused(
                &FitParams {
                    selection_margin: bad,
                    ..FitParams::default()
                },
                "selection_margin",
            );
        }
    }

    #[test]
    fn early_selection_compares_there_and_runs_the_chosen_schedule_alone() {
        let (v, f, x) = grid_case();
        let params = FitParams {
            iterations: 20,
            selection_at: 0.5,
            ..FitParams::default()
        };
        let mut seen = Vec::new();
        let early = fit(&v, &f, &x, None, &params, &mut |p| {
            seen.push((p.iteration, p.iterations));
            true
        })
        .unwrap();
        assert_eq!(seen, (1..=20).map(|i| (i, 20)).collect::<Vec<_>>());
        let given = FitParams {
            selection: Selection::Single,
            ..params.clone()
        };
        let schedules = [given, params.sharp_schedule()];
        // Each candidate at iteration 10: its single run stopped there.
        let at_10: Vec<FitResult> = schedules
            .iter()
            .map(|p| fit(&v, &f, &x, None, p, &mut |p| p.iteration < 10).unwrap())
            .collect();
        let d: Vec<f64> = at_10.iter().map(|r| mean_scan_distance(&x, r)).collect();
        assert_eq!(early.diagnostics.candidate_scan_distances, d);
        let spreads = edge_spreads(&v, &f, &at_10);
        assert_eq!(early.diagnostics.candidate_edge_spreads, spreads);
        let k = select_schedule(&d, &spreads, params.selection_margin);
        assert_eq!(early.diagnostics.schedule, ["given", "sharp"][k]);
        // The chosen schedule then ran on alone: its single run's fit, bit for bit.
        let alone = fit_simple(&v, &f, &x, None, &schedules[k]).unwrap();
        assert_eq!(early.iterations, 20);
        assert_eq!(early.vertices, alone.vertices);
        assert_eq!(early.wvf_accumulated, alone.wvf_accumulated);
        for bad in [0.0, -0.1, 1.5, f64::NAN] {
            assert_refused(
                &FitParams {
                    selection_at: bad,
                    ..FitParams::default()
                },
                "selection_at",
            );
        }
    }

    #[test]
    fn selection_chooses_between_the_given_and_the_sharp_schedule() {
        let (v, f, x) = grid_case();
        let params = FitParams {
            iterations: 20,
            ..FitParams::default()
        };
        let chosen = fit_simple(&v, &f, &x, None, &params).unwrap();
        let given = FitParams {
            selection: Selection::Single,
            ..params.clone()
        };
        let runs = [
            fit_simple(&v, &f, &x, None, &given).unwrap(),
            fit_simple(&v, &f, &x, None, &params.sharp_schedule()).unwrap(),
        ];
        let dist = |r: &FitResult| mean_scan_distance(&x, r);
        let d = chosen.diagnostics.candidate_scan_distances.clone();
        assert_eq!(d, vec![dist(&runs[0]), dist(&runs[1])]);
        let spreads = edge_spreads(&v, &f, &runs);
        assert_eq!(chosen.diagnostics.candidate_edge_spreads, spreads);
        let k = select_schedule(&d, &spreads, params.selection_margin);
        assert_eq!(chosen.vertices, runs[k].vertices);
        assert_eq!(chosen.diagnostics.schedule, ["given", "sharp"][k]);
        assert_eq!(chosen.params, params);
        // The runs advance in lockstep: progress counts ξ, with the given schedule's figures.
        let mut seen = Vec::new();
        fit(&v, &f, &x, None, &params, &mut |p| {
            seen.push((p.iteration, p.iterations, p.record));
            true
        })
        .unwrap();
        assert_eq!(
            seen,
            (1..=20)
                .map(|i| (i, 20, runs[0].history[i - 1]))
                .collect::<Vec<_>>()
        );
        // A stop applies to both runs: each candidate equals its single run stopped there.
        let stopped = |p: &FitParams| fit(&v, &f, &x, None, p, &mut |p| p.iteration < 7).unwrap();
        let both = stopped(&params);
        assert!(both.diagnostics.stopped_by_callback && both.iterations == 7);
        let alone = [stopped(&given), stopped(&params.sharp_schedule())];
        assert_eq!(
            both.diagnostics.candidate_scan_distances,
            vec![dist(&alone[0]), dist(&alone[1])]
        );
        // The sharp schedule differs from the given one only in its schedule fields.
        let sharp = params.sharp_schedule();
        assert_eq!(
            (sharp.two_way, sharp.coarse_fraction, sharp.anneal),
            (1.0, 0.3, 1.0)
        );
        assert_eq!(sharp.selection, Selection::Single);
        assert_eq!(
            FitParams {
                two_way: params.two_way,
                coarse_fraction: params.coarse_fraction,
                anneal: params.anneal,
                anneal_fraction: params.anneal_fraction,
                selection: params.selection,
                ..sharp
            },
            params
        );
    }

    #[test]
    fn rest_ring_placement_recovers_a_rigid_motion_of_the_rest_shape() {
        // Proposed = R · rest + t on every ring: each vertex goes to R · rest[v] + t exactly.
        let (rest, f) = crate::synthetic::grid_sheet(6, 5, 1.0, 0.8);
        let rest: Vec<[f64; 3]> = rest
            .iter()
            .map(|p| [p[0], p[1], 0.3 * p[0] * p[1]])
            .collect();
        let rings = n_rings(&f, rest.len(), 2);
        let r = nalgebra::Rotation3::from_scaled_axis(Vec3::new(0.3, -0.5, 0.9)).into_inner();
        let t = Vec3::new(0.2, -1.0, 0.4);
        let moved = |p: &[f64; 3]| r * vec3(p) + t;
        let proposed: Vec<[f64; 3]> = rest.iter().map(|p| moved(p).into()).collect();
        for fast in [true, false] {
            for v in 0..rest.len() {
                let ring = rings.of(v);
                let (c_rest, c) = ring_centroids(ring, &rest, &proposed);
                let placed = rest_ring_placement(ring, v, &rest, &c_rest, &proposed, &c, fast);
                assert!((placed - moved(&rest[v])).norm() < 1e-12, "vertex {v}");
            }
        }
    }

    #[test]
    fn rest_rigidity_keeps_the_template_edge_lengths_over_a_scan_hole() {
        // A flat sheet onto a wavy scan with a hole: the rest-shape term keeps the edge lengths
        // closer to the template's; 0 is the update without it, and out-of-range values fail.
        let (v, f, x) = wavy_grid_case(17, 0.03);
        let x: Vec<[f64; 3]> = x
            .into_iter()
            .filter(|p| (p[0] - 0.6).hypot(p[1] - 0.4) > 0.2)
            .collect();
        let spread = |params: &FitParams| {
            let r = fit_simple(&v, &f, &x, None, params).unwrap();
            crate::metrics::edge_length_spread(&v, &r.vertices, &f)
        };
        let with_rigidity = FitParams {
            iterations: 40,
            coarse_fraction: 0.2,
            selection: Selection::Single,
            ..FitParams::default()
        };
        assert_eq!(with_rigidity.rest_rigidity, 0.65);
        let with = spread(&with_rigidity);
        let without = spread(&FitParams {
            rest_rigidity: 0.0,
            ..with_rigidity.clone()
        });
        assert!(
            with < 0.8 * without,
            "edge-length spread {with} vs {without}"
        );
        for bad in [-0.1, 1.5, f64::NAN] {
            assert_refused(
                &FitParams {
                    rest_rigidity: bad,
                    ..FitParams::default()
                },
                "rest_rigidity",
            );
        }
    }
}
