//! Mesh files read by the crate's own readers ([`crate::io`]) for the Python layer, so that
//! `fm.fit("template.obj", None, "scan.ply")` reads them exactly as the `foldmatch` command
//! does.

use super::{array2, compute, to_pyerr};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use std::path::PathBuf;

/// A `.ply` or `.obj` file as `(vertices (n, 3) float64, faces (t, 3) int64, values)`: faces
/// is `(0, 3)` for a point cloud; `values` is the per-vertex PLY property `property` as float64
/// when one is named, else `None`.
#[pyfunction]
#[pyo3(signature = (path, property=None))]
pub(super) fn read_mesh<'py>(
    py: Python<'py>,
    path: PathBuf,
    property: Option<String>,
) -> PyResult<(
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<i64>>,
    Option<Bound<'py, PyArray1<f64>>>,
)> {
    let (mesh, values) = compute(py, None, |_| match &property {
        Some(name) => crate::io::read_ply_property(&path, name).map(|(m, v)| (m, Some(v))),
        None => crate::io::read_mesh(&path).map(|m| (m, None)),
    })?
    .map_err(to_pyerr)?;
    let faces: Vec<i64> = mesh.faces.iter().flat_map(|f| f.map(i64::from)).collect();
    let faces = Array2::from_shape_vec((mesh.faces.len(), 3), faces).expect("t×3");
    Ok((
        array2(py, mesh.vertices),
        faces.into_pyarray(py),
        values.map(|v| v.into_pyarray(py)),
    ))
}

/// The vertex normals of a mesh or point cloud file (PLY `nx ny nz`), `None` when it has none.
#[pyfunction]
pub(super) fn read_normals(
    py: Python<'_>,
    path: PathBuf,
) -> PyResult<Option<Bound<'_, PyArray2<f64>>>> {
    let mesh = compute(py, None, |_| crate::io::read_mesh(&path))?.map_err(to_pyerr)?;
    Ok(mesh.normals.map(|n| array2(py, n)))
}

/// A one-dimensional NumPy `.npy` file (per-point scan weights) as float64.
#[pyfunction]
pub(super) fn read_weights(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray1<f64>>> {
    let values = compute(py, None, |_| crate::io::read_npy(&path))?.map_err(to_pyerr)?;
    Ok(values.into_pyarray(py))
}
