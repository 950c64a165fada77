//! `fm.render` / `FitResult.preview` and the wrinkle-field colors of `FitResult.to_trimesh`:
//! thin wrappers over [`crate::render`] and [`crate::io::wrinkle_colors`], so that Python and
//! the CLI draw and color a fit identically.

use super::{compute, faces as face_array, points, to_pyerr};
use crate::error::FoldMatchError;
use crate::render::{render, write_png, PreviewOptions, Scene, View};
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use std::path::PathBuf;

/// The preview of a mesh (and scan) as an (H, W, 3) uint8 array; also a PNG at `path`.
#[pyfunction]
#[pyo3(signature = (vertices, faces, scan=None, scan_faces=None, field=None, magnitude=None, path=None, panel=320, views=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn render_preview<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    scan: Option<PyReadonlyArray2<'py, f64>>,
    scan_faces: Option<PyReadonlyArray2<'py, i64>>,
    field: Option<PyReadonlyArray2<'py, f64>>,
    magnitude: Option<PyReadonlyArray1<'py, f64>>,
    path: Option<PathBuf>,
    panel: u32,
    views: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let v = points("vertices", &vertices)?;
    let f = face_array("faces", &faces, v.len())?;
    let scan_points = scan.as_ref().map(|s| points("scan", s)).transpose()?;
    let scan_f = match (&scan_faces, scan_points) {
        (Some(sf), Some(sp)) => Some(face_array("scan_faces", sf, sp.len())?),
        (Some(_), None) => {
            return Err(to_pyerr(FoldMatchError::shape(
                "scan_faces",
                "given without a scan",
            )))
        }
        _ => None,
    };
    let field_magnitude: Option<Vec<f64>> = match (&field, &magnitude) {
        (Some(w), _) => Some(crate::fit::magnitudes(points("field", w)?)),
        (None, Some(m)) => Some(
            m.as_slice()
                .map_err(|_| {
                    to_pyerr(FoldMatchError::shape(
                        "field",
                        "expected a C-contiguous array",
                    ))
                })?
                .to_vec(),
        ),
        (None, None) => None,
    };
    let views = match views {
        None => View::DEFAULT.to_vec(),
        Some(names) => names
            .iter()
            .map(|n| {
                View::from_name(n).ok_or_else(|| {
                    to_pyerr(FoldMatchError::parameter(
                        "views",
                        n,
                        "each view is one of front, three-quarter, side, back",
                    ))
                })
            })
            .collect::<PyResult<_>>()?,
    };
    let scene = Scene {
        field: field_magnitude.as_deref(),
        scan: scan_points,
        scan_faces: scan_f.as_deref(),
        ..Scene::mesh(v, &f)
    };
    let options = PreviewOptions { panel, views };
    let image = compute(py, None, |_| {
        let preview = render(&scene, &options)?;
        if let Some(path) = &path {
            write_png(path, &preview.image, &preview.png_text())?;
        }
        Ok::<_, FoldMatchError>(preview.image)
    })?
    .map_err(to_pyerr)?;
    let shape = (image.height as usize, image.width as usize, 3);
    Ok(Array3::from_shape_vec(shape, image.pixels)
        .expect("height × width × 3")
        .into_pyarray(py))
}

/// The wrinkle-field colors of `magnitude` (viridis over its 2nd–98th percentiles) as an
/// (n, 3) uint8 array, with the range used.
#[pyfunction]
pub(super) fn wrinkle_colors<'py>(
    py: Python<'py>,
    magnitude: PyReadonlyArray1<'py, f64>,
) -> PyResult<(Bound<'py, PyArray2<u8>>, (f64, f64))> {
    let m = magnitude.as_array().to_vec();
    let (colors, range) = crate::io::wrinkle_colors(&m);
    let n = colors.len();
    let array = Array2::from_shape_vec((n, 3), colors.into_flattened()).expect("n × 3");
    Ok((array.into_pyarray(py), range))
}

/// Writes the fitted mesh with its wrinkle-vector field as the CLI does (`.ply` or `.obj`).
#[pyfunction]
#[pyo3(signature = (path, vertices, faces, field, ascii=false))]
pub(super) fn write_fitted<'py>(
    py: Python<'py>,
    path: PathBuf,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    field: PyReadonlyArray2<'py, f64>,
    ascii: bool,
) -> PyResult<()> {
    let v = points("vertices", &vertices)?;
    let f = face_array("faces", &faces, v.len())?;
    let w = points("field", &field)?;
    if w.len() != v.len() {
        return Err(to_pyerr(FoldMatchError::shape(
            "field",
            format!("{} vectors for {} vertices", w.len(), v.len()),
        )));
    }
    compute(py, None, |_| {
        let (mesh, extra) = crate::io::fitted_mesh(v, &f, w);
        crate::io::write_mesh(&path, &mesh, &extra, ascii)
    })?
    .map_err(to_pyerr)
}
