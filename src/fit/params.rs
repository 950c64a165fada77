//! Every setting of a fit ([`FitParams`]), its enums and named constants, and the values derived
//! from them (the phases' lengths, samples and radii).

use super::isometric::PlaneNormal;
use crate::nbody::{NBodyParams, TwoWayPull};
use crate::regularize::Regularization;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Which motion/deformation model updates the template.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's method: n-ring deformation gradients, Eq. 4–8.
    #[serde(rename = "foldmatch")]
    FoldMatch,
    /// The NRGa baseline: per-vertex rigid (Kabsch) fit of a k-NN neighborhood.
    Nrga,
}

/// Which gradient enters the rotation solve of Eq. 8.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RotationSource {
    /// The regularized gradient `R̄ Ū` (default). Û commutes with Ū, so R* = R̄ and ψ moves no
    /// vertex: it shapes only the wrinkle-vector field (docs/method.md, "Rotation and translation,
    /// Eq. 8").
    Regularized,
    /// The raw Eq. 4 gradient, in which ψ does act on the rotation.
    Raw,
}

/// How the template is placed on the scan before the fit (docs/method.md, "Global
/// pre-alignment").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Prealign {
    /// Fit as given; a template whose centroid is more than [`FAR_AWAY`] target diagonals from the
    /// scan's centroid is rejected with
    /// [`FoldMatchError::FarAway`](crate::error::FoldMatchError::FarAway) (the `"paper"` and
    /// `"tracking"` presets).
    None,
    /// Translate the template so its centroid lies on the scan's centroid first.
    Centroid,
    /// The rigid motion that best places the template on a scan in any orientation and
    /// position ([`crate::prealign::align`]); a template already placed is left as given
    /// (default). A template more than [`SIZE_MISMATCH`] times larger or smaller than the scan is
    /// refused with [`FoldMatchError::SizeMismatch`](crate::error::FoldMatchError::SizeMismatch).
    Rigid,
    /// As [`Prealign::Rigid`], with a uniform scale too (a scan in other units, or of another
    /// size).
    Similarity,
}

/// Schedule selection (docs/method.md, "Beyond the paper: the default configuration").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// Run the schedule the parameters describe.
    Single,
    /// Also run the *sharp* schedule ([`FitParams::sharp_schedule`]: two-way 1, coarse 30 %,
    /// constant softening) and return the fit closer to the scan (the mean distance from every scan
    /// point to its nearest fitted vertex), a near-tie — within
    /// [`selection_margin`](crate::fit::Schedule::selection_margin) of the closest — going to the
    /// fit whose edge lengths spread least from the template's
    /// ([`crate::metrics::edge_length_spread`]; see [`select_schedule`](super::select_schedule)).
    /// FoldMatch only; twice the work, the two runs side by side (concurrently, sharing the setup).
    ScanDistance,
    /// Like [`Selection::ScanDistance`] with a third candidate, the *gentle* schedule
    /// ([`FitParams::gentle_schedule`]: the given one with ⅔ of the two-way weight and a
    /// longer annealing); three times the work of one schedule (docs/method.md).
    ScanDistanceWide,
}

/// The default [`carry_unsupported`](crate::fit::Schedule::carry_unsupported) (docs/method.md
/// "Partial scans").
pub const DEFAULT_CARRY_UNSUPPORTED: f64 = 2.0;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): the nearest scan point of an
/// unsupported vertex is explained by a vertex farther than this many mean edges from it on
/// the template.
pub const CARRY_FAR_EDGES: f64 = 3.0;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): a vertex explains its scan
/// points without a surplus while the mean count of scan points whose nearest vertex is it or
/// one of its ring (the model's n-ring) stays within this multiple of the typical (median)
/// count; a surplus
/// means another layer of the template belongs there (a garment folded flat).
pub const CARRY_SURPLUS: f64 = 1.5;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): unsupported regions
/// (connected through the vertices' rings) smaller than this share of the template are
/// attracted as usual: a sleeve still far from its scan, not a side the scan never saw.
pub const CARRY_MIN_SHARE: f64 = 0.12;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): nothing is carried when the
/// scan's extent along its thinnest principal axis is below this share of its extent along
/// the middle one (standard deviations): a garment lying flat, whose hidden lower layer lies
/// under the scanned one.
pub const CARRY_MIN_DEPTH: f64 = 0.2;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): a region is carried only
/// when the depths of its vertices behind the scanned side (along the scan's thinnest
/// principal axis), summed, reach this many units (the radius's unit) per template vertex:
/// what collapsing it onto the scan would move the template by on average. The back of a
/// garment seen from the front is a large region a body's depth behind it; a region that the
/// rigid phase left a few units off a whole scan (a garment blown flat, its two layers close)
/// is small or near, and attracted.
pub const CARRY_MIN_BEHIND: f64 = 1.0;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): when the schedule carried a
/// region without scan support, the isometric refinement's spring weight
/// ([`isometric_weight`](crate::fit::Schedule::isometric_weight)) is this many times the
/// given one. A third of the template then has no data term, and the scan at its border pulls
/// the carried region's edges out of the template's metric; stiffer springs keep its shape
/// (docs/method.md "Partial scans").
pub const CARRIED_SPRING_FACTOR: f64 = 3.0;
/// A garment pass (the refit and the cuts of a scan of a dressed person; with
/// [`UnstretchedRefinement::EveryFit`] also a fit of a scan of the garment alone) whose
/// schedule left the garment unstretched — the spread of its stretch field
/// ([`EdgeLengths::stretch_field_spread`](crate::metrics::EdgeLengths::stretch_field_spread),
/// [`UNSTRETCHED_SMOOTHING`] rounds) below this — is refined to the rest shape's metric: its
/// isometric refinement runs [`UNSTRETCHED_STEPS`] steps with the hold only where the scan has
/// no points for the fit. The simulated skirts' passes lie at 0.028–0.037, the T-shirts' (not
/// the template's isometries: ARCSim's rest shape differs from the pattern's) at 0.06–0.15
/// (docs/method.md "Isometric refinement", unstretched garments).
pub const UNSTRETCHED_SPREAD: f64 = 0.05;
/// Neighbour averagings of the stretch field behind [`UNSTRETCHED_SPREAD`].
pub const UNSTRETCHED_SMOOTHING: usize = 40;
/// The refinement steps of an unstretched garment pass ([`UNSTRETCHED_SPREAD`]): without the
/// hold the springs converge slowly.
pub const UNSTRETCHED_STEPS: usize = 300;
/// An unstretched fit's refinement ([`UNSTRETCHED_SPREAD`]) outside a garment pass that turns
/// over more than this share of the faces (their normals against the schedule's result) is
/// run again with the hold everywhere: on a noisy scan the freed springs follow the noise at
/// the edge-length scale (`bench.variants`, the `"accurate"` preset: a wind frame's flipped
/// faces beyond its truth's + 1 point at 0.005; docs/method.md "Isometric refinement").
pub const UNSTRETCHED_FLIPS: f64 = 0.003;
/// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported): the vertices within this
/// many of the model's n-rings of a carried vertex (and not carried themselves) move only
/// along their vertex normal in the coarse and fine phases. The scan's edge there is where
/// the rig stopped seeing, not where the garment ends, and the pulls toward the seen side
/// slide them around the garment onto it (docs/method.md "Partial scans").
pub const CARRY_BAND: usize = 2;

/// The default [`strain_limit`](crate::fit::Schedule::strain_limit) (docs/method.md "Strain
/// limiting").
pub const DEFAULT_STRAIN_LIMIT: f64 = 0.15;

/// The default [`isometric_weight`](crate::fit::Schedule::isometric_weight) (docs/method.md
/// "Isometric refinement").
pub const DEFAULT_ISOMETRIC_WEIGHT: f64 = 3.0;

/// The default [`isometric_iterations`](crate::fit::Schedule::isometric_iterations): a single
/// fit ends with this many refinement steps, which undo the schedule's slides along the scan
/// (docs/method.md "Isometric refinement").
pub const DEFAULT_ISOMETRIC_ITERATIONS: usize = 30;

/// The default [`rim_weight`](crate::fit::Schedule::rim_weight).
pub const DEFAULT_RIM_WEIGHT: f64 = 0.05;

/// The default [`coherent_gate`](crate::fit::Schedule::coherent_gate): a fit of a scan of the
/// garment alone whose edges spread this much (the verdict's `edge_distortion`) is fitted a
/// second time from a coherent start (docs/method.md "Coherent candidate"). The harness's fits
/// that drape, crumple or fold the template far from its rest shape reach 1.23–1.42; the fits
/// of the real, generated and wind cases that end right stay at or below 1.20.
pub const DEFAULT_COHERENT_GATE: f64 = 1.2;

/// The default [`isometric_hold`](crate::fit::Schedule::isometric_hold): a single fit's
/// refinement keeps each edge near the schedule's result, so that it corrects slides without
/// crumpling the mesh after the scan's noise.
pub const DEFAULT_ISOMETRIC_HOLD: f64 = 0.6;

/// The default [`iterations`](crate::fit::FitParams::iterations) ξ: 80, and the isometric
/// refinement after them, fit closer to the truth than 100 without it at about the same time
/// (docs/method.md "Isometric refinement").
pub const DEFAULT_ITERATIONS: usize = 80;

/// [`iterations`](crate::fit::FitParams::iterations) of the `"paper"` preset: the 100 of the
/// paper's experiments (SPEC §7), without the refinement.
pub const PAPER_ITERATIONS: usize = 100;

/// [`iterations`](crate::fit::FitParams::iterations) of the `"fast"` preset, which runs no
/// isometric refinement.
pub const FAST_ITERATIONS: usize = 100;

/// [`isometric_iterations`](crate::fit::Schedule::isometric_iterations) of the `"tracking"`
/// preset.
pub const TRACKING_ISOMETRIC_ITERATIONS: usize = 60;

/// [`iterations`](crate::fit::FitParams::iterations) of the `"tracking"` preset (the
/// default's is [`DEFAULT_ITERATIONS`]): a warm-started frame starts near its scan.
pub const TRACKING_ITERATIONS: usize = 60;

/// [`rest_rigidity`](crate::fit::Schedule::rest_rigidity) of the `"tracking"` preset (the
/// default's is 0.65).
pub const TRACKING_REST_RIGIDITY: f64 = 0.15;

/// The `"tracking"` preset's [`strain_limit`](crate::fit::Schedule::strain_limit) and
/// [`compression_limit`](crate::fit::Schedule::compression_limit).
pub const TRACKING_STRAIN_LIMIT: f64 = 0.05;

/// The default [`garment_refit`](crate::fit::Schedule::garment_refit): the garment is the scan
/// within one trust unit of the first fit (docs/method.md "Scans of dressed people").
pub const DEFAULT_GARMENT_REFIT: f64 = 1.0;

/// The default [`garment_cut`](crate::fit::Schedule::garment_cut): a step of twice the scan's
/// median distance from a point to its neighbours' plane is cheap to cut (docs/method.md "Scans
/// of dressed people").
pub const DEFAULT_GARMENT_CUT: f64 = 2.0;

/// The default [`keep_margin`](crate::fit::Schedule::keep_margin): started exactly at the truth
/// of a real garment resampled with noise, the fits come 2–9 % closer to the scan than the truth
/// (they follow its noise); a start 10 % farther from the scan than the fit is worth moving
/// (docs/method.md "Do no harm").
pub const DEFAULT_KEEP_MARGIN: f64 = 0.1;

/// The names of the candidate schedules, in [`FitParams::candidate_schedules`] order.
pub const SCHEDULE_NAMES: [&str; 3] = ["given", "sharp", "gentle"];

/// Scan points per rigid-phase vertex below which the automatic
/// [`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample) does not sample the scan.
pub const RIGID_SCAN_POINTS_PER_VERTEX: usize = 8;

/// The largest scan-sample stride
/// ([`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample),
/// [`coarse_scan_sample`](crate::fit::Acceleration::coarse_scan_sample)), given or automatic.
pub const MAX_SCAN_SAMPLE: usize = 64;

/// Scan points per coarse-phase vertex that the automatic
/// [`coarse_scan_sample`](crate::fit::Acceleration::coarse_scan_sample) leaves at least: it samples
/// only scans with twice as many points as that per vertex.
pub const COARSE_SCAN_POINTS_PER_VERTEX: usize = 4;

/// The largest stride the automatic
/// [`coarse_scan_sample`](crate::fit::Acceleration::coarse_scan_sample) takes: the coarse phase
/// moves every vertex by the Kabsch fit of its own ring, so its forces must stay dense enough per
/// ring; larger strides cost accuracy on dense scans (docs/method.md, "Beyond the paper: the
/// default configuration").
pub const COARSE_SCAN_MAX_AUTO_STRIDE: usize = 2;

/// The automatic coarse ring radius ([`coarse_rings`](crate::fit::Schedule::coarse_rings) = 0) at
/// [`COARSE_RINGS_REFERENCE_VERTICES`] template vertices and below.
pub const AUTO_COARSE_RINGS: usize = 8;

/// The template size at which the automatic coarse radius is [`AUTO_COARSE_RINGS`] (a 41 × 41
/// sheet); above it the radius grows as the square root of the vertex count, so each rigid
/// piece keeps about the same share of the surface.
pub const COARSE_RINGS_REFERENCE_VERTICES: f64 = 1_700.0;

/// The largest automatic coarse radius: an 8-ring holds ~130 vertices of a grid, a 12-ring
/// ~290, and the cost of the ring rows and their sums grows with it; beyond 12 rings the
/// pieces no longer fit closer (docs/method.md, "Beyond the paper: the default
/// configuration").
pub const AUTO_COARSE_RINGS_MAX: usize = 12;

/// Two-way weight of the `"fast"` preset's one schedule ([`FitParams::fast`]): between the
/// sharp schedule's 1 and the default's 4.5, the weight that fits best with a 30 % coarse
/// phase and constant softening.
pub const FAST_TWO_WAY: f64 = 3.0;

/// The default [`two_way_trust`](crate::fit::Schedule::two_way_trust).
pub const DEFAULT_TWO_WAY_TRUST: f64 = 4.0;

/// The default [`two_way_rim`](crate::fit::Schedule::two_way_rim).
pub const DEFAULT_TWO_WAY_RIM: f64 = 1.0;

/// Iterations of the `"accurate"` preset ([`FitParams::accurate`]).
pub const ACCURATE_ITERATIONS: usize = 150;

/// The default [`knn_slack`](crate::fit::Acceleration::knn_slack): σ = 0.1 leaves the fit's
/// accuracy as with exact neighborhoods and spares many fresh k-NN queries of template points still
/// far off the scan; larger σ start to cost accuracy (docs/method.md, "Target neighborhoods Γᵏ_X").
pub const DEFAULT_KNN_SLACK: f64 = 0.1;

/// Default ρ: K = 14 at the paper's 14,400 scan points, where 0.2 % gives 28; scans under
/// 8,000 points stay at `k_min` = 8 either way. The smaller neighborhoods fit paper-sized
/// scans closer and faster; smooth sheets under noise prefer 0.2 % (docs/method.md, "Target
/// neighborhoods Γᵏ_X").
pub const DEFAULT_RHO: f64 = 0.001;

/// The paper's ρ = 0.2 % (§4, the upper end of "typically 0.02 – 0.2 %"), kept by
/// [`FitParams::paper`].
pub const PAPER_RHO: f64 = 0.002;

/// Default upper clamp of K: reached from 32,000 scan points on (at ρ = 0.1 %), where a
/// larger K only averages more of the same surface and costs time (docs/method.md, "Target
/// neighborhoods Γᵏ_X").
pub const DEFAULT_K_MAX: usize = 32;

/// The upper clamp of K of the paper's reading (docs/method.md, "Target neighborhoods Γᵏ_X"),
/// kept by [`FitParams::paper`].
pub const PAPER_K_MAX: usize = 64;

/// The default [`FitParams::landmark_weight`]: the landmarks weigh as much as the scan in
/// every rigid fit, and a landmark vertex closes half its gap to its target per iteration.
pub const DEFAULT_LANDMARK_WEIGHT: f64 = 1.0;

/// Distance (in target bounding-box diagonals) beyond which an unaligned template is refused.
pub const FAR_AWAY: f64 = 1.0;

/// A template whose bounding-box diagonal is more than this many times the scan's, or less
/// than its inverse, is refused by a rigid pre-alignment
/// ([`FoldMatchError::SizeMismatch`](crate::error::FoldMatchError::SizeMismatch)): centimetres
/// against metres at the least (a garment on a full-body scan is a third to a half of it).
pub const SIZE_MISMATCH: f64 = 20.0;

/// Every parameter of a fit, in groups (each flattened, so the JSON form is one flat object).
/// `Default` gives the paper's constants (§4) with the converging readings of docs/method.md.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default)]
pub struct FitParams {
    /// FoldMatch or NRGa.
    pub method: Method,
    /// ξ, the number of iterations ([`DEFAULT_ITERATIONS`] by default).
    pub iterations: usize,
    /// Stop early when the mean displacement of an iteration (normalized units) is below this
    /// (0 disables).
    pub tolerance: f64,
    /// How the template is placed on the scan before the fit: by a global search over rigid
    /// motions by default, so a scan written z-up, turned or displaced is found
    /// (docs/method.md "Global pre-alignment").
    pub prealign: Prealign,
    /// η, the weight of the landmarks ([`crate::landmarks::Landmarks`]) against the scan,
    /// dimensionless (default [`DEFAULT_LANDMARK_WEIGHT`]; 0: the landmarks only decide the
    /// pre-alignment). In a coarse-phase vertex's fit of its coarse ring the landmark
    /// vertices in the ring pull their targets with η times the weight of all its
    /// scan-driven pairs together (the rigid phase fits the scan alone); in the FoldMatch (or NRGa)
    /// iterations a landmark vertex's proposal and then its update x each move to
    /// `(x + η t) / (1 + η)`, t its target: a spring that closes at least `η / (1 + η)` of the
    /// remaining gap every iteration (docs/method.md "Landmarks").
    pub landmark_weight: f64,
    /// Keep the vertex positions every this many iterations (0 keeps none).
    pub snapshot_every: usize,
    /// The model's constants: the paper's §4 values (n, ρ and the clamps of K, ψ, γ) and the
    /// ([`ModelConstants`]).
    #[serde(flatten)]
    pub model: ModelConstants,
    /// Paper readings: the switches choosing between readings of the paper where it admits more
    /// ([`Readings`]).
    #[serde(flatten)]
    pub readings: Readings,
    /// The schedule of a fit beyond the paper: its phases (rigid, coarse, fine), the two-way
    /// ([`Schedule`]).
    #[serde(flatten)]
    pub schedule: Schedule,
    /// Acceleration: samples and approximate neighborhoods that make a fit faster and change its
    /// ([`Acceleration`]).
    #[serde(flatten)]
    pub acceleration: Acceleration,
    /// Round-off-only speed switches (not serialized; see [`Internal`]).
    #[serde(skip)]
    pub(crate) internal: Internal,
}

/// The model's constants: the paper's §4 values (n, ρ and the clamps of K, ψ, γ) and the
/// N-body constants of Eq. 2–3 with their readings ([`NBodyParams`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default)]
pub struct ModelConstants {
    /// n of the n-ring template neighborhoods Γᵏ_Y.
    pub rings: usize,
    /// ρ, the target neighborhood size as a fraction of the scan's point count:
    /// `K = clamp(⌊ρN⌋, k_min, k_max)`. Default [`DEFAULT_RHO`] (0.1 %); the `"paper"` preset
    /// keeps [`PAPER_RHO`] (0.2 %), the upper end of the paper's "typically 0.02 – 0.2 %".
    pub rho: f64,
    /// Lower clamp of K.
    pub k_min: usize,
    /// Upper clamp of K. Default [`DEFAULT_K_MAX`] (32); the `"paper"` preset keeps
    /// [`PAPER_K_MAX`].
    pub k_max: usize,
    /// N-body constants and readings.
    #[serde(flatten)]
    pub nbody: NBodyParams,
    /// ψ, the wrinkle stretch coefficient.
    pub psi: f64,
    /// γ, weight of the normal completion of Eq. 4 (0 disables it).
    pub normal_completion: f64,
}

/// Paper readings: the switches choosing between readings of the paper where it admits more
/// than one (docs/method.md, "Ablation of the readings").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default)]
pub struct Readings {
    /// Mean used by Eq. 5.
    pub regularization: Regularization,
    /// Gradient used by Eq. 8.
    pub rotation_source: RotationSource,
    /// Set velocities to the applied motion after each update (docs/method.md, "Integration, Eq.
    /// 3"); `false` keeps the integrated velocity (literal reading).
    pub velocity_sync: bool,
    /// Work in the normalized frame (docs/method.md, "Frame").
    pub normalize: bool,
    /// Use the curvature term of Eq. 2 (`false` sets κ = 0, i.e. α = 1).
    pub use_curvature: bool,
}

/// The schedule of a fit beyond the paper: its phases (rigid, coarse, fine), the two-way
/// attraction, the rest-shape rigidity, the softening annealing and schedule selection
/// (docs/method.md, "Beyond the paper: the default configuration").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default)]
pub struct Schedule {
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
    /// unit (docs/method.md, "Beyond the paper: the default configuration").
    pub coarse_rings: usize,
    /// Levels of the coarse phase: its iterations are split evenly into this many levels, level
    /// `l` using neighborhoods of radius `max(1, r / 2^l)`, r the coarse radius
    /// ([`FitParams::coarse_radius`]) (1: one radius throughout),
    /// so the pieces that move rigidly shrink as the fit proceeds, like the decreasing
    /// stiffness of non-rigid ICP.
    pub coarse_levels: usize,
    /// Rest-shape rigidity β₀ of the FoldMatch iterations (as-rigid-as-possible blending): in
    /// the j-th of the J iterations after the rigid and coarse phases every vertex goes to
    /// `(1 − β) ·` its Eq. 8 update `+ β ·` the placement of its template n-ring, as given
    /// (the rest shape), by the Kabsch rigid fit of that ring onto the proposed positions,
    /// with `β = β₀ (1 − j / J)` (stiff first, the paper's update alone at the end, like
    /// non-rigid ICP's decreasing stiffness). Eq. 8 moves the *current* ring, so edge lengths
    /// drift where the scan does not pin them (tangential sliding, holes); the rest-shape term
    /// remembers the template's metric, as ARAP's local step does. 0: the paper's update
    /// alone. FoldMatch only (docs/method.md, "Beyond the paper: the default configuration");
    /// 0.15 in the `"tracking"` preset, whose isometric refinement holds the metric.
    pub rest_rigidity: f64,
    /// Carrying the template where the scan has nothing for it, as when a rig saw the garment
    /// from one side (docs/method.md "Partial scans: carrying the unsupported"): once the
    /// rigid phase has placed the template, a vertex farther than `carry_unsupported ×` the
    /// larger of the median vertex → scan distance and the mean edge from every scan point,
    /// whose nearest scan point another part of the template (more than 3 mean edges away on
    /// the template, [`CARRY_FAR_EDGES`]) already explains without a surplus of points, and
    /// which lies behind the scan (inside its footprint along its thinnest axis), not beside
    /// it, has no scan support: the garment's back. Such vertices, in regions of at least 12 %
    /// of the template ([`CARRY_MIN_SHARE`]) lying far enough behind the scanned side
    /// ([`CARRY_MIN_BEHIND`]), are not attracted in the coarse and fine phases and follow
    /// their template rings (full rest-shape rigidity) instead of collapsing onto the scanned
    /// side (and the isometric refinement's springs are [`CARRIED_SPRING_FACTOR`] times as
    /// stiff), and the vertices next to them ([`CARRY_BAND`]) move only along their normals.
    /// `FitResult.support` reports the carried vertices, and the verdict leaves them out of
    /// its fit → scan distance and its test of the unsupported share
    /// (`quality["carried_share"]`). Nothing is carried on a flat scan ([`CARRY_MIN_DEPTH`]):
    /// a garment lying flat hides a lower layer that lies under the scanned one. On a whole
    /// scan nothing is carried, so the default (2) serves one-sided and whole scans alike
    /// (docs/guide.md "One-sided scans"); 0: off, every vertex attracted, as the paper.
    pub carry_unsupported: f64,
    /// Softening annealing: ε starts at `anneal × ε` and decreases linearly to ε over the
    /// first `anneal_fraction` of the ξ iterations (1: constant ε, the paper's reading).
    pub anneal: f64,
    /// Fraction of the iterations over which the softening anneals.
    pub anneal_fraction: f64,
    /// Run one schedule, or two and keep the fit closer to the scan ([`Selection`]).
    pub selection: Selection,
    /// Schedule selection's near-tie margin: candidates whose mean scan→fit distance is within
    /// `(1 + selection_margin) ×` the closest one's are tied, and the tie goes to the least
    /// edge-length spread ([`select_schedule`](super::select_schedule)). 0: the closest fit alone. The given
    /// schedule's stronger two-way pull minimizes exactly the distance compared, so it wins it by a
    /// few per cent even where its fit slid along the scan (docs/method.md, "Beyond the paper: the
    /// default configuration").
    pub selection_margin: f64,
    /// When schedule selection compares its candidates, as a fraction of the ξ iterations: at
    /// iteration `⌈selection_at · ξ⌉` the candidates' fits are compared by the same rule
    /// ([`select_schedule`](super::select_schedule)) and only the chosen one runs on; the others'
    /// remaining iterations are spared. A case whose choice there is the one made at the end gets
    /// the same fit, bit for bit (the chosen run never sees the others). 1: at the end.
    pub selection_at: f64,
    /// Do no harm: the template where the fit started is returned unchanged when its scan
    /// distance — the median distance from the scan points (those schedule selection compares)
    /// to their nearest vertex — is within `(1 + keep_margin) ×` the fit's. A fit started on its
    /// scan only trades the scan's noise for a slide along it (on noisy points the data term has
    /// no tangential fixed point) and comes no closer to the scan than the noise allows
    /// (docs/method.md "Do no harm"). 0: off, the fit is always returned (the `"paper"` and
    /// `"tracking"` presets).
    pub keep_margin: f64,
    /// The garment refit on a scan that holds more than the garment (a dressed body: its
    /// bounding-box diagonal exceeds the template's 1.5-fold): the scan points the first fit
    /// explains — within `garment_refit ×` the larger of the median vertex-to-scan distance and
    /// the mean edge length of a fitted vertex, and not outward of the fit's rim — are taken as
    /// the garment, and the template is fitted again from its start onto them alone, as onto a
    /// garment-only scan (about 1.7× the time of one fit on such scans; docs/method.md "Scans of
    /// dressed people"). 0: off (the `"paper"` preset).
    pub garment_refit: f64,
    /// The garment cut after the garment refit: the scan's points are separated into the
    /// garment and the body by a minimum cut of their neighbour graph, whose edges are cheap to
    /// cut where the scan's surface steps (from the garment onto the skin under it) or has a
    /// gap; the seeds are the points the refit explains three rings or more inside its rim and
    /// the points far from it. The template is fitted a third time, from its start, onto the
    /// garment's side — which reaches past the refit's rim as far as the garment's surface runs
    /// on, and not across the step; when a second cut from that fit moves more than 1 % of the
    /// points, a fourth fit onto it (about 1.5× the time of the refit alone; docs/method.md
    /// "Scans of dressed people"). The step is `garment_cut ×` the scan's median distance from
    /// a point to its neighbours' plane (its noise). 0: off, the refit stands.
    pub garment_cut: f64,
    /// Strain limiting in the fine phase (Provot 1995): after every update, edges longer than
    /// `(1 + strain_limit) ×` their length in the rest shape are moved back towards that length
    /// by up to [`strain_passes`](Self::strain_passes) Jacobi passes of position projections.
    /// Cloth barely stretches, so a fit that stretches it has slid along the scan or been pulled
    /// onto what is not the garment (docs/method.md "Strain limiting"). 0: off (the `"paper"`
    /// preset); 0.05 in the `"tracking"` preset, whose rest shape is the first frame's own mesh.
    pub strain_limit: f64,
    /// Jacobi passes of [`strain_limit`](Self::strain_limit) and
    /// [`compression_limit`](Self::compression_limit) per fine-phase iteration (fewer when a
    /// pass moves nothing).
    pub strain_passes: usize,
    /// The same for compression: edges shorter than their rest length ÷ `(1 + compression_limit)`
    /// are moved back. 0: off (the default: a scan cannot tell sub-edge wrinkles from
    /// compression, and limiting it flips faces); 0.05 in the `"tracking"` preset.
    pub compression_limit: f64,
    /// Isometric refinement: after the schedule, this many local–global steps move the fit to
    /// the minimum of edge springs at the rest shape's lengths (bending left free) plus the
    /// fit → scan (point-to-plane) and scan → fit distances (docs/method.md "Isometric
    /// refinement"). It undoes sliding along the scan, which the schedule's pulls cannot see:
    /// a tracked sequence (whose rest shape is the first frame's own mesh) no longer drifts.
    /// 30 by default (a single fit; on a scan larger than the garment, in every pass: the first
    /// onto the points the template explains, the garment refit's onto the garment's points),
    /// 60 in the `"tracking"` preset; 0: off (the `"paper"` and `"fast"` presets).
    pub isometric_iterations: usize,
    /// The weight of an edge spring of [`isometric_iterations`](Self::isometric_iterations)
    /// against a vertex's fit → scan distance (weight 1): higher keeps the rest shape's
    /// lengths more strictly.
    pub isometric_weight: f64,
    /// The weight of holding each edge of [`isometric_iterations`](Self::isometric_iterations)
    /// at its vector in the schedule's result (against a vertex's fit → scan weight of 1): it
    /// keeps the refinement from crumpling the mesh after the noise of a noisy scan (flipped
    /// faces), and holds back the slides the refinement corrects. 0.6 by default; 0 (off) in
    /// the `"tracking"` preset, whose springs hold the sequence's own metric.
    pub isometric_hold: f64,
    /// The normal of the plane each vertex of [`isometric_iterations`](Self::isometric_iterations)
    /// is pulled onto, through its nearest scan point: `"scan"` (the scan's own plane there,
    /// of its 12 nearest points; default) or `"fit"` (the fit's vertex normal: the vertex moves
    /// across its surface only). A scan's plane tilted against the fit, at a fold or by the
    /// noise, also pushes the fit along itself: in a single fit that moves a slid fit back, in
    /// a tracked sequence it adds a slide to every frame, which piles up (`"fit"` in the
    /// `"tracking"` preset; docs/method.md "Tracking").
    pub isometric_plane: PlaneNormal,
    /// Which fits whose schedule left the template unstretched — the spread of its stretch
    /// field below [`UNSTRETCHED_SPREAD`] — are refined to the rest shape's metric, the hold
    /// only where the scan has no points for the fit ([`UNSTRETCHED_STEPS`] steps; outside a
    /// garment pass, the hold everywhere where that turns over more than [`UNSTRETCHED_FLIPS`]
    /// of the faces):
    /// `"garments"` (the garment passes of a scan of a dressed person; default), `"every_fit"`
    /// (also every fit of a scan of the garment alone that carried no region without scan
    /// support; the `"accurate"` preset) or `"off"` (docs/method.md "Isometric refinement").
    pub unstretched_refinement: UnstretchedRefinement,
    /// On a mesh target (`target_faces`) of the garment alone, the weight of the spring that
    /// lays the template's boundary loops onto the target's at their rest arc length, in the
    /// fine phase and the isometric refinement (docs/method.md "Rim matching"): a fit slid or
    /// swirled along the target's surface is placed by where the cloth ends. 0: off.
    pub rim_weight: f64,
    /// A fit of a scan of the garment alone (no garment passes, landmarks or rest shape) whose
    /// edges spread at least this much (the verdict's `edge_distortion`) gets a second,
    /// coherent candidate: the template moved onto the scan by Coherent Point Drift (a smooth
    /// motion field that does not lock onto the nearest surface), fitted again from there with
    /// that shape as its rest shape, and kept when it lies closer to the scan in both directed
    /// distances (docs/method.md "Coherent candidate"). Large drapes, heaps and flags whose
    /// template must stretch far from its rest shape are placed better so; the candidate costs
    /// its Coherent Point Drift and a second fit where it runs. 0: off.
    pub coherent_gate: f64,
}

/// Which fits [`Schedule::unstretched_refinement`] refines to the rest shape's metric.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum UnstretchedRefinement {
    /// The garment passes (the refit and the cuts) of a scan of a dressed person.
    #[default]
    Garments,
    /// Also every fit of a scan of the garment alone that carried no region without scan
    /// support: those fits come closer to their truth, at up to three times the time of the
    /// fits it frees (docs/method.md "Isometric refinement").
    EveryFit,
    /// None: every fit keeps the hold everywhere.
    Off,
}

/// Acceleration: samples and approximate neighborhoods that make a fit faster and change its
/// result a little (beyond round-off).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default)]
pub struct Acceleration {
    /// Rigid phase on a sample: the N-body forces (and the two-way attraction's pulls) are
    /// computed for every `rigid_sample`-th template vertex only, and the one Kabsch fit of
    /// those vertices moves the whole template (1: every vertex). The rigid phase only needs
    /// the one rigid motion, so 4 (the default) costs no accuracy and cuts the phase's k-NN,
    /// two-way and force work by about 4× (docs/method.md, "Beyond the paper: the default
    /// configuration").
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
    /// Coarse phase on a scan sample, as
    /// [`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample) for the rigid phase: the
    /// coarse phase sees every `coarse_scan_sample`-th scan point, with `⌈K / s⌉` target
    /// neighbours; each vertex there moves by the Kabsch fit of its coarse ring, which the sampled
    /// forces estimate. 0 (the default): automatic, the largest stride leaving
    /// [`COARSE_SCAN_POINTS_PER_VERTEX`] scan points per vertex of the coarse phase's sample, at
    /// most [`COARSE_SCAN_MAX_AUTO_STRIDE`] (so 2 where the scan has at least 8 points per vertex,
    /// as a 1M-point scan under a 100K-vertex template, else 1 — the whole scan); 1: the whole
    /// scan.
    pub coarse_scan_sample: usize,
    /// Coarse phase on a sample: the forces are computed for every `coarse_sample`-th vertex
    /// only, and every vertex moves by the Kabsch fit of the sampled members of its coarse
    /// ring (1: every vertex; more needs coarse rings of radius ≥ 3 at every level).
    pub coarse_sample: usize,
    /// σ of the rigid and coarse phases' approximate target neighborhoods: there the k-NN
    /// cache ([`crate::knn::NeighborCache::set_slack`]) re-uses a vertex's candidates while
    /// every returned neighbour is within `(1 + σ) ×` the true K-th nearest distance, sparing
    /// the fresh queries of template points still far off the scan (their candidates all lie
    /// at about their height, so the exact test fails at nearly every move). The FoldMatch
    /// iterations stay exact. 0: exact throughout. Default [`DEFAULT_KNN_SLACK`]
    /// (docs/method.md, "Target neighborhoods Γᵏ_X").
    pub knn_slack: f64,
}

/// Speed switches that change a fit by round-off only: not user settings (not serialized),
/// kept for the equivalence tests of the fast paths against the exact ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Internal {
    /// Fast 3×3 matrix functions, each agreeing with the eigen-decomposition to round-off:
    /// truncated series for the logarithms and exponentials of Eq. 5 near the identity, the
    /// unit-quaternion (Horn / QCP) solution for polar factors and nearest rotations (Eq. 5's
    /// rotation mean, Eq. 8, the Kabsch fits of the rigid and coarse phases, of the rest-shape
    /// rigidity and of NRGa), closed-form eigenvalues and a direct inverse for well-conditioned
    /// Eq. 4 systems. `false` always uses the Jacobi eigen-decomposition (the exact reference
    /// path).
    pub(crate) matrix_series: bool,
    /// Re-use earlier k-NN candidates when that is provably exact (see
    /// [`crate::knn::NeighborCache`]), and read the two-way attraction's nearest template
    /// vertices off the inverted k-NN lists where certified ([`crate::knn::ReverseNearest`]);
    /// `false` queries a k-d tree for every vertex and every scan point every iteration.
    /// Results are the same either way.
    pub(crate) knn_cache: bool,
    /// [`CARRY_BAND`] (0: no border band); the tests compare against 0.
    pub(crate) carry_band: usize,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            method: Method::FoldMatch,
            iterations: DEFAULT_ITERATIONS,
            tolerance: 0.0,
            prealign: Prealign::Rigid,
            landmark_weight: DEFAULT_LANDMARK_WEIGHT,
            snapshot_every: 0,
            model: ModelConstants::default(),
            readings: Readings::default(),
            schedule: Schedule::default(),
            acceleration: Acceleration::default(),
            internal: Internal::default(),
        }
    }
}

impl Default for ModelConstants {
    fn default() -> Self {
        Self {
            rings: 2,
            rho: DEFAULT_RHO,
            k_min: 8,
            k_max: DEFAULT_K_MAX,
            nbody: NBodyParams::default(),
            psi: 0.05,
            normal_completion: 0.3,
        }
    }
}

impl Default for Readings {
    fn default() -> Self {
        Self {
            regularization: Regularization::LogEuclidean,
            rotation_source: RotationSource::Regularized,
            velocity_sync: true,
            normalize: true,
            use_curvature: true,
        }
    }
}

impl Default for Schedule {
    fn default() -> Self {
        Self {
            two_way: 4.5,
            two_way_trust: DEFAULT_TWO_WAY_TRUST,
            two_way_rim: DEFAULT_TWO_WAY_RIM,
            two_way_pull: TwoWayPull::Coverage,
            rigid_fraction: 0.3,
            coarse_fraction: 0.5,
            coarse_rings: 0,
            coarse_levels: 1,
            rest_rigidity: 0.65,
            carry_unsupported: DEFAULT_CARRY_UNSUPPORTED,
            anneal: 3.0,
            anneal_fraction: 0.6,
            selection: Selection::ScanDistance,
            selection_margin: 0.06,
            selection_at: 1.0,
            keep_margin: DEFAULT_KEEP_MARGIN,
            garment_refit: DEFAULT_GARMENT_REFIT,
            garment_cut: DEFAULT_GARMENT_CUT,
            strain_limit: DEFAULT_STRAIN_LIMIT,
            strain_passes: 4,
            compression_limit: 0.0,
            isometric_iterations: DEFAULT_ISOMETRIC_ITERATIONS,
            isometric_weight: DEFAULT_ISOMETRIC_WEIGHT,
            isometric_hold: DEFAULT_ISOMETRIC_HOLD,
            isometric_plane: PlaneNormal::Scan,
            unstretched_refinement: UnstretchedRefinement::Garments,
            rim_weight: DEFAULT_RIM_WEIGHT,
            coherent_gate: DEFAULT_COHERENT_GATE,
        }
    }
}

impl Default for Acceleration {
    fn default() -> Self {
        Self {
            rigid_sample: 4,
            rigid_scan_sample: 0,
            coarse_scan_sample: 0,
            coarse_sample: 1,
            knn_slack: DEFAULT_KNN_SLACK,
        }
    }
}

impl Default for Internal {
    fn default() -> Self {
        Self {
            matrix_series: true,
            knn_cache: true,
            carry_band: CARRY_BAND,
        }
    }
}

impl FitParams {
    /// The stride of the rigid phase's scan sample
    /// ([`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample)) for a template of `m`
    /// vertices and a scan of `n` points.
    pub fn rigid_scan_stride(&self, m: usize, n: usize) -> usize {
        let (per_vertex, most) = (RIGID_SCAN_POINTS_PER_VERTEX, MAX_SCAN_SAMPLE);
        scan_stride(
            self.acceleration.rigid_scan_sample,
            self.acceleration.rigid_sample,
            per_vertex,
            most,
            m,
            n,
        )
    }

    /// The stride of the coarse phase's scan sample
    /// ([`coarse_scan_sample`](crate::fit::Acceleration::coarse_scan_sample)).
    pub fn coarse_scan_stride(&self, m: usize, n: usize) -> usize {
        let (per_vertex, most) = (COARSE_SCAN_POINTS_PER_VERTEX, COARSE_SCAN_MAX_AUTO_STRIDE);
        scan_stride(
            self.acceleration.coarse_scan_sample,
            self.acceleration.coarse_sample,
            per_vertex,
            most,
            m,
            n,
        )
    }

    /// The coarse phase's ring radius for a template of `m` vertices:
    /// [`coarse_rings`](crate::fit::Schedule::coarse_rings) when given, else `clamp(round(8 √(m /
    /// 1,700)), 8, 12)` ([`AUTO_COARSE_RINGS`], [`COARSE_RINGS_REFERENCE_VERTICES`],
    /// [`AUTO_COARSE_RINGS_MAX`]).
    pub fn coarse_radius(&self, m: usize) -> usize {
        if self.schedule.coarse_rings > 0 {
            return self.schedule.coarse_rings;
        }
        let scaled = AUTO_COARSE_RINGS as f64 * (m as f64 / COARSE_RINGS_REFERENCE_VERTICES).sqrt();
        (scaled.round() as usize).clamp(AUTO_COARSE_RINGS, AUTO_COARSE_RINGS_MAX)
    }

    /// Whether the schedule carries the vertices without scan support
    /// ([`carry_unsupported`](crate::fit::Schedule::carry_unsupported)): FoldMatch only.
    pub fn carries(&self) -> bool {
        self.method == Method::FoldMatch && self.schedule.carry_unsupported > 0.0
    }

    /// Iterations of the rigid and coarse phases: `(rigid, coarse)`, both 0 for NRGa.
    pub fn phase_iterations(&self) -> (usize, usize) {
        if self.method == Method::Nrga {
            return (0, 0);
        }
        let rigid = (self.schedule.rigid_fraction * self.iterations as f64).round() as usize;
        let coarse = (self.schedule.coarse_fraction * self.iterations as f64).round() as usize;
        (rigid, coarse.min(self.iterations.saturating_sub(rigid)))
    }

    /// The k-NN slack σ in force at iteration `it` (1-based):
    /// [`knn_slack`](crate::fit::Acceleration::knn_slack) in the rigid and coarse phases, 0 in the
    /// FoldMatch (or NRGa) iterations.
    pub fn knn_slack_at(&self, it: usize) -> f64 {
        let (rigid, coarse) = self.phase_iterations();
        if it <= rigid + coarse {
            self.acceleration.knn_slack
        } else {
            0.0
        }
    }
}

/// The stride of a phase's scan sample: `sample` when set, else (0, automatic) the largest
/// stride that leaves `per_vertex` scan points for each of the phase's `⌈m / vertex_stride⌉`
/// vertices, within `1..=most`.
pub(super) fn scan_stride(
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
