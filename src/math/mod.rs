//! Small 3×3 linear algebra used by every stage: type aliases, a Jacobi symmetric
//! eigensolver, functions of symmetric positive-definite (SPD) matrices and the polar
//! decomposition; the nearest rotation without an eigen-decomposition is in `math/procrustes.rs`.
//!
//! All routines work on stack values (`Matrix3`, `Vector3`) and never allocate, so they can be
//! called from the per-iteration hot loop.

use nalgebra as na;

mod procrustes;
pub use procrustes::{
    nearest_rotation_fast, nearest_rotation_of_near_rotation, nearest_rotation_with,
    rotation_near_orthogonal, rotation_quaternion, NEAR_ORTHOGONAL_MAX_DEFECT,
    QUATERNION_MIN_RELATIVE_GAP,
};

/// The float type used throughout.
pub type Real = f64;
/// A 3D point / vector.
pub type Vec3 = na::Vector3<Real>;
/// A 3×3 matrix.
pub type Mat3 = na::Matrix3<Real>;

/// Converts a `[f64; 3]` row into a [`Vec3`].
#[inline]
pub fn vec3(p: &[Real; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

/// The squared distance between two points.
#[inline]
pub fn dist2(a: &[Real; 3], b: &[Real; 3]) -> Real {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Result of a symmetric 3×3 eigen-decomposition, eigenvalues sorted in descending order.
#[derive(Clone, Copy, Debug)]
pub struct SymEigen3 {
    /// Eigenvalues λ1 ≥ λ2 ≥ λ3.
    pub values: Vec3,
    /// Unit eigenvectors as columns (column i belongs to `values[i]`), forming a right-handed
    /// orthonormal basis (det = +1).
    pub vectors: Mat3,
}

impl SymEigen3 {
    /// Rebuilds `Σ f(λ_i) e_i e_iᵀ`: the matrix function `f` of the decomposed matrix.
    #[inline]
    pub fn map(&self, f: impl Fn(Real) -> Real) -> Mat3 {
        let v = &self.vectors;
        let d = Vec3::new(f(self.values[0]), f(self.values[1]), f(self.values[2]));
        let mut out = Mat3::zeros();
        for i in 0..3 {
            let e = v.column(i);
            out += d[i] * e * e.transpose();
        }
        out
    }
}

/// Eigen-decomposition of a symmetric 3×3 matrix by cyclic Jacobi rotations.
///
/// The input is symmetrized first (`(A + Aᵀ)/2`), so tiny asymmetries from round-off are
/// harmless. Jacobi is unconditionally convergent and accurate to a few ulps relative to ‖A‖,
/// including for repeated eigenvalues (where closed-form cubic solvers lose precision). The
/// rotations use the symmetric update of Rutishauser (Numerical Recipes §11.1) on the six
/// distinct entries; at most 16 sweeps, in practice 3–5.
pub fn sym_eigen3(a: &Mat3) -> SymEigen3 {
    // Diagonal d[i] = a_ii; off-diagonal o[r] = a_pq for {p, q, r} = {0, 1, 2}.
    let mut d = [a[(0, 0)], a[(1, 1)], a[(2, 2)]];
    let mut o = [
        0.5 * (a[(1, 2)] + a[(2, 1)]),
        0.5 * (a[(0, 2)] + a[(2, 0)]),
        0.5 * (a[(0, 1)] + a[(1, 0)]),
    ];
    // Eigenvectors as rows of `v` transposed: v[k][i] = component k of eigenvector i.
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..16 {
        let off = o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
        let diag = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if off <= 1e-32 * diag || off == 0.0 {
            break;
        }
        for (p, q, r) in [(0usize, 1usize, 2usize), (0, 2, 1), (1, 2, 0)] {
            let apq = o[r];
            if apq == 0.0 {
                continue;
            }
            let theta = (d[q] - d[p]) / (2.0 * apq);
            let t = if theta.abs() > 1e100 {
                0.5 / theta
            } else {
                let t = 1.0 / (theta.abs() + (theta * theta + 1.0).sqrt());
                if theta < 0.0 {
                    -t
                } else {
                    t
                }
            };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            let tau = s / (1.0 + c);
            d[p] -= t * apq;
            d[q] += t * apq;
            o[r] = 0.0;
            // a_rp is o[q], a_rq is o[p].
            let (arp, arq) = (o[q], o[p]);
            o[q] = arp - s * (arq + tau * arp);
            o[p] = arq + s * (arp - tau * arq);
            for row in &mut v {
                let (kp, kq) = (row[p], row[q]);
                row[p] = kp - s * (kq + tau * kp);
                row[q] = kq + s * (kp - tau * kq);
            }
        }
    }
    // Sort descending.
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| d[j].total_cmp(&d[i]));
    let values = Vec3::new(d[idx[0]], d[idx[1]], d[idx[2]]);
    let vectors = Mat3::from_fn(|r, col| v[r][idx[col]]);
    // Right-handed basis: the third column as the cross product of the first two (the
    // eigenvectors are orthonormal, so this only fixes the sign).
    let e3 = vectors.column(0).cross(&vectors.column(1));
    let mut vectors = vectors;
    if e3.dot(&vectors.column(2)) < 0.0 {
        let c = -vectors.column(2);
        vectors.set_column(2, &c);
    }
    SymEigen3 { values, vectors }
}

/// Polar decomposition `H = R U` with `R ∈ SO(3)` and `U` symmetric positive semi-definite.
///
/// Computed from the eigen-decomposition of `Hᵀ H = V Σ² Vᵀ`: `U = V Σ Vᵀ`, and the rotation's
/// columns `w_i = H v_i / σ_i` for the two largest singular values, the third completed as
/// `w_1 × w_2`. Consequences, both intended:
/// * the result is a proper rotation even when `H` is rank-deficient (σ₃ = 0);
/// * when `det H < 0` (an inverted, orientation-reversing gradient) the reflection is dropped:
///   `R U` is then the nearest orientation-preserving deformation, not `H` itself.
#[derive(Clone, Copy, Debug)]
pub struct Polar {
    /// The rotation factor `R`.
    pub rotation: Mat3,
    /// The stretch factor `U` (SPD when `H` is non-singular).
    pub stretch: Mat3,
}

/// See [`Polar`].
pub fn polar(h: &Mat3) -> Polar {
    let eig = sym_eigen3(&(h.transpose() * h));
    let sigma = eig.values.map(|x| x.max(0.0).sqrt());
    let stretch = eig.map(|x| x.max(0.0).sqrt());
    let rotation = rotation_from_svd_parts(h, &eig.vectors, &sigma);
    Polar { rotation, stretch }
}

/// The rotation closest to `m` in the Frobenius norm (orthogonal Procrustes with the
/// determinant fixed to +1): `argmin_{R ∈ SO(3)} ‖m − R‖_F`.
pub fn nearest_rotation(m: &Mat3) -> Mat3 {
    let eig = sym_eigen3(&(m.transpose() * m));
    let sigma = eig.values.map(|x| x.max(0.0).sqrt());
    rotation_from_svd_parts(m, &eig.vectors, &sigma)
}

/// Smallest `det H / (‖H‖_F/√3)³` (a cube of the ratio of the geometric to the quadratic mean
/// of the singular values) at which [`polar_fast`] takes its stretch as `Rᵀ H`: below it
/// (near-singular or reflecting input) the eigen-decomposition path keeps the stretch
/// `√(HᵀH)` positive semi-definite.
pub const ORIENTED_MIN_NORMALIZED_DET: Real = 1e-3;

/// [`polar`] with the rotation from [`rotation_near_orthogonal`] (near a rotation) or
/// [`rotation_quaternion`] and `U = Rᵀ H` (symmetrized) where
/// `h` is well inside the orientation-preserving matrices (its normalized determinant above
/// [`ORIENTED_MIN_NORMALIZED_DET`], so that `Rᵀ H` is the positive-definite stretch), else by
/// the eigen-decomposition (whose stretch `√(HᵀH)` stays positive semi-definite there).
pub fn polar_fast(h: &Mat3) -> Polar {
    let scale = h.norm() / 3.0f64.sqrt();
    let oriented = h.determinant() > ORIENTED_MIN_NORMALIZED_DET * scale * scale * scale;
    let rotation = oriented.then(|| rotation_near_orthogonal(h).or_else(|| rotation_quaternion(h)));
    match rotation.flatten() {
        Some(rotation) => {
            let u = rotation.transpose() * h;
            Polar {
                rotation,
                stretch: 0.5 * (u + u.transpose()),
            }
        }
        None => polar(h),
    }
}

/// `(det, trace)` of a symmetric matrix that Sylvester's criterion (positive leading minors)
/// shows positive definite, else `None`: the pieces of the eigenvalue-free bounds
/// `λ_min ≥ 4 det / tr²` (as `λ1 λ2 < (tr/2)²`), `λ_max ≤ tr` and `λ_max ≥ tr/3`.
#[inline]
pub fn positive_definite_det_trace(m: &Mat3) -> Option<(Real, Real)> {
    let minor2 = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)];
    let det = m.determinant();
    (m[(0, 0)] > 0.0 && minor2 > 0.0 && det > 0.0 && det.is_finite()).then(|| (det, m.trace()))
}

/// Eigenvalues of a symmetric 3×3 matrix, descending, by the closed-form trigonometric
/// solution of the characteristic cubic (Smith 1961). Absolute error a few ulps of ‖A‖: fine
/// for thresholds and weights, not for eigenvectors of near-repeated eigenvalues (use
/// [`sym_eigen3`] for those).
pub fn sym_eigenvalues3(a: &Mat3) -> [Real; 3] {
    let (a00, a11, a22) = (a[(0, 0)], a[(1, 1)], a[(2, 2)]);
    let a01 = 0.5 * (a[(0, 1)] + a[(1, 0)]);
    let a02 = 0.5 * (a[(0, 2)] + a[(2, 0)]);
    let a12 = 0.5 * (a[(1, 2)] + a[(2, 1)]);
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let q = (a00 + a11 + a22) / 3.0;
    let (b00, b11, b22) = (a00 - q, a11 - q, a22 - q);
    let p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1;
    if p2 <= 0.0 {
        return [q; 3];
    }
    let p = (p2 / 6.0).sqrt();
    let det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
        + a02 * (a01 * a12 - b11 * a02);
    let r = (det / (2.0 * p * p * p)).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let l1 = q + 2.0 * p * phi.cos();
    let l3 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    [l1, 3.0 * q - l1 - l3, l3]
}

/// Builds `W Vᵀ` from `m`, its right singular vectors `v` (right-handed) and singular values.
fn rotation_from_svd_parts(m: &Mat3, v: &Mat3, sigma: &Vec3) -> Mat3 {
    let scale = sigma[0];
    if scale <= 0.0 || !scale.is_finite() {
        return Mat3::identity();
    }
    let v1 = v.column(0).into_owned();
    let v2 = v.column(1).into_owned();
    let w1 = (m * v1) / sigma[0];
    // Second left singular vector: Gram–Schmidt against w1 for robustness; when σ₂ ≈ 0
    // (rank-1 input) any unit vector orthogonal to w1 is a valid choice.
    let mut w2 = if sigma[1] > 1e-12 * scale {
        m * v2 / sigma[1]
    } else {
        any_orthogonal(&w1)
    };
    let w1 = w1.normalize();
    w2 -= w1 * w1.dot(&w2);
    let n2 = w2.norm();
    let w2 = if n2 > 1e-12 {
        w2 / n2
    } else {
        any_orthogonal(&w1)
    };
    let w3 = w1.cross(&w2);
    let v3 = v1.cross(&v2);
    w1 * v1.transpose() + w2 * v2.transpose() + w3 * v3.transpose()
}

/// A unit vector orthogonal to the unit vector `a`.
pub fn any_orthogonal(a: &Vec3) -> Vec3 {
    let helper = if a.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    a.cross(&helper).normalize()
}

/// Precomputed square root and inverse square root of an SPD matrix (one eigen-decomposition).
#[derive(Clone, Copy, Debug)]
pub struct SpdRoots {
    /// `U^{½}`.
    pub sqrt: Mat3,
    /// `U^{-½}`.
    pub inv_sqrt: Mat3,
}

/// Smallest eigenvalue accepted when inverting an SPD matrix (values are clamped up to it).
pub const SPD_FLOOR: Real = 1e-12;

/// `U^{½}` and `U^{-½}` of a symmetric positive (semi-)definite matrix; eigenvalues are
/// clamped to [`SPD_FLOOR`] so the result is always finite.
pub fn spd_roots(u: &Mat3) -> SpdRoots {
    let e = sym_eigen3(u);
    SpdRoots {
        sqrt: e.map(|x| x.max(SPD_FLOOR).sqrt()),
        inv_sqrt: e.map(|x| 1.0 / x.max(SPD_FLOOR).sqrt()),
    }
}

/// Matrix logarithm of an SPD matrix (eigenvalues clamped to [`SPD_FLOOR`]).
pub fn spd_log(m: &Mat3) -> Mat3 {
    sym_eigen3(m).map(|x| x.max(SPD_FLOOR).ln())
}

/// Matrix exponential of a symmetric matrix.
pub fn sym_exp(m: &Mat3) -> Mat3 {
    sym_eigen3(m).map(Real::exp)
}

/// Largest Frobenius norm at which [`sym_exp_small`] uses its truncated Taylor series
/// instead of an eigen-decomposition (the logarithm's radius is [`LOG_SERIES_RADIUS`]).
pub const SERIES_RADIUS: Real = 0.1;

/// Relative truncation error the series stop at.
const SERIES_TOLERANCE: Real = 1e-16;

/// Largest Frobenius distance from the identity at which [`spd_log_near_identity`] uses its
/// series: `Z = E(2I + E)⁻¹` then has ‖Z‖ ≈ ‖E‖/2 ≤ 0.25, so at most ~13 terms reach the
/// tolerance — still cheaper than the Jacobi sweeps, which the affine-invariant mean of Eq. 5
/// otherwise ran for the neighbour pairs of a strongly deforming ring (12 % of the paper
/// preset's time with the radius at [`SERIES_RADIUS`]).
pub const LOG_SERIES_RADIUS: Real = 0.5;

/// `1/k` for k = 0..=16 (the 0th unused): [`sym_exp_small`]'s Horner factors, multiplied
/// instead of divided (a division's latency sat on Horner's dependency chain); its series has
/// at most 16 terms.
const RECIPROCALS: [Real; 17] = {
    let mut r = [0.0; 17];
    let mut k = 1;
    while k < 17 {
        r[k] = 1.0 / k as Real;
        k += 1;
    }
    r
};

/// `1/(2k+1)` for the terms of [`spd_log_near_identity`]'s series.
const ODD_RECIPROCALS: [Real; 25] = {
    let mut r = [0.0; 25];
    let mut k = 0;
    while k < 25 {
        r[k] = 1.0 / (2 * k + 1) as Real;
        k += 1;
    }
    r
};

/// A symmetric 3×3 matrix by its upper triangle `[m00, m01, m02, m11, m12, m22]`.
type Sym3 = [Real; 6];

#[inline]
fn sym_of(m: &Mat3) -> Sym3 {
    [
        m[(0, 0)],
        0.5 * (m[(0, 1)] + m[(1, 0)]),
        0.5 * (m[(0, 2)] + m[(2, 0)]),
        m[(1, 1)],
        0.5 * (m[(1, 2)] + m[(2, 1)]),
        m[(2, 2)],
    ]
}

#[inline]
fn mat_of(s: &Sym3) -> Mat3 {
    Mat3::new(s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5])
}

/// `a b` for symmetric `a`, `b` that commute (so the product is symmetric): the upper
/// triangle only, 18 multiplications instead of 27.
#[inline]
fn sym_mul_commuting(a: &Sym3, b: &Sym3) -> Sym3 {
    [
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
        a[0] * b[1] + a[1] * b[3] + a[2] * b[4],
        a[0] * b[2] + a[1] * b[4] + a[2] * b[5],
        a[1] * b[1] + a[3] * b[3] + a[4] * b[4],
        a[1] * b[2] + a[3] * b[4] + a[4] * b[5],
        a[2] * b[2] + a[4] * b[4] + a[5] * b[5],
    ]
}

/// `‖s‖_F`.
#[inline]
fn sym_norm(s: &Sym3) -> Real {
    (s[0] * s[0] + s[3] * s[3] + s[5] * s[5] + 2.0 * (s[1] * s[1] + s[2] * s[2] + s[4] * s[4]))
        .sqrt()
}

/// `log M` for an SPD matrix near the identity, by the inverse-hyperbolic-tangent series
/// `log(I + E) = 2 Σ Z²ⁿ⁺¹/(2n+1)` with `Z = E (2I + E)⁻¹` (E symmetric, so Z is too and
/// ‖Z‖ ≈ ‖E‖/2), used when `‖E‖_F = ‖M − I‖_F ≤` [`LOG_SERIES_RADIUS`]; else [`spd_log`]. The
/// series is cut when the bound `2‖Z‖²ᴺ⁺³/((2N+3)(1 − ‖Z‖²))` on the rest drops below
/// 1e-16·‖Z‖ (3–13 terms): the result agrees with the eigen-decomposition to round-off, at a
/// fraction of the Jacobi sweeps' cost. E, (2I + E)⁻¹, Z and every power of it commute and
/// are symmetric, so the products run on upper triangles.
pub fn spd_log_near_identity(m: &Mat3) -> Mat3 {
    let mut e = sym_of(m);
    e[0] -= 1.0;
    e[3] -= 1.0;
    e[5] -= 1.0;
    let r = sym_norm(&e);
    if r > LOG_SERIES_RADIUS || !r.is_finite() {
        return spd_log(m);
    }
    if r == 0.0 {
        return Mat3::zeros();
    }
    // (2I + E)⁻¹ by its adjugate (symmetric).
    let a = [e[0] + 2.0, e[1], e[2], e[3] + 2.0, e[4], e[5] + 2.0];
    let cof = [
        a[3] * a[5] - a[4] * a[4],
        a[2] * a[4] - a[1] * a[5],
        a[1] * a[4] - a[2] * a[3],
        a[0] * a[5] - a[2] * a[2],
        a[1] * a[2] - a[0] * a[4],
        a[0] * a[3] - a[1] * a[1],
    ];
    let det = a[0] * cof[0] + a[1] * cof[1] + a[2] * cof[2];
    if det <= 0.0 || det.is_nan() {
        return spd_log(m);
    }
    let inv_det = 1.0 / det;
    let inv = cof.map(|c| c * inv_det);
    let z = sym_mul_commuting(&e, &inv);
    let w = sym_mul_commuting(&z, &z);
    let rz = sym_norm(&z);
    let rw = rz * rz;
    // Smallest N with 2 rz^{2N+3} / ((2N+3)(1 − rz²)) ≤ tol · rz (no division in the loop).
    let mut n = 0usize;
    let mut power = rz * rw; // rz^{2n+3}
    let bound = SERIES_TOLERANCE * rz * (1.0 - rw);
    while 2.0 * power > bound * (2 * n + 3) as Real && n < ODD_RECIPROCALS.len() - 1 {
        power *= rw;
        n += 1;
    }
    let diagonal = |d: Real| [d, 0.0, 0.0, d, 0.0, d];
    let mut p = diagonal(ODD_RECIPROCALS[n]);
    for &d in ODD_RECIPROCALS[..n].iter().rev() {
        let wp = sym_mul_commuting(&w, &p);
        p = [wp[0] + d, wp[1], wp[2], wp[3] + d, wp[4], wp[5] + d];
    }
    mat_of(&sym_mul_commuting(&z, &p).map(|x| 2.0 * x))
}

/// `exp S` for a symmetric matrix, by the Taylor series when `‖S‖_F ≤` [`SERIES_RADIUS`]
/// (cut when `‖S‖ⁿ⁺¹/(n+1)!` drops below 1e-16), else by [`sym_exp`]. S and every polynomial
/// in it commute and are symmetric, so Horner's steps run on upper triangles (as in
/// [`spd_log_near_identity`]: 18 + 6 multiplications a step instead of 27 and 9 divisions,
/// and no symmetrization at the end).
pub fn sym_exp_small(s: &Mat3) -> Mat3 {
    let s = sym_of(s);
    let r = sym_norm(&s);
    if r > SERIES_RADIUS || !r.is_finite() {
        return sym_exp(&mat_of(&s));
    }
    let mut n = 0;
    let mut term = 1.0; // r^n / n!
    while term > SERIES_TOLERANCE && n < RECIPROCALS.len() - 1 {
        n += 1;
        term *= r / n as Real;
    }
    let mut p: Sym3 = [1.0, 0.0, 0.0, 1.0, 0.0, 1.0];
    for &inv in RECIPROCALS[1..=n].iter().rev() {
        let sp = sym_mul_commuting(&s, &p);
        p = [
            1.0 + sp[0] * inv,
            sp[1] * inv,
            sp[2] * inv,
            1.0 + sp[3] * inv,
            sp[4] * inv,
            1.0 + sp[5] * inv,
        ];
    }
    mat_of(&p)
}

/// Polar decomposition and the roots `U^{±½}` of its stretch, from one eigen-decomposition.
pub fn polar_with_roots(h: &Mat3) -> (Polar, SpdRoots) {
    let eig = sym_eigen3(&(h.transpose() * h));
    let sigma = eig.values.map(|x| x.max(0.0).sqrt());
    let polar = Polar {
        rotation: rotation_from_svd_parts(h, &eig.vectors, &sigma),
        stretch: eig.map(|x| x.max(0.0).sqrt()),
    };
    let roots = SpdRoots {
        sqrt: eig.map(|x| x.max(0.0).sqrt().max(SPD_FLOOR).sqrt()),
        inv_sqrt: eig.map(|x| 1.0 / x.max(0.0).sqrt().max(SPD_FLOOR).sqrt()),
    };
    (polar, roots)
}

/// Whether every entry is finite.
#[inline]
pub fn is_finite3(m: &Mat3) -> bool {
    m.iter().all(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_rotation(rng: &mut ChaCha8Rng) -> Mat3 {
        let axis = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5);
        let angle = rng.random_range(-3.0..3.0);
        *na::Rotation3::from_axis_angle(&na::Unit::new_normalize(axis), angle).matrix()
    }

    #[test]
    fn jacobi_reconstructs_random_symmetric() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..200 {
            let a = Mat3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let s = a + a.transpose();
            let e = sym_eigen3(&s);
            assert!(e.values[0] >= e.values[1] && e.values[1] >= e.values[2]);
            assert_relative_eq!(e.map(|x| x), s, epsilon = 1e-12);
            assert_relative_eq!(e.vectors.determinant(), 1.0, epsilon = 1e-12);
            assert_relative_eq!(
                e.vectors.transpose() * e.vectors,
                Mat3::identity(),
                epsilon = 1e-12
            );
        }
    }

    #[test]
    fn jacobi_handles_repeated_eigenvalues() {
        let e = sym_eigen3(&(Mat3::identity() * 2.0));
        assert_relative_eq!(e.values, Vec3::repeat(2.0));
        let d = Mat3::from_diagonal(&Vec3::new(1.0, 3.0, 3.0));
        let e = sym_eigen3(&d);
        assert_relative_eq!(e.values, Vec3::new(3.0, 3.0, 1.0));
    }

    #[test]
    fn polar_recovers_random_rotation_and_stretch() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..200 {
            let r = random_rotation(&mut rng);
            let b = Mat3::from_fn(|_, _| rng.random_range(-0.5..0.5));
            let u = Mat3::identity() + b * b.transpose();
            let p = polar(&(r * u));
            assert_relative_eq!(p.rotation, r, epsilon = 1e-9);
            assert_relative_eq!(p.stretch, u, epsilon = 1e-9);
        }
    }

    #[test]
    fn polar_of_rank_deficient_is_a_rotation() {
        let h = Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        let p = polar(&h);
        assert_relative_eq!(p.rotation, Mat3::identity(), epsilon = 1e-12);
        let p = polar(&Mat3::zeros());
        assert_relative_eq!(p.rotation, Mat3::identity());
    }

    #[test]
    fn polar_drops_reflection() {
        let h = Mat3::from_diagonal(&Vec3::new(1.0, 2.0, -0.5));
        let p = polar(&h);
        assert_relative_eq!(p.rotation.determinant(), 1.0, epsilon = 1e-12);
        let e = sym_eigen3(&p.stretch);
        assert!(e.values[2] > 0.0);
    }

    #[test]
    fn fast_rotation_and_polar_match_eigen_path() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let mut used = 0;
        for i in 0..2000 {
            let r = *nalgebra::Rotation3::from_euler_angles(
                rng.random::<f64>() * 6.0,
                rng.random::<f64>() * 3.0,
                rng.random::<f64>() * 6.0,
            )
            .matrix();
            // Near-rotations, general stretches, and (every 7th) near-singular or reflecting.
            let spread = if i % 2 == 0 { 0.05 } else { 1.5 };
            let mut m = r;
            for x in m.iter_mut() {
                *x += spread * (rng.random::<f64>() - 0.5);
            }
            if i % 7 == 0 {
                m.set_column(2, &(m.column(0) * (rng.random::<f64>() - 0.5)));
            }
            let exact = nearest_rotation(&m);
            assert_relative_eq!(nearest_rotation_fast(&m), exact, epsilon = 1e-12);
            let (pf, pe) = (polar_fast(&m), polar(&m));
            assert_relative_eq!(pf.rotation, pe.rotation, epsilon = 1e-12);
            assert_relative_eq!(pf.stretch, pe.stretch, epsilon = 1e-12 * m.norm());
            used += usize::from(rotation_quaternion(&m).is_some());
        }
        assert!(
            used > 1500,
            "the quaternion path should apply to most inputs ({used})"
        );
        // A reflecting input: the rotation from the quaternion, the stretch from √(HᵀH).
        let reflecting = Mat3::from_diagonal(&Vec3::new(1.0, 2.0, -0.5));
        assert_relative_eq!(
            polar_fast(&reflecting).stretch,
            polar(&reflecting).stretch,
            epsilon = 1e-14
        );
    }

    #[test]
    fn closed_form_eigenvalues_match_jacobi() {
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        for i in 0..2000 {
            let mut s = Mat3::zeros();
            for r in 0..3 {
                for c in r..3 {
                    let x = rng.random::<f64>() - 0.5;
                    s[(r, c)] = x;
                    s[(c, r)] = x;
                }
            }
            if i % 3 == 0 {
                s = s.transpose() * s; // PSD, sometimes nearly repeated
            }
            if i % 5 == 0 {
                s = Mat3::identity() * 0.7 + s * 1e-9;
            }
            let e = sym_eigen3(&s).values;
            let c = sym_eigenvalues3(&s);
            for k in 0..3 {
                assert!((e[k] - c[k]).abs() <= 1e-14 * (1.0 + s.norm()), "{e} {c:?}");
            }
        }
        assert_eq!(sym_eigenvalues3(&(Mat3::identity() * 2.0)), [2.0; 3]);
    }

    #[test]
    fn nearest_rotation_matches_svd() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            let m = Mat3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let r = nearest_rotation(&m);
            let svd = m.svd(true, true);
            let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
            let mut d = Mat3::identity();
            d[(2, 2)] = (u * vt).determinant().signum();
            assert_relative_eq!(r, u * d * vt, epsilon = 1e-8);
        }
    }

    #[test]
    fn series_agree_with_eigen_decomposition() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for scale in [1e-9, 1e-4, 1e-2, 0.05, 0.099, 0.3, 0.49, 0.8] {
            for _ in 0..50 {
                let b = Mat3::from_fn(|_, _| rng.random_range(-1.0..1.0));
                let e = (b + b.transpose()) * (scale / (b + b.transpose()).norm());
                let m = Mat3::identity() + e;
                assert_relative_eq!(spd_log_near_identity(&m), spd_log(&m), epsilon = 1e-14);
                if scale < 0.5 {
                    assert_relative_eq!(sym_exp_small(&e), sym_exp(&e), epsilon = 1e-14);
                }
            }
        }
        let h = Mat3::new(1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 1.2);
        let (p, roots) = polar_with_roots(&h);
        let want = spd_roots(&polar(&h).stretch);
        assert_relative_eq!(p.stretch, polar(&h).stretch, epsilon = 1e-14);
        assert_relative_eq!(roots.sqrt, want.sqrt, epsilon = 1e-13);
        assert_relative_eq!(roots.inv_sqrt, want.inv_sqrt, epsilon = 1e-13);
    }

    #[test]
    fn spd_functions_are_consistent() {
        let b = Mat3::new(0.3, 0.1, 0.0, 0.1, 0.2, 0.05, 0.0, 0.05, 0.4);
        let u = Mat3::identity() + b * b.transpose();
        let r = spd_roots(&u);
        assert_relative_eq!(r.sqrt * r.sqrt, u, epsilon = 1e-12);
        assert_relative_eq!(r.sqrt * r.inv_sqrt, Mat3::identity(), epsilon = 1e-12);
        assert_relative_eq!(sym_exp(&spd_log(&u)), u, epsilon = 1e-12);
    }
}
