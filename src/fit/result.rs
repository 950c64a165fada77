//! What a fit returns and reports: the fitted vertices and wrinkle fields, per-iteration
//! figures, stage times and diagnostics.

use super::params::FitParams;
use crate::normalize::Frame;
use crate::quality::Quality;
use serde::{Deserialize, Serialize};

/// One iteration's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
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
    /// This progress of part `part` of `parts` that each count `total` iterations, as progress
    /// over `total` iterations in all: each part counts `1 / parts` (a part past the last, as
    /// a repeated garment cut's fit, reports the end).
    pub(super) fn of_parts(&self, part: usize, parts: usize, total: usize) -> Progress {
        Progress {
            iteration: (part * total + self.iteration)
                .div_ceil(parts.max(1))
                .min(total),
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

/// The figures of one connected component of the template (one garment of several).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ComponentFigures {
    /// Its lowest vertex index (components are listed in this order).
    pub first_vertex: usize,
    /// Its vertex count.
    pub vertices: usize,
    /// Mean distance from its fitted vertices to their nearest scan points ÷ the scan's
    /// bounding-box diagonal (the verdict's `fit_to_scan`, over this component).
    pub fit_to_scan: f64,
    /// Share of its vertices without scan support.
    pub unsupported_share: f64,
}

/// The [`ComponentFigures`] of every connected component with faces of the template
/// `(faces, m vertices)`, from the per-vertex `residuals` and `support` of a fit; empty when
/// there are fewer than two.
pub(super) fn component_figures(
    faces: &[[u32; 3]],
    residuals: &[f64],
    support: &[bool],
    diagonal: f64,
) -> Vec<ComponentFigures> {
    let m = residuals.len();
    let (label, count) = crate::mesh::connected_components(faces, m);
    let mut has_faces = vec![false; count];
    for f in faces {
        has_faces[label[f[0] as usize] as usize] = true;
    }
    if has_faces.iter().filter(|&&f| f).count() < 2 {
        return Vec::new();
    }
    let mut out: Vec<ComponentFigures> = (0..count)
        .map(|_| ComponentFigures {
            first_vertex: usize::MAX,
            ..ComponentFigures::default()
        })
        .collect();
    for v in 0..m {
        let c = &mut out[label[v] as usize];
        c.first_vertex = c.first_vertex.min(v);
        c.vertices += 1;
        c.fit_to_scan += residuals[v];
        c.unsupported_share += f64::from(u8::from(!support[v]));
    }
    for c in &mut out {
        let n = c.vertices.max(1) as f64;
        c.fit_to_scan /= n * if diagonal > 0.0 { diagonal } else { 1.0 };
        c.unsupported_share /= n;
    }
    out.into_iter()
        .zip(has_faces)
        .filter_map(|(c, f)| f.then_some(c))
        .collect()
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
    /// Whether the fit took its scan for one that holds more than the garment (skin, hair,
    /// another garment; docs/method.md "Scans of dressed people") and was set for the garment
    /// passes ([`garment_refit`](super::Schedule::garment_refit)), whether or not they ran.
    #[serde(default)]
    pub dressed: bool,
    /// Per connected component of the template, when it has several (garments, each fitted on
    /// its own; docs/dressed.md "Several garments at once"): its figures against the scan;
    /// empty for a template of one piece.
    #[serde(default)]
    pub components: Vec<ComponentFigures>,
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
    /// How the isometric refinement ended the fit: `"held"` (the hold on every edge),
    /// `"freed"` (a fit the schedule left unstretched, held only where the scan has no points
    /// for it: [`unstretched_refinement`](super::Schedule::unstretched_refinement)),
    /// `"held_after_flips"` (freed, then run again with the hold everywhere because the freed
    /// run turned over more than [`UNSTRETCHED_FLIPS`](super::UNSTRETCHED_FLIPS) of the
    /// faces) or `""` (no refinement: off, or the do-no-harm rule kept the start). Several
    /// garments: theirs joined by `" + "`.
    #[serde(default)]
    pub refinement: String,
    /// How many template boundary vertices the rim matching laid onto the mesh target's
    /// boundary in the fit's last fine-phase iterations
    /// ([`rim_weight`](super::Schedule::rim_weight), docs/method.md "Rim matching"); 0 when
    /// it did not run (a point-cloud target, off) or matched no loop.
    #[serde(default)]
    pub rim_matched: usize,
    /// How many axes the template turns onto itself about (a tube's own axis: 1), which the
    /// rigid phase does not turn it about (docs/method.md "Rigid phase"): the fit's turn about
    /// such an axis is the one it was placed with, which no scan can tell; landmarks settle
    /// it. 0: none, or no rigid phase.
    #[serde(default)]
    pub free_axes: usize,
    /// The global pre-alignment ([`FitParams::prealign`](super::FitParams::prealign) `"rigid"`
    /// or `"similarity"`, docs/method.md "Global pre-alignment"); `None` when it did not run
    /// (another mode, landmarks, a template of several garments).
    pub prealign: Option<PrealignFigures>,
    /// The coherent candidate ([`Schedule::coherent_gate`](super::Schedule::coherent_gate),
    /// docs/method.md "Coherent candidate"), when it ran.
    #[serde(default)]
    pub coherent: Option<CoherentFigures>,
}

/// What the coherent candidate found: both fits' directed distances (each ÷ the scan's
/// bounding-box diagonal, as the verdict's), and which was kept.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CoherentFigures {
    /// The first fit's `edge_distortion`, which reached the gate.
    pub edge_distortion: f64,
    /// The first fit's, then the candidate's, fit → scan distance.
    pub fit_to_scan: [f64; 2],
    /// The first fit's, then the candidate's, scan → fit distance.
    pub scan_to_fit: [f64; 2],
    /// Whether the candidate was kept (closer to the scan in both directions).
    pub kept: bool,
    /// The Coherent Point Drift's EM iterations.
    pub cpd_iterations: usize,
    /// Seconds the candidate took (its Coherent Point Drift and its fit).
    pub seconds: f64,
}

/// What the global pre-alignment found ([`crate::prealign::align`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PrealignFigures {
    /// Whether the placements were searched (false: the template as given lay on a scan larger
    /// than the garment, a dressed body, and was kept without a search).
    pub searched: bool,
    /// Whether the template was moved from where it was given.
    pub moved: bool,
    /// The trimmed two-sided distance of the placement as given (scan units).
    pub identity_score: f64,
    /// The same of the placement the fit started from.
    pub score: f64,
    /// The lowest of every rigid placement the search refined (the placement as given's when
    /// nothing was searched): the quality verdict's pose-gap reference.
    #[serde(default)]
    pub best_score: f64,
    /// The placements a fit starts from (template → scan; the second when two readings were
    /// fitted): the quality verdict's pose-turn reference.
    #[serde(skip)]
    pub(crate) readings_placed: [Option<crate::prealign::Similarity>; 2],
    /// The distinct orientations that fit the scan within 10 % of the best: above 1, the scan
    /// cannot tell the template's symmetric readings apart and the least turned was taken (a
    /// garment may be placed back to front: landmarks settle it); 0 when nothing was searched.
    pub readings: usize,
    /// 2 when two of those readings were other shapes of the template (not its symmetric
    /// images) and the fit was made from both, the one closer to the scan kept; else 1 (0 when
    /// nothing was searched).
    #[serde(default)]
    pub fitted_readings: usize,
    /// With `prealign="similarity"`: the median stretch of the edges of a first fit from the
    /// similarity's placement, by which the template was scaled before the fit that was kept
    /// when it lay more than 3 % from 1 (docs/method.md "Global pre-alignment"); 1 otherwise.
    #[serde(default = "one")]
    pub scale_stretch: f64,
    /// When two readings were fitted (`fitted_readings` 2): how much farther from the scan the
    /// fit from the other reading ended than the fit kept, as a share of the kept fit's distance
    /// (each fit's mean fit → scan plus scan → fit distance, every vertex counted). Below
    /// [`READING_MARGIN`](crate::fit::READING_MARGIN), including below 0 (the other reading lay
    /// closer, by too little to replace the least turned one), the scan does not tell the two
    /// apart: a nearly symmetric garment may be back to front, and landmarks settle it
    /// (docs/method.md "Global pre-alignment"). `None` when one reading was fitted.
    #[serde(default)]
    pub reading_gap: Option<f64>,
}

fn one() -> f64 {
    1.0
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
    /// The fit's own segmentation of a scan that holds more than the garment (a dressed body;
    /// docs/dressed.md "What the fit took for the garment"): the indices, into the target as
    /// given and increasing, of the scan points the returned fit was fitted to — the garment
    /// refit's or the garment cut's points, over every garment of a template of several. Empty
    /// when the fit ran on the whole scan (a garment-only scan, or no refit).
    pub garment_points: Vec<u32>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{fit_simple, FitParams};
    use crate::synthetic::grid_sheet;

    #[test]
    fn each_component_has_its_own_figures() {
        // Two triangles (vertices 0–2 and 3–5) and a lone vertex 6 (no faces: not listed).
        let faces = [[0, 1, 2], [3, 4, 5]];
        let residuals = [1.0, 2.0, 3.0, 10.0, 10.0, 40.0, 99.0];
        let support = [true, true, false, true, false, false, true];
        let c = component_figures(&faces, &residuals, &support, 2.0);
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].first_vertex, c[0].vertices), (0, 3));
        assert_eq!((c[1].first_vertex, c[1].vertices), (3, 3));
        assert!(
            (c[0].fit_to_scan - 1.0).abs() < 1e-12,
            "{}",
            c[0].fit_to_scan
        );
        assert!((c[1].fit_to_scan - 10.0).abs() < 1e-12);
        assert!((c[0].unsupported_share - 1.0 / 3.0).abs() < 1e-12);
        assert!((c[1].unsupported_share - 2.0 / 3.0).abs() < 1e-12);
        // One piece: nothing per component.
        assert!(component_figures(&faces[..1], &residuals[..3], &support[..3], 2.0).is_empty());
    }

    #[test]
    fn a_fit_of_two_garments_reports_each() {
        // Two sheets side by side; the scan is the left one only, lifted a little: the right
        // sheet ends far from every scan point and unsupported.
        let (sheet, f) = grid_sheet(9, 9, 1.0, 1.0);
        let n = sheet.len() as u32;
        let mut v: Vec<[f64; 3]> = sheet.iter().map(|p| [p[0] - 0.8, p[1], 0.0]).collect();
        v.extend(sheet.iter().map(|p| [p[0] + 0.8, p[1], 0.0]));
        let mut faces = f.clone();
        faces.extend(f.iter().map(|t| t.map(|i| i + n)));
        let (dense, _) = grid_sheet(21, 21, 1.0, 1.0);
        let scan: Vec<[f64; 3]> = dense.iter().map(|p| [p[0] - 0.8, p[1], 0.02]).collect();
        let params = FitParams {
            iterations: 20,
            ..FitParams::default()
        };
        let r = fit_simple(&v, &faces, &scan, None, &params).unwrap();
        let c = &r.diagnostics.components;
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].vertices, c[1].vertices), (81, 81));
        assert!(c[0].fit_to_scan < 0.05 && c[1].fit_to_scan > 0.2, "{c:?}");
        assert!(
            c[0].unsupported_share < 0.1 && c[1].unsupported_share > 0.9,
            "{c:?}"
        );
        // A template of one piece reports none.
        let one = fit_simple(&sheet, &f, &scan, None, &params).unwrap();
        assert!(one.diagnostics.components.is_empty());
    }
}
