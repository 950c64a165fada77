//! The FoldMatch deformation model (Eq. 4–8) on one motion of the template: deformation
//! gradients, their regularization, the ψ-modified stretch, the wrinkle vectors and the
//! rotation solve.

use super::params::{FitParams, RotationSource};
use super::result::{timed, StageTimes};
use crate::deformation::deformation_gradient;
use crate::math::Mat3;
use crate::mesh::{vertex_normals, VertexFaces};
use crate::regularize::{regularize, RegularizeBuffers};
use crate::rings::Neighborhoods;
use crate::rotation::{solve_rotation, PointMoments};
use crate::wrinkle::{modified_stretch, stretch_stays_positive};
use rayon::prelude::*;

/// Per-vertex buffers of the FoldMatch deformation model, allocated once per fit.
pub struct Workspace {
    normals_old: Vec<[f64; 3]>,
    normals_new: Vec<[f64; 3]>,
    raw: Vec<Mat3>,
    degenerate: Vec<bool>,
    reg: RegularizeBuffers,
    reg_rotation: Vec<Mat3>,
    reg_stretch: Vec<Mat3>,
    /// Wrinkle vector of every vertex from the last [`deformation_model`] call (Eq. 6–7).
    pub wvf: Vec<[f64; 3]>,
    /// Whether the last deformation step left `wvf` to [`Workspace::fill_wrinkle_field`].
    wvf_stale: bool,
    /// Solved rotation R_k* of every vertex.
    pub rotation: Vec<Mat3>,
    /// Per-point moments of the coarse phase's Kabsch fits ([`ring_fit_from_moments`](crate::rotation::ring_fit_from_moments)), and
    /// their sums over every vertex's coarse ring ([`RingDeltas::sums`](crate::rings::RingDeltas::sums)).
    pub(super) moments: Vec<PointMoments>,
    pub(super) ring_sums: Vec<PointMoments>,
    /// Seconds spent per stage so far.
    pub times: StageTimes,
}

impl Workspace {
    /// Buffers for `m` vertices.
    pub fn new(m: usize) -> Self {
        Self {
            normals_old: vec![[0.0; 3]; m],
            normals_new: vec![[0.0; 3]; m],
            raw: vec![Mat3::identity(); m],
            degenerate: vec![false; m],
            reg: RegularizeBuffers::new(m),
            reg_rotation: vec![Mat3::identity(); m],
            reg_stretch: vec![Mat3::identity(); m],
            wvf: vec![[0.0; 3]; m],
            wvf_stale: false,
            rotation: vec![Mat3::identity(); m],
            moments: vec![[0.0; 15]; m],
            ring_sums: vec![[0.0; 15]; m],
            times: StageTimes::default(),
        }
    }

    /// The wrinkle-vector field (Eq. 6–7) of the last deformation step, from its regularized
    /// stretches, if that step left it stale.
    pub fn fill_wrinkle_field(&mut self, params: &FitParams) {
        if !std::mem::take(&mut self.wvf_stale) {
            return;
        }
        let start = std::time::Instant::now();
        let stretch = &self.reg_stretch;
        self.wvf.par_iter_mut().enumerate().for_each(|(k, w)| {
            *w = modified_stretch(&stretch[k], params.model.psi)
                .wrinkle
                .into();
        });
        self.times.rotation += start.elapsed().as_secs_f64();
    }
}

/// The mesh-side inputs of the deformation model.
pub struct TemplateTopology<'a> {
    /// Template faces (cleaned).
    pub faces: &'a [[u32; 3]],
    /// Vertex → faces incidence.
    pub incidence: &'a VertexFaces,
    /// Γᵏ_Y.
    pub rings: &'a Neighborhoods,
}

/// Runs Eq. 4–8 on the motion `old → new`: fills `ws.rotation` (R_k*) and `ws.wvf`, and returns
/// the number of rank-deficient gradients.
pub fn deformation_model(
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    topo: &TemplateTopology<'_>,
    params: &FitParams,
    ws: &mut Workspace,
) -> usize {
    let degenerate = deformation_rotations(old, new, topo, params, ws);
    ws.fill_wrinkle_field(params);
    degenerate
}

/// [`deformation_model`] without the wrinkle-vector field, which only the last iteration's
/// state needs (the fit computes it once from `ws`'s regularized stretches when it finishes,
/// [`Workspace::fill_wrinkle_field`]): fills `ws.rotation` and marks `ws.wvf` stale.
///
/// Eq. 8's rotation is the polar factor of `H̄ Ûᵀ = R̄ Ū Û`. With the regularized gradient as
/// its source (the default), Ū and Û share their eigenvectors, so `Ū Û` is symmetric and,
/// where every ψ-modified eigenvalue stays positive ([`stretch_stays_positive`]), positive
/// definite: the polar factor is then `R̄` itself, and the Procrustes solve and the
/// ψ-stretch's eigen-decomposition are skipped (under `matrix_series`; equal to round-off, the
/// solve's own error). Elsewhere, and with `matrix_series` off, both are computed.
pub(super) fn deformation_rotations(
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    topo: &TemplateTopology<'_>,
    params: &FitParams,
    ws: &mut Workspace,
) -> usize {
    let mut times = ws.times;
    timed(&mut times.gradient, || {
        vertex_normals(old, topo.faces, topo.incidence, &mut ws.normals_old);
        vertex_normals(new, topo.faces, topo.incidence, &mut ws.normals_new);
        let (n_old, n_new) = (&ws.normals_old, &ws.normals_new);
        ws.raw
            .par_iter_mut()
            .zip(ws.degenerate.par_iter_mut())
            .enumerate()
            .for_each(|(k, (h, deg))| {
                let (g, d) = deformation_gradient(
                    k,
                    topo.rings.of(k),
                    old,
                    new,
                    &n_old[k],
                    &n_new[k],
                    params.model.normal_completion,
                    params.internal.matrix_series,
                );
                *h = g;
                *deg = d;
            });
    });
    timed(&mut times.regularize, || {
        regularize(
            &ws.raw,
            topo.rings,
            params.readings.regularization,
            params.internal.matrix_series,
            &mut ws.reg,
            &mut ws.reg_rotation,
            &mut ws.reg_stretch,
        )
    });
    timed(&mut times.rotation, || {
        let (raw, reg_r, reg_u) = (&ws.raw, &ws.reg_rotation, &ws.reg_stretch);
        let shortcut = params.internal.matrix_series
            && params.readings.rotation_source == RotationSource::Regularized;
        ws.rotation.par_iter_mut().enumerate().for_each(|(k, rot)| {
            if shortcut && stretch_stays_positive(&reg_u[k], params.model.psi) {
                *rot = reg_r[k];
                return;
            }
            let m = modified_stretch(&reg_u[k], params.model.psi);
            let h = match params.readings.rotation_source {
                RotationSource::Regularized => reg_r[k] * reg_u[k],
                RotationSource::Raw => raw[k],
            };
            *rot = solve_rotation(&h, &m.stretch, params.internal.matrix_series);
        });
    });
    ws.times = times;
    ws.wvf_stale = true;
    ws.degenerate.iter().filter(|&&d| d).count()
}
