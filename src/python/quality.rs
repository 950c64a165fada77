//! The binding of the quality verdict (`foldmatch_rs.assess`, [`crate::quality`]).

use super::{compute, faces, points, to_pyerr};
use crate::quality::{self, AssessInput, Assessment, VerdictThresholds};
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The per-vertex figures of an assessment and its summary (`quality`, a dict) in a dict.
pub(super) fn assessment_items(d: &Bound<'_, PyDict>, a: Assessment) -> PyResult<()> {
    let py = d.py();
    let summary = pythonize::pythonize(py, &a.quality)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(format!("quality: {e}")))?;
    d.set_item("quality", summary)?;
    d.set_item("correspondences", a.correspondences.into_pyarray(py))?;
    d.set_item("residuals", a.residuals.into_pyarray(py))?;
    d.set_item("support", a.support.into_pyarray(py))?;
    Ok(())
}

/// The quality verdict of a fit; see `foldmatch_rs.assess`.
#[pyfunction]
#[pyo3(signature = (template_vertices, template_faces, fitted_vertices, scan, thresholds=None))]
pub(super) fn assess_raw<'py>(
    py: Python<'py>,
    template_vertices: PyReadonlyArray2<'py, f64>,
    template_faces: PyReadonlyArray2<'py, i64>,
    fitted_vertices: PyReadonlyArray2<'py, f64>,
    scan: PyReadonlyArray2<'py, f64>,
    thresholds: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let thresholds: VerdictThresholds = match thresholds {
        Some(given) => pythonize::depythonize(&given).map_err(|e| {
            to_pyerr(crate::FoldMatchError::parameter(
                "thresholds",
                given.to_string(),
                &format!("must map threshold names to numbers: {e}"),
            ))
        })?,
        None => VerdictThresholds::default(),
    };
    let tv = points("template_vertices", &template_vertices)?;
    let fv = points("fitted_vertices", &fitted_vertices)?;
    let x = points("scan", &scan)?;
    let f = faces("template_faces", &template_faces, tv.len())?;
    let input = AssessInput {
        template_vertices: tv,
        faces: &f,
        fitted_vertices: fv,
        scan: x,
    };
    let a = compute(py, None, |_| quality::assess(&input, &thresholds))?.map_err(to_pyerr)?;
    let d = PyDict::new(py);
    assessment_items(&d, a)?;
    Ok(d)
}
