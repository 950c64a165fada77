//! Tensor-interpolation regularization of the deformation gradients (paper Eq. 5; docs/method.md
//! "Regularization, Eq. 5").
//!
//! The printed formula is the affine-invariant (Riemannian) mean step for SPD matrices, but
//! H_k carries a rotation, so it is applied to the stretch part (Arsigny et al. / Pennec's
//! tensor interpolation): every `H_j = R_j U_j` is polar-decomposed, then
//!
//! `Ū_k = U_k^{½} exp(Σ β_j log(U_k^{-½} U_j U_k^{-½})) U_k^{½}`  (affine-invariant, default)
//! `Ū_k = exp(Σ β_j log U_j)`                                       (log-Euclidean, faster)
//!
//! and the rotations are averaged separately by the chordal mean `R̄_k = proj_SO(3)(Σ β_j R_j)`.
//! The regularized gradient is `H̄_k = R̄_k Ū_k`.

use crate::math::{
    nearest_rotation, nearest_rotation_of_near_rotation, polar, polar_fast, polar_with_roots,
    spd_log, spd_log_near_identity, spd_roots, sym_exp, sym_exp_small, Mat3, SpdRoots,
};
use crate::rings::Neighborhoods;
use rayon::prelude::*;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Which mean regularizes the stretch tensors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Regularization {
    /// Eq. 5 on the stretch part, as printed (the `"paper"` preset).
    AffineInvariant,
    /// Log-Euclidean mean `exp(Σ β log U_j)` (the default: the same fits to four digits on
    /// the benchmark, one logarithm per vertex instead of one per neighbor pair).
    LogEuclidean,
    /// No regularization: `H̄_k = R_k U_k` (the polar-projected raw gradient).
    None,
}

/// Per-vertex buffers of the regularization stage, allocated once per fit.
#[derive(Clone, Debug, Default)]
pub struct RegularizeBuffers {
    /// Rotation factor R_j of every raw gradient.
    pub rotation: Vec<Mat3>,
    /// Stretch factor U_j of every raw gradient (or `log U_j` for the log-Euclidean mean).
    pub stretch: Vec<Mat3>,
    /// `U_j^{±½}` of every stretch (affine-invariant mean with `series`).
    pub roots: Vec<SpdRoots>,
}

impl RegularizeBuffers {
    /// Buffers for `m` vertices.
    pub fn new(m: usize) -> Self {
        let identity_roots = SpdRoots {
            sqrt: Mat3::identity(),
            inv_sqrt: Mat3::identity(),
        };
        Self {
            rotation: vec![Mat3::identity(); m],
            stretch: vec![Mat3::identity(); m],
            roots: vec![identity_roots; m],
        }
    }
}

/// Regularizes `raw` gradients over the neighborhoods `rings` into `regularized` (as
/// rotation and stretch: `H̄_k = rotation[k] · stretch[k]`).
///
/// With `series`, logarithms and exponentials of near-identity matrices use truncated series
/// ([`spd_log_near_identity`], [`sym_exp_small`]) and `U_k^{±½}` come from the polar
/// decomposition's own eigen-decomposition, and polar factors and the chordal mean's rotation
/// come from the Newton–Schulz or unit-quaternion solutions ([`polar_fast`],
/// [`nearest_rotation_of_near_rotation`]); the results agree with the eigen-decomposition path
/// (`series = false`, kept as the exact reference) to round-off.
pub fn regularize(
    raw: &[Mat3],
    rings: &Neighborhoods,
    mode: Regularization,
    series: bool,
    buffers: &mut RegularizeBuffers,
    out_rotation: &mut [Mat3],
    out_stretch: &mut [Mat3],
) {
    let log = if series {
        spd_log_near_identity
    } else {
        spd_log
    };
    let exp = if series { sym_exp_small } else { sym_exp };
    buffers
        .rotation
        .par_iter_mut()
        .zip(buffers.stretch.par_iter_mut())
        .zip(buffers.roots.par_iter_mut())
        .zip(raw.par_iter())
        .for_each(|(((r, u), roots), h)| {
            let p = if series && mode == Regularization::AffineInvariant {
                let (p, rt) = polar_with_roots(h);
                *roots = rt;
                p
            } else if series {
                polar_fast(h)
            } else {
                polar(h)
            };
            *r = p.rotation;
            *u = match mode {
                Regularization::LogEuclidean => log(&p.stretch),
                _ => p.stretch,
            };
        });
    let (rot, stretch, all_roots) = (&buffers.rotation, &buffers.stretch, &buffers.roots);
    out_rotation
        .par_iter_mut()
        .zip(out_stretch.par_iter_mut())
        .enumerate()
        .for_each(|(k, (r_out, u_out))| {
            let ring = rings.of(k);
            let beta = 1.0 / ring.len() as f64;
            if mode == Regularization::None {
                *r_out = rot[k];
                *u_out = stretch[k];
                return;
            }
            let mut r_sum = Mat3::zeros();
            let mut log_sum = Mat3::zeros();
            match mode {
                Regularization::AffineInvariant => {
                    let roots = if series {
                        all_roots[k]
                    } else {
                        spd_roots(&stretch[k])
                    };
                    for &j in ring {
                        let j = j as usize;
                        r_sum += beta * rot[j];
                        if j != k {
                            let m = roots.inv_sqrt * stretch[j] * roots.inv_sqrt;
                            log_sum += beta * log(&m);
                        }
                    }
                    *u_out = roots.sqrt * exp(&log_sum) * roots.sqrt;
                }
                Regularization::LogEuclidean => {
                    for &j in ring {
                        r_sum += beta * rot[j as usize];
                        log_sum += beta * stretch[j as usize];
                    }
                    *u_out = exp(&log_sum);
                }
                Regularization::None => unreachable!(),
            }
            *r_out = if series {
                nearest_rotation_of_near_rotation(&r_sum)
            } else {
                nearest_rotation(&r_sum)
            };
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rings::Neighborhoods;
    use approx::assert_relative_eq;

    fn all_ring(m: usize) -> Neighborhoods {
        Neighborhoods::from_rows(
            (0..m)
                .map(|k| {
                    let mut r = vec![k as u32];
                    r.extend((0..m as u32).filter(|&j| j != k as u32));
                    r
                })
                .collect(),
        )
    }

    #[test]
    fn identical_neighborhoods_are_unchanged() {
        let r = *nalgebra::Rotation3::from_euler_angles(0.2, 0.4, -0.9).matrix();
        let u = Mat3::new(1.3, 0.1, 0.0, 0.1, 0.8, 0.05, 0.0, 0.05, 1.0);
        let h = vec![r * u; 5];
        for mode in [
            Regularization::AffineInvariant,
            Regularization::LogEuclidean,
            Regularization::None,
        ] {
            let mut buf = RegularizeBuffers::new(5);
            let (mut ro, mut uo) = (vec![Mat3::zeros(); 5], vec![Mat3::zeros(); 5]);
            regularize(&h, &all_ring(5), mode, true, &mut buf, &mut ro, &mut uo);
            for k in 0..5 {
                assert_relative_eq!(ro[k], r, epsilon = 1e-10);
                assert_relative_eq!(uo[k], u, epsilon = 1e-10);
            }
        }
    }

    #[test]
    fn two_commuting_stretches_average_geometrically() {
        // diag(1,1,1) and diag(4,1,1): both means give the geometric mean diag(2,1,1).
        let h = vec![
            Mat3::identity(),
            Mat3::from_diagonal(&nalgebra::Vector3::new(4.0, 1.0, 1.0)),
        ];
        for mode in [
            Regularization::AffineInvariant,
            Regularization::LogEuclidean,
        ] {
            let mut buf = RegularizeBuffers::new(2);
            let (mut ro, mut uo) = (vec![Mat3::zeros(); 2], vec![Mat3::zeros(); 2]);
            regularize(&h, &all_ring(2), mode, true, &mut buf, &mut ro, &mut uo);
            let want = Mat3::from_diagonal(&nalgebra::Vector3::new(2.0, 1.0, 1.0));
            assert_relative_eq!(uo[0], want, epsilon = 1e-10);
            assert_relative_eq!(uo[1], want, epsilon = 1e-10);
            assert_relative_eq!(ro[0], Mat3::identity(), epsilon = 1e-12);
        }
    }
}
