//! The binding of sequence tracking (`foldmatch_rs.track`, [`crate::track`]): one
//! [`crate::track::Tracker`] per sequence, each frame fitted without the GIL.

use super::{
    compute, faces, params, points, result_dict, threads_arg, to_pyerr, weights, InternalError,
};
use crate::track::{self, TrackParams};
use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::Ordering;
use std::sync::Mutex;

/// A sequence in progress; see `foldmatch_rs.track`.
#[pyclass(frozen, module = "foldmatch_rs._foldmatch_rs")]
pub struct Tracker(Mutex<track::Tracker>);

impl Tracker {
    fn inner(&self) -> PyResult<std::sync::MutexGuard<'_, track::Tracker>> {
        self.0
            .lock()
            .map_err(|_| InternalError::new_err("the tracker was poisoned by an earlier panic"))
    }
}

#[pymethods]
impl Tracker {
    /// A tracker of `template_vertices` (the rest shape of every frame) with the fit settings
    /// `params` (a dict, as `fit_raw` takes them) and the tracking rules.
    #[new]
    #[pyo3(signature = (template_vertices, template_faces, params, prediction, distortion_jump, distance_jump, reanchor))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        template_vertices: PyReadonlyArray2<'_, f64>,
        template_faces: PyReadonlyArray2<'_, i64>,
        params: &Bound<'_, PyDict>,
        prediction: f64,
        distortion_jump: f64,
        distance_jump: f64,
        reanchor: bool,
    ) -> PyResult<Self> {
        let fit = params::from_dict(py, params)?;
        let tv = points("template_vertices", &template_vertices)?;
        let tf = faces("template_faces", &template_faces, tv.len())?;
        crate::limits::check_snapshots(&fit, tv.len()).map_err(to_pyerr)?;
        let rules = TrackParams {
            fit,
            prediction,
            distortion_jump,
            distance_jump,
            reanchor,
            ..TrackParams::default()
        };
        let tracker = track::Tracker::new(tv, &tf, rules).map_err(to_pyerr)?;
        Ok(Self(Mutex::new(tracker)))
    }

    /// The frames seen so far.
    #[getter]
    fn frames(&self) -> PyResult<usize> {
        Ok(self.inner()?.frames())
    }

    /// Records a frame that could not be read: the next starts from the last fit.
    fn skip(&self) -> PyResult<()> {
        self.inner()?.skip();
        Ok(())
    }

    /// Takes `fitted` as the next frame's fit without fitting it (a frame done elsewhere).
    fn accept(&self, fitted: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let pts = points("fitted", &fitted)?;
        self.inner()?.accept(pts).map_err(to_pyerr)?;
        Ok(())
    }

    /// Fits the next frame: `fit_raw`'s dict, with the frame's figures under `"tracking"`.
    #[pyo3(signature = (target, target_faces=None, target_weights=None, threads=None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        target: PyReadonlyArray2<'py, f64>,
        target_faces: Option<PyReadonlyArray2<'py, i64>>,
        target_weights: Option<PyReadonlyArray1<'py, f64>>,
        threads: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let threads = threads_arg(threads.as_ref())?;
        let x = points("target", &target)?;
        let xf = match &target_faces {
            Some(f) => Some(faces("target_faces", f, x.len())?),
            None => None,
        };
        let weights = weights(&target_weights)?;
        let mut tracker = self.inner()?;
        let tracker = &mut *tracker;
        let outcome = compute(py, threads, |cancel| {
            let mut observer = |_: &crate::fit::Progress| !cancel.load(Ordering::Relaxed);
            tracker.step(x, xf.as_deref(), weights, &mut observer)
        })?;
        let frame = outcome.map_err(to_pyerr)?;
        let figures = pythonize::pythonize(py, &frame.figures)
            .map_err(|e| InternalError::new_err(format!("tracking figures: {e}")))?;
        let d = result_dict(py, frame.result)?;
        d.set_item("tracking", figures)?;
        Ok(d)
    }
}
