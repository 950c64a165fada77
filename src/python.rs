//! Python bindings (`foldmatch_rs._foldmatch_rs`): thin wrappers that only convert types and
//! errors. Inputs are read without a copy when they are C-contiguous float64 (the Python layer
//! converts anything else once); outputs are NumPy arrays that take ownership of Rust `Vec`s.
//! The GIL is released during compute, and a panic is caught and raised as
//! `foldmatch_rs.InternalError` rather than crossing the boundary.

#![allow(clippy::type_complexity)] // tuples of NumPy arrays returned to Python

use crate::error::FoldMatchError;
use crate::fit::{self, FitParams, Progress};
use crate::landmarks::Landmarks;
use crate::math::Mat3;
use crate::{
    curvature, deformation, knn, metrics, nbody, prealign, regularize, rings, rotation, synthetic,
    wrinkle,
};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};

mod cluster;
mod meshes;
mod params;
mod quality;
mod render;
mod stages;
mod track;

/// Set in a forked child (see `_mark_forked`): rayon's global pool does not survive `fork`, so
/// the child computes in a fresh pool of its own.
static FORKED: AtomicBool = AtomicBool::new(false);

// The exception classes of `foldmatch_rs.errors` (each also subclasses the built-in class a
// caller expects, `ValueError`, `OSError`, ..., which `create_exception!`'s single base cannot
// give), imported as typed Rust exceptions.
pyo3::import_exception!(foldmatch_rs.errors, InvalidInputError);
pyo3::import_exception!(foldmatch_rs.errors, InvalidParameterError);
pyo3::import_exception!(foldmatch_rs.errors, MeshFileError);
pyo3::import_exception!(foldmatch_rs.errors, MeshFormatError);
pyo3::import_exception!(foldmatch_rs.errors, FitCancelled);
pyo3::import_exception!(foldmatch_rs.errors, NumericalError);
pyo3::import_exception!(foldmatch_rs.errors, OutOfMemoryError);
pyo3::import_exception!(foldmatch_rs.errors, RunSetupError);
pyo3::import_exception!(foldmatch_rs.errors, InternalError);

/// Maps a crate error to its exception class of `foldmatch_rs.errors`.
fn to_pyerr(err: FoldMatchError) -> PyErr {
    let message = err.to_string();
    match &err {
        FoldMatchError::Shape { .. }
        | FoldMatchError::NonFinite { .. }
        | FoldMatchError::FaceIndex { .. }
        | FoldMatchError::Landmark { .. }
        | FoldMatchError::FarAway { .. }
        | FoldMatchError::SizeMismatch { .. } => InvalidInputError::new_err(message),
        FoldMatchError::Parameter { .. } => InvalidParameterError::new_err(message),
        FoldMatchError::Io { .. } => MeshFileError::new_err(message),
        FoldMatchError::Format { .. } => MeshFormatError::new_err(message),
        FoldMatchError::Cancelled { .. } => FitCancelled::new_err(message),
        FoldMatchError::Numerical(_) => NumericalError::new_err(message),
        FoldMatchError::OutOfMemory { .. } => OutOfMemoryError::new_err(message),
    }
}

/// How often a computation's calling thread looks for signals (Ctrl-C) while it waits.
const SIGNAL_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// Runs `work` without the GIL on a worker thread, in a dedicated pool when `threads` is
/// given or after a fork, turning a panic into `InternalError`.
///
/// The calling thread waits for it and, every [`SIGNAL_POLL`], takes the GIL briefly to run
/// `Python::check_signals`: when that raises (Ctrl-C: `KeyboardInterrupt`), the flag passed
/// to `work` is set (the fit's observer and the chunked stages stop at their next check),
/// the work is waited for, its result dropped and the exception raised. Signal handlers only
/// run on Python's main thread; called from another thread, nothing is interrupted.
fn compute<T: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    work: impl FnOnce(&AtomicBool) -> T + Send,
) -> PyResult<T> {
    let cancel = AtomicBool::new(false);
    let mut interrupt: Option<PyErr> = None;
    let outcome = py.detach(|| {
        std::thread::scope(|scope| {
            let (tx, rx) = std::sync::mpsc::channel();
            let cancel = &cancel;
            let spawned = std::thread::Builder::new()
                .name("foldmatch-call".into())
                .stack_size(16 << 20)
                .spawn_scoped(scope, move || {
                    let outcome = catch_unwind(AssertUnwindSafe(|| {
                        if threads.is_some() || FORKED.load(Ordering::Relaxed) {
                            let pool = rayon::ThreadPoolBuilder::new()
                                .num_threads(threads.unwrap_or(0))
                                .build();
                            match pool {
                                Ok(pool) => Ok(pool.install(|| work(cancel))),
                                Err(e) => Err(format!("could not start {threads:?} threads: {e}")),
                            }
                        } else {
                            Ok(work(cancel))
                        }
                    }));
                    let _ = tx.send(outcome);
                });
            if let Err(e) = spawned {
                return Ok(Err(format!("could not start a worker thread: {e}")));
            }
            loop {
                match rx.recv_timeout(SIGNAL_POLL) {
                    Ok(outcome) => return outcome,
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                        if interrupt.is_none() {
                            if let Err(e) = Python::attach(|py| py.check_signals()) {
                                interrupt = Some(e);
                                cancel.store(true, Ordering::Relaxed);
                            }
                        }
                    }
                    // The worker ended without sending: only a panic in the sending itself.
                    Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                        return Ok(Err("the worker thread ended without a result".into()));
                    }
                }
            }
        })
    });
    if let Some(e) = interrupt {
        return Err(e);
    }
    match outcome {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(msg)) => Err(InternalError::new_err(msg)),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(InternalError::new_err(format!(
                "internal error (please report): {msg}"
            )))
        }
    }
}

/// A whole-number argument: a Python int that does not fit (negative, or too large) or is not
/// an int at all raises `InvalidParameterError` naming the argument, not `OverflowError`.
fn whole(name: &str, obj: &Bound<'_, PyAny>, rule: &str) -> PyResult<usize> {
    obj.extract::<usize>().map_err(|_| {
        let shown = obj
            .repr()
            .map(|r| r.to_string())
            .unwrap_or_else(|_| "?".into());
        to_pyerr(FoldMatchError::parameter(name, shown, rule))
    })
}

/// A count or size argument (`usize`).
fn count(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(name, obj, "must be a whole number >= 0")
}

/// The `threads` argument: `None`, or 1 ..= [`crate::limits::max_threads`].
fn threads_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<usize>> {
    let Some(obj) = obj else { return Ok(None) };
    let most = crate::limits::max_threads();
    let n: usize = whole(
        "threads",
        obj,
        &format!("must be a whole number in 1..={most}"),
    )?;
    crate::limits::check_threads("threads", n)
        .map(Some)
        .map_err(to_pyerr)
}

/// The `rings` argument: 1 ..= [`crate::limits::MAX_RINGS`] (the Python layer turns a
/// negative or oversized int into `InvalidParameterError` before it gets here).
fn rings_arg(n: usize) -> PyResult<usize> {
    let most = crate::limits::MAX_RINGS;
    if !(1..=most).contains(&n) {
        return Err(to_pyerr(FoldMatchError::parameter(
            "rings",
            n,
            &format!("must be in 1..={most}"),
        )));
    }
    Ok(n)
}

/// A `(n, 3)` float64 C-contiguous array viewed as points, without a copy.
fn points<'a>(name: &str, a: &'a PyReadonlyArray2<'_, f64>) -> PyResult<&'a [[f64; 3]]> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(to_pyerr(FoldMatchError::shape(
            name,
            format!("expected shape (n, 3), got {shape:?}"),
        )));
    }
    let flat = a
        .as_slice()
        .map_err(|_| to_pyerr(FoldMatchError::shape(name, "expected a C-contiguous array")))?;
    Ok(flat.as_chunks::<3>().0)
}

/// Optional `target_weights`, a `(N,)` float64 C-contiguous array, viewed without a copy (its
/// values are the core's to check).
fn weights<'a>(w: &'a Option<PyReadonlyArray1<'_, f64>>) -> PyResult<Option<&'a [f64]>> {
    w.as_ref()
        .map(|w| {
            w.as_slice().map_err(|_| {
                to_pyerr(FoldMatchError::shape(
                    "target_weights",
                    "must be a contiguous (N,) float64 array",
                ))
            })
        })
        .transpose()
}

/// A `(t, 3)` int64 face array as `u32` triples (copied: faces are small, and the indices are
/// range-checked on the way, negative ones included).
fn faces(name: &str, a: &PyReadonlyArray2<'_, i64>, n_vertices: usize) -> PyResult<Vec<[u32; 3]>> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(to_pyerr(FoldMatchError::shape(
            name,
            format!("expected shape (t, 3), got {shape:?}"),
        )));
    }
    let view = a.as_array();
    let mut out = Vec::with_capacity(shape[0]);
    for (face, row) in view.outer_iter().enumerate() {
        let mut f = [0u32; 3];
        for (c, &v) in row.iter().enumerate() {
            if v < 0 || v as usize >= n_vertices {
                return Err(to_pyerr(FoldMatchError::FaceIndex {
                    name: name.into(),
                    face,
                    vertex: v,
                    count: n_vertices,
                }));
            }
            f[c] = v as u32;
        }
        out.push(f);
    }
    Ok(out)
}

fn array2(py: Python<'_>, v: Vec<[f64; 3]>) -> Bound<'_, PyArray2<f64>> {
    let n = v.len();
    Array2::from_shape_vec((n, 3), v.into_flattened())
        .expect("n×3")
        .into_pyarray(py)
}

fn mats_to_array<'py>(py: Python<'py>, m: &[Mat3]) -> Bound<'py, PyArray3<f64>> {
    let mut flat = Vec::with_capacity(m.len() * 9);
    for a in m {
        for r in 0..3 {
            for c in 0..3 {
                flat.push(a[(r, c)]);
            }
        }
    }
    Array3::from_shape_vec((m.len(), 3, 3), flat)
        .expect("n×3×3")
        .into_pyarray(py)
}

fn array_to_mats(name: &str, a: &PyReadonlyArray3<'_, f64>) -> PyResult<Vec<Mat3>> {
    let shape = a.shape();
    if shape[1] != 3 || shape[2] != 3 {
        return Err(to_pyerr(FoldMatchError::shape(
            name,
            format!("expected shape (n, 3, 3), got {shape:?}"),
        )));
    }
    let v = a.as_array();
    Ok((0..shape[0])
        .map(|i| Mat3::from_fn(|r, c| v[[i, r, c]]))
        .collect())
}

fn csr<'a>(
    offsets: &'a PyReadonlyArray1<'_, i64>,
    members: &'a PyReadonlyArray1<'_, i64>,
) -> PyResult<rings::Neighborhoods> {
    let offsets: Vec<usize> = offsets
        .as_array()
        .iter()
        .map(|&x| x.max(0) as usize)
        .collect();
    let members: Vec<u32> = members
        .as_array()
        .iter()
        .map(|&x| x.max(0) as u32)
        .collect();
    let ok = !offsets.is_empty()
        && offsets[0] == 0
        && offsets.windows(2).all(|w| w[0] <= w[1])
        && *offsets.last().unwrap() == members.len()
        && members.iter().all(|&j| (j as usize) < offsets.len() - 1);
    if !ok {
        return Err(to_pyerr(FoldMatchError::shape(
            "neighborhoods",
            "offsets/members do not form a valid CSR over the vertices",
        )));
    }
    Ok(rings::Neighborhoods { offsets, members })
}

/// The settings of a stage function (`nbody_step`, `foldmatch_update`): the default's, with
/// the given ones over them.
fn params_from(py: Python<'_>, given: Option<&Bound<'_, PyDict>>) -> PyResult<FitParams> {
    params::over(py, &FitParams::default(), given)
}

/// Fits a template to a target; see `foldmatch_rs.fit`.
#[pyfunction]
#[pyo3(signature = (template_vertices, template_faces, target, target_faces, params, callback=None, threads=None, target_weights=None, landmark_vertices=None, landmark_positions=None, target_normals=None))]
#[allow(clippy::too_many_arguments)]
fn fit_raw<'py>(
    py: Python<'py>,
    template_vertices: PyReadonlyArray2<'py, f64>,
    template_faces: PyReadonlyArray2<'py, i64>,
    target: PyReadonlyArray2<'py, f64>,
    target_faces: Option<PyReadonlyArray2<'py, i64>>,
    params: &Bound<'py, PyDict>,
    callback: Option<Py<PyAny>>,
    threads: Option<Bound<'py, PyAny>>,
    target_weights: Option<PyReadonlyArray1<'py, f64>>,
    landmark_vertices: Option<PyReadonlyArray1<'py, i64>>,
    landmark_positions: Option<PyReadonlyArray2<'py, f64>>,
    target_normals: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let threads = threads_arg(threads.as_ref())?;
    let params = params::from_dict(py, params)?;
    let normals = match &target_normals {
        Some(n) => Some(points("target_normals", n)?),
        None => None,
    };
    let tv = points("template_vertices", &template_vertices)?;
    let x = points("target", &target)?;
    let tf = faces("template_faces", &template_faces, tv.len())?;
    crate::limits::check_snapshots(&params, tv.len()).map_err(to_pyerr)?;
    let xf = match &target_faces {
        Some(f) => Some(faces("target_faces", f, x.len())?),
        None => None,
    };
    let weights = weights(&target_weights)?;
    let landmarks = match (&landmark_vertices, &landmark_positions) {
        (Some(v), Some(p)) => {
            let v = v.as_slice().map_err(|_| {
                to_pyerr(FoldMatchError::shape(
                    "landmarks",
                    "vertex indices must be a contiguous (L,) int64 array",
                ))
            })?;
            let p = points("landmarks", p)?;
            Some(Landmarks::new(v, p, tv.len()).map_err(to_pyerr)?)
        }
        (None, None) => None,
        _ => {
            return Err(to_pyerr(FoldMatchError::shape(
                "landmarks",
                "need both the vertex indices and the target positions",
            )))
        }
    };
    let mut callback_error: Option<PyErr> = None;
    let result = {
        let callback_error = &mut callback_error;
        let callback = &callback;
        // Every iteration: stop when Ctrl-C was seen (`compute` sets `cancel`), else call the
        // callback (with the GIL, briefly).
        let mut step = move |cancel: &AtomicBool, p: &Progress| -> bool {
            if cancel.load(Ordering::Relaxed) {
                return false;
            }
            let Some(cb) = callback else { return true };
            Python::attach(|py| {
                let info = PyDict::new(py);
                let filled = info
                    .set_item("iteration", p.iteration)
                    .and_then(|_| info.set_item("iterations", p.iterations))
                    .and_then(|_| info.set_item("mean_displacement", p.record.mean_displacement))
                    .and_then(|_| info.set_item("max_displacement", p.record.max_displacement));
                match filled.and_then(|_| cb.call1(py, (info,))) {
                    // Only an explicit `False` stops the fit (None continues).
                    Ok(ret) => {
                        !ret.bind(py).is_instance_of::<pyo3::types::PyBool>()
                            || ret.is_truthy(py).unwrap_or(true)
                    }
                    Err(e) => {
                        *callback_error = Some(e);
                        false
                    }
                }
            })
        };
        compute(py, threads, |cancel| {
            let mut observer = |p: &Progress| step(cancel, p);
            let landmarks = landmarks.as_ref();
            let extras = fit::ScanExtras {
                faces: xf.as_deref(),
                weights,
                normals,
                landmarks,
            };
            fit::fit_scan(tv, &tf, x, &extras, &params, &mut observer)
        })?
    };
    if let Some(e) = callback_error {
        return Err(e);
    }
    result_dict(py, result.map_err(to_pyerr)?)
}

/// A fit's outcome as `fit_raw` returns it: every array and figure of `FitResult`, by name.
fn result_dict(py: Python<'_>, r: fit::FitResult) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("wvf_magnitude", fit::magnitudes(&r.wvf).into_pyarray(py))?;
    d.set_item(
        "wvf_accumulated_magnitude",
        fit::magnitudes(&r.wvf_accumulated).into_pyarray(py),
    )?;
    d.set_item("vertices", array2(py, r.vertices))?;
    d.set_item("wvf", array2(py, r.wvf))?;
    d.set_item("wvf_accumulated", array2(py, r.wvf_accumulated))?;
    d.set_item("iterations", r.iterations)?;
    let h = &r.history;
    d.set_item(
        "mean_displacement",
        h.iter()
            .map(|x| x.mean_displacement)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "max_displacement",
        h.iter()
            .map(|x| x.max_displacement)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "degenerate_gradients",
        h.iter()
            .map(|x| x.degenerate_gradients as u64)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    let snaps: Vec<(usize, Bound<'_, PyArray2<f64>>)> = r
        .snapshots
        .into_iter()
        .map(|(i, s)| (i, array2(py, s)))
        .collect();
    d.set_item("snapshots", snaps)?;
    d.set_item("params", params::to_dict(py, &r.params)?)?;
    let diagnostics = pythonize::pythonize(py, &r.diagnostics)
        .map_err(|e| InternalError::new_err(format!("diagnostics: {e}")))?;
    d.set_item("diagnostics", diagnostics)?;
    d.set_item("garment_points", r.garment_points.into_pyarray(py))?;
    quality::assessment_items(
        &d,
        crate::quality::Assessment {
            quality: r.quality,
            correspondences: r.correspondences,
            residuals: r.residuals,
            support: r.support,
        },
    )?;
    Ok(d)
}

/// The generated folded-sheet case: a dict of arrays (template_vertices, faces, ground_truth,
/// scan).
#[pyfunction]
#[pyo3(signature = (nx=41, ny=41, width=1.0, height=1.0, fold_amplitude=0.06, folds=2.5, rotation_degrees=8.0, offset=(0.03, -0.02, 0.04), scan_points=0, noise=0.0, seed=1))]
#[allow(clippy::too_many_arguments)]
fn folded_sheet<'py>(
    py: Python<'py>,
    nx: usize,
    ny: usize,
    width: f64,
    height: f64,
    fold_amplitude: f64,
    folds: f64,
    rotation_degrees: f64,
    offset: (f64, f64, f64),
    scan_points: usize,
    noise: f64,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let spec = synthetic::SheetSpec {
        nx,
        ny,
        width,
        height,
        fold_amplitude,
        folds,
        rotation_degrees,
        offset: [offset.0, offset.1, offset.2],
        scan_points,
        noise,
        seed,
    };
    spec.validate().map_err(to_pyerr)?;
    let c = compute(py, None, |_| synthetic::folded_sheet(&spec))?;
    let d = PyDict::new(py);
    d.set_item("template_vertices", array2(py, c.template_vertices))?;
    let faces: Vec<i64> = c.faces.iter().flat_map(|f| f.map(i64::from)).collect();
    d.set_item(
        "faces",
        Array2::from_shape_vec((c.faces.len(), 3), faces)
            .expect("t×3")
            .into_pyarray(py),
    )?;
    d.set_item("ground_truth", array2(py, c.ground_truth))?;
    d.set_item("scan", array2(py, c.scan))?;
    Ok(d)
}

/// The paper's metrics (paper §4) of a fit: a dict keyed by the metric names.
#[pyfunction]
#[pyo3(signature = (template_vertices, template_faces, fitted_vertices, target, ground_truth=None, tau_s=0.02, tau_e=2.0, target_weights=None))]
#[allow(clippy::too_many_arguments)]
fn evaluate<'py>(
    py: Python<'py>,
    template_vertices: PyReadonlyArray2<'py, f64>,
    template_faces: PyReadonlyArray2<'py, i64>,
    fitted_vertices: PyReadonlyArray2<'py, f64>,
    target: PyReadonlyArray2<'py, f64>,
    ground_truth: Option<PyReadonlyArray2<'py, f64>>,
    tau_s: f64,
    tau_e: f64,
    target_weights: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let weights = weights(&target_weights)?;
    let tv = points("template_vertices", &template_vertices)?;
    let fv = points("fitted_vertices", &fitted_vertices)?;
    let x = points("target", &target)?;
    let gt = match &ground_truth {
        Some(g) => Some(points("ground_truth", g)?),
        None => None,
    };
    let f = faces("template_faces", &template_faces, tv.len())?;
    let params = metrics::MetricsParams {
        tau_s,
        tau_e,
        ..Default::default()
    };
    let input = metrics::MetricsInput {
        template_vertices: tv,
        faces: &f,
        fitted_vertices: fv,
        target: x,
        ground_truth: gt,
    };
    let m = compute(py, None, |_| {
        metrics::evaluate_weighted(&input, weights, &params)
    })?
    .map_err(to_pyerr)?;
    let d = PyDict::new(py);
    d.set_item("f_H", m.f_h)?;
    d.set_item("f_S", m.f_s)?;
    d.set_item("f_E", m.f_e)?;
    d.set_item("f_F", m.f_f)?;
    d.set_item("f_R", m.f_r)?;
    d.set_item("f_lambda", m.f_lambda)?;
    d.set_item("f_lambda_terms", m.f_lambda_terms)?;
    d.set_item("chamfer", m.chamfer)?;
    d.set_item("scan_to_fit_mean", m.scan_to_fit_mean)?;
    d.set_item("scan_to_fit_p95", m.scan_to_fit_p95)?;
    d.set_item("fit_to_scan_mean", m.fit_to_scan_mean)?;
    d.set_item("hausdorff_before", m.hausdorff_before)?;
    d.set_item("hausdorff_after", m.hausdorff_after)?;
    d.set_item("rmse", m.rmse)?;
    d.set_item("target_diagonal", m.target_diagonal)?;
    d.set_item("num_faces", m.num_faces)?;
    d.set_item("num_degenerate_faces", m.num_degenerate_faces)?;
    d.set_item("num_evaluated_faces", m.num_evaluated_faces)?;
    d.set_item("num_collapsed_faces", m.num_collapsed_faces)?;
    d.set_item("num_expanded_faces", m.num_expanded_faces)?;
    d.set_item("num_flipped_faces", m.num_flipped_faces)?;
    Ok(d)
}

/// Marks this process as a forked child (registered with `os.register_at_fork`).
#[pyfunction]
fn _mark_forked() {
    FORKED.store(true, Ordering::Relaxed);
}

/// Runs the `foldmatch` command line program (the same Rust code as the standalone binary)
/// with `argv` (`argv[0]` is the program name) and returns its exit code; used by
/// `python -m foldmatch_rs` and the `foldmatch` console script. The GIL is released while it
/// runs; it installs a Ctrl-C handler for the process (see `cli::run`).
#[pyfunction]
fn run_cli(py: Python<'_>, argv: Vec<String>) -> i32 {
    py.detach(|| crate::cli::run(argv))
}

/// The compiled core of `foldmatch_rs`.
#[pymodule]
fn _foldmatch_rs(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(params::fit_params, m)?)?;
    m.add_function(wrap_pyfunction!(params::param_names, m)?)?;
    m.add_function(wrap_pyfunction!(params::param_reference, m)?)?;
    m.add_function(wrap_pyfunction!(meshes::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(meshes::read_weights, m)?)?;
    m.add_function(wrap_pyfunction!(meshes::read_normals, m)?)?;
    m.add_function(wrap_pyfunction!(fit_raw, m)?)?;
    m.add_function(wrap_pyfunction!(stages::knn_query, m)?)?;
    m.add_function(wrap_pyfunction!(stages::nbody_step, m)?)?;
    m.add_function(wrap_pyfunction!(stages::n_rings, m)?)?;
    m.add_function(wrap_pyfunction!(stages::gaussian_curvature, m)?)?;
    m.add_function(wrap_pyfunction!(stages::prealign_transform, m)?)?;
    m.add_function(wrap_pyfunction!(stages::deformation_gradients, m)?)?;
    m.add_function(wrap_pyfunction!(stages::regularize_gradients, m)?)?;
    m.add_function(wrap_pyfunction!(stages::polar_decomposition, m)?)?;
    m.add_function(wrap_pyfunction!(stages::wrinkle_field, m)?)?;
    m.add_function(wrap_pyfunction!(stages::solve_rotations, m)?)?;
    m.add_function(wrap_pyfunction!(stages::foldmatch_update, m)?)?;
    m.add_function(wrap_pyfunction!(folded_sheet, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(quality::assess_raw, m)?)?;
    m.add_function(wrap_pyfunction!(_mark_forked, m)?)?;
    m.add_function(wrap_pyfunction!(run_cli, m)?)?;
    m.add_function(wrap_pyfunction!(render::render_preview, m)?)?;
    m.add_function(wrap_pyfunction!(render::wrinkle_colors, m)?)?;
    m.add_function(wrap_pyfunction!(render::write_fitted, m)?)?;
    m.add_function(wrap_pyfunction!(cluster::cluster_request, m)?)?;
    m.add_class::<cluster::RunBook>()?;
    m.add_class::<track::Tracker>()?;
    m.add_class::<cluster::FileFitter>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
