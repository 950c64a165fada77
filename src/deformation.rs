//! Deformation gradients H_k (paper Eq. 4; docs/method.md "Deformation gradient, Eq. 4").
//!
//! With δY_j = Y_j − Y_k (the printed numerator `Y_j^{t+Δt} − Y_j^{t+Δt}` is a typo for the
//! same difference at t+Δt) and β = 1/|Γᵏ_Y|:
//!
//! `H_k = (Σ β δY'_j ⊗ δY_j + w ŝ n'_k ⊗ n_k)(Σ β δY_j ⊗ δY_j + w n_k ⊗ n_k)⁻¹`
//!
//! The normal pair is the completion that keeps H_k defined on a surface, where the second
//! matrix has rank ≤ 2 (as the fourth vertex of deformation transfer, Sumner & Popović 2004):
//! the old vertex normal n_k maps to the new one n'_k, scaled by the ring's RMS length change
//! `ŝ = (Σβ‖δY'‖² / Σβ‖δY‖²)^{½}` so a uniform scaling stays uniform. Its weight adapts to the
//! neighborhood: `w = max(0, γ·tr(B)/3 − λ_min(B))` with `B = Σβ δY⊗δY` and γ the
//! `normal_completion` parameter. A flat ring gets `w = γ·tr(B)/3`; a ring that already spans
//! 3D (λ_min ≥ γ·tr(B)/3) gets none, so an affine map of a curved patch is recovered exactly.
//! Whatever rank deficiency remains (a ring with no normal: isolated vertex, collinear ring) is
//! not inverted: those directions map by the identity and the vertex is counted as degenerate.

use crate::math::{positive_definite_det_trace, sym_eigen3, sym_eigenvalues3, vec3, Mat3, Vec3};

/// Relative eigenvalue below which a direction of the completed second-moment matrix counts
/// as missing.
pub const RANK_TOLERANCE: f64 = 1e-9;

/// Deformation gradient of one vertex.
///
/// * `k` — the vertex; `ring` — its neighborhood Γᵏ_Y (k itself may be included: it adds a
///   zero term but counts in β);
/// * `old`, `new` — all positions at t and t+Δt;
/// * `normal_old`, `normal_new` — unit normals of k at t and t+Δt (zero when undefined);
/// * `completion` — γ (0 disables the normal completion);
/// * `fast` — closed-form eigenvalues and an adjugate inverse where B is well-conditioned
///   (the same result to round-off; see [`solve_gradient_fast`]), else eigen-decompositions.
///
/// Returns `(H_k, degenerate)`.
#[allow(clippy::too_many_arguments)]
pub fn deformation_gradient(
    k: usize,
    ring: &[u32],
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    normal_old: &[f64; 3],
    normal_new: &[f64; 3],
    completion: f64,
    fast: bool,
) -> (Mat3, bool) {
    let yk = vec3(&old[k]);
    let yk_new = vec3(&new[k]);
    let beta = 1.0 / ring.len().max(1) as f64;
    let mut a = Mat3::zeros();
    let mut b = Mat3::zeros();
    let (mut len_old, mut len_new) = (0.0, 0.0);
    for &j in ring {
        let d = vec3(&old[j as usize]) - yk;
        let d_new = vec3(&new[j as usize]) - yk_new;
        a += beta * d_new * d.transpose();
        b += beta * d * d.transpose();
        len_old += beta * d.norm_squared();
        len_new += beta * d_new.norm_squared();
    }
    let n = vec3(normal_old);
    let n_new = vec3(normal_new);
    if completion > 0.0 && n.norm_squared() > 0.5 && n_new.norm_squared() > 0.5 && len_old > 0.0 {
        let trace = b.trace();
        let lambda_min = if fast {
            sym_eigenvalues3(&b)[2]
        } else {
            sym_eigen3(&b).values[2]
        }
        .max(0.0);
        let w = (completion * trace / 3.0 - lambda_min).max(0.0);
        if w > 0.0 {
            let s = (len_new / len_old).sqrt();
            a += w * s * n_new * n.transpose();
            b += w * n * n.transpose();
        }
    }
    if fast {
        solve_gradient_fast(&a, &b)
    } else {
        solve_gradient(&a, &b)
    }
}

/// Smallest `λ_min/λ_max` of B at which [`solve_gradient_fast`] inverts B directly: far above
/// [`RANK_TOLERANCE`], so the closed-form eigenvalues' round-off cannot change which path
/// [`solve_gradient`] would take.
pub const DIRECT_INVERSE_MIN_RATIO: f64 = 1e-3;

/// [`solve_gradient`] without an eigen-decomposition when B is well-conditioned
/// (`λ_min > 10⁻³ λ_max` by the closed-form eigenvalues): then no direction is null and
/// `H = A B⁻¹` with the adjugate inverse equals the eigen path to round-off.
pub fn solve_gradient_fast(a: &Mat3, b: &Mat3) -> (Mat3, bool) {
    if well_conditioned(b) || {
        let l = sym_eigenvalues3(b);
        l[0] > 0.0 && l[0].is_finite() && l[2] > DIRECT_INVERSE_MIN_RATIO * l[0]
    } {
        if let Some(inv) = b.try_inverse() {
            return (a * inv, false);
        }
    }
    solve_gradient(a, b)
}

/// A sufficient test, without eigenvalues, that the symmetric `b` is positive definite with
/// `λ_min > 10` [`DIRECT_INVERSE_MIN_RATIO`] `λ_max` (by a wide margin, so the closed-form
/// eigenvalues' round-off could not decide otherwise): `λ_min ≥ 4 det / tr²` against
/// `λ_max ≤ tr` ([`positive_definite_det_trace`]). The completed B of a surface ring passes it
/// (its normal direction gets γ·tr/3), so Eq. 4 computes one cubic per vertex instead of two.
fn well_conditioned(b: &Mat3) -> bool {
    positive_definite_det_trace(b).is_some_and(|(det, trace)| {
        4.0 * det > 10.0 * DIRECT_INVERSE_MIN_RATIO * trace * trace * trace
    })
}

/// `H = A B⁻¹`, with the null directions of B (relative eigenvalue below [`RANK_TOLERANCE`])
/// mapped by the identity instead of inverted. Returns `(H, degenerate)`.
pub fn solve_gradient(a: &Mat3, b: &Mat3) -> (Mat3, bool) {
    let e = sym_eigen3(b);
    let top = e.values[0];
    if top <= 0.0 || !top.is_finite() {
        return (Mat3::identity(), true);
    }
    let mut inv = Mat3::zeros();
    let mut null = Mat3::zeros();
    let mut degenerate = false;
    for i in 0..3 {
        let v: Vec3 = e.vectors.column(i).into();
        if e.values[i] > RANK_TOLERANCE * top {
            inv += v * v.transpose() / e.values[i];
        } else {
            null += v * v.transpose();
            degenerate = true;
        }
    }
    (a * inv + null, degenerate)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// A strongly curved patch: the center of a paraboloid and a 5×5 grid around it.
    fn curved_patch() -> Vec<[f64; 3]> {
        let mut p = vec![[0.0, 0.0, 0.0]];
        for i in -2..=2 {
            for j in -2..=2 {
                if i != 0 || j != 0 {
                    let (x, y) = (0.5 * i as f64, 0.5 * j as f64);
                    p.push([x, y, x * x + y * y]);
                }
            }
        }
        p
    }

    fn apply(m: &Mat3, t: &Vec3, pts: &[[f64; 3]]) -> Vec<[f64; 3]> {
        pts.iter().map(|p| (m * vec3(p) + t).into()).collect()
    }

    #[test]
    fn affine_map_of_a_curved_patch_is_recovered() {
        let old = curved_patch();
        let ring: Vec<u32> = (0..old.len() as u32).collect();
        let a = Mat3::new(1.2, 0.3, -0.1, 0.05, 0.9, 0.2, -0.3, 0.1, 1.1);
        let new = apply(&a, &Vec3::new(0.4, -1.0, 2.0), &old);
        let n = [0.0, 0.0, 1.0];
        let (h, degenerate) = deformation_gradient(0, &ring, &old, &new, &n, &n, 0.3, false);
        assert!(!degenerate);
        assert_relative_eq!(h, a, epsilon = 1e-10);
    }

    #[test]
    fn rigid_motion_of_a_flat_patch_gives_its_rotation() {
        let old: Vec<[f64; 3]> = curved_patch().iter().map(|p| [p[0], p[1], 0.0]).collect();
        let ring: Vec<u32> = (0..old.len() as u32).collect();
        let r = *nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1).matrix();
        let new = apply(&r, &Vec3::new(1.0, 2.0, 3.0), &old);
        let n_new: [f64; 3] = (r * Vec3::z()).into();
        let (h, degenerate) =
            deformation_gradient(0, &ring, &old, &new, &[0.0, 0.0, 1.0], &n_new, 0.3, false);
        assert!(!degenerate);
        assert_relative_eq!(h, r, epsilon = 1e-10);
        // Without completion the flat ring is rank 2: flagged, never silently inverted.
        let (_, degenerate) =
            deformation_gradient(0, &ring, &old, &new, &[0.0, 0.0, 1.0], &n_new, 0.0, false);
        assert!(degenerate);
    }

    #[test]
    fn the_conditioning_bound_only_admits_what_the_eigenvalues_admit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut admitted = 0;
        for i in 0..20_000 {
            // Random symmetric matrices, from well-conditioned SPD to indefinite.
            let g = Mat3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let shift = [0.0, 0.05, 0.5, 2.0][i % 4];
            let b = g * g.transpose() + shift * Mat3::identity() - 0.1 * Mat3::identity();
            if well_conditioned(&b) {
                admitted += 1;
                let l = sym_eigen3(&b).values;
                assert!(l[2] > 10.0 * DIRECT_INVERSE_MIN_RATIO * l[0], "{b}");
            }
        }
        assert!(admitted > 5_000, "{admitted}");
        // A flat ring's B completed by its normal (γ = 0.3): admitted.
        let flat = Mat3::from_diagonal(&Vec3::new(0.5, 0.4, 0.0));
        let w = 0.3 * flat.trace() / 3.0;
        assert!(well_conditioned(
            &(flat + w * Mat3::from_diagonal(&Vec3::z()))
        ));
        assert!(!well_conditioned(&flat));
    }

    #[test]
    fn isolated_vertex_gets_identity() {
        let (h, degenerate) = deformation_gradient(
            0,
            &[0],
            &[[1.0; 3]],
            &[[2.0; 3]],
            &[0.0; 3],
            &[0.0; 3],
            0.3,
            false,
        );
        assert!(degenerate);
        assert_eq!(h, Mat3::identity());
    }
}
