//! Fit quality metrics (SPEC §3, paper §4 "Evaluation Metric").
//!
//! Notation: `Y` the original template vertices, `Ŷ` the fitted vertices (same count and faces
//! as `Y`), `X` the target point set, `G` optional ground-truth positions of the template
//! vertices. Everything is measured in the **user's frame and units** (not the normalized
//! frame of the fit); the `f_*` terms are unitless.
//!
//! | field | definition |
//! |---|---|
//! | [`Metrics::f_h`] | `D_H(X, Ŷ) / D_H(X, Y)`, `D_H` the symmetric Hausdorff distance between *point sets* (all template vertices, referenced by a face or not) |
//! | [`Metrics::f_s`] | fraction of evaluated faces with `area(Ŷ)/area(Y) < τ_S` (collapsed) |
//! | [`Metrics::f_e`] | fraction of evaluated faces with `area(Ŷ)/area(Y) > τ_E` (expanded; the paper prints this ratio upside down, SPEC §3 fixes it) |
//! | [`Metrics::f_f`] | fraction of evaluated faces with `n·n̂ < 0` (flipped) |
//! | [`Metrics::f_r`] | `RMSE(Ŷ, G) / diag(bbox(X))`, only with ground truth |
//! | [`Metrics::f_lambda`] | mean of the available terms, named in [`Metrics::f_lambda_terms`] |
//!
//! Plus the distances SPEC §3 asks for beside them (Chamfer, scan-to-fit mean and 95th
//! percentile, fit-to-scan mean, the two Hausdorff distances) and face counts.
//!
//! # Edge cases (the choices made here)
//!
//! * **Degenerate template faces.** A face whose template area is at most
//!   `degenerate_area_rel · diag(bbox(Y))²` (default `1e-12`, so exactly-zero areas, repeated
//!   indices and collinear corners) has no meaningful area ratio or normal. It is excluded from
//!   the denominators *and* numerators of `f_S`, `f_E`, `f_F` and counted in
//!   [`Metrics::num_degenerate_faces`]. Duplicate faces are not special: each counts.
//! * **Degenerate fitted faces.** A fitted face of zero area has ratio 0 (so it counts as
//!   collapsed when `τ_S > 0`) and a zero normal, so `n·n̂ = 0` is *not* a flip.
//! * **No evaluable face** (no faces, or all degenerate). `f_S = f_E = f_F = 0` (vacuously:
//!   no face collapsed, expanded or flipped) and the three are **left out of `f_λ`**; check
//!   [`Metrics::f_lambda_terms`] or [`Metrics::num_evaluated_faces`].
//! * **`D_H(X, Y) = 0`** (the template already coincides with the target as point sets).
//!   `f_H = 0` when `D_H(X, Ŷ) = 0` too (a perfect fit has no residual, whatever the
//!   start), and `f_H = +∞` otherwise (the fit moved away from a perfect start). `f_λ` is then
//!   `+∞` as well. The same rule gives `f_R` when the target's bounding box has zero diagonal
//!   (all target points equal): `0` for a zero RMSE, `+∞` otherwise. `serde_json` writes `+∞`
//!   as `null`.
//! * **Shapes.** `template_vertices` and `target` must be non-empty; `fitted_vertices` and
//!   `ground_truth` must have exactly as many rows as `template_vertices`
//!   ([`FoldMatchError::Shape`]); coordinates must be finite ([`FoldMatchError::NonFinite`]);
//!   face indices must be in range ([`FoldMatchError::FaceIndex`]). Faces may be empty.
//!
//! # Determinism
//!
//! Nearest-neighbour queries and per-face work run in parallel (rayon), but every
//! floating-point reduction is either a `max` (order-free) or a sum taken sequentially in index
//! order over a collected vector; face counts are integers. The result is therefore bitwise
//! identical for any number of threads.
//!
//! # Cost
//!
//! Three k-d trees (over `X`, `Y`, `Ŷ`; built once, concurrently) and `2·(N + M)` nearest-one
//! queries: `O((N + M) log(N + M))`. The trees index rotated copies of the points (a fixed
//! generic rotation) so that flat, axis-aligned templates do not defeat kiddo's cyclic
//! splits; reported distances always come from the original coordinates. Measured on 2 cores:
//! about 5 s for a 100K-vertex flat template against a 1M-point scan.
#![warn(missing_docs)]

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{FoldMatchError, Result};

/// Default collapse threshold `τ_S` (paper §4).
pub const DEFAULT_TAU_S: f64 = 0.02;
/// Default expansion threshold `τ_E` (paper §4).
pub const DEFAULT_TAU_E: f64 = 2.0;
/// Default relative area below which a template face is degenerate (see the module docs).
pub const DEFAULT_DEGENERATE_AREA_REL: f64 = 1e-12;

/// Term names used in [`Metrics::f_lambda_terms`], in the order they are averaged.
pub const TERM_NAMES: [&str; 5] = ["f_H", "f_S", "f_E", "f_F", "f_R"];

/// Minimum number of items per rayon task for the cheap per-point / per-face loops.
const MIN_PAR_LEN: usize = 512;

/// Thresholds of the metrics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MetricsParams {
    /// Collapse threshold `τ_S`: a face is collapsed when `area(Ŷ)/area(Y) < tau_s`.
    /// Default [`DEFAULT_TAU_S`] (0.02). Must be finite and `≥ 0`.
    pub tau_s: f64,
    /// Expansion threshold `τ_E`: a face is expanded when `area(Ŷ)/area(Y) > tau_e`.
    /// Default [`DEFAULT_TAU_E`] (2.0). Must be finite and `> 0`.
    pub tau_e: f64,
    /// A template face with `area ≤ degenerate_area_rel · diag(bbox(Y))²` is degenerate and
    /// excluded from `f_S`, `f_E`, `f_F`. Default [`DEFAULT_DEGENERATE_AREA_REL`]. Must be
    /// finite and `≥ 0` (0 excludes only exactly-zero areas).
    pub degenerate_area_rel: f64,
}

impl Default for MetricsParams {
    fn default() -> Self {
        Self {
            tau_s: DEFAULT_TAU_S,
            tau_e: DEFAULT_TAU_E,
            degenerate_area_rel: DEFAULT_DEGENERATE_AREA_REL,
        }
    }
}

impl MetricsParams {
    /// Checks the ranges documented on each field ([`FoldMatchError::Parameter`] otherwise).
    pub fn validate(&self) -> Result<()> {
        if !(self.tau_s.is_finite() && self.tau_s >= 0.0) {
            return Err(FoldMatchError::parameter(
                "tau_s",
                self.tau_s,
                "must be finite and >= 0",
            ));
        }
        if !(self.tau_e.is_finite() && self.tau_e > 0.0) {
            return Err(FoldMatchError::parameter(
                "tau_e",
                self.tau_e,
                "must be finite and > 0",
            ));
        }
        if !(self.degenerate_area_rel.is_finite() && self.degenerate_area_rel >= 0.0) {
            return Err(FoldMatchError::parameter(
                "degenerate_area_rel",
                self.degenerate_area_rel,
                "must be finite and >= 0",
            ));
        }
        Ok(())
    }
}

/// What [`evaluate`] measures, all in the user's frame.
#[derive(Debug, Clone, Copy)]
pub struct MetricsInput<'a> {
    /// Original template vertices `Y` (M rows, non-empty).
    pub template_vertices: &'a [[f64; 3]],
    /// Template faces (shared by `Y` and `Ŷ`); may be empty.
    pub faces: &'a [[u32; 3]],
    /// Fitted vertices `Ŷ` (M rows, same order as `Y`).
    pub fitted_vertices: &'a [[f64; 3]],
    /// Target point set `X` (N rows, non-empty).
    pub target: &'a [[f64; 3]],
    /// Ground-truth positions `G` of the template vertices (M rows), when known.
    pub ground_truth: Option<&'a [[f64; 3]]>,
}

/// The metrics of one fit. Serialized field names (JSON, Python dict keys) follow the paper:
/// `f_H`, `f_S`, `f_E`, `f_F`, `f_R`, the rest as spelled here.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// `f_H = D_H(X, Ŷ) / D_H(X, Y)` = `hausdorff_after / hausdorff_before` (0 / +∞ when
    /// `hausdorff_before = 0`, see the module docs). 1 means "no better than the template".
    #[serde(rename = "f_H")]
    pub f_h: f64,
    /// Fraction of evaluated faces with `area(Ŷ)/area(Y) < τ_S` (0 when none is evaluated).
    #[serde(rename = "f_S")]
    pub f_s: f64,
    /// Fraction of evaluated faces with `area(Ŷ)/area(Y) > τ_E` (0 when none is evaluated).
    #[serde(rename = "f_E")]
    pub f_e: f64,
    /// Fraction of evaluated faces with `n·n̂ < 0`, `n` / `n̂` the template / fitted face
    /// normals (0 when none is evaluated).
    #[serde(rename = "f_F")]
    pub f_f: f64,
    /// `RMSE(Ŷ, G) / diag(bbox(X))` with `RMSE = sqrt(mean_i ‖Ŷ_i − G_i‖²)`; `None` without
    /// ground truth.
    #[serde(rename = "f_R")]
    pub f_r: Option<f64>,
    /// Mean of the available terms ([`Metrics::f_lambda_terms`]).
    pub f_lambda: f64,
    /// Names of the terms averaged into `f_lambda`, in order, from [`TERM_NAMES`]: `f_H`
    /// always; `f_S`, `f_E`, `f_F` when at least one face was evaluated; `f_R` with ground
    /// truth.
    pub f_lambda_terms: Vec<String>,
    /// Chamfer distance, point to point, in the user's units (not squared):
    /// `½ (mean_{x∈X} min_{ŷ∈Ŷ} ‖x − ŷ‖ + mean_{ŷ∈Ŷ} min_{x∈X} ‖ŷ − x‖)`,
    /// i.e. the mean of `scan_to_fit_mean` and `fit_to_scan_mean`.
    pub chamfer: f64,
    /// `mean_{x∈X} min_{ŷ∈Ŷ} ‖x − ŷ‖`: distance from each target point to the nearest fitted
    /// vertex, averaged.
    pub scan_to_fit_mean: f64,
    /// 95th percentile of the same distances, linear interpolation between order statistics
    /// (NumPy's default `np.percentile(d, 95)`).
    pub scan_to_fit_p95: f64,
    /// `mean_{ŷ∈Ŷ} min_{x∈X} ‖ŷ − x‖`: distance from each fitted vertex to the nearest target
    /// point, averaged.
    pub fit_to_scan_mean: f64,
    /// `D_H(X, Y)`: symmetric Hausdorff distance between the target and the original template.
    pub hausdorff_before: f64,
    /// `D_H(X, Ŷ)`: symmetric Hausdorff distance between the target and the fit.
    pub hausdorff_after: f64,
    /// `RMSE(Ŷ, G)` in the user's units; `None` without ground truth.
    pub rmse: Option<f64>,
    /// `diag(bbox(X))`, the normalizer of `f_R`.
    pub target_diagonal: f64,
    /// Number of template faces.
    pub num_faces: usize,
    /// Template faces excluded as degenerate (see [`MetricsParams::degenerate_area_rel`]).
    pub num_degenerate_faces: usize,
    /// Faces evaluated for `f_S`, `f_E`, `f_F`: `num_faces − num_degenerate_faces`.
    pub num_evaluated_faces: usize,
    /// Evaluated faces counted as collapsed (numerator of `f_S`).
    pub num_collapsed_faces: usize,
    /// Evaluated faces counted as expanded (numerator of `f_E`).
    pub num_expanded_faces: usize,
    /// Evaluated faces counted as flipped (numerator of `f_F`).
    pub num_flipped_faces: usize,
}

/// Computes every metric of a fit; see the module docs for definitions and edge cases.
///
/// Errors: [`FoldMatchError::Parameter`] for invalid `params`, [`FoldMatchError::Shape`] for
/// empty `template_vertices` / `target` or a row-count mismatch of `fitted_vertices` /
/// `ground_truth`, [`FoldMatchError::NonFinite`], [`FoldMatchError::FaceIndex`].
pub fn evaluate(input: &MetricsInput<'_>, params: &MetricsParams) -> Result<Metrics> {
    params.validate()?;
    validate_input(input)?;
    let y = input.template_vertices;
    let y_hat = input.fitted_vertices;
    let x = input.target;

    // Trees built once, concurrently.
    let (tree_x, (tree_y, tree_fit)) = rayon::join(
        || NnIndex::new(x),
        || rayon::join(|| NnIndex::new(y), || NnIndex::new(y_hat)),
    );

    let ((x_to_y, y_to_x), (x_to_fit, fit_to_x)) = rayon::join(
        || rayon::join(|| tree_y.distances(x), || tree_x.distances(y)),
        || rayon::join(|| tree_fit.distances(x), || tree_x.distances(y_hat)),
    );
    let hausdorff_before = max_of(&x_to_y).max(max_of(&y_to_x));
    let hausdorff_after = max_of(&x_to_fit).max(max_of(&fit_to_x));
    let f_h = safe_ratio(hausdorff_after, hausdorff_before);

    let scan_to_fit_mean = mean_of(&x_to_fit);
    let fit_to_scan_mean = mean_of(&fit_to_x);
    let chamfer = 0.5 * (scan_to_fit_mean + fit_to_scan_mean);
    let scan_to_fit_p95 = percentile_linear(&x_to_fit, 95.0);

    let counts = face_counts(y, y_hat, input.faces, params);
    let fraction = |k: usize| {
        if counts.evaluated == 0 {
            0.0
        } else {
            k as f64 / counts.evaluated as f64
        }
    };
    let f_s = fraction(counts.collapsed);
    let f_e = fraction(counts.expanded);
    let f_f = fraction(counts.flipped);

    let target_diagonal = bbox_diagonal(x);
    let rmse = input.ground_truth.map(|g| rmse_of(y_hat, g));
    let f_r = rmse.map(|r| safe_ratio(r, target_diagonal));

    let mut terms: Vec<(&str, f64)> = vec![(TERM_NAMES[0], f_h)];
    if counts.evaluated > 0 {
        terms.extend([
            (TERM_NAMES[1], f_s),
            (TERM_NAMES[2], f_e),
            (TERM_NAMES[3], f_f),
        ]);
    }
    if let Some(r) = f_r {
        terms.push((TERM_NAMES[4], r));
    }
    let f_lambda = terms.iter().map(|t| t.1).sum::<f64>() / terms.len() as f64;

    Ok(Metrics {
        f_h,
        f_s,
        f_e,
        f_f,
        f_r,
        f_lambda,
        f_lambda_terms: terms.iter().map(|t| t.0.to_string()).collect(),
        chamfer,
        scan_to_fit_mean,
        scan_to_fit_p95,
        fit_to_scan_mean,
        hausdorff_before,
        hausdorff_after,
        rmse,
        target_diagonal,
        num_faces: input.faces.len(),
        num_degenerate_faces: counts.degenerate,
        num_evaluated_faces: counts.evaluated,
        num_collapsed_faces: counts.collapsed,
        num_expanded_faces: counts.expanded,
        num_flipped_faces: counts.flipped,
    })
}

/// Euclidean distance from every point of `from` to its nearest point of `to`, in the order of
/// `from` (one k-d tree over `to`, parallel queries).
///
/// When `to` is empty every distance is `+∞` (the minimum over an empty set). Inputs are
/// expected to be finite (non-finite coordinates give unspecified, but non-panicking, results).
pub fn nearest_distances(from: &[[f64; 3]], to: &[[f64; 3]]) -> Vec<f64> {
    NnIndex::new(to).distances(from)
}

/// The spread of the mesh's edge lengths against the template's: the population standard
/// deviation of `ln(‖ŷᵢ − ŷⱼ‖ / ‖yᵢ − yⱼ‖)` over the unique edges `{i, j}` of `faces` (each
/// edge once, however many faces share it) whose template length is positive.
///
/// 0 for any similarity of the template (a rigid motion with a uniform scale), so it measures
/// how far the fit is from an isometry up to scale, whatever the units; schedule selection
/// breaks near-ties in scan distance with it (cloth barely stretches, docs/method.md "Eighth
/// round"). A fitted edge collapsed to zero length counts as the ratio `1e-12`. No edge: 0.
/// For several fits of one template, build [`EdgeLengths`] once.
pub fn edge_length_spread(template: &[[f64; 3]], fitted: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    EdgeLengths::new(template, faces).spread(fitted)
}

/// A template's unique edges of positive length and their lengths: the rest state that
/// [`edge_length_spread`] compares fits with, built once for all the fits of one template.
pub struct EdgeLengths {
    edges: Vec<(u32, u32)>,
    rest: Vec<f64>,
}

impl EdgeLengths {
    /// The unique edges of `faces` (each once, however many faces share it) whose length on
    /// `template` is positive.
    pub fn new(template: &[[f64; 3]], faces: &[[u32; 3]]) -> Self {
        let mut edges: Vec<(u32, u32)> = faces
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let rest: Vec<f64> = edges.iter().map(|&e| edge_length(template, e)).collect();
        let (edges, rest) = edges
            .into_iter()
            .zip(rest)
            .filter(|&(_, r)| r > 0.0)
            .unzip();
        Self { edges, rest }
    }

    /// The unique edges `(i, j)`, `i < j`, each once.
    pub fn edges(&self) -> &[(u32, u32)] {
        &self.edges
    }

    /// Every edge's length on `fitted` over its template length, in [`EdgeLengths::edges`]
    /// order (0 for an edge collapsed to a point).
    pub fn ratios(&self, fitted: &[[f64; 3]]) -> Vec<f64> {
        self.edges
            .iter()
            .zip(&self.rest)
            .map(|(&e, &rest)| edge_length(fitted, e) / rest)
            .collect()
    }

    /// [`edge_length_spread`] of `fitted` (the template's vertices, moved).
    pub fn spread(&self, fitted: &[[f64; 3]]) -> f64 {
        if self.edges.is_empty() {
            return 0.0;
        }
        let logs: Vec<f64> = self
            .edges
            .iter()
            .zip(&self.rest)
            .map(|(&e, &rest)| (edge_length(fitted, e) / rest).max(1e-12).ln())
            .collect();
        let n = logs.len() as f64;
        let mean = logs.iter().sum::<f64>() / n;
        (logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / n).sqrt()
    }
}

/// The length of the edge `(a, b)` on the points `p`.
fn edge_length(p: &[[f64; 3]], (a, b): (u32, u32)) -> f64 {
    let (a, b) = (&p[a as usize], &p[b as usize]);
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Symmetric Hausdorff distance between two point sets:
/// `max(max_{a∈A} min_{b∈B} ‖a − b‖, max_{b∈B} min_{a∈A} ‖a − b‖)`.
///
/// Conventions for empty sets: both empty → 0; exactly one empty → `+∞`. Inputs are expected
/// to be finite.
pub fn hausdorff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let (ta, tb) = rayon::join(|| NnIndex::new(a), || NnIndex::new(b));
    let (ab, ba) = rayon::join(|| tb.distances(a), || ta.distances(b));
    max_of(&ab).max(max_of(&ba))
}

/// A fixed, generic rotation (from the unit quaternion ∝ (0.8, 0.3, −0.5, 0.4)) applied to the
/// points inside [`NnIndex`].
///
/// kiddo's `ImmutableKdTree` splits on the axes in turn; when the indexed points are flat along
/// an axis (a flat cloth template at z = 0, an axis-aligned grid) every split on that axis is
/// useless and a nearest-one query visits ~2× more leaves per such level (measured: 5.6 s
/// instead of 0.85 s for 1M queries into a 100K-point z = 0 grid). Rotating everything by a
/// generic rotation removes that degeneracy. Distances are then recomputed from the original
/// coordinates, so the rotation only steers the search and never enters a reported value.
const SEARCH_ROTATION: [[f64; 3]; 3] = [
    [0.2807017543859649, -0.824561403508772, -0.49122807017543857],
    [0.2982456140350878, 0.5614035087719298, -0.7719298245614035],
    [0.9122807017543859, 0.07017543859649122, 0.4035087719298246],
];

/// `SEARCH_ROTATION · p`.
#[inline]
fn rotate(p: &[f64; 3]) -> [f64; 3] {
    SEARCH_ROTATION.map(|r| dot(r, *p))
}

/// A nearest-one index over a point set: a k-d tree over the rotated points (see
/// [`SEARCH_ROTATION`]); `None` for an empty set (kiddo needs points).
struct NnIndex<'a> {
    points: &'a [[f64; 3]],
    tree: Option<ImmutableKdTree<f64, 3>>,
}

impl<'a> NnIndex<'a> {
    fn new(points: &'a [[f64; 3]]) -> Self {
        let tree = (!points.is_empty()).then(|| {
            let rotated: Vec<[f64; 3]> = points
                .par_iter()
                .with_min_len(MIN_PAR_LEN)
                .map(rotate)
                .collect();
            ImmutableKdTree::new_from_slice(&rotated)
        });
        Self { points, tree }
    }

    /// Distance from each query to its nearest indexed point (`+∞` when the index is empty),
    /// computed from the original coordinates.
    fn distances(&self, queries: &[[f64; 3]]) -> Vec<f64> {
        match &self.tree {
            None => vec![f64::INFINITY; queries.len()],
            Some(tree) => queries
                .par_iter()
                .with_min_len(MIN_PAR_LEN)
                .map(|q| {
                    let nn = tree.nearest_one::<SquaredEuclidean>(&rotate(q));
                    let p = &self.points[nn.item as usize];
                    let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                    dot(d, d).sqrt()
                })
                .collect(),
        }
    }
}

/// Face classification counts (integers, so the parallel reduction is exact).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
struct FaceCounts {
    degenerate: usize,
    evaluated: usize,
    collapsed: usize,
    expanded: usize,
    flipped: usize,
}

impl std::ops::Add for FaceCounts {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            degenerate: self.degenerate + o.degenerate,
            evaluated: self.evaluated + o.evaluated,
            collapsed: self.collapsed + o.collapsed,
            expanded: self.expanded + o.expanded,
            flipped: self.flipped + o.flipped,
        }
    }
}

/// Classifies every face (degenerate / collapsed / expanded / flipped).
fn face_counts(
    y: &[[f64; 3]],
    y_hat: &[[f64; 3]],
    faces: &[[u32; 3]],
    params: &MetricsParams,
) -> FaceCounts {
    let diag = bbox_diagonal(y);
    let min_area = params.degenerate_area_rel * diag * diag;
    faces
        .par_iter()
        .with_min_len(MIN_PAR_LEN)
        .map(|f| {
            let n = cross_of(y, f);
            let area = 0.5 * norm(n);
            if area <= min_area {
                return FaceCounts {
                    degenerate: 1,
                    ..FaceCounts::default()
                };
            }
            let n_hat = cross_of(y_hat, f);
            let ratio = 0.5 * norm(n_hat) / area;
            FaceCounts {
                degenerate: 0,
                evaluated: 1,
                collapsed: usize::from(ratio < params.tau_s),
                expanded: usize::from(ratio > params.tau_e),
                flipped: usize::from(dot(n, n_hat) < 0.0),
            }
        })
        .reduce(FaceCounts::default, |a, b| a + b)
}

/// `(b − a) × (c − a)` of face `f` over `p`: the normal scaled by twice the area.
#[inline]
pub(crate) fn cross_of(p: &[[f64; 3]], f: &[u32; 3]) -> [f64; 3] {
    let [a, b, c] = f.map(|i| p[i as usize]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Length of the diagonal of the axis-aligned bounding box (0 for an empty set).
pub(crate) fn bbox_diagonal(points: &[[f64; 3]]) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    let (mut lo, mut hi) = (*first, *first);
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    norm([hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]])
}

/// `sqrt(mean_i ‖a_i − b_i‖²)` (same lengths, non-empty); summed in index order.
fn rmse_of(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let sq: Vec<f64> = a
        .par_iter()
        .zip(b.par_iter())
        .with_min_len(MIN_PAR_LEN)
        .map(|(p, q)| {
            let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
            dot(d, d)
        })
        .collect();
    mean_of(&sq).sqrt()
}

/// `num / den`, with `0/0 = 0` and `x/0 = +∞` for `x > 0` (see the module docs).
fn safe_ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 {
        num / den
    } else if num == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// Largest value (0 for an empty slice: the directed Hausdorff distance of an empty set).
fn max_of(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

/// Arithmetic mean summed sequentially in index order (deterministic); NaN when empty.
fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// The `p`-th percentile (`0 ≤ p ≤ 100`) with linear interpolation between the order
/// statistics at ranks `⌊h⌋` and `⌊h⌋+1`, `h = (n − 1)·p/100` (NumPy's default). NaN when
/// empty. O(n) by selection.
pub(crate) fn percentile_linear(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut w = v.to_vec();
    let h = (w.len() - 1) as f64 * (p / 100.0);
    let lo = (h.floor() as usize).min(w.len() - 1);
    let t = h - lo as f64;
    let (_, &mut a, rest) = w.select_nth_unstable_by(lo, f64::total_cmp);
    if t == 0.0 || rest.is_empty() {
        return a;
    }
    let b = rest.iter().copied().fold(f64::INFINITY, f64::min);
    a + t * (b - a)
}

/// Shapes, finiteness and face indices of `input` (see [`evaluate`]).
fn validate_input(input: &MetricsInput<'_>) -> Result<()> {
    let m = input.template_vertices.len();
    check_points("template_vertices", input.template_vertices, None)?;
    check_points("fitted_vertices", input.fitted_vertices, Some(m))?;
    check_points("target", input.target, None)?;
    if let Some(g) = input.ground_truth {
        check_points("ground_truth", g, Some(m))?;
    }
    for (face, f) in input.faces.iter().enumerate() {
        if let Some(&v) = f.iter().find(|&&v| v as usize >= m) {
            return Err(FoldMatchError::FaceIndex {
                name: "template_faces".into(),
                face,
                vertex: i64::from(v),
                count: m,
            });
        }
    }
    Ok(())
}

/// Non-empty, finite, and `expected` rows when given (the template's vertex count).
fn check_points(name: &str, points: &[[f64; 3]], expected: Option<usize>) -> Result<()> {
    match expected {
        Some(m) if points.len() != m => {
            return Err(FoldMatchError::shape(
                name,
                format!(
                    "expected {m} rows (one per template vertex), got {}",
                    points.len()
                ),
            ));
        }
        None if points.is_empty() => {
            return Err(FoldMatchError::shape(
                name,
                "expected at least one point, got 0 rows",
            ));
        }
        _ => {}
    }
    for (row, p) in points.iter().enumerate() {
        if let Some(&value) = p.iter().find(|v| !v.is_finite()) {
            return Err(FoldMatchError::NonFinite {
                name: name.into(),
                row,
                value,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn edge_length_spread_counts_each_edge_once_and_ignores_similarities() {
        // A unit square as two triangles sharing the diagonal 0–2: five unique edges.
        let square = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let faces = [[0, 1, 2], [0, 2, 3]];
        // Stretched ×2 along x: edge ratios 2 (0–1), 1 (1–2), √(5/2) (0–2), 2 (2–3), 1 (3–0).
        let stretched: Vec<[f64; 3]> = square.iter().map(|p| [2.0 * p[0], p[1], p[2]]).collect();
        let logs = [2f64.ln(), 0.0, 2.5f64.sqrt().ln(), 2f64.ln(), 0.0];
        let mean = logs.iter().sum::<f64>() / 5.0;
        let want = (logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / 5.0).sqrt();
        assert_relative_eq!(
            edge_length_spread(&square, &stretched, &faces),
            want,
            max_relative = 1e-14
        );
        // A rotation, a uniform scale and a translation change no ratio's logarithm but by a
        // constant: spread 0.
        let (c, s) = (0.6f64, 0.8f64);
        let similar: Vec<[f64; 3]> = square
            .iter()
            .map(|p| {
                [
                    3.0 * (c * p[0] - s * p[1]) + 5.0,
                    3.0 * (s * p[0] + c * p[1]),
                    -2.0,
                ]
            })
            .collect();
        assert!(edge_length_spread(&square, &similar, &faces) < 1e-14);
        // A collapsed edge is finite (ratio 1e-12); no face, no edge: 0.
        let collapsed = [square[0], square[0], square[2], square[3]];
        assert!(edge_length_spread(&square, &collapsed, &faces).is_finite());
        assert_eq!(edge_length_spread(&square, &stretched, &[]), 0.0);
    }

    // ---------- brute-force references (O(N·M), written independently) ----------

    fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    fn brute_nearest(from: &[[f64; 3]], to: &[[f64; 3]]) -> Vec<f64> {
        from.iter()
            .map(|p| to.iter().map(|q| dist(p, q)).fold(f64::INFINITY, f64::min))
            .collect()
    }

    fn brute_hausdorff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        let ab = brute_nearest(a, b).into_iter().fold(0.0, f64::max);
        let ba = brute_nearest(b, a).into_iter().fold(0.0, f64::max);
        ab.max(ba)
    }

    fn brute_percentile(v: &[f64], p: f64) -> f64 {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let h = (s.len() - 1) as f64 * p / 100.0;
        let lo = h.floor() as usize;
        let hi = (lo + 1).min(s.len() - 1);
        s[lo] + (h - lo as f64) * (s[hi] - s[lo])
    }

    fn tri_area_normal(p: &[[f64; 3]], f: &[u32; 3]) -> (f64, [f64; 3]) {
        let a = p[f[0] as usize];
        let b = p[f[1] as usize];
        let c = p[f[2] as usize];
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        (0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt(), n)
    }

    /// Returns (f_S, f_E, f_F, degenerate count) by a plain loop.
    fn brute_faces(
        y: &[[f64; 3]],
        yh: &[[f64; 3]],
        faces: &[[u32; 3]],
        p: &MetricsParams,
    ) -> (f64, f64, f64, usize) {
        let diag = {
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for q in y {
                for k in 0..3 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
            dist(&lo, &hi)
        };
        let (mut s, mut e, mut fl, mut deg, mut n) = (0, 0, 0, 0, 0);
        for f in faces {
            let (a, na) = tri_area_normal(y, f);
            if a <= p.degenerate_area_rel * diag * diag {
                deg += 1;
                continue;
            }
            n += 1;
            let (b, nb) = tri_area_normal(yh, f);
            s += usize::from(b / a < p.tau_s);
            e += usize::from(b / a > p.tau_e);
            fl += usize::from(na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2] < 0.0);
        }
        let frac = |k: usize| if n == 0 { 0.0 } else { k as f64 / n as f64 };
        (frac(s), frac(e), frac(fl), deg)
    }

    fn random_points(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<[f64; 3]> {
        (0..n)
            .map(|_| {
                [
                    rng.random_range(-scale..scale),
                    rng.random_range(-scale..scale),
                    rng.random_range(-scale..scale),
                ]
            })
            .collect()
    }

    /// A (nx × ny) grid in the xy-plane with a little z noise, triangulated.
    fn grid_mesh(rng: &mut ChaCha8Rng, nx: usize, ny: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut v = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                v.push([
                    i as f64 / (nx - 1) as f64,
                    j as f64 / (ny - 1) as f64,
                    rng.random_range(-0.02..0.02),
                ]);
            }
        }
        let mut f = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let b = a + 1;
                let c = a + nx as u32;
                let d = c + 1;
                f.push([a, b, d]);
                f.push([a, d, c]);
            }
        }
        (v, f)
    }

    fn input<'a>(
        y: &'a [[f64; 3]],
        f: &'a [[u32; 3]],
        yh: &'a [[f64; 3]],
        x: &'a [[f64; 3]],
        g: Option<&'a [[f64; 3]]>,
    ) -> MetricsInput<'a> {
        MetricsInput {
            template_vertices: y,
            faces: f,
            fitted_vertices: yh,
            target: x,
            ground_truth: g,
        }
    }

    fn single_triangle() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        (
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
        )
    }

    // ---------- helpers vs brute force ----------

    #[test]
    fn nearest_distances_match_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for &(n, m) in &[(1, 1), (7, 3), (200, 150), (500, 40), (33, 700)] {
            let a = random_points(&mut rng, n, 1.0);
            let b = random_points(&mut rng, m, 2.0);
            let got = nearest_distances(&a, &b);
            let want = brute_nearest(&a, &b);
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert_relative_eq!(g, w, max_relative = 1e-12, epsilon = 1e-15);
            }
        }
    }

    #[test]
    fn nearest_distances_with_duplicates_and_flat_axes() {
        // Many points on an axis-aligned plane and many exact duplicates (hard for k-d trees).
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let mut b: Vec<[f64; 3]> = (0..300)
            .map(|_| {
                [
                    rng.random_range(0..5) as f64,
                    rng.random_range(0..5) as f64,
                    0.0,
                ]
            })
            .collect();
        b.extend(std::iter::repeat_n([0.5, 0.5, 0.0], 100));
        let a = random_points(&mut rng, 200, 3.0);
        let got = nearest_distances(&a, &b);
        let want = brute_nearest(&a, &b);
        for (g, w) in got.iter().zip(&want) {
            assert_relative_eq!(g, w, max_relative = 1e-12, epsilon = 1e-15);
        }
        // A point of the set is at distance exactly 0.
        assert_eq!(nearest_distances(&b, &b), vec![0.0; b.len()]);
    }

    #[test]
    fn nearest_distances_empty_sets() {
        let a = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]];
        assert_eq!(nearest_distances(&a, &[]), vec![f64::INFINITY; 2]);
        assert!(nearest_distances(&[], &a).is_empty());
    }

    #[test]
    fn hausdorff_matches_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        for &(n, m) in &[(1, 1), (10, 90), (250, 180)] {
            let a = random_points(&mut rng, n, 1.0);
            let b = random_points(&mut rng, m, 1.5);
            let h = hausdorff(&a, &b);
            assert_relative_eq!(h, brute_hausdorff(&a, &b), max_relative = 1e-12);
            assert_eq!(h, hausdorff(&b, &a), "symmetric");
        }
    }

    #[test]
    fn hausdorff_known_values_and_conventions() {
        let a = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let b = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 3.0, 4.0]];
        // a ⊂ b: directed a→b = 0, b→a = 5.
        assert_relative_eq!(hausdorff(&a, &b), 5.0);
        assert_eq!(hausdorff(&a, &a), 0.0);
        assert_eq!(hausdorff(&[], &[]), 0.0);
        assert_eq!(hausdorff(&a, &[]), f64::INFINITY);
        assert_eq!(hausdorff(&[], &a), f64::INFINITY);
    }

    #[test]
    fn percentile_matches_numpy_linear() {
        let v: Vec<f64> = (0..=100).rev().map(f64::from).collect();
        assert_eq!(percentile_linear(&v, 95.0), 95.0);
        assert_relative_eq!(percentile_linear(&[0.0, 10.0], 95.0), 9.5);
        assert_eq!(percentile_linear(&[3.0], 95.0), 3.0);
        assert_eq!(percentile_linear(&[4.0, 1.0, 3.0], 100.0), 4.0);
        assert_eq!(percentile_linear(&[4.0, 1.0, 3.0], 0.0), 1.0);
        assert!(percentile_linear(&[], 95.0).is_nan());
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        for n in [2usize, 3, 19, 20, 21, 101, 997] {
            let v: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
            assert_relative_eq!(
                percentile_linear(&v, 95.0),
                brute_percentile(&v, 95.0),
                max_relative = 1e-14
            );
        }
    }

    // ---------- evaluate vs brute force ----------

    #[test]
    fn evaluate_matches_brute_force_on_random_meshes() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let params = MetricsParams::default();
        let mut seen = [0usize; 3];
        for trial in 0..6 {
            let (mut y, mut faces) = grid_mesh(&mut rng, 9 + trial, 7);
            // A repeated-index face and a collinear face (first row, flattened): degenerate.
            for p in &mut y[..3] {
                p[2] = 0.0;
            }
            faces.push([0, 0, 1]);
            faces.push([0, 1, 2]);
            // Large noise so that collapsed / expanded / flipped faces all occur.
            let amp = 0.05 + 0.05 * trial as f64;
            let mut yh: Vec<[f64; 3]> = y
                .iter()
                .map(|p| {
                    [
                        p[0] + rng.random_range(-amp..amp),
                        p[1] + rng.random_range(-amp..amp),
                        p[2] + rng.random_range(-amp..amp),
                    ]
                })
                .collect();
            // Snap a few fitted vertices onto a grid neighbour: faces sharing that edge collapse.
            for k in [10 + trial, 20 + 2 * trial, 30] {
                yh[k] = yh[k + 1];
            }
            let x = random_points(&mut rng, 150 + 37 * trial, 0.8);
            let g: Vec<[f64; 3]> = y
                .iter()
                .map(|p| [p[0] + 0.01, p[1] - 0.02, p[2] + rng.random_range(-0.1..0.1)])
                .collect();
            let m = evaluate(&input(&y, &faces, &yh, &x, Some(&g)), &params).unwrap();

            let x_to_fit = brute_nearest(&x, &yh);
            let fit_to_x = brute_nearest(&yh, &x);
            let before = brute_hausdorff(&x, &y);
            let after = brute_hausdorff(&x, &yh);
            let s2f = x_to_fit.iter().sum::<f64>() / x.len() as f64;
            let f2s = fit_to_x.iter().sum::<f64>() / yh.len() as f64;
            let (fs, fe, ff, deg) = brute_faces(&y, &yh, &faces, &params);
            let rmse = (yh
                .iter()
                .zip(&g)
                .map(|(a, b)| dist(a, b).powi(2))
                .sum::<f64>()
                / y.len() as f64)
                .sqrt();
            let diag_x = {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for q in &x {
                    for k in 0..3 {
                        lo[k] = lo[k].min(q[k]);
                        hi[k] = hi[k].max(q[k]);
                    }
                }
                dist(&lo, &hi)
            };

            let tol = 1e-12;
            assert_relative_eq!(m.hausdorff_before, before, max_relative = tol);
            assert_relative_eq!(m.hausdorff_after, after, max_relative = tol);
            assert_relative_eq!(m.f_h, after / before, max_relative = tol);
            assert_relative_eq!(m.scan_to_fit_mean, s2f, max_relative = tol);
            assert_relative_eq!(m.fit_to_scan_mean, f2s, max_relative = tol);
            assert_relative_eq!(m.chamfer, 0.5 * (s2f + f2s), max_relative = tol);
            assert_relative_eq!(
                m.scan_to_fit_p95,
                brute_percentile(&x_to_fit, 95.0),
                max_relative = tol
            );
            assert_eq!((m.f_s, m.f_e, m.f_f), (fs, fe, ff));
            assert_eq!(m.num_degenerate_faces, deg);
            assert_eq!(deg, 2);
            assert_eq!(m.num_faces, faces.len());
            assert_eq!(m.num_evaluated_faces, faces.len() - 2);
            assert_relative_eq!(m.rmse.unwrap(), rmse, max_relative = tol);
            assert_relative_eq!(m.target_diagonal, diag_x, max_relative = tol);
            assert_relative_eq!(m.f_r.unwrap(), rmse / diag_x, max_relative = tol);
            assert_eq!(m.f_lambda_terms, ["f_H", "f_S", "f_E", "f_F", "f_R"]);
            assert_relative_eq!(
                m.f_lambda,
                (after / before + fs + fe + ff + rmse / diag_x) / 5.0,
                max_relative = tol
            );
            seen[0] += m.num_collapsed_faces;
            seen[1] += m.num_expanded_faces;
            seen[2] += m.num_flipped_faces;
        }
        // The trials exercise every face class.
        assert!(seen.iter().all(|&k| k > 0), "{seen:?}");
    }

    #[test]
    fn evaluate_is_deterministic_across_thread_counts() {
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        let (y, faces) = grid_mesh(&mut rng, 60, 50);
        let yh: Vec<[f64; 3]> = y
            .iter()
            .map(|p| {
                [
                    p[0] * 1.1,
                    p[1] + rng.random_range(-0.01..0.01),
                    p[2] + 0.3 * p[0] * p[1],
                ]
            })
            .collect();
        let x = random_points(&mut rng, 7000, 1.0);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    evaluate(
                        &input(&y, &faces, &yh, &x, Some(&y)),
                        &MetricsParams::default(),
                    )
                    .unwrap()
                })
        };
        let one = run(1);
        for t in [2, 3, 8] {
            assert_eq!(run(t), one, "{t} threads");
        }
    }

    // ---------- analytic cases ----------

    #[test]
    fn scaled_triangle_is_expanded() {
        let (y, f) = single_triangle();
        let yh: Vec<[f64; 3]> = y.iter().map(|p| p.map(|c| 3.0 * c)).collect();
        let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
        // Area ratio 9 > 2.
        assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 1.0, 0.0));
        assert_eq!(m.num_expanded_faces, 1);
    }

    #[test]
    fn shrunk_triangle_is_collapsed() {
        let (y, f) = single_triangle();
        let yh: Vec<[f64; 3]> = y.iter().map(|p| p.map(|c| 0.1 * c)).collect();
        let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
        // Area ratio 0.01 < 0.02.
        assert_eq!((m.f_s, m.f_e, m.f_f), (1.0, 0.0, 0.0));
        // A custom threshold below the ratio no longer counts it.
        let p = MetricsParams {
            tau_s: 0.005,
            ..MetricsParams::default()
        };
        assert_eq!(
            evaluate(&input(&y, &f, &yh, &y, None), &p).unwrap().f_s,
            0.0
        );
    }

    #[test]
    fn mirrored_triangle_is_flipped() {
        let (y, f) = single_triangle();
        let yh: Vec<[f64; 3]> = y.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
        // Same area, normal reversed.
        assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 1.0));
    }

    #[test]
    fn fully_collapsed_fitted_face_is_collapsed_not_flipped() {
        let (y, f) = single_triangle();
        let yh = vec![[0.2, 0.2, 0.2]; 3];
        let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
        assert_eq!((m.f_s, m.f_e, m.f_f), (1.0, 0.0, 0.0));
    }

    #[test]
    fn identical_fit_and_template() {
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        let (y, f) = grid_mesh(&mut rng, 8, 6);
        let x = random_points(&mut rng, 100, 2.0);
        let m = evaluate(&input(&y, &f, &y, &x, None), &MetricsParams::default()).unwrap();
        assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 0.0));
        assert_eq!(m.f_h, 1.0);
        assert_eq!(m.hausdorff_before, m.hausdorff_after);
        assert_eq!(m.f_r, None);
        assert_eq!(m.rmse, None);
        assert_eq!(m.f_lambda_terms, ["f_H", "f_S", "f_E", "f_F"]);
        assert_relative_eq!(m.f_lambda, 0.25);
    }

    #[test]
    fn fit_onto_target_vertices_gives_zero_distances() {
        let mut rng = ChaCha8Rng::seed_from_u64(32);
        let (y, f) = grid_mesh(&mut rng, 6, 6);
        let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0] + 0.5, p[1], p[2]]).collect();
        let m = evaluate(&input(&y, &f, &yh, &yh, None), &MetricsParams::default()).unwrap();
        assert_eq!(m.f_h, 0.0);
        assert_eq!(
            (
                m.chamfer,
                m.scan_to_fit_mean,
                m.scan_to_fit_p95,
                m.fit_to_scan_mean
            ),
            (0.0, 0.0, 0.0, 0.0)
        );
        assert_relative_eq!(m.hausdorff_before, 0.5, max_relative = 1e-12);
        assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 0.0));
    }

    #[test]
    fn zero_hausdorff_before() {
        let (y, f) = single_triangle();
        // Template already equals the target; fit stays → f_H = 0.
        let m = evaluate(&input(&y, &f, &y, &y, None), &MetricsParams::default()).unwrap();
        assert_eq!(m.hausdorff_before, 0.0);
        assert_eq!(m.f_h, 0.0);
        assert_eq!(m.f_lambda, 0.0);
        // Fit moves away → f_H = +∞, and so is f_λ.
        let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0], p[1], p[2] + 0.1]).collect();
        let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
        assert_eq!(m.f_h, f64::INFINITY);
        assert_eq!(m.f_lambda, f64::INFINITY);
    }

    #[test]
    fn ground_truth_rmse_is_normalized_by_target_diagonal() {
        let (y, f) = single_triangle();
        // Target spans the unit cube: diagonal √3.
        let x = vec![[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, 0.9, 0.1]];
        let g: Vec<[f64; 3]> = y.iter().map(|p| [p[0] + 2.0, p[1], p[2]]).collect();
        // Fitted = ground truth + a constant offset (0, 0.3, 0.4) of length 0.5: RMSE = 0.5.
        let yh: Vec<[f64; 3]> = g.iter().map(|p| [p[0], p[1] + 0.3, p[2] + 0.4]).collect();
        let m = evaluate(&input(&y, &f, &yh, &x, Some(&g)), &MetricsParams::default()).unwrap();
        assert_relative_eq!(m.rmse.unwrap(), 0.5, max_relative = 1e-12);
        assert_relative_eq!(m.target_diagonal, 3f64.sqrt(), max_relative = 1e-12);
        assert_relative_eq!(m.f_r.unwrap(), 0.5 / 3f64.sqrt(), max_relative = 1e-12);
        assert_eq!(m.f_lambda_terms.last().unwrap(), "f_R");
        // Fit equal to the ground truth: f_R = 0.
        let m = evaluate(&input(&y, &f, &g, &x, Some(&g)), &MetricsParams::default()).unwrap();
        assert_eq!(m.f_r, Some(0.0));
        // A single-point target has zero diagonal: 0 / 0 = 0, x / 0 = +∞.
        let x1 = [[0.0, 0.0, 0.0]];
        let m = evaluate(&input(&y, &f, &g, &x1, Some(&g)), &MetricsParams::default()).unwrap();
        assert_eq!(m.f_r, Some(0.0));
        let m = evaluate(
            &input(&y, &f, &yh, &x1, Some(&g)),
            &MetricsParams::default(),
        )
        .unwrap();
        assert_eq!(m.f_r, Some(f64::INFINITY));
    }

    #[test]
    fn degenerate_and_missing_faces() {
        let y = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0], p[1] * 10.0, p[2]]).collect();
        // [0,1,2] collinear, [1,1,3] repeated index: both degenerate; [0,1,3] expands ×10.
        let faces = vec![[0, 1, 2], [1, 1, 3], [0, 1, 3]];
        let m = evaluate(&input(&y, &faces, &yh, &y, None), &MetricsParams::default()).unwrap();
        assert_eq!(
            (m.num_faces, m.num_degenerate_faces, m.num_evaluated_faces),
            (3, 2, 1)
        );
        assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 1.0, 0.0));
        // All faces degenerate, or none at all: face terms 0 and out of f_λ.
        for faces in [vec![[0, 1, 2], [1, 1, 3]], vec![]] {
            let m = evaluate(&input(&y, &faces, &yh, &y, None), &MetricsParams::default()).unwrap();
            assert_eq!(m.num_evaluated_faces, 0);
            assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 0.0));
            assert_eq!(m.f_lambda_terms, ["f_H"]);
            assert_eq!(m.f_lambda, m.f_h);
        }
    }

    // ---------- errors ----------

    #[test]
    fn shape_and_value_errors() {
        let (y, f) = single_triangle();
        let p = MetricsParams::default();
        let short = &y[..2];
        let shape_name = |r: Result<Metrics>| match r {
            Err(FoldMatchError::Shape { name, .. }) => name,
            other => panic!("expected Shape error, got {other:?}"),
        };
        assert_eq!(
            shape_name(evaluate(&input(&y, &f, short, &y, None), &p)),
            "fitted_vertices"
        );
        assert_eq!(
            shape_name(evaluate(&input(&y, &f, &y, &y, Some(short)), &p)),
            "ground_truth"
        );
        assert_eq!(
            shape_name(evaluate(&input(&y, &f, &y, &[], None), &p)),
            "target"
        );
        assert_eq!(
            shape_name(evaluate(&input(&[], &[], &[], &y, None), &p)),
            "template_vertices"
        );

        let bad = [[0.0, 0.0, 0.0], [1.0, f64::NAN, 0.0], [0.0, 1.0, 0.0]];
        match evaluate(&input(&y, &f, &bad, &y, None), &p) {
            Err(FoldMatchError::NonFinite { name, row, .. }) => {
                assert_eq!((name.as_str(), row), ("fitted_vertices", 1))
            }
            other => panic!("{other:?}"),
        }
        match evaluate(&input(&y, &[[0, 1, 3]], &y, &y, None), &p) {
            Err(FoldMatchError::FaceIndex {
                face,
                vertex,
                count,
                ..
            }) => assert_eq!((face, vertex, count), (0, 3, 3)),
            other => panic!("{other:?}"),
        }
        for bad in [
            MetricsParams { tau_s: -0.1, ..p },
            MetricsParams { tau_e: 0.0, ..p },
            MetricsParams {
                tau_e: f64::NAN,
                ..p
            },
            MetricsParams {
                degenerate_area_rel: f64::INFINITY,
                ..p
            },
        ] {
            assert!(matches!(
                evaluate(&input(&y, &f, &y, &y, None), &bad),
                Err(FoldMatchError::Parameter { .. })
            ));
        }
    }

    #[test]
    fn serializes_with_paper_names() {
        let (y, f) = single_triangle();
        let m = evaluate(
            &input(&y, &f, &y, &[[0.0, 0.0, 1.0]], None),
            &MetricsParams::default(),
        )
        .unwrap();
        let json = serde_json::to_value(&m).unwrap();
        for key in [
            "f_H",
            "f_S",
            "f_E",
            "f_F",
            "f_R",
            "f_lambda",
            "f_lambda_terms",
            "chamfer",
            "scan_to_fit_mean",
            "scan_to_fit_p95",
            "fit_to_scan_mean",
            "hausdorff_before",
            "hausdorff_after",
            "num_faces",
            "num_degenerate_faces",
        ] {
            assert!(json.get(key).is_some(), "missing {key}");
        }
        assert!(json["f_R"].is_null());
    }
}
