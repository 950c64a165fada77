//! The rotation nearest to a 3×3 matrix (its orthogonal polar factor, the orthogonal
//! Procrustes problem) without an eigen-decomposition: Horn's quaternion solution (Horn 1987,
//! "Closed-form solution of absolute orientation using unit quaternions") for general input,
//! and the Newton–Schulz polar iteration for input near a rotation (per-iteration deformation
//! gradients, chordal means of nearby rotations). Both equal [`nearest_rotation`] to round-off
//! (tested); the callers fall back to it where neither applies.

use super::{nearest_rotation, Mat3, Real};

/// `‖cof m‖_F²`, the sum of the squared 2×2 minors of `m`: `Σ_{i<j} σᵢ² σⱼ²`.
#[inline]
fn cofactor_norm_squared(m: &Mat3) -> Real {
    let mut sum = 0.0;
    for (r0, r1) in [(0, 1), (0, 2), (1, 2)] {
        for (c0, c1) in [(0, 1), (0, 2), (1, 2)] {
            let minor = m[(r0, c0)] * m[(r1, c1)] - m[(r0, c1)] * m[(r1, c0)];
            sum += minor * minor;
        }
    }
    sum
}

/// The six 2×2 minors of the rows `r` over `t`, columns (0,1) (0,2) (0,3) (1,2) (1,3) (2,3).
#[inline]
fn pair_minors(r: &[Real; 4], t: &[Real; 4]) -> [Real; 6] {
    [
        r[0] * t[1] - t[0] * r[1],
        r[0] * t[2] - t[0] * r[2],
        r[0] * t[3] - t[0] * r[3],
        r[1] * t[2] - t[1] * r[2],
        r[1] * t[3] - t[1] * r[3],
        r[2] * t[3] - t[2] * r[3],
    ]
}

/// The 2×2 minors of a 4×4 matrix's first two rows (`s`) and last two rows (`c`), from which
/// every entry of its adjugate takes one short sum (Laplace expansion by complementary
/// minors).
struct Adjugate4 {
    a: [[Real; 4]; 4],
    s: [Real; 6],
    c: [Real; 6],
}

impl Adjugate4 {
    #[inline]
    fn of(a: [[Real; 4]; 4]) -> Self {
        let (s, c) = (pair_minors(&a[0], &a[1]), pair_minors(&a[2], &a[3]));
        Self { a, s, c }
    }

    /// The adjugate's diagonal (the entries `row(i)[i]`, without the rest of each row).
    #[inline]
    fn diagonal(&self) -> [Real; 4] {
        let ([r0, r1, r2, r3], s, c) = (&self.a, &self.s, &self.c);
        [
            r1[1] * c[5] - r1[2] * c[4] + r1[3] * c[3],
            r0[0] * c[5] - r0[2] * c[2] + r0[3] * c[1],
            r3[0] * s[4] - r3[1] * s[2] + r3[3] * s[0],
            r2[0] * s[3] - r2[1] * s[1] + r2[2] * s[0],
        ]
    }

    /// Row `i` of the adjugate (its column `i` when the matrix is symmetric).
    #[inline]
    fn row(&self, i: usize) -> [Real; 4] {
        let ([r0, r1, r2, r3], s, c) = (&self.a, &self.s, &self.c);
        match i {
            0 => [
                r1[1] * c[5] - r1[2] * c[4] + r1[3] * c[3],
                -r0[1] * c[5] + r0[2] * c[4] - r0[3] * c[3],
                r3[1] * s[5] - r3[2] * s[4] + r3[3] * s[3],
                -r2[1] * s[5] + r2[2] * s[4] - r2[3] * s[3],
            ],
            1 => [
                -r1[0] * c[5] + r1[2] * c[2] - r1[3] * c[1],
                r0[0] * c[5] - r0[2] * c[2] + r0[3] * c[1],
                -r3[0] * s[5] + r3[2] * s[2] - r3[3] * s[1],
                r2[0] * s[5] - r2[2] * s[2] + r2[3] * s[1],
            ],
            2 => [
                r1[0] * c[4] - r1[1] * c[2] + r1[3] * c[0],
                -r0[0] * c[4] + r0[1] * c[2] - r0[3] * c[0],
                r3[0] * s[4] - r3[1] * s[2] + r3[3] * s[0],
                -r2[0] * s[4] + r2[1] * s[2] - r2[3] * s[0],
            ],
            _ => [
                -r1[0] * c[3] + r1[1] * c[1] - r1[2] * c[0],
                r0[0] * c[3] - r0[1] * c[1] + r0[2] * c[0],
                -r3[0] * s[3] + r3[1] * s[1] - r3[2] * s[0],
                r2[0] * s[3] - r2[1] * s[1] + r2[2] * s[0],
            ],
        }
    }
}

/// Smallest `(λ₁ − λ₂)(λ₁ − λ₃)(λ₁ − λ₄) / (√3 ‖M‖_F)³` — the product of the gaps between
/// the largest eigenvalue of Horn's matrix and the others, relative to its scale — at which
/// [`rotation_quaternion`] is used: below it (a covariance of nearly collinear points, whose
/// best rotation is nearly undetermined) the eigen-decomposition path decides.
pub const QUATERNION_MIN_RELATIVE_GAP: Real = 1e-3;

/// The rotation closest to `m` in the Frobenius norm (the maximizer of `tr(Rᵀ m)` over
/// SO(3), as [`nearest_rotation`]) by Horn's unit-quaternion method, or `None` when the
/// answer is nearly undetermined (see [`QUATERNION_MIN_RELATIVE_GAP`]).
///
/// `tr(R(q)ᵀ m) = qᵀ N q` for the 4×4 symmetric, traceless matrix `N` of Horn (1987), so the
/// best rotation is that of the eigenvector of N's largest eigenvalue λ₁ (= σ₁ + σ₂ ± σ₃, the
/// sign of det m). λ₁ is the largest root of the characteristic quartic
/// `λ⁴ − 2‖m‖²λ² − 8 det(m) λ + det N`, found by Newton's method from an upper bound
/// (`√3 ‖m‖_F`, tightened below), from which it decreases monotonically onto the root
/// (beyond the largest root of a polynomial with real roots every derivative is positive;
/// Theobald's QCP, 2005), and the eigenvector is the best-scaled column of the adjugate of
/// `N − λ₁ I` (rank one). Unlike Newton's polar
/// iteration it needs no full rank: a flat neighbourhood's rank-2 covariance has a
/// well-separated λ₁. Equal to the eigen-decomposition path to round-off (tested to 1e-12),
/// in about half the instructions of the scaled Newton polar iteration it replaced
/// (docs/performance.md) and under half of the eigen-decomposition's.
pub fn rotation_quaternion(m: &Mat3) -> Option<Mat3> {
    let (m00, m01, m02) = (m[(0, 0)], m[(0, 1)], m[(0, 2)]);
    let (m10, m11, m12) = (m[(1, 0)], m[(1, 1)], m[(1, 2)]);
    let (m20, m21, m22) = (m[(2, 0)], m[(2, 1)], m[(2, 2)]);
    // Horn's N in the order (w, x, y, z).
    let n = [
        [m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01],
        [m21 - m12, m00 - m11 - m22, m01 + m10, m02 + m20],
        [m02 - m20, m01 + m10, -m00 + m11 - m22, m12 + m21],
        [m10 - m01, m02 + m20, m12 + m21, -m00 - m11 + m22],
    ];
    let norm2 = m.norm_squared();
    if !(norm2 > 0.0 && norm2.is_finite()) {
        return None;
    }
    // The quartic's coefficients from the invariants of m: with I₂ = Σ_{i<j} σᵢ²σⱼ² = ‖cof m‖²,
    // det N = Π λᵢ = (Σσ²)² − 4 I₂.
    let det = m.determinant();
    let i2 = cofactor_norm_squared(m);
    let (c2, c1, c0) = (-2.0 * norm2, -8.0 * det, norm2 * norm2 - 4.0 * i2);
    let scale = (3.0 * norm2).sqrt();
    // The start: with det m ≥ 0, λ₁ = σ₁ + σ₂ + σ₃ is the fixed point of
    // f(λ) = (‖m‖² + 2 (I₂ + 2 det(m) λ)^½)^½ ((Σσ)² = Σσ² + 2 e₂ and
    // e₂² = I₂ + 2 σ₁σ₂σ₃ Σσ), increasing in λ, so f of an upper bound is a tighter one:
    // two steps from √3 ‖m‖ leave Newton 2–3 iterations instead of 6–10 for a flat
    // covariance (f is exact there: det = 0). With det m < 0, f would undershoot.
    let mut lambda = scale;
    if det >= 0.0 {
        let tighter = |l: Real| (norm2 + 2.0 * (i2 + 2.0 * det * l).max(0.0).sqrt()).sqrt();
        lambda = tighter(tighter(scale)).min(scale);
    }
    for _ in 0..64 {
        let l2 = lambda * lambda;
        let p = (l2 + c2) * l2 + c1 * lambda + c0;
        let dp = (4.0 * l2 + 2.0 * c2) * lambda + c1;
        if !(p > 0.0 && dp > 0.0) {
            break;
        }
        let next = lambda - p / dp;
        if next.is_nan() || next >= lambda {
            break;
        }
        let step = lambda - next;
        lambda = next;
        // Quadratic convergence: after a step of 1e-8 the root is ~1e-16 away (and the
        // Rayleigh refinement below absorbs what is left where the gaps are small).
        if step <= 1e-8 * scale {
            break;
        }
    }
    // adj(N − λ₁ I) = −(λ₁ − λ₂)(λ₁ − λ₃)(λ₁ − λ₄) q qᵀ: every column ∝ q; the one with the
    // largest diagonal entry (∝ q_i²) is the best scaled, and its trace the gaps' product.
    let shifted = |lambda: Real| {
        let mut a = n;
        for (i, row) in a.iter_mut().enumerate() {
            row[i] -= lambda;
        }
        Adjugate4::of(a)
    };
    let adj = shifted(lambda);
    let diag = adj.diagonal();
    let gaps = -(diag[0] + diag[1] + diag[2] + diag[3]);
    let cube = scale * scale * scale;
    if gaps.is_nan() || gaps <= QUATERNION_MIN_RELATIVE_GAP * cube {
        return None;
    }
    let best = (1..4).fold(0, |b, i| if diag[i].abs() > diag[b].abs() { i } else { b });
    let mut q = adj.row(best);
    // The quartic's root carries the round-off of its coefficients, δλ ≈ 4ε‖N‖⁴/P'(λ₁) with
    // P'(λ₁) the gaps' product G, and the column an error δλ / (λ₁ − λ₂) ≲ 16ε (scale³/G)².
    // Where G < scale³ / 2 the Rayleigh quotient of the column (exact to second order in its
    // error) gives a λ from which the column is as accurate as the eigenvector's conditioning
    // allows.
    if gaps < 0.5 * cube {
        let q0n2 = q.iter().map(|x| x * x).sum::<Real>();
        if !(q0n2 > 0.0 && q0n2.is_finite()) {
            return None;
        }
        let mut rayleigh = 0.0;
        for (qi, row) in q.iter().zip(&n) {
            rayleigh += qi * (row[0] * q[0] + row[1] * q[1] + row[2] * q[2] + row[3] * q[3]);
        }
        q = shifted(rayleigh / q0n2).row(best);
    }
    let qn2 = q.iter().map(|x| x * x).sum::<Real>();
    if !(qn2 > 0.0 && qn2.is_finite()) {
        return None;
    }
    let [w, x, y, z] = q;
    let s = 2.0 / qn2;
    let (wx, wy, wz) = (s * w * x, s * w * y, s * w * z);
    let (xx, xy, xz) = (s * x * x, s * x * y, s * x * z);
    let (yy, yz, zz) = (s * y * y, s * y * z, s * z * z);
    Some(Mat3::new(
        1.0 - yy - zz,
        xy - wz,
        xz + wy,
        xy + wz,
        1.0 - xx - zz,
        yz - wx,
        xz - wy,
        yz + wx,
        1.0 - xx - yy,
    ))
}

/// Largest entry of `|XᵀX − I|` at which [`rotation_near_orthogonal`] iterates: then the
/// squared singular values lie within `1 ± 3 × 0.25`, inside the Newton–Schulz iteration's
/// region of convergence `(0, 3)`.
pub const NEAR_ORTHOGONAL_MAX_DEFECT: Real = 0.25;

/// The rotation nearest to `m` (its orthogonal polar factor) when `m` is close to a rotation —
/// a per-iteration deformation gradient, or the chordal mean of a ring's nearby rotations (Eq.
/// 5) — by the Newton–Schulz polar iteration `X ← X (3I − XᵀX) / 2` from `X = m`; `None` when
/// `det m ≤ 0` or `max |mᵀm − I| > ` [`NEAR_ORTHOGONAL_MAX_DEFECT`] (the callers then take
/// [`rotation_quaternion`]).
///
/// Each step squares the defect (a singular value `1 + e` becomes `1 − 1.5 e² − …`), so a
/// defect of 1e-2 takes four steps to round-off; the iteration stops after the step taken at
/// a defect below 1e-8. Nothing but multiplications and additions (about 90 a step), where the
/// quaternion solution is one dependent chain of square roots, Newton divisions and a 4 × 4
/// adjugate: on the FoldMatch iterations' near-identity inputs it is the faster of the two.
/// Equal to [`nearest_rotation`] to round-off (tested).
#[inline]
pub fn rotation_near_orthogonal(m: &Mat3) -> Option<Mat3> {
    let det = m.determinant();
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let mut x = *m;
    for _ in 0..8 {
        // XᵀX is symmetric: its six distinct entries, the columns' dot products.
        let (c0, c1, c2) = (x.column(0), x.column(1), x.column(2));
        let (g00, g11, g22) = (c0.dot(&c0), c1.dot(&c1), c2.dot(&c2));
        let (g01, g02, g12) = (c0.dot(&c1), c0.dot(&c2), c1.dot(&c2));
        let defect = (g00 - 1.0)
            .abs()
            .max((g11 - 1.0).abs())
            .max((g22 - 1.0).abs())
            .max(g01.abs())
            .max(g02.abs())
            .max(g12.abs());
        if defect.is_nan() || defect > NEAR_ORTHOGONAL_MAX_DEFECT {
            return None;
        }
        // (3I − XᵀX) / 2.
        let step = Mat3::new(
            1.5 - 0.5 * g00,
            -0.5 * g01,
            -0.5 * g02,
            -0.5 * g01,
            1.5 - 0.5 * g11,
            -0.5 * g12,
            -0.5 * g02,
            -0.5 * g12,
            1.5 - 0.5 * g22,
        );
        x *= step;
        if defect < 1e-8 {
            return Some(x);
        }
    }
    None
}

/// [`nearest_rotation`] for an input expected near a rotation: [`rotation_near_orthogonal`],
/// else [`nearest_rotation_fast`].
#[inline]
pub fn nearest_rotation_of_near_rotation(m: &Mat3) -> Mat3 {
    rotation_near_orthogonal(m).unwrap_or_else(|| nearest_rotation_fast(m))
}

/// [`nearest_rotation`] by [`rotation_quaternion`] where it applies, else by the
/// eigen-decomposition.
#[inline]
pub fn nearest_rotation_fast(m: &Mat3) -> Mat3 {
    rotation_quaternion(m).unwrap_or_else(|| nearest_rotation(m))
}

/// [`nearest_rotation_fast`] when `fast` (the `matrix_series` paths), else [`nearest_rotation`].
#[inline]
pub fn nearest_rotation_with(m: &Mat3, fast: bool) -> Mat3 {
    if fast {
        nearest_rotation_fast(m)
    } else {
        nearest_rotation(m)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{polar, polar_fast, Vec3};
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra as na;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_rotation(rng: &mut ChaCha8Rng) -> Mat3 {
        let axis = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5);
        let angle = rng.random_range(-3.0..3.0);
        *na::Rotation3::from_axis_angle(&na::Unit::new_normalize(axis), angle).matrix()
    }

    #[test]
    fn newton_schulz_rotation_matches_eigen_path_near_rotations() {
        let mut rng = ChaCha8Rng::seed_from_u64(29);
        for i in 0..3000 {
            let r = random_rotation(&mut rng);
            // Per-iteration gradients and rings' mean rotations: rotations times a stretch
            // within a few per cent of the identity, up to the refusal bound.
            let spread = [1e-6, 1e-3, 2e-2, 0.07][i % 4];
            let m =
                r * (Mat3::identity() + Mat3::from_fn(|_, _| spread * rng.random_range(-1.0..1.0)));
            let fast = rotation_near_orthogonal(&m).expect("near a rotation");
            assert_relative_eq!(fast, nearest_rotation(&m), epsilon = 1e-13);
            assert_relative_eq!(fast, rotation_quaternion(&m).unwrap(), epsilon = 1e-13);
            assert_relative_eq!(nearest_rotation_of_near_rotation(&m), fast);
            let p = polar_fast(&m);
            assert_relative_eq!(p.rotation, fast);
            assert_relative_eq!(p.stretch, polar(&m).stretch, epsilon = 1e-13);
        }
        // Refused: a reflection however orthogonal, a stretch beyond the bound, non-finite
        // input; the fallback still answers.
        let r = random_rotation(&mut rng);
        let reflection = r * Mat3::from_diagonal(&Vec3::new(1.0, 1.0, -1.0));
        assert!(rotation_near_orthogonal(&reflection).is_none());
        let stretched = r * Mat3::from_diagonal(&Vec3::new(1.3, 1.0, 1.0));
        assert!(rotation_near_orthogonal(&stretched).is_none());
        assert_relative_eq!(
            nearest_rotation_of_near_rotation(&stretched),
            r,
            epsilon = 1e-13
        );
        assert!(rotation_near_orthogonal(&(r * Real::NAN)).is_none());
    }

    #[test]
    fn quaternion_rotation_matches_eigen_path() {
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        let mut used = 0;
        for i in 0..4000 {
            let r = random_rotation(&mut rng);
            // Near-rotations, general stretches, flat (rank-2) covariances, reflecting inputs
            // and (every 11th) nearly collinear ones.
            let spread = [0.05, 1.5, 0.3][i % 3];
            let mut m = r;
            for x in m.iter_mut() {
                *x += spread * (rng.random::<f64>() - 0.5);
            }
            if i % 5 == 0 {
                let c = m.column(0) * (rng.random::<f64>() - 0.5) + m.column(1) * 0.3;
                m.set_column(2, &c);
            }
            if i % 7 == 0 {
                m.set_column(2, &(-m.column(2)));
            }
            if i % 11 == 0 {
                let c = m.column(0) * 0.7 + m.column(1) * 1e-7;
                m.set_column(1, &c);
            }
            m *= 10f64.powi(rng.random_range(-3..4));
            let exact = nearest_rotation(&m);
            if let Some(q) = rotation_quaternion(&m) {
                used += 1;
                assert_relative_eq!(q, exact, epsilon = 1e-12);
                assert_relative_eq!(q.transpose() * q, Mat3::identity(), epsilon = 1e-14);
            }
        }
        assert!(
            used > 3500,
            "the quaternion path should apply to most inputs ({used})"
        );
        // Rank 1 and zero: undetermined, left to the eigen path.
        let rank1 = Vec3::new(1.0, 2.0, 3.0) * Vec3::new(0.5, -1.0, 0.2).transpose();
        assert!(rotation_quaternion(&rank1).is_none());
        assert!(rotation_quaternion(&Mat3::zeros()).is_none());
        // A flat covariance (rank 2): a well-separated λ₁.
        let flat = Mat3::from_diagonal(&Vec3::new(2.0, 1.0, 0.0));
        assert_relative_eq!(
            rotation_quaternion(&flat).unwrap(),
            Mat3::identity(),
            epsilon = 1e-15
        );
    }
}
