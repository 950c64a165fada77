//! Does a fit look right? Figures a user has without ground truth, and a verdict from them.
//!
//! A fit can wrap the scan closely and still be wrong: started back to front, the template
//! is pulled through itself onto the scan's nearest surface and the scan→fit distance stays
//! small (docs/method.md "Quality verdict"). What gives such a fit away is what it did to
//! the template and what it left uncovered, so [`assess`] measures both sides:
//!
//! | figure | definition |
//! |---|---|
//! | [`Quality::fit_to_scan`] | mean over fitted vertices of the distance to the nearest scan point, ÷ the scan's bounding-box diagonal (a fit's own verdict leaves out the vertices it carried without support: docs/method.md "Partial scans") |
//! | [`Quality::scan_to_fit`] | mean over scan points of the distance to the fitted surface (the faces around the nearest fitted vertex), ÷ the same diagonal |
//! | [`Quality::asymmetry`] | `(fit_to_scan − scan_to_fit) / (fit_to_scan + scan_to_fit + r/D)`, in `(−1, 1)`, `r` the support radius and `D` the diagonal (distances below the support radius are sampling, not disagreement): positive when template parts hang off the scan, negative when scan parts are left uncovered |
//! | [`Quality::unsupported_share`] | share of template vertices without scan support (below) |
//! | [`Quality::carried_share`] | share of template vertices the fit carried without support (docs/method.md "Partial scans"): counted in `unsupported_share`, left out of the verdict's test of it |
//! | [`Quality::flipped_share`] | share of template faces whose fitted normal points against the template normal carried by the local rotation of the face's 2-ring (template → fit, Kabsch) |
//! | [`Quality::collapsed_share`] | share of template faces whose area fell below `τ_S` (0.02, [`crate::metrics::DEFAULT_TAU_S`]) of the template's |
//! | [`Quality::edge_distortion`] | 95th percentile over the template's edges of `max(ℓ̂/ℓ, ℓ/ℓ̂)`, fitted over template length, after dividing out the fit's median edge ratio (so a uniform scale, e.g. millimetres against metres, is not a distortion) |
//! | [`Quality::pose_gap`] | the trimmed two-sided distance to the scan of the rigid placement of the template that trimmed ICP reaches from the fit's rigid pose (Kabsch, template → fit, at the fit's median edge ratio), over that of the best rigid placement the pre-alignment's search finds, ≥ 1 (`pose`) |
//! | [`Quality::pose_turn`] | the angle in degrees from the fit's rigid pose to the placement the pre-alignment would start a fit from (the nearer of its two readings when it fits both), when the pose gap is at least 1.02 ([`TURN_GAIN`]), else 0 (`pose`) |
//!
//! **Support.** A template vertex `v` has scan support when its nearest scan point `x` lies
//! within the support radius `r` of the fitted vertex and `x`'s own nearest fitted vertex `u`
//! is `v` or one of its template neighbours (`‖Y_u − Y_v‖ ≤ 3` median template edges): the
//! scan point is there and is explained by this part of the template, not by a layer that
//! was pulled onto it. `r = 2 · max(s, ℓ̂)`, `s` the scan spacing (median distance from a
//! scan point to its nearest other scan point) and `ℓ̂` the fit's median edge length. A
//! vertex the fit carried without support (docs/method.md "Partial scans") has none.
//!
//! The faces are the template's, degenerate ones (zero template area) left out of the face
//! shares. The verdict is `suspicious` when any figure passes its threshold
//! ([`VerdictThresholds`], calibrated by `bench/verdict.py` on harness cases whose fit is
//! right and wrong, docs/method.md "Quality verdict"), with every such figure named.
#![warn(missing_docs)]

mod geometry;
mod pose;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

use crate::error::{FoldMatchError, Result};
use crate::knn::PointIndex;
use crate::mesh::{validate_faces, validate_points};
use crate::metrics::{bbox_diagonal, cross_of, percentile_linear, EdgeLengths, DEFAULT_TAU_S};
use crate::rings::{adjacency, n_rings_of, Neighborhoods};

pub use geometry::{closest_barycentric, point_triangle_distance};
pub use pose::{fit_pose, pose_figures, PoseFigures, PoseReference, TURN_GAIN};

/// The support radius in units of `max(scan spacing, fitted median edge)`.
pub const SUPPORT_RADIUS_FACTOR: f64 = 2.0;
/// How far (in median template edges) the scan point's nearest fitted vertex may lie from the
/// vertex on the template for the vertex to count as supported.
pub const SUPPORT_NEIGHBOUR_EDGES: f64 = 3.0;
/// A fit's pre-alignment's best rigid distance serves as the pose gap's reference while the
/// fit's median edge ratio lies within this of 1 (the search ran on the template's own size).
const REFERENCE_SCALE_TOLERANCE: f64 = 0.1;
/// Scan points sampled (evenly by index) for the scan spacing.
const SPACING_SAMPLE: usize = 4096;

/// The thresholds of the verdict: a fit is `suspicious` when a figure exceeds its threshold
/// (for `asymmetry`, when its absolute value does). The defaults come from `bench/verdict.py`
/// (docs/method.md "Quality verdict"); `f64::INFINITY` turns a figure's test off.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VerdictThresholds {
    /// Most [`Quality::fit_to_scan`].
    pub fit_to_scan: f64,
    /// Most [`Quality::scan_to_fit`].
    pub scan_to_fit: f64,
    /// Most `|`[`Quality::asymmetry`]`|`.
    pub asymmetry: f64,
    /// Most [`Quality::unsupported_share`].
    pub unsupported_share: f64,
    /// Most [`Quality::flipped_share`].
    pub flipped_share: f64,
    /// Most [`Quality::collapsed_share`].
    pub collapsed_share: f64,
    /// Most [`Quality::edge_distortion`].
    pub edge_distortion: f64,
    /// Most [`Quality::pose_gap`].
    pub pose_gap: f64,
    /// Most [`Quality::pose_turn`] (degrees).
    pub pose_turn: f64,
}

impl Default for VerdictThresholds {
    /// `bench/verdict.py --calibrate` on its tuning half (real and small harness cases under
    /// placed, turned, z-up, stopped-early, front-half and other-garment fits): each figure's
    /// largest value among the right fits × 1.25 (the pose gap: 1 + 1.25 × its excess over 1),
    /// at least 0.5 % collapsed and 1.5 % flipped faces, at most 40 % unsupported vertices,
    /// rounded (docs/method.md "Quality verdict").
    fn default() -> Self {
        Self {
            fit_to_scan: 0.027,
            scan_to_fit: 0.17,
            asymmetry: 0.83,
            unsupported_share: 0.4,
            flipped_share: 0.022,
            collapsed_share: 0.005,
            edge_distortion: 1.77,
            pose_gap: 1.38,
            pose_turn: 45.0,
        }
    }
}

impl VerdictThresholds {
    /// Every threshold must be positive (or `+∞`) and not NaN ([`FoldMatchError::Parameter`]).
    pub fn validate(&self) -> Result<()> {
        for (name, value) in self.named() {
            if value.is_nan() || value <= 0.0 {
                return Err(FoldMatchError::parameter(
                    name,
                    value,
                    "must be > 0 (+inf turns the test off)",
                ));
            }
        }
        Ok(())
    }

    fn named(&self) -> [(&'static str, f64); 9] {
        [
            ("fit_to_scan", self.fit_to_scan),
            ("scan_to_fit", self.scan_to_fit),
            ("asymmetry", self.asymmetry),
            ("unsupported_share", self.unsupported_share),
            ("flipped_share", self.flipped_share),
            ("collapsed_share", self.collapsed_share),
            ("edge_distortion", self.edge_distortion),
            ("pose_gap", self.pose_gap),
            ("pose_turn", self.pose_turn),
        ]
    }
}

/// The verdict on a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// No figure passed its threshold.
    Ok,
    /// At least one figure passed its threshold ([`Quality::reasons`]).
    Suspicious,
}

impl Verdict {
    /// `"ok"` or `"suspicious"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Ok => "ok",
            Verdict::Suspicious => "suspicious",
        }
    }
}

/// The figures of one fit and the verdict (see the module docs for the definitions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Quality {
    /// `ok` or `suspicious`.
    pub verdict: Verdict,
    /// One sentence per figure past its threshold (empty when `ok`).
    pub reasons: Vec<String>,
    /// Mean fitted-vertex → scan distance ÷ the scan's bounding-box diagonal.
    pub fit_to_scan: f64,
    /// Mean scan → fitted-surface distance ÷ the scan's bounding-box diagonal.
    pub scan_to_fit: f64,
    /// `(fit_to_scan − scan_to_fit) / (fit_to_scan + scan_to_fit + support_radius/diagonal)`.
    pub asymmetry: f64,
    /// Share of template vertices without scan support.
    pub unsupported_share: f64,
    /// Share of template vertices the fit carried without scan support (the unseen side of a
    /// one-sided scan: docs/method.md "Partial scans"); counted in `unsupported_share`, but
    /// not held against the fit by the verdict (0 for [`assess`]).
    #[serde(default)]
    pub carried_share: f64,
    /// Share of evaluated faces flipped against the locally rotated template.
    pub flipped_share: f64,
    /// Share of evaluated faces whose area fell below τ_S of the template's.
    pub collapsed_share: f64,
    /// 95th percentile of the edge-length distortion `max(ℓ̂/ℓ, ℓ/ℓ̂)` (median ratio divided
    /// out); 1 for a similarity of the template.
    pub edge_distortion: f64,
    /// The trimmed two-sided distance to the scan of the best rigid placement of the template
    /// near the fit's rigid pose (its ICP basin) over that of the best rigid placement found
    /// anywhere (≥ 1; 1 when none is better): large when the fit kept a wrong orientation and
    /// wrapped the scan regardless.
    #[serde(default = "one")]
    pub pose_gap: f64,
    /// The angle in degrees from the fit's rigid pose to the placement the pre-alignment would
    /// start a fit from (the nearer of its two readings when it fits both), when the pose gap
    /// is at least 1 + [`TURN_GAIN`], else 0: large when the fit kept an orientation that the
    /// search turns (a garment wrapped back to front, whose pose gap stays small because the
    /// garment is nearly its own image turned).
    #[serde(default)]
    pub pose_turn: f64,
    /// The support radius used, in the scan's units.
    pub support_radius: f64,
    /// The scan's bounding-box diagonal (the distances' normalizer), in the scan's units.
    pub scan_diagonal: f64,
    /// The thresholds the verdict was given under.
    pub thresholds: VerdictThresholds,
}

/// [`Quality`] with the per-vertex figures behind it.
#[derive(Debug, Clone, PartialEq)]
pub struct Assessment {
    /// The summary and verdict.
    pub quality: Quality,
    /// Per template vertex, the index of the scan point it ends nearest to.
    pub correspondences: Vec<u32>,
    /// Per template vertex, the distance from the fitted vertex to that scan point (scan
    /// units).
    pub residuals: Vec<f64>,
    /// Per template vertex, whether it has scan support.
    pub support: Vec<bool>,
}

/// The template, its fit and the scan, all in the scan's frame.
#[derive(Debug, Clone, Copy)]
pub struct AssessInput<'a> {
    /// Template vertices `Y` as given (M rows; any frame: only lengths and the local
    /// rotations to the fit are read from them).
    pub template_vertices: &'a [[f64; 3]],
    /// Template faces (may be empty: then no face or edge figure, support without the
    /// neighbour test).
    pub faces: &'a [[u32; 3]],
    /// Fitted vertices `Ŷ` (M rows).
    pub fitted_vertices: &'a [[f64; 3]],
    /// Scan points `X` (N rows, non-empty).
    pub scan: &'a [[f64; 3]],
}

/// Measures a fit and gives the verdict (module docs).
///
/// Errors: [`FoldMatchError::Shape`] for an empty template or scan or a row-count mismatch,
/// [`FoldMatchError::NonFinite`], [`FoldMatchError::FaceIndex`], and
/// [`FoldMatchError::Parameter`] for invalid thresholds.
pub fn assess(input: &AssessInput<'_>, thresholds: &VerdictThresholds) -> Result<Assessment> {
    assess_with(input, thresholds, None, None)
}

/// What a fit already holds of the template's mesh figures, so that its verdict does not build
/// them again: the template's edges ([`EdgeLengths::new`] of the template vertices and faces
/// assessed) and, when it has them, every vertex's 2-ring (the order of [`n_rings_of`]).
#[derive(Clone, Copy)]
pub(crate) struct KnownMesh<'a> {
    pub two_rings: Option<&'a Neighborhoods>,
    pub edges: &'a EdgeLengths,
    /// Each scan point's nearest fitted vertex, when the fit found them already.
    pub scan_nearest: Option<&'a [u32]>,
    /// How the pose figures are found ([`PoseSource`]).
    pub pose: PoseSource<'a>,
    /// The vertices the fit carried without scan support (docs/method.md "Partial scans"),
    /// when it carried any: unsupported by the fit's own account, and left out of
    /// [`Quality::fit_to_scan`] (they were never pulled towards the scan).
    pub carried: Option<&'a [bool]>,
}

/// Where [`assess_with`]'s pose figures come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum PoseSource<'a> {
    /// A search of its own ([`pose_figures`] without a reference).
    Search,
    /// What the fit's own pre-alignment found on the assessed points ([`pose_figures`]'
    /// `reference`).
    Reference(&'a PoseReference),
    /// Not now: 1 until the caller sets it (a pass of a fit that goes on, whose verdict is
    /// replaced by the last pass's).
    Deferred,
}

/// [`assess`], with the mesh figures a fit already holds.
/// `diagonal`: the unit of the relative figures when the scan assessed is part of a larger
/// one (the whole scan's bounding-box diagonal); `None`: the assessed scan's own.
pub(crate) fn assess_with(
    input: &AssessInput<'_>,
    thresholds: &VerdictThresholds,
    known: Option<KnownMesh<'_>>,
    diagonal: Option<f64>,
) -> Result<Assessment> {
    thresholds.validate()?;
    let AssessInput {
        template_vertices: y,
        faces,
        fitted_vertices: fit,
        scan,
    } = *input;
    validate_points("template_vertices", y)?;
    validate_points("fitted_vertices", fit)?;
    validate_points("scan", scan)?;
    if fit.len() != y.len() {
        return Err(FoldMatchError::Shape {
            name: "fitted_vertices".into(),
            reason: format!("has {} rows, the template {}", fit.len(), y.len()),
        });
    }
    validate_faces("template_faces", faces, y.len())?;

    let known_nearest = known
        .and_then(|k| k.scan_nearest)
        .filter(|n| n.len() == scan.len());
    // Each scan point's nearest fitted vertex (unless known), beside the scan's own index.
    let (scan_index, found) = rayon::join(
        || PointIndex::new(scan),
        || match known_nearest {
            Some(_) => Vec::new(),
            None => {
                let fit_index = PointIndex::new(fit);
                scan.par_iter()
                    .map(|x| fit_index.nearest_one(x).0)
                    .collect::<Vec<u32>>()
            }
        },
    );
    let scan_nearest: &[u32] = known_nearest.unwrap_or(&found);
    // Each fitted vertex's nearest scan point: the correspondences and residuals.
    let (correspondences, residuals): (Vec<u32>, Vec<f64>) = fit
        .par_iter()
        .map(|p| {
            let (j, d2) = scan_index.nearest_one(p);
            (j, d2.sqrt())
        })
        .unzip();
    // Each scan point's distance to the faces around its nearest fitted vertex.
    let incident = vertex_faces(faces, y.len());

    let scan_distances: Vec<f64> = scan
        .par_iter()
        .zip(scan_nearest)
        .map(|(x, &u)| {
            let vertex = crate::math::dist2(x, &fit[u as usize]).sqrt();
            incident
                .of(u as usize)
                .iter()
                .map(|&f| {
                    let c = faces[f as usize].map(|i| fit[i as usize]);
                    point_triangle_distance(x, &c)
                })
                .fold(vertex, f64::min)
        })
        .collect();

    let diagonal = diagonal.unwrap_or_else(|| bbox_diagonal(scan));
    let relative = |d: f64| if diagonal > 0.0 { d / diagonal } else { d };
    let carried = known
        .and_then(|k| k.carried)
        .filter(|c| c.len() == y.len() && c.iter().any(|&b| !b));
    let fit_to_scan = relative(match carried {
        Some(c) => mean_where_not(&residuals, c),
        None => mean(&residuals),
    });
    let scan_to_fit = relative(mean(&scan_distances));
    let spacing = scan_spacing(scan, &scan_index);
    let built_edges;
    let edges = match known {
        Some(k) => k.edges,
        None => {
            built_edges = EdgeLengths::new(y, faces);
            &built_edges
        }
    };
    let fitted_edge = median_edge(edges, fit);
    let support_radius = SUPPORT_RADIUS_FACTOR * spacing.max(fitted_edge);
    // Distances below the support radius are sampling, not disagreement.
    let asymmetry =
        (fit_to_scan - scan_to_fit) / (fit_to_scan + scan_to_fit + relative(support_radius));

    let ratios = edges.ratios(fit);
    let rest_edge = median_edge(edges, y);
    let edge_distortion = distortion_p95(&ratios);
    let fit_scale = fit_scale(&ratios);
    let source = known.map_or(PoseSource::Search, |k| k.pose);
    let pose = match source {
        PoseSource::Deferred => PoseFigures::NONE,
        // A reference measured on the template at its own size holds for a fit near that size.
        PoseSource::Reference(r) if (fit_scale - 1.0).abs() <= REFERENCE_SCALE_TOLERANCE => {
            pose_figures(y, fit, scan, fit_scale, Some(r))
        }
        _ => pose_figures(y, fit, scan, fit_scale, None),
    };

    let neighbour = SUPPORT_NEIGHBOUR_EDGES * rest_edge;
    let support: Vec<bool> = (0..y.len())
        .into_par_iter()
        .map(|v| {
            if residuals[v] > support_radius || carried.is_some_and(|c| c[v]) {
                return false;
            }
            let u = scan_nearest[correspondences[v] as usize] as usize;
            faces.is_empty() || crate::math::dist2(&y[u], &y[v]).sqrt() <= neighbour
        })
        .collect();
    let unsupported_share = support.iter().filter(|&&s| !s).count() as f64 / support.len() as f64;

    let faces_figures = face_shares(y, fit, faces, known.and_then(|k| k.two_rings));
    let quality = Quality {
        verdict: Verdict::Ok,
        reasons: Vec::new(),
        fit_to_scan,
        scan_to_fit,
        asymmetry,
        unsupported_share,
        carried_share: carried.map_or(0.0, |c| {
            c.iter().filter(|&&b| b).count() as f64 / c.len().max(1) as f64
        }),
        flipped_share: faces_figures.flipped,
        collapsed_share: faces_figures.collapsed,
        edge_distortion,
        pose_gap: pose.gap,
        pose_turn: pose.turn,
        support_radius,
        scan_diagonal: diagonal,
        thresholds: *thresholds,
    };
    Ok(Assessment {
        quality: judged(quality, thresholds),
        correspondences,
        residuals,
        support,
    })
}

/// [`assess`] against the scan points `points` (indices into `scan`; `None`: every point),
/// with the correspondences indexing `scan` itself.
pub fn assess_points(
    template_vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    fitted_vertices: &[[f64; 3]],
    scan: &[[f64; 3]],
    points: Option<&[usize]>,
    thresholds: &VerdictThresholds,
) -> Result<Assessment> {
    let input = AssessInput {
        template_vertices,
        faces,
        fitted_vertices,
        scan,
    };
    assess_points_with(&input, points, thresholds, None)
}

/// [`assess_points`], with the mesh figures a fit already holds.
pub(crate) fn assess_points_with(
    whole: &AssessInput<'_>,
    points: Option<&[usize]>,
    thresholds: &VerdictThresholds,
    known: Option<KnownMesh<'_>>,
) -> Result<Assessment> {
    let scan_points = chosen_points(whole.scan, points);
    let input = AssessInput {
        scan: &scan_points,
        ..*whole
    };
    // Figures relative to the diagonal of the scan as given, not of the points chosen.
    let diagonal = points.map(|_| bbox_diagonal(whole.scan));
    let mut a = assess_with(&input, thresholds, known, diagonal)?;
    if let Some(p) = points {
        for c in &mut a.correspondences {
            *c = p[*c as usize] as u32;
        }
    }
    Ok(a)
}

/// `quality` with the pose figures of `fitted` (the template `template`'s fit) against the scan
/// points `points` of `scan` (`None`: every point) found by a search, and its verdict again:
/// the pose figures that [`PoseSource::Deferred`] left out, once the fit is final.
pub(crate) fn with_pose_figures(
    quality: Quality,
    template: &[[f64; 3]],
    edges: &EdgeLengths,
    fitted: &[[f64; 3]],
    scan: &[[f64; 3]],
    points: Option<&[usize]>,
) -> Quality {
    let scan = chosen_points(scan, points);
    let scale = fit_scale(&edges.ratios(fitted));
    let thresholds = quality.thresholds;
    let pose = pose_figures(template, fitted, &scan, scale, None);
    judged(
        Quality {
            pose_gap: pose.gap,
            pose_turn: pose.turn,
            ..quality
        },
        &thresholds,
    )
}

/// The points `points` of `scan` (`None`: all of them, borrowed).
fn chosen_points<'a>(scan: &'a [[f64; 3]], points: Option<&[usize]>) -> Cow<'a, [[f64; 3]]> {
    match points {
        Some(p) => Cow::Owned(p.iter().map(|&j| scan[j]).collect()),
        None => Cow::Borrowed(scan),
    }
}

/// A fit's scale: the median of its edge ratios to the template (1 without edges).
fn fit_scale(ratios: &[f64]) -> f64 {
    if ratios.is_empty() {
        1.0
    } else {
        percentile_linear(ratios, 50.0)
    }
}

/// `quality` with its verdict and reasons under `thresholds`.
pub fn judged(mut quality: Quality, thresholds: &VerdictThresholds) -> Quality {
    let q = &quality;
    let figures = [
        ("fit→scan distance", q.fit_to_scan, "of the scan diagonal"),
        ("scan→fit distance", q.scan_to_fit, "of the scan diagonal"),
        ("|asymmetry|", q.asymmetry.abs(), "of the two distances"),
        if q.carried_share > 0.0 {
            (
                "share of unsupported vertices, less those carried",
                q.unsupported_share - q.carried_share,
                "",
            )
        } else {
            ("share of unsupported vertices", q.unsupported_share, "")
        },
        ("share of flipped faces", q.flipped_share, ""),
        ("share of collapsed faces", q.collapsed_share, ""),
        ("edge-length distortion (95th pct)", q.edge_distortion, ""),
        (
            "pose gap (a rigid placement elsewhere lies closer to the scan)",
            q.pose_gap,
            "",
        ),
        (
            "pose turn (the pre-alignment would start the fit turned from where it lies)",
            q.pose_turn,
            "degrees",
        ),
    ];
    let reasons: Vec<String> = figures
        .iter()
        .zip(thresholds.named())
        .filter(|((_, value, _), (_, limit))| value > limit)
        .map(|((label, value, unit), (_, limit))| {
            let unit = if unit.is_empty() {
                String::new()
            } else {
                format!(" {unit}")
            };
            format!("{label} {value:.4}{unit} exceeds {limit:.4}")
        })
        .collect();
    quality.thresholds = *thresholds;
    quality.verdict = if reasons.is_empty() {
        Verdict::Ok
    } else {
        Verdict::Suspicious
    };
    quality.reasons = reasons;
    quality
}

/// The faces incident to each vertex (CSR; degenerate faces included: they still bound the
/// surface a scan point may be nearest to).
fn vertex_faces(faces: &[[u32; 3]], m: usize) -> Neighborhoods {
    // A face is listed once per distinct corner (a corner repeated in a degenerate face once).
    let corners = |tri: &[u32; 3]| {
        let [a, b, c] = *tri;
        [
            Some(a),
            (b != a).then_some(b),
            (c != a && c != b).then_some(c),
        ]
    };
    Neighborhoods::from_pairs(m, || {
        faces.iter().enumerate().flat_map(move |(f, tri)| {
            corners(tri)
                .into_iter()
                .flatten()
                .map(move |v| (v, f as u32))
        })
    })
}

fn one() -> f64 {
    1.0
}

/// The mean of `v` over the entries whose `skip` is false (at least one is).
fn mean_where_not(v: &[f64], skip: &[bool]) -> f64 {
    let (sum, n) = v
        .iter()
        .zip(skip)
        .filter(|(_, &s)| !s)
        .fold((0.0, 0usize), |(sum, n), (&x, _)| (sum + x, n + 1));
    sum / n as f64
}

/// Arithmetic mean in index order (0 when empty).
fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// The median length of the template's edges on `points` (0 without edges).
fn median_edge(edges: &EdgeLengths, points: &[[f64; 3]]) -> f64 {
    let lengths: Vec<f64> = edges
        .edges()
        .iter()
        .map(|&(a, b)| crate::math::dist2(&points[a as usize], &points[b as usize]).sqrt())
        .collect();
    if lengths.is_empty() {
        0.0
    } else {
        percentile_linear(&lengths, 50.0)
    }
}

/// The 95th percentile of `max(r/m, m/r)` over the edge ratios `r`, `m` their median (1 without
/// edges; a collapsed edge counts as the ratio 1e-12).
fn distortion_p95(ratios: &[f64]) -> f64 {
    if ratios.is_empty() {
        return 1.0;
    }
    let median = percentile_linear(ratios, 50.0).max(1e-12);
    let distortion: Vec<f64> = ratios
        .iter()
        .map(|&r| {
            let r = (r / median).max(1e-12);
            r.max(1.0 / r)
        })
        .collect();
    percentile_linear(&distortion, 95.0)
}

/// The median distance from a scan point to its nearest other scan point, over an even sample
/// of at most [`SPACING_SAMPLE`] points (0 for a single point).
fn scan_spacing(scan: &[[f64; 3]], index: &PointIndex) -> f64 {
    if scan.len() < 2 {
        return 0.0;
    }
    let step = scan.len().div_ceil(SPACING_SAMPLE);
    let d: Vec<f64> = (0..scan.len())
        .step_by(step)
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&j| {
            let mut idx = [0u32; 2];
            let mut d2 = [0.0; 2];
            index.nearest_into(&scan[j], &mut idx, &mut d2);
            d2[1].sqrt()
        })
        .collect();
    percentile_linear(&d, 50.0)
}

/// The face shares of the verdict.
struct FaceShares {
    flipped: f64,
    collapsed: f64,
}

/// Flipped and collapsed shares of the non-degenerate faces (0 and 0 when there are none).
/// A face is flipped when its fitted normal points against its template normal rotated by
/// the Kabsch rotation of the 2-ring of its first corner (template → fit): a fit may turn
/// the whole garment or a sleeve, which is no flip.
fn face_shares(
    y: &[[f64; 3]],
    fit: &[[f64; 3]],
    faces: &[[u32; 3]],
    two_rings: Option<&Neighborhoods>,
) -> FaceShares {
    if faces.is_empty() {
        return FaceShares {
            flipped: 0.0,
            collapsed: 0.0,
        };
    }
    let built;
    let rings = match two_rings {
        Some(r) => r,
        None => {
            built = n_rings_of(&adjacency(faces, y.len()), 2);
            &built
        }
    };
    let diag = bbox_diagonal(y);
    let min_area = crate::metrics::DEFAULT_DEGENERATE_AREA_REL * diag * diag;
    let evaluated_face = |f: &[u32; 3]| 0.5 * crate::math::vec3(&cross_of(y, f)).norm() > min_area;
    // The rotation of each face's first corner's 2-ring, once per corner (faces share corners).
    let mut is_first = vec![false; y.len()];
    for f in faces.iter().filter(|f| evaluated_face(f)) {
        is_first[f[0] as usize] = true;
    }
    let rotations: Vec<crate::math::Mat3> = (0..y.len())
        .into_par_iter()
        .map(|v| {
            if !is_first[v] {
                return crate::math::Mat3::identity();
            }
            let ring = rings.of(v);
            let (c_old, c_new) = crate::rotation::ring_centroids(ring, y, fit);
            crate::rotation::kabsch(ring, y, fit, &c_old, &c_new, false)
        })
        .collect();
    let (evaluated, flipped, collapsed) = faces
        .par_iter()
        .map(|f| {
            let n = crate::math::vec3(&cross_of(y, f));
            let area = 0.5 * n.norm();
            if area <= min_area {
                return (0usize, 0usize, 0usize);
            }
            let n_fit = crate::math::vec3(&cross_of(fit, f));
            let r = rotations[f[0] as usize];
            let flip = (r * n).dot(&n_fit) < 0.0;
            let collapse = 0.5 * n_fit.norm() / area < DEFAULT_TAU_S;
            (1, usize::from(flip), usize::from(collapse))
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    let share = |k: usize| {
        if evaluated == 0 {
            0.0
        } else {
            k as f64 / evaluated as f64
        }
    };
    FaceShares {
        flipped: share(flipped),
        collapsed: share(collapsed),
    }
}

#[cfg(test)]
mod tests;
