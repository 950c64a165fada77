//! Tracking a 4D sequence (docs/method.md "Tracking"): the frames of a sequence fitted in
//! order, each warm-started from the previous fit for position but anchored to the template's
//! rest shape for its metric, so that the errors of one frame do not become the next frame's
//! template.
//!
//! Per frame t (scan X_t), with Y⁰ the template and Y_{t−1}, Y_{t−2} the earlier fits:
//! 1. the start: `Y_{t−1} + λ (Y_{t−1} − Y_{t−2})`, the previous fit moved on by λ times its
//!    last motion (a constant-velocity prediction, λ = [`TrackParams::prediction`]); the
//!    template itself at t = 0;
//! 2. [`crate::fit::fit_anchored`] from that start onto X_t, with Y⁰ as the rest shape of the
//!    rest-shape rigidity and of the quality verdict;
//! 3. the frame's figures ([`FrameFigures`]): the verdict's distances and edge distortion
//!    against the template, and the jumps against the first frame's; a frame past a jump
//!    threshold is flagged (its verdict `suspicious`, with the reasons);
//! 4. re-anchoring ([`TrackParams::reanchor`]): a flagged frame is fitted again from the
//!    template placed rigidly onto its fit (the rest shape, at the fit's position), and the
//!    second fit is kept when its edge distortion is lower at no larger scan distance.
//!
//! `foldmatch sequence` and the Python `foldmatch_rs.track` both run a [`Tracker`].

use crate::error::{FoldMatchError, Result};
use crate::fit::{fit_anchored, FitParams, FitResult, Progress};
use crate::knn::PointIndex;
use crate::math::vec3;
use crate::mesh::{validate_faces, validate_points};
use crate::metrics::{percentile_linear, positive_points, EdgeLengths};
use crate::quality::Verdict;
use crate::rotation::{kabsch, ring_centroids, transform_vertex};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// The settings of a [`Tracker`]: the fit of every frame and the tracking rules.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackParams {
    /// The fit of every frame (the `"tracking"` preset by default).
    pub fit: FitParams,
    /// λ of the constant-velocity prediction of a frame's start, in `[0, 1]`: 0 (the default)
    /// starts from the previous fit, 1 moves it on by its whole last motion (captures whose
    /// frames are far apart move other than at constant velocity: docs/method.md "Tracking").
    pub prediction: f64,
    /// A frame is flagged when its edge distortion exceeds the first frame's by more than
    /// this (the verdict's 95th-percentile distortion against the template, 1 = isometric).
    pub distortion_jump: f64,
    /// A frame is flagged when its fit→scan or scan→fit distance exceeds this multiple of the
    /// first frame's.
    pub distance_jump: f64,
    /// Fit a flagged frame again from the template rigidly placed on its fit, and keep the
    /// better of the two fits (off by default: on the DiffCloth wind sequence the second fit
    /// was kept on 2 of 20 flagged frames, at twice their time; docs/method.md "Tracking").
    pub reanchor: bool,
    /// The do-no-harm margin ([`keep_margin`](crate::fit::Schedule::keep_margin)) of the first
    /// frame, which starts from the template itself as a single fit does (the later frames,
    /// warm-started, use the fit's own, 0 in the `"tracking"` preset): a template that is the
    /// first frame's mesh stays on it. 0: the fit's own for every frame.
    pub first_keep_margin: f64,
}

/// The tracking rules' defaults (docs/method.md "Tracking").
pub const DEFAULT_PREDICTION: f64 = 0.0;
/// See [`TrackParams::distortion_jump`].
pub const DEFAULT_DISTORTION_JUMP: f64 = 0.15;
/// See [`TrackParams::distance_jump`].
pub const DEFAULT_DISTANCE_JUMP: f64 = 2.0;
/// A warm-started frame whose start lies farther from its scan than this many mean template
/// edges (the 95th percentile of the start's vertex → scan distances) moved far since the last
/// one: its fit gets proportionally more schedule iterations (docs/method.md "Tracking").
pub const FAR_FRAME_EDGES: f64 = 2.0;
/// The most a far frame multiplies the schedule's iterations by.
pub const MAX_ITERATION_FACTOR: f64 = 3.0;

impl Default for TrackParams {
    fn default() -> Self {
        Self {
            fit: FitParams::tracking(),
            prediction: DEFAULT_PREDICTION,
            distortion_jump: DEFAULT_DISTORTION_JUMP,
            distance_jump: DEFAULT_DISTANCE_JUMP,
            reanchor: false,
            first_keep_margin: crate::fit::DEFAULT_KEEP_MARGIN,
        }
    }
}

impl TrackParams {
    /// The fit's parameters and the rules' ranges ([`FoldMatchError::Parameter`] naming the
    /// setting).
    pub fn validate(&self) -> Result<()> {
        self.fit.validate()?;
        if !(0.0..=1.0).contains(&self.prediction) {
            return Err(FoldMatchError::parameter(
                "prediction",
                self.prediction,
                "must be in [0, 1]",
            ));
        }
        if self.distortion_jump.is_nan() || self.distortion_jump <= 0.0 {
            return Err(FoldMatchError::parameter(
                "distortion_jump",
                self.distortion_jump,
                "must be > 0 (+inf turns the test off)",
            ));
        }
        if self.first_keep_margin.is_nan() || self.first_keep_margin < 0.0 {
            return Err(FoldMatchError::parameter(
                "first_keep_margin",
                self.first_keep_margin,
                "must be >= 0",
            ));
        }
        if self.distance_jump.is_nan() || self.distance_jump <= 1.0 {
            return Err(FoldMatchError::parameter(
                "distance_jump",
                self.distance_jump,
                "must be > 1 (+inf turns the test off)",
            ));
        }
        Ok(())
    }
}

/// One frame's tracking figures (the distances in scan diagonals, as the quality verdict's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameFigures {
    /// The frame's index in the sequence (0-based).
    pub frame: usize,
    /// Mean fitted-vertex → scan distance ÷ the scan diagonal.
    pub fit_to_scan: f64,
    /// Mean scan → fitted-surface distance ÷ the scan diagonal.
    pub scan_to_fit: f64,
    /// 95th percentile of the edge-length distortion against the template (1: isometric).
    pub edge_distortion: f64,
    /// Mean distance of the fitted vertices from the previous frame's ÷ the scan diagonal
    /// (0 at the first frame).
    pub motion: f64,
    /// Whether the frame started from a previous fit (not at the first frame, nor after a
    /// frame that failed).
    pub warm_started: bool,
    /// Whether the kept fit is the re-anchored one.
    pub reanchored: bool,
    /// Whether a figure jumped past its threshold (the frame's verdict is then `suspicious`).
    pub flagged: bool,
    /// One sentence per jump (empty when not flagged).
    pub reasons: Vec<String>,
}

/// A frame's fit and its tracking figures.
#[derive(Clone, Debug)]
pub struct TrackedFrame {
    /// The fit (its `quality` verdict includes the tracking flags).
    pub result: FitResult,
    /// The frame's figures.
    pub figures: FrameFigures,
}

/// What a [`Tracker`] carries from one frame to the next (its last two fits, the first
/// frame's figures, the frames seen): a sequence whose frames run as separate tasks (a Dask
/// chain, `foldmatch sequence --scheduler`) passes it from each frame's task to the next, so
/// that it tracks exactly as one local [`Tracker`] does.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackerState {
    /// The last two fits, latest first.
    pub previous: Vec<Vec<[f64; 3]>>,
    /// The first frame's figures (the jumps' reference).
    pub first: Option<FrameFigures>,
    /// The frames seen (fitted, accepted or failed).
    pub frames: usize,
}

/// A sequence in progress: the template, the settings and the last fits.
pub struct Tracker {
    template: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    /// The template's mean edge length (each edge once; [`FAR_FRAME_EDGES`]' unit).
    mean_edge: f64,
    params: TrackParams,
    /// The last two fits, latest first.
    previous: Vec<Vec<[f64; 3]>>,
    /// The first frame's figures: the jumps' reference.
    first: Option<FrameFigures>,
    frames: usize,
}

impl Tracker {
    /// A tracker of sequences of `template` (its vertices are the rest shape of every frame).
    /// Errors: the template's and the settings' ([`FoldMatchError`]).
    pub fn new(template: &[[f64; 3]], faces: &[[u32; 3]], params: TrackParams) -> Result<Self> {
        validate_points("template_vertices", template)?;
        validate_faces("template_faces", faces, template.len())?;
        params.validate()?;
        let mean_edge = EdgeLengths::new(template, faces).mean_length();
        Ok(Self {
            template: template.to_vec(),
            faces: faces.to_vec(),
            mean_edge,
            params,
            previous: Vec::new(),
            first: None,
            frames: 0,
        })
    }

    /// What the next frame needs of the frames so far ([`TrackerState`]).
    pub fn state(&self) -> TrackerState {
        TrackerState {
            previous: self.previous.clone(),
            first: self.first.clone(),
            frames: self.frames,
        }
    }

    /// Continues from `state` (another tracker's [`Tracker::state`] over the same template);
    /// fits of another vertex count are refused.
    pub fn restore(&mut self, state: TrackerState) -> Result<()> {
        for fitted in &state.previous {
            validate_points("tracker state", fitted)?;
            if fitted.len() != self.template.len() {
                return Err(self.count_error(fitted.len()));
            }
        }
        self.previous = state.previous;
        self.previous.truncate(2);
        self.first = state.first;
        self.frames = state.frames;
        Ok(())
    }

    /// The frames seen so far (fitted, accepted or failed).
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The settings.
    pub fn params(&self) -> &TrackParams {
        &self.params
    }

    /// Takes `fitted` as the next frame's fit without fitting it (a frame done by an earlier
    /// run, `sequence --resume`); a wrong vertex count is refused.
    pub fn accept(&mut self, fitted: &[[f64; 3]]) -> Result<()> {
        validate_points("fitted frame", fitted)?;
        if fitted.len() != self.template.len() {
            return Err(self.count_error(fitted.len()));
        }
        self.push(fitted.to_vec());
        self.frames += 1;
        Ok(())
    }

    /// Records a frame that could not be fitted: the next one starts from the last fit, with
    /// no prediction across the gap.
    pub fn skip(&mut self) {
        self.previous.truncate(1);
        self.frames += 1;
    }

    /// Fits the next frame (`target`, with optional faces and per-point weights as
    /// [`crate::fit::ScanExtras::weights`] are for a fit). Errors are the fit's; the frame then counts
    /// as skipped ([`Tracker::skip`]).
    pub fn step(
        &mut self,
        target: &[[f64; 3]],
        target_faces: Option<&[[u32; 3]]>,
        target_weights: Option<&[f64]>,
        observer: &mut (dyn FnMut(&Progress) -> bool + Send),
    ) -> Result<TrackedFrame> {
        let frame = self.frames;
        let start = self.start();
        let warm_started = !self.previous.is_empty();
        // The first frame starts from the template: the do-no-harm rule of a single fit.
        let first_params;
        let params = if warm_started || self.params.first_keep_margin == 0.0 {
            &self.params.fit
        } else {
            let mut p = self.params.fit.clone();
            p.schedule.keep_margin = p.schedule.keep_margin.max(self.params.first_keep_margin);
            first_params = p;
            &first_params
        };
        // A frame that moved far from the last fit gets more schedule iterations.
        let far_params;
        let factor = if warm_started {
            Self::far_frame_factor(&start, target, target_weights, self.mean_edge)
        } else {
            1.0
        };
        let params = if factor > 1.0 {
            let mut p = params.clone();
            p.iterations = (p.iterations as f64 * factor).round() as usize;
            far_params = p;
            &far_params
        } else {
            params
        };
        let fit = |start: &[[f64; 3]], observer: &mut (dyn FnMut(&Progress) -> bool + Send)| {
            fit_anchored(
                start,
                &self.template,
                &self.faces,
                target,
                target_faces,
                target_weights,
                params,
                observer,
            )
        };
        let mut result = match fit(&start, observer) {
            Ok(r) => r,
            Err(e) => {
                self.skip();
                return Err(e);
            }
        };
        let mut figures = self.figures(frame, &result, warm_started, false);
        if figures.flagged && self.params.reanchor && !result.diagnostics.stopped_by_callback {
            let placed = placed_rigidly(&self.template, &result.vertices);
            let again = fit(&placed, observer)?;
            let other = self.figures(frame, &again, warm_started, true);
            let nearest = figures.scan_to_fit.max(figures.fit_to_scan);
            if other.edge_distortion < figures.edge_distortion
                && other.scan_to_fit.max(other.fit_to_scan) <= nearest
            {
                result = again;
                figures = other;
            }
        }
        if figures.flagged {
            let q = &mut result.quality;
            q.verdict = Verdict::Suspicious;
            q.reasons.extend(figures.reasons.iter().cloned());
        }
        if self.first.is_none() {
            self.first = Some(figures.clone());
        }
        self.push(result.vertices.clone());
        self.frames += 1;
        Ok(TrackedFrame { result, figures })
    }

    /// How many times the schedule's iterations a warm-started frame gets: the 95th percentile of
    /// its start's vertex → scan distances (scan points of positive weight) in units of
    /// [`FAR_FRAME_EDGES`] mean template edges `mean_edge`, clamped to `[1, MAX_ITERATION_FACTOR]`.
    fn far_frame_factor(
        start: &[[f64; 3]],
        target: &[[f64; 3]],
        weights: Option<&[f64]>,
        mean_edge: f64,
    ) -> f64 {
        let live = match weights {
            Some(w) => Cow::Owned(positive_points(target, w)),
            None => Cow::Borrowed(target),
        };
        if live.is_empty() || start.is_empty() || mean_edge.is_nan() || mean_edge <= 0.0 {
            return 1.0;
        }
        let index = PointIndex::new(&live);
        let distances: Vec<f64> = start
            .par_iter()
            .map(|p| index.nearest_one(p).1.sqrt())
            .collect();
        let reach = percentile_linear(&distances, 95.0) / mean_edge;
        (reach / FAR_FRAME_EDGES).clamp(1.0, MAX_ITERATION_FACTOR)
    }

    /// The next frame's start: the template first, then the previous fit moved on by
    /// λ × its last motion.
    fn start(&self) -> Vec<[f64; 3]> {
        let lambda = self.params.prediction;
        match self.previous.as_slice() {
            [] => self.template.clone(),
            [last] => last.clone(),
            [last, before, ..] => last
                .iter()
                .zip(before)
                .map(|(a, b)| (vec3(a) + lambda * (vec3(a) - vec3(b))).into())
                .collect(),
        }
    }

    fn push(&mut self, fitted: Vec<[f64; 3]>) {
        self.previous.insert(0, fitted);
        self.previous.truncate(2);
    }

    fn count_error(&self, got: usize) -> FoldMatchError {
        FoldMatchError::shape(
            "fitted frame",
            format!("has {got} vertices, the template {}", self.template.len()),
        )
    }

    /// The figures of `result` as frame `frame`, flagged against the first frame's.
    fn figures(
        &self,
        frame: usize,
        result: &FitResult,
        warm_started: bool,
        reanchored: bool,
    ) -> FrameFigures {
        let q = &result.quality;
        let motion = match self.previous.first() {
            Some(last) if q.scan_diagonal > 0.0 => {
                let sum: f64 = last
                    .iter()
                    .zip(&result.vertices)
                    .map(|(a, b)| (vec3(a) - vec3(b)).norm())
                    .sum();
                sum / last.len() as f64 / q.scan_diagonal
            }
            _ => 0.0,
        };
        let mut reasons = Vec::new();
        if let Some(first) = &self.first {
            let jump = self.params.distortion_jump;
            if q.edge_distortion > first.edge_distortion + jump {
                reasons.push(format!(
                    "tracking: edge-length distortion {:.3} against the template, more than \
                     {jump} above the first frame's {:.3}",
                    q.edge_distortion, first.edge_distortion
                ));
            }
            let times = self.params.distance_jump;
            for (name, now, then) in [
                ("fit→scan", q.fit_to_scan, first.fit_to_scan),
                ("scan→fit", q.scan_to_fit, first.scan_to_fit),
            ] {
                if now > times * then {
                    reasons.push(format!(
                        "tracking: {name} distance {:.4} of the scan diagonal, more than \
                         {times}× the first frame's {:.4}",
                        now, then
                    ));
                }
            }
        }
        FrameFigures {
            frame,
            fit_to_scan: q.fit_to_scan,
            scan_to_fit: q.scan_to_fit,
            edge_distortion: q.edge_distortion,
            motion,
            warm_started,
            reanchored,
            flagged: !reasons.is_empty(),
            reasons,
        }
    }
}

/// `rest` moved by the rigid motion (Kabsch, all vertices) that best places it on `fitted`.
pub fn placed_rigidly(rest: &[[f64; 3]], fitted: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let all: Vec<u32> = (0..rest.len() as u32).collect();
    let (c_rest, c_fit) = ring_centroids(&all, rest, fitted);
    let r = kabsch(&all, rest, fitted, &c_rest, &c_fit, false);
    rest.iter()
        .map(|p| transform_vertex(&r, &vec3(p), &c_rest, &c_fit).into())
        .collect()
}

#[cfg(test)]
mod tests;
