//! The method's building blocks one call at a time (`foldmatch_rs.knn`, `nbody_step`,
//! `n_rings`, `gaussian_curvature`, `prealign`, `deformation_gradients`, `regularize`,
//! `polar_decomposition`, `wrinkle_field`, `solve_rotations`, `foldmatch_update`): each
//! stage of an iteration (paper §2–3, docs/method.md) exposed on its own, for inspection,
//! teaching and tests against the paper's equations.

#![allow(clippy::type_complexity)] // tuples of NumPy arrays returned to Python

use super::*;

/// k nearest neighbours: `(indices (q, k) uint32, squared distances (q, k))`.
#[pyfunction]
#[pyo3(signature = (points, queries, k, threads=None))]
pub(super) fn knn_query<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    queries: PyReadonlyArray2<'py, f64>,
    k: Bound<'py, PyAny>,
    threads: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyArray2<u32>>, Bound<'py, PyArray2<f64>>)> {
    let k = count("k", &k)?;
    let threads = threads_arg(threads.as_ref())?;
    let p = self::points("points", &points)?;
    let q = self::points("queries", &queries)?;
    crate::mesh::validate_points("points", p).map_err(to_pyerr)?;
    if k == 0 || k > p.len() {
        return Err(to_pyerr(FoldMatchError::parameter(
            "k",
            k,
            &format!("must be in 1..={}", p.len()),
        )));
    }
    // q·k results: reserved up front, a failure is OutOfMemoryError.
    let cells = q
        .len()
        .checked_mul(k)
        .ok_or_else(|| to_pyerr(FoldMatchError::out_of_memory("knn results", usize::MAX)))?;
    let mut idx = crate::limits::try_vec::<u32>(cells, "knn results").map_err(to_pyerr)?;
    let mut d2 = crate::limits::try_vec::<f64>(cells, "knn results").map_err(to_pyerr)?;
    idx.resize(cells, 0);
    d2.resize(cells, 0.0);
    let (idx, d2) = compute(py, threads, |cancel| {
        let index = knn::PointIndex::new(p);
        // In chunks of queries, so that Ctrl-C stops it between two.
        const CHUNK: usize = 1 << 15;
        for (c, qs) in q.chunks(CHUNK).enumerate() {
            if cancel.load(Ordering::Relaxed) {
                break;
            }
            let range = c * CHUNK * k..(c * CHUNK + qs.len()) * k;
            index.nearest_all(qs, k, &mut idx[range.clone()], &mut d2[range]);
        }
        (idx, d2)
    })?;
    Ok((
        Array2::from_shape_vec((q.len(), k), idx)
            .expect("q×k")
            .into_pyarray(py),
        Array2::from_shape_vec((q.len(), k), d2)
            .expect("q×k")
            .into_pyarray(py),
    ))
}

/// One N-body step (Eq. 2–3): `(velocities, proposed positions)`.
#[pyfunction]
#[pyo3(signature = (positions, velocities, target, neighbours, curvature, params=None))]
pub(super) fn nbody_step<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray2<'py, f64>,
    velocities: PyReadonlyArray2<'py, f64>,
    target: PyReadonlyArray2<'py, f64>,
    neighbours: PyReadonlyArray2<'py, i64>,
    curvature: PyReadonlyArray1<'py, f64>,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>)> {
    let params = params_from(py, params)?;
    let y = points("positions", &positions)?;
    let v = points("velocities", &velocities)?;
    let x = points("target", &target)?;
    let kappa = curvature.as_slice().map_err(|_| {
        to_pyerr(FoldMatchError::shape(
            "curvature",
            "expected a contiguous 1-D array",
        ))
    })?;
    let nshape = neighbours.shape();
    if v.len() != y.len() || nshape[0] != y.len() || nshape[1] == 0 || kappa.len() != x.len() {
        return Err(to_pyerr(FoldMatchError::shape(
            "nbody_step",
            "positions, velocities and neighbours need M rows; curvature needs N values",
        )));
    }
    let k = nshape[1];
    let mut nn = Vec::with_capacity(y.len() * k);
    for &j in neighbours.as_array().iter() {
        if j < 0 || j as usize >= x.len() {
            return Err(to_pyerr(FoldMatchError::shape(
                "neighbours",
                format!("index {j} out of range 0..{}", x.len()),
            )));
        }
        nn.push(j as u32);
    }
    let (vel, prop) = compute(py, None, |_| {
        let mut vel = v.to_vec();
        let mut prop = vec![[0.0; 3]; y.len()];
        nbody::step(
            y,
            &mut vel,
            &nn,
            k,
            x,
            kappa,
            None,
            None,
            &params.model.nbody,
            None,
            &mut prop,
        );
        (vel, prop)
    })?;
    Ok((array2(py, vel), array2(py, prop)))
}

/// n-ring neighborhoods as CSR `(offsets (M+1,), members)`, each row starting with the vertex.
#[pyfunction]
#[pyo3(signature = (faces, n_vertices, rings=2))]
pub(super) fn n_rings<'py>(
    py: Python<'py>,
    faces: PyReadonlyArray2<'py, i64>,
    n_vertices: Bound<'py, PyAny>,
    rings: usize,
) -> PyResult<(Bound<'py, PyArray1<u64>>, Bound<'py, PyArray1<u32>>)> {
    let most = crate::limits::MAX_VERTICES;
    let n_vertices: usize = whole(
        "n_vertices",
        &n_vertices,
        &format!("must be a whole number in 0..={most}"),
    )?;
    if n_vertices > most {
        return Err(to_pyerr(FoldMatchError::parameter(
            "n_vertices",
            n_vertices,
            &format!("must be at most {most} (32-bit vertex indices)"),
        )));
    }
    let rings = rings_arg(rings)?;
    let f = self::faces("faces", &faces, n_vertices)?;
    // Every vertex is in its own ring: offsets and members take at least 12 bytes a vertex.
    // Ask for them first, so that a count the machine cannot hold is OutOfMemoryError.
    drop(
        crate::limits::try_vec::<[u32; 3]>(n_vertices.saturating_add(1), "n_rings")
            .map_err(to_pyerr)?,
    );
    let nb = compute(py, None, |_| rings::n_rings(&f, n_vertices, rings))?;
    let offsets: Vec<u64> = nb.offsets.iter().map(|&o| o as u64).collect();
    Ok((offsets.into_pyarray(py), nb.members.into_pyarray(py)))
}

/// Gaussian curvature per point: angle deficit when `faces` is given, quadric fit otherwise.
#[pyfunction]
#[pyo3(signature = (points, faces=None))]
pub(super) fn gaussian_curvature<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    faces: Option<PyReadonlyArray2<'py, i64>>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let p = self::points("points", &points)?;
    crate::mesh::validate_points("points", p).map_err(to_pyerr)?;
    let f = match &faces {
        Some(f) => Some(self::faces("faces", f, p.len())?),
        None => None,
    };
    let k = compute(py, None, |_| match &f {
        Some(f) => curvature::gaussian_curvature_mesh(p, f),
        None => curvature::gaussian_curvature_points(p, &knn::PointIndex::new(p)),
    })?;
    Ok(k.into_pyarray(py))
}

/// Global pre-alignment of a template onto a scan ([`crate::prealign::align`]): the transform
/// `p ↦ scale · rotation · p + translation` and the two-sided distances before and after.
#[pyfunction]
#[pyo3(signature = (template_vertices, target, scaled=false))]
pub(super) fn prealign_transform<'py>(
    py: Python<'py>,
    template_vertices: PyReadonlyArray2<'py, f64>,
    target: PyReadonlyArray2<'py, f64>,
    scaled: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let t = points("template_vertices", &template_vertices)?;
    let x = points("target", &target)?;
    crate::mesh::validate_points("template_vertices", t).map_err(to_pyerr)?;
    crate::mesh::validate_points("target", x).map_err(to_pyerr)?;
    let motion = if scaled {
        prealign::Motion::Similarity
    } else {
        prealign::Motion::Rigid
    };
    let a = compute(py, None, |_| prealign::align(t, x, motion))?;
    let r = a.transform.rotation;
    let d = PyDict::new(py);
    d.set_item(
        "rotation",
        Array2::from_shape_fn((3, 3), |(i, j)| r[(i, j)]).into_pyarray(py),
    )?;
    d.set_item("scale", a.transform.scale)?;
    let tr = a.transform.translation;
    d.set_item(
        "translation",
        Array1::from_vec(vec![tr.x, tr.y, tr.z]).into_pyarray(py),
    )?;
    d.set_item("score", a.score)?;
    d.set_item("identity_score", a.identity_score)?;
    d.set_item("searched", a.searched)?;
    d.set_item("readings", a.readings)?;
    Ok(d)
}

/// Deformation gradients (Eq. 4) of the motion `old → new` over n-ring neighborhoods:
/// `(gradients (M, 3, 3), degenerate (M,) bool)`.
#[pyfunction]
#[pyo3(signature = (old, new, faces, rings=2, normal_completion=0.3))]
pub(super) fn deformation_gradients<'py>(
    py: Python<'py>,
    old: PyReadonlyArray2<'py, f64>,
    new: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    rings: usize,
    normal_completion: f64,
) -> PyResult<(Bound<'py, PyArray3<f64>>, Bound<'py, PyArray1<bool>>)> {
    let rings = rings_arg(rings)?;
    let o = points("old", &old)?;
    let n = points("new", &new)?;
    if o.len() != n.len() {
        return Err(to_pyerr(FoldMatchError::shape(
            "new",
            format!("expected {} rows like old, got {}", o.len(), n.len()),
        )));
    }
    let f = self::faces("faces", &faces, o.len())?;
    let (h, deg) = compute(py, None, |_| {
        let clean = crate::mesh::clean_faces(&f).faces;
        let inc = crate::mesh::VertexFaces::new(&clean, o.len());
        let nb = rings::n_rings(&clean, o.len(), rings);
        let mut no = vec![[0.0; 3]; o.len()];
        let mut nn = vec![[0.0; 3]; o.len()];
        crate::mesh::vertex_normals(o, &clean, &inc, &mut no);
        crate::mesh::vertex_normals(n, &clean, &inc, &mut nn);
        (0..o.len())
            .map(|k| {
                deformation::deformation_gradient(
                    k,
                    nb.of(k),
                    o,
                    n,
                    &no[k],
                    &nn[k],
                    normal_completion,
                    false,
                )
            })
            .unzip::<_, _, Vec<_>, Vec<_>>()
    })?;
    Ok((
        mats_to_array(py, &h),
        Array1::from_vec(deg).into_pyarray(py),
    ))
}

/// Regularization (Eq. 5): `(rotations, stretches)`, each (M, 3, 3).
#[pyfunction]
#[pyo3(signature = (gradients, offsets, members, mode="affine_invariant"))]
pub(super) fn regularize_gradients<'py>(
    py: Python<'py>,
    gradients: PyReadonlyArray3<'py, f64>,
    offsets: PyReadonlyArray1<'py, i64>,
    members: PyReadonlyArray1<'py, i64>,
    mode: &str,
) -> PyResult<(Bound<'py, PyArray3<f64>>, Bound<'py, PyArray3<f64>>)> {
    let h = array_to_mats("gradients", &gradients)?;
    let nb = csr(&offsets, &members)?;
    if nb.len() != h.len() {
        return Err(to_pyerr(FoldMatchError::shape(
            "offsets",
            format!("expected {} rows, got {}", h.len(), nb.len()),
        )));
    }
    let mode: regularize::Regularization =
        serde_json::from_value(serde_json::Value::String(mode.into())).map_err(|_| {
            to_pyerr(FoldMatchError::parameter(
                "mode",
                mode,
                "one of affine_invariant, log_euclidean, none",
            ))
        })?;
    let (r, u) = compute(py, None, |_| {
        let mut buf = regularize::RegularizeBuffers::new(h.len());
        let (mut r, mut u) = (vec![Mat3::zeros(); h.len()], vec![Mat3::zeros(); h.len()]);
        regularize::regularize(&h, &nb, mode, true, &mut buf, &mut r, &mut u);
        (r, u)
    })?;
    Ok((mats_to_array(py, &r), mats_to_array(py, &u)))
}

/// Polar decomposition `H = R U` of every matrix: `(rotations, stretches)`.
#[pyfunction]
pub(super) fn polar_decomposition<'py>(
    py: Python<'py>,
    matrices: PyReadonlyArray3<'py, f64>,
) -> PyResult<(Bound<'py, PyArray3<f64>>, Bound<'py, PyArray3<f64>>)> {
    let h = array_to_mats("matrices", &matrices)?;
    let (r, u): (Vec<Mat3>, Vec<Mat3>) = h
        .iter()
        .map(|m| {
            let p = crate::math::polar(m);
            (p.rotation, p.stretch)
        })
        .unzip();
    Ok((mats_to_array(py, &r), mats_to_array(py, &u)))
}

/// ψ-modified stretch and wrinkle vectors (Eq. 6–7): `(modified stretches (M,3,3), wvf (M,3))`.
#[pyfunction]
#[pyo3(signature = (stretches, psi=0.05))]
pub(super) fn wrinkle_field<'py>(
    py: Python<'py>,
    stretches: PyReadonlyArray3<'py, f64>,
    psi: f64,
) -> PyResult<(Bound<'py, PyArray3<f64>>, Bound<'py, PyArray2<f64>>)> {
    let u = array_to_mats("stretches", &stretches)?;
    let (uh, w): (Vec<Mat3>, Vec<[f64; 3]>) = u
        .iter()
        .map(|m| {
            let s = wrinkle::modified_stretch(m, psi);
            (s.stretch, <[f64; 3]>::from(s.wrinkle))
        })
        .unzip();
    Ok((mats_to_array(py, &uh), array2(py, w)))
}

/// Rotation solve of Eq. 8 for every vertex: `argmin_R ‖H − R Û‖_F`, (M, 3, 3).
#[pyfunction]
pub(super) fn solve_rotations<'py>(
    py: Python<'py>,
    gradients: PyReadonlyArray3<'py, f64>,
    modified_stretches: PyReadonlyArray3<'py, f64>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let h = array_to_mats("gradients", &gradients)?;
    let u = array_to_mats("modified_stretches", &modified_stretches)?;
    if h.len() != u.len() {
        return Err(to_pyerr(FoldMatchError::shape(
            "modified_stretches",
            "needs as many matrices as gradients",
        )));
    }
    let r: Vec<Mat3> = h
        .iter()
        .zip(&u)
        .map(|(h, u)| rotation::solve_rotation(h, u, false))
        .collect();
    Ok(mats_to_array(py, &r))
}

/// One FoldMatch update (Eq. 4–8 and the per-vertex transform) of the motion `old → proposed`:
/// `(new positions (M,3), per-step wvf (M,3))`.
#[pyfunction]
#[pyo3(signature = (old, proposed, faces, params=None))]
pub(super) fn foldmatch_update<'py>(
    py: Python<'py>,
    old: PyReadonlyArray2<'py, f64>,
    proposed: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>)> {
    let params = params_from(py, params)?;
    let o = points("old", &old)?;
    let n = points("proposed", &proposed)?;
    if o.len() != n.len() {
        return Err(to_pyerr(FoldMatchError::shape(
            "proposed",
            "needs as many rows as old",
        )));
    }
    let f = self::faces("faces", &faces, o.len())?;
    let (next, wvf) = compute(py, None, |_| {
        let clean = crate::mesh::clean_faces(&f).faces;
        let inc = crate::mesh::VertexFaces::new(&clean, o.len());
        let nb = rings::n_rings(&clean, o.len(), params.model.rings);
        let topo = fit::TemplateTopology {
            faces: &clean,
            incidence: &inc,
            rings: &nb,
        };
        let mut ws = fit::Workspace::new(o.len());
        fit::deformation_model(o, n, &topo, &params, &mut ws);
        let next: Vec<[f64; 3]> = (0..o.len())
            .map(|v| {
                let (co, cn) = rotation::ring_centroids(nb.of(v), o, n);
                rotation::transform_vertex(&ws.rotation[v], &crate::math::vec3(&o[v]), &co, &cn)
                    .into()
            })
            .collect();
        (next, ws.wvf)
    })?;
    Ok((array2(py, next), array2(py, wvf)))
}
