//! The bindings of the Dask path (`foldmatch_rs.distributed`): [`RunBook`] on the driver,
//! [`FileFitter`] on the workers, and `cluster_request`, which reads a `batch` / `sequence`
//! command line with `--scheduler` for the console script. Plans, entries and reports cross as
//! JSON (the schema of `report.json`); vertices as `(n, 3)` float64 arrays.

use super::{InvalidParameterError, RunSetupError};
use crate::cli::cluster::{self, FileReport, Planned, Request, TrackOptions, Verbosity};
use crate::track::TrackerState;
use pyo3::prelude::*;

fn verbosity(name: &str) -> PyResult<Verbosity> {
    match name {
        "quiet" => Ok(Verbosity::Quiet),
        "normal" => Ok(Verbosity::Normal),
        "verbose" => Ok(Verbosity::Verbose),
        other => Err(InvalidParameterError::new_err(format!(
            "verbosity {other:?}: expected \"quiet\", \"normal\" or \"verbose\""
        ))),
    }
}

fn from_json<T: serde::de::DeserializeOwned>(what: &str, text: &str) -> PyResult<T> {
    serde_json::from_str(text).map_err(|e| InvalidParameterError::new_err(format!("{what}: {e}")))
}

fn to_json<T: serde::Serialize>(value: &T) -> String {
    serde_json::to_string(value).expect("plain data serializes")
}

/// The driver's side of a `batch` or `sequence` run on a cluster: plans it, keeps
/// `OUT_DIR/report.json`, prints the log lines and the progress bar. See
/// `foldmatch_rs.distributed`.
#[pyclass(frozen, module = "foldmatch_rs._foldmatch_rs")]
pub struct RunBook(cluster::RunBook);

#[pymethods]
impl RunBook {
    /// Plans the run of `request_json` (template, scans, output, options); raises
    /// `RunSetupError` with the local command's message when it cannot start.
    #[new]
    #[pyo3(signature = (request_json, verbosity="normal"))]
    fn new(py: Python<'_>, request_json: &str, verbosity: &str) -> PyResult<Self> {
        let request: Request = from_json("request", request_json)?;
        let verbosity = self::verbosity(verbosity)?;
        py.detach(|| cluster::RunBook::start(&request, verbosity))
            .map(Self)
            .map_err(RunSetupError::new_err)
    }

    /// The files to send to workers (JSON list of `{index, name, scan, output, gt, resumed}`).
    fn files_json(&self) -> String {
        to_json(&self.0.files())
    }

    /// The resolved fit parameters, every key (JSON).
    #[getter]
    fn params_json(&self) -> String {
        self.0.params_json()
    }

    /// A sequence's tracking rules (JSON, for `FileFitter.track`).
    #[getter]
    fn tracking_json(&self) -> String {
        self.0.tracking_json()
    }

    /// The template's path.
    #[getter]
    fn template(&self) -> String {
        self.0.template().display().to_string()
    }

    /// Where the report is written.
    #[getter]
    fn report_path(&self) -> String {
        self.0.report_path().display().to_string()
    }

    /// The number of files of the run.
    #[getter]
    fn total(&self) -> usize {
        self.0.total()
    }

    /// Prints a normal line on standard error (not when quiet).
    fn info(&self, message: &str) {
        self.0.info(message);
    }

    /// Records a finished file's entry (JSON, as `FileFitter.fit` returns it).
    fn record(&self, index: usize, entry_json: &str) -> PyResult<()> {
        let entry: FileReport = from_json("entry", entry_json)?;
        self.0
            .record(index, entry)
            .map_err(InvalidParameterError::new_err)
    }

    /// Records a file whose task failed on the cluster, with why.
    fn record_failure(&self, index: usize, message: &str) -> PyResult<()> {
        self.0
            .record_failure(index, message)
            .map_err(InvalidParameterError::new_err)
    }

    /// Writes the last report and prints the summary: `(exit code, report JSON)`.
    fn finish(&self, interrupted: bool) -> (i32, String) {
        let (code, report) = self.0.finish(interrupted);
        (code, to_json(&report))
    }
}

/// The worker's side: a run's template and parameters, loaded once, and a thread pool of
/// `threads` threads of its own.
#[pyclass(frozen, module = "foldmatch_rs._foldmatch_rs")]
pub struct FileFitter(cluster::FileFitter);

#[pymethods]
impl FileFitter {
    /// Loads `template` for the parameters `params_json` (`RunBook.params_json`).
    #[new]
    fn new(py: Python<'_>, template: &str, params_json: &str, threads: usize) -> PyResult<Self> {
        py.detach(|| cluster::FileFitter::new(template.as_ref(), params_json, threads))
            .map(Self)
            .map_err(RunSetupError::new_err)
    }

    /// Fits one planned file (JSON, from `RunBook.files_json`) as `batch` does and writes its
    /// output to the staged path that `RunBook.record` commits: the entry (JSON). A failed
    /// file is an `error` entry, not an exception.
    #[pyo3(signature = (file_json, ascii=false))]
    fn fit(&self, py: Python<'_>, file_json: &str, ascii: bool) -> PyResult<String> {
        let file: Planned = from_json("file", file_json)?;
        let outcome = py.detach(|| self.0.fit(&file, ascii));
        Ok(to_json(&outcome.report))
    }

    /// Fits one frame of a sequence as `sequence` does: a tracker with the rules
    /// `tracking_json` (`RunBook.tracking_json`) continued from `state_json` (the previous
    /// frame's; `None` for the first), the entry's warm start named `warm_name`. Returns
    /// `(entry JSON, the next frame's state JSON, whether the frame was fitted)`.
    #[pyo3(signature = (file_json, tracking_json, state_json=None, warm_name=None, ascii=false))]
    fn track(
        &self,
        py: Python<'_>,
        file_json: &str,
        tracking_json: &str,
        state_json: Option<&str>,
        warm_name: Option<&str>,
        ascii: bool,
    ) -> PyResult<(String, String, bool)> {
        let file: Planned = from_json("file", file_json)?;
        let tracking: TrackOptions = from_json("tracking", tracking_json)?;
        let state: Option<TrackerState> = state_json.map(|s| from_json("state", s)).transpose()?;
        let (outcome, next) = py.detach(|| self.0.track(&file, ascii, tracking, state, warm_name));
        Ok((
            to_json(&outcome.report),
            to_json(&next),
            outcome.fitted.is_some(),
        ))
    }

    /// `sequence --resume`: `(entry JSON, the next frame's state JSON)` with the frame's
    /// earlier output taken as its fit, or `None` when it cannot be reused (the frame is then
    /// fitted again).
    #[pyo3(signature = (file_json, state_json=None, warm_name=None))]
    fn resume_frame(
        &self,
        py: Python<'_>,
        file_json: &str,
        state_json: Option<&str>,
        warm_name: Option<&str>,
    ) -> PyResult<Option<(String, String)>> {
        let file: Planned = from_json("file", file_json)?;
        let state: Option<TrackerState> = state_json.map(|s| from_json("state", s)).transpose()?;
        let resumed = py.detach(|| {
            self.0
                .resume_frame(&file, warm_name)
                .map(|(entry, vertices)| (entry, self.0.accept(state, &vertices)))
        });
        Ok(resumed
            .ok()
            .map(|(entry, next)| (to_json(&entry), to_json(&next))))
    }
}

/// The run that a `foldmatch` command line asks of a Dask cluster (`batch` or `sequence` with
/// `--scheduler`) as JSON `{request, scheduler, workers, threads, verbosity}`, or `None`.
#[pyfunction]
pub fn cluster_request(argv: Vec<String>) -> Option<String> {
    Request::from_cli(argv).map(|run| to_json(&run))
}
