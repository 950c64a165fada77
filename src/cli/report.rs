//! The JSON reports: one object per fitted file ([`FileReport`]), gathered by `batch` and
//! `sequence` into a [`RunReport`] (written atomically, and rewritten as files finish so that an
//! interrupted run still leaves a valid report), or written alone by `fit --report`
//! ([`FitReport`]).

use crate::io::write_atomically;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::io::Write;
use std::path::Path;

/// What became of one file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Fitted and written.
    Ok,
    /// Failed; `error` says why. Nothing was written for it.
    Error,
    /// Done by an earlier run (`--resume`); its figures are copied from that run's report.
    Skipped,
    /// Stopped by Ctrl-C before it finished; nothing was written for it.
    Interrupted,
    /// Not started (the run was interrupted first).
    Pending,
}

impl Status {
    /// Whether the file's output is complete (`ok` or `skipped`).
    pub fn is_done(self) -> bool {
        matches!(self, Self::Ok | Self::Skipped)
    }
}

/// One file's entry.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FileReport {
    /// The scan's path relative to the scanned folder (`batch`, `sequence`), or as given (`fit`).
    pub name: String,
    /// The scan's path.
    pub scan: String,
    /// The output's path.
    pub output: String,
    /// What became of it.
    pub status: Status,
    /// Why it failed, naming the file.
    pub error: Option<String>,
    /// Iterations run.
    pub iterations: Option<usize>,
    /// Wall time of the fit itself, in seconds.
    pub seconds: Option<f64>,
    /// Wall time of the whole file (reading, fit, writing, metrics), in seconds.
    pub total_seconds: Option<f64>,
    /// [`crate::metrics::Metrics`] of the template, the fit and the scan (user's frame).
    pub metrics: Option<Value>,
    /// [`crate::fit::Diagnostics`] of the fit.
    pub diagnostics: Option<Value>,
    /// [`crate::quality::Quality`] of the fit: the figures without ground truth and the
    /// verdict (`ok` / `suspicious`, with the reasons).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<Value>,
    /// Ground-truth file used for f_R, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground_truth: Option<String>,
    /// `sequence`: the frame whose fit this one started from (none: the template).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warm_start: Option<String>,
    /// `sequence`: the frame's tracking figures ([`crate::track::FrameFigures`]: distances,
    /// edge distortion against the template, motion, whether it was flagged or re-anchored).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracking: Option<Value>,
    /// Where the scan's per-point weights came from (`--scan-weights`,
    /// `--scan-weights-property`); none: every point weighs 1. With weights, `metrics` are of
    /// the scan points of positive weight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scan_weights: Option<ScanWeightsReport>,
    /// The preview image drawn of the fit (`--preview`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
    /// The garment mask written of the fit (`--garment-mask`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub garment_mask: Option<String>,
}

/// Where a file's scan weights came from, and how many points they removed.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScanWeightsReport {
    /// `file` (a NumPy `.npy` array) or `property` (a per-vertex property of the scan's PLY).
    pub source: String,
    /// The `.npy` file (`source` = `file`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// The PLY property's name (`source` = `property`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub property: Option<String>,
    /// The number of weights (= scan points).
    pub points: usize,
    /// Points of weight 0: removed before the fit.
    pub zero_weight: usize,
}

impl ScanWeightsReport {
    /// Weights from a `.npy` file (not counted yet).
    pub fn file(path: &Path) -> Self {
        Self {
            source: "file".into(),
            file: Some(path.display().to_string()),
            property: None,
            points: 0,
            zero_weight: 0,
        }
    }

    /// Weights from a PLY property (not counted yet).
    pub fn property(name: &str) -> Self {
        Self {
            source: "property".into(),
            file: None,
            property: Some(name.to_string()),
            points: 0,
            zero_weight: 0,
        }
    }

    /// With the counts of `weights`.
    pub fn counted(self, weights: &[f64]) -> Self {
        Self {
            points: weights.len(),
            zero_weight: weights.iter().filter(|&&w| w == 0.0).count(),
            ..self
        }
    }
}

impl FileReport {
    /// The reasons of a `suspicious` verdict (`None` when the fit has no verdict or it is
    /// `ok`).
    pub fn suspicious_reasons(&self) -> Option<Vec<String>> {
        let q = self.quality.as_ref()?;
        if q.get("verdict")?.as_str()? != "suspicious" {
            return None;
        }
        let reasons = q.get("reasons").and_then(Value::as_array);
        Some(
            reasons
                .into_iter()
                .flatten()
                .filter_map(|r| r.as_str().map(str::to_string))
                .collect(),
        )
    }

    /// A note for a fit whose pre-alignment fitted two readings of the template that its scan
    /// does not tell apart (`diagnostics.prealign.reading_gap` below
    /// [`READING_MARGIN`](crate::fit::READING_MARGIN)): the fit may be back to front, and
    /// landmarks settle it (docs/method.md "Global pre-alignment"). `None` otherwise.
    pub fn reading_note(&self) -> Option<String> {
        let gap = self
            .diagnostics
            .as_ref()?
            .get("prealign")?
            .get("reading_gap")?
            .as_f64()?;
        (gap < crate::fit::READING_MARGIN).then(|| {
            format!(
                "the template fits this scan about as closely turned to another reading (the \
                 two fits' scan distances {:.1} % apart): a nearly symmetric garment may be back \
                 to front; a landmark or two off its symmetry plane settle it (--landmarks)",
                100.0 * gap.abs()
            )
        })
    }

    /// What the coherent candidate did (`diagnostics.coherent`, docs/method.md "Coherent
    /// candidate"), for a log line; `None` when it did not run.
    pub fn coherent_note(&self) -> Option<String> {
        let c = self.diagnostics.as_ref()?.get("coherent")?;
        let pair = |k: &str| -> Option<(f64, f64)> {
            let v = c.get(k)?.as_array()?;
            Some((v.first()?.as_f64()?, v.get(1)?.as_f64()?))
        };
        let (f0, f1) = pair("fit_to_scan")?;
        let (s0, s1) = pair("scan_to_fit")?;
        let kept = c.get("kept")?.as_bool()?;
        let spread = c.get("edge_distortion")?.as_f64()?;
        let gain = 100.0 * (1.0 - (f1 + s1) / (f0 + s0));
        Some(format!(
            "coherent candidate (the first fit's edges spread {spread:.2}, at or above \
             coherent_gate): {}, its scan distances {:.1} % {} than the first fit's",
            if kept { "kept" } else { "not kept" },
            gain.abs(),
            if gain >= 0.0 { "smaller" } else { "larger" }
        ))
    }

    /// The verdict and every figure of the fit's quality, for a log line (empty without
    /// one); the module docs of [`crate::quality`] define the figures.
    pub fn quality_note(&self) -> String {
        let Some(q) = &self.quality else {
            return String::new();
        };
        let f = |k: &str| q.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN);
        // A one-sided scan's carried vertices (docs/method.md "Partial scans").
        let carried = q
            .get("carried_share")
            .and_then(Value::as_f64)
            .filter(|&c| c > 0.0)
            .map(|c| format!(" ({:.1} % carried)", 100.0 * c))
            .unwrap_or_default();
        format!(
            "quality {}: fit→scan {:.4} and scan→fit {:.4} of the scan diagonal (mean), \
             asymmetry {:+.2}, unsupported vertices {:.1} %{carried}, flipped faces {:.1} %, collapsed \
             faces {:.1} %, edge-length distortion {:.2} (95th percentile), pose gap {:.2}, pose turn {:.0}°",
            q.get("verdict").and_then(Value::as_str).unwrap_or("?"),
            f("fit_to_scan"),
            f("scan_to_fit"),
            f("asymmetry"),
            100.0 * f("unsupported_share"),
            100.0 * f("flipped_share"),
            100.0 * f("collapsed_share"),
            f("edge_distortion"),
            f("pose_gap"),
            f("pose_turn"),
        )
    }

    /// The mean scan-to-fit distance of a fitted file, formatted for a log line after
    /// `label` (empty when there are no metrics).
    pub fn scan_to_fit_note(&self, label: &str) -> String {
        self.metrics
            .as_ref()
            .and_then(|m| m.get("scan_to_fit_mean"))
            .and_then(|d| d.as_f64())
            .map(|d| format!(", {label} {d:.4}"))
            .unwrap_or_default()
    }

    /// A file that failed before its fit could report: an `error` entry with `error`.
    pub fn failed(name: &str, scan: &Path, output: &Path, error: String) -> Self {
        Self {
            status: Status::Error,
            error: Some(error),
            ..Self::pending(name, scan, output)
        }
    }

    /// A file not started yet.
    pub fn pending(name: &str, scan: &Path, output: &Path) -> Self {
        Self {
            name: name.to_string(),
            scan: scan.display().to_string(),
            output: output.display().to_string(),
            status: Status::Pending,
            error: None,
            iterations: None,
            seconds: None,
            total_seconds: None,
            metrics: None,
            diagnostics: None,
            quality: None,
            ground_truth: None,
            warm_start: None,
            tracking: None,
            scan_weights: None,
            preview: None,
            garment_mask: None,
        }
    }
}

/// Counts of the statuses.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Summary {
    /// Files in the run.
    pub total: usize,
    /// Fitted by this run.
    pub ok: usize,
    /// Failed.
    pub error: usize,
    /// Done by an earlier run.
    pub skipped: usize,
    /// Stopped by Ctrl-C.
    pub interrupted: usize,
    /// Not started.
    pub pending: usize,
}

impl Summary {
    /// Counts `files`.
    pub fn of(files: &[FileReport]) -> Self {
        let count = |s: Status| files.iter().filter(|f| f.status == s).count();
        Self {
            total: files.len(),
            ok: count(Status::Ok),
            error: count(Status::Error),
            skipped: count(Status::Skipped),
            interrupted: count(Status::Interrupted),
            pending: count(Status::Pending),
        }
    }
}

/// Where a run stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    /// Still working (the report is rewritten as files finish).
    Running,
    /// Every file was attempted.
    Complete,
    /// Stopped by Ctrl-C.
    Interrupted,
}

/// The report of `batch` and `sequence`: `OUT_DIR/report.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunReport {
    /// Version of the program that wrote it.
    pub foldmatch_version: String,
    /// `batch` or `sequence`.
    pub command: String,
    /// The template's path.
    pub template: String,
    /// The folder of scans or frames.
    pub input_dir: String,
    /// The output folder.
    pub output_dir: String,
    /// Where the run stands.
    pub state: RunState,
    /// Wall time so far, in seconds.
    pub seconds: f64,
    /// Counts of the statuses.
    pub summary: Summary,
    /// The [`crate::fit::FitParams`] used (every key).
    pub params: Value,
    /// The names of the fitted files whose quality verdict is `suspicious` (their entries say
    /// why), in processing order.
    #[serde(default)]
    pub suspicious: Vec<String>,
    /// One entry per file, in processing order (natural order of the relative paths).
    pub files: Vec<FileReport>,
}

impl RunReport {
    /// Reads an earlier report (for `--resume`).
    pub fn load(path: &Path) -> Result<Self, String> {
        let bytes = crate::io::read_file(path).map_err(|e| e.to_string())?;
        serde_json::from_slice(&bytes)
            .map_err(|e| format!("{}: not a foldmatch report: {e}", path.display()))
    }
}

/// The report of `fit --report`: one file's entry with the run's context.
#[derive(Clone, Debug, Serialize)]
pub struct FitReport<'a> {
    /// Version of the program that wrote it.
    pub foldmatch_version: &'a str,
    /// `fit`.
    pub command: &'a str,
    /// The template's path.
    pub template: String,
    /// The file's entry.
    #[serde(flatten)]
    pub file: &'a FileReport,
    /// The [`crate::fit::FitParams`] used.
    pub params: Value,
}

/// Writes `value` as pretty JSON to `path`, atomically (temporary file + rename).
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<(), String> {
    let text = serde_json::to_vec_pretty(value).map_err(|e| format!("{}: {e}", path.display()))?;
    write_atomically(path, |w| {
        w.write_all(&text)?;
        w.write_all(b"\n")
    })
    .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_gap(gap: Option<f64>) -> FileReport {
        let mut r = FileReport::pending("a", Path::new("a.ply"), Path::new("a.fit.ply"));
        r.diagnostics = Some(serde_json::json!({
            "prealign": { "fitted_readings": 2, "reading_gap": gap },
        }));
        r
    }

    #[test]
    fn a_fit_whose_two_readings_tie_gets_a_note_and_one_clearly_closer_does_not() {
        let note = with_gap(Some(0.012))
            .reading_note()
            .expect("a tie is noted");
        assert!(
            note.contains("1.2 %") && note.contains("--landmarks"),
            "{note}"
        );
        // The other reading closer, by less than the margin that would have taken it.
        assert!(with_gap(Some(-0.02)).reading_note().is_some());
        assert!(with_gap(Some(crate::fit::READING_MARGIN + 0.01))
            .reading_note()
            .is_none());
        assert!(with_gap(None).reading_note().is_none());
        let mut plain = with_gap(None);
        plain.diagnostics = None;
        assert!(plain.reading_note().is_none());
    }

    #[test]
    fn the_coherent_candidate_is_noted_with_its_gain_when_it_ran() {
        let mut r = with_gap(None);
        r.diagnostics = Some(serde_json::json!({
            "coherent": { "edge_distortion": 1.25, "fit_to_scan": [0.01, 0.009],
                          "scan_to_fit": [0.01, 0.009], "kept": true,
                          "cpd_iterations": 20, "seconds": 0.5 },
        }));
        let note = r.coherent_note().expect("it ran");
        assert!(note.contains("kept") && note.contains("10.0 % smaller") && note.contains("1.25"));
        r.diagnostics = Some(serde_json::json!({
            "coherent": { "edge_distortion": 1.3, "fit_to_scan": [0.01, 0.009],
                          "scan_to_fit": [0.01, 0.012], "kept": false,
                          "cpd_iterations": 20, "seconds": 0.5 },
        }));
        let note = r.coherent_note().expect("it ran");
        assert!(
            note.contains("not kept") && note.contains("5.0 % larger"),
            "{note}"
        );
        assert!(with_gap(Some(0.1)).coherent_note().is_none());
    }
}
