//! Per-vertex transformation (paper Eq. 8; docs/method.md "Rotation and translation, Eq. 8").
//!
//! `R_k* = argmin_{R ∈ SO(3)} ‖H_k − R Û_k‖_F` is an orthogonal Procrustes problem: R* is the
//! rotation factor of `H_k Û_kᵀ`. The translation is `t_k* = Ȳ'_k − R_k* Ȳ_k` with Ȳ, Ȳ' the
//! centroids of Γᵏ_Y at t and t+Δt, and the vertex moves to `R_k* Y_k + t_k*`. For NRGa
//! (docs/method.md "NRGa mode") the rotation is the Kabsch fit of the neighborhood's old to new
//! positions instead.

use crate::math::{nearest_rotation_with, vec3, Mat3, Vec3};

/// Solves Eq. 8: the rotation closest to `h` once the stretch `u_hat` is factored out
/// (`fast`: by [`crate::math::nearest_rotation_fast`], equal to round-off).
#[inline]
pub fn solve_rotation(h: &Mat3, u_hat: &Mat3, fast: bool) -> Mat3 {
    nearest_rotation_with(&(h * u_hat.transpose()), fast)
}

/// Centroids of `ring` in `old` and `new` positions.
#[inline]
pub fn ring_centroids(ring: &[u32], old: &[[f64; 3]], new: &[[f64; 3]]) -> (Vec3, Vec3) {
    let mut c_old = Vec3::zeros();
    let mut c_new = Vec3::zeros();
    for &j in ring {
        c_old += vec3(&old[j as usize]);
        c_new += vec3(&new[j as usize]);
    }
    let n = ring.len().max(1) as f64;
    (c_old / n, c_new / n)
}

/// The updated position `R Y_k + t` with `t = Ȳ' − R Ȳ`, i.e. `Ȳ' + R (Y_k − Ȳ)`.
#[inline]
pub fn transform_vertex(rotation: &Mat3, y: &Vec3, c_old: &Vec3, c_new: &Vec3) -> Vec3 {
    c_new + rotation * (y - c_old)
}

/// Kabsch rotation of the neighborhood: the rotation best mapping `old − Ȳ` onto `new − Ȳ'`.
/// With `fast`, the nearest rotation of the covariance comes from the unit-quaternion solution
/// (a flat neighborhood's rank-2 covariance included), agreeing with the eigen-decomposition
/// to round-off ([`crate::math::nearest_rotation_fast`]).
pub fn kabsch(
    ring: &[u32],
    old: &[[f64; 3]],
    new: &[[f64; 3]],
    c_old: &Vec3,
    c_new: &Vec3,
    fast: bool,
) -> Mat3 {
    let mut cov = Mat3::zeros();
    for &j in ring {
        cov += (vec3(&new[j as usize]) - c_new) * (vec3(&old[j as usize]) - c_old).transpose();
    }
    nearest_rotation_with(&cov, fast)
}

/// One point's moments for [`ring_fit_from_moments`]: its old position, its new position and
/// their outer product `new oldᵀ` (row-major).
pub type PointMoments = [f64; 15];

/// The moments of a point moving `old → new`.
#[inline]
pub fn point_moments(old: &[f64; 3], new: &[f64; 3]) -> PointMoments {
    let mut m = [0.0; 15];
    m[..3].copy_from_slice(old);
    m[3..6].copy_from_slice(new);
    for r in 0..3 {
        for c in 0..3 {
            m[6 + 3 * r + c] = new[r] * old[c];
        }
    }
    m
}

/// Centroids `(Ȳ, Ȳ')` and covariance `Σ (new − Ȳ')(old − Ȳ)ᵀ = Σ new oldᵀ − |ring| Ȳ' Ȳᵀ` of
/// a neighborhood from its members' [`point_moments`]: one pass of 15 additions per member
/// instead of [`ring_centroids`] and [`kabsch`]'s two passes (30 flops). The product form
/// cancels where the ring is small against its distance from the origin, which costs a few
/// digits (relative error ≈ ε (|Y| / ring radius)², e.g. 1e-13 for an 8-ring at the paper's
/// size in the normalized frame), not the result's agreement to 1e-9.
pub fn ring_fit_from_moments(ring: &[u32], moments: &[PointMoments]) -> (Vec3, Vec3, Mat3) {
    let mut sum = [0.0; 15];
    for &j in ring {
        for (s, m) in sum.iter_mut().zip(&moments[j as usize]) {
            *s += m;
        }
    }
    ring_fit_from_sum(&sum, ring.len())
}

/// [`ring_fit_from_moments`] from the sum of the ring's `len` members' moments (as
/// [`crate::rings::RingDeltas::sums`] gives it).
pub fn ring_fit_from_sum(sum: &PointMoments, len: usize) -> (Vec3, Vec3, Mat3) {
    let n = len.max(1) as f64;
    let c_old = Vec3::new(sum[0], sum[1], sum[2]) / n;
    let c_new = Vec3::new(sum[3], sum[4], sum[5]) / n;
    let cov = Mat3::from_row_slice(&sum[6..15]) - n * c_new * c_old.transpose();
    (c_old, c_new, cov)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn procrustes_recovers_random_rotation() {
        let r = *nalgebra::Rotation3::from_euler_angles(1.0, -0.4, 2.5).matrix();
        let u = Mat3::new(1.2, 0.1, 0.0, 0.1, 0.9, 0.0, 0.0, 0.0, 1.0);
        assert_relative_eq!(solve_rotation(&(r * u), &u, false), r, epsilon = 1e-10);
        // Any SPD Û sharing U's eigenvectors gives the same rotation.
        assert_relative_eq!(
            solve_rotation(&(r * u), &(u * u), false),
            r,
            epsilon = 1e-10
        );
    }

    #[test]
    fn moments_give_the_two_pass_centroids_and_covariance() {
        // A ring of 145 points of radius 0.07 at distance ~0.6 from the origin (an 8-ring of
        // the paper-sized sheet in the normalized frame), moved non-rigidly.
        let r = *nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.9).matrix();
        let old: Vec<[f64; 3]> = (0..145)
            .map(|i| {
                let (a, b) = (i as f64 * 0.71, i as f64 * 0.37);
                [
                    0.5 + 0.07 * a.sin(),
                    -0.3 + 0.07 * b.cos(),
                    0.2 + 0.01 * (a + b).sin(),
                ]
            })
            .collect();
        let new: Vec<[f64; 3]> = old
            .iter()
            .map(|p| {
                let q = r * vec3(p) + Vec3::new(0.01, 0.02, -0.03);
                [
                    q.x + 0.003 * (9.0 * p[0]).sin(),
                    q.y,
                    q.z + 0.002 * (7.0 * p[1]).cos(),
                ]
            })
            .collect();
        let moments: Vec<PointMoments> = old
            .iter()
            .zip(&new)
            .map(|(o, n)| point_moments(o, n))
            .collect();
        let ring: Vec<u32> = (0..145).rev().step_by(2).collect();
        let (c_old, c_new) = ring_centroids(&ring, &old, &new);
        let mut cov = Mat3::zeros();
        for &j in &ring {
            cov += (vec3(&new[j as usize]) - c_new) * (vec3(&old[j as usize]) - c_old).transpose();
        }
        let (m_old, m_new, m_cov) = ring_fit_from_moments(&ring, &moments);
        assert_relative_eq!(m_old, c_old, epsilon = 1e-15);
        assert_relative_eq!(m_new, c_new, epsilon = 1e-15);
        assert_relative_eq!(m_cov, cov, epsilon = 1e-12 * cov.norm());
        assert_relative_eq!(
            nearest_rotation_with(&m_cov, true),
            kabsch(&ring, &old, &new, &c_old, &c_new, false),
            epsilon = 1e-11
        );
    }

    #[test]
    fn kabsch_recovers_rigid_motion() {
        let old = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 3.0],
            [1.0, 1.0, 1.0],
        ];
        let r = *nalgebra::Rotation3::from_euler_angles(0.5, 0.2, -1.3).matrix();
        let t = Vec3::new(3.0, -2.0, 0.5);
        let new: Vec<[f64; 3]> = old.iter().map(|p| (r * vec3(p) + t).into()).collect();
        let ring = [0, 1, 2, 3, 4];
        let (co, cn) = ring_centroids(&ring, &old, &new);
        let rk = kabsch(&ring, &old, &new, &co, &cn, false);
        assert_relative_eq!(rk, r, epsilon = 1e-10);
        assert_relative_eq!(
            transform_vertex(&rk, &vec3(&old[4]), &co, &cn),
            vec3(&new[4]),
            epsilon = 1e-10
        );
    }
}
