//! ψ-modified stretch and the wrinkle-vector field (paper Eq. 6–7; docs/method.md "Stretch and
//! wrinkle-vector field, Eq. 6–7").
//!
//! The stretch tensor `U = Σ λ_i e_i e_iᵀ` (λ1 ≥ λ2 ≥ λ3; `C = Hᵀ H = U²`, Eq. 6) gets the
//! stretch coefficient ψ added along the principal direction e1 and half of it removed from
//! the other two, renormalized by
//! `s = (((λ1+ψ)² + (λ2−ψ/2)² + (λ3−ψ/2)²) / 3)^{½}`:
//! `λ̂1 = (λ1+ψ)/s, λ̂2 = (λ2−ψ/2)/s, λ̂3 = (λ3−ψ/2)/s`, `Û = Σ λ̂_i e_i e_iᵀ`.
//! The wrinkle vector is `v = λ̂1 e1` (Eq. 7), with e1's sign fixed so that its first
//! coordinate of magnitude above 1e-12 (x, then y, then z) is positive.

use crate::math::{positive_definite_det_trace, sym_eigen3, Mat3, Vec3};

/// The ψ-modified stretch of one vertex.
#[derive(Clone, Copy, Debug)]
pub struct ModifiedStretch {
    /// `Û`.
    pub stretch: Mat3,
    /// The wrinkle vector `λ̂1 e1`.
    pub wrinkle: Vec3,
}

/// Applies ψ to the stretch tensor `u` (symmetric) and returns `Û` and the wrinkle vector.
pub fn modified_stretch(u: &Mat3, psi: f64) -> ModifiedStretch {
    let e = sym_eigen3(u);
    let raw = [
        e.values[0] + psi,
        e.values[1] - psi / 2.0,
        e.values[2] - psi / 2.0,
    ];
    let s = ((raw[0] * raw[0] + raw[1] * raw[1] + raw[2] * raw[2]) / 3.0).sqrt();
    let s = if s > 0.0 { s } else { 1.0 };
    let mut stretch = Mat3::zeros();
    for (i, r) in raw.iter().enumerate() {
        let v = e.vectors.column(i);
        stretch += (r / s) * v * v.transpose();
    }
    let mut e1: Vec3 = e.vectors.column(0).into();
    if let Some(c) = e1.iter().find(|c| c.abs() > 1e-12) {
        if *c < 0.0 {
            e1 = -e1;
        }
    }
    ModifiedStretch {
        stretch,
        wrinkle: (raw[0] / s) * e1,
    }
}

/// A sufficient test, without an eigen-decomposition, that `u` is positive definite and
/// that every ψ-modified eigenvalue of [`modified_stretch`] stays positive: `λ1 + ψ > 0` and
/// `λ3 − ψ/2 > 0`. Then `u Û` is positive definite, which makes Eq. 8's rotation the
/// regularized one (see `fit::deformation_rotations`).
///
/// Positive definiteness by Sylvester's criterion, then `λ3 ≥ 4 det / tr²` and `λ1 ≥ tr / 3`
/// ([`positive_definite_det_trace`]).
pub fn stretch_stays_positive(u: &Mat3, psi: f64) -> bool {
    positive_definite_det_trace(u)
        .is_some_and(|(det, trace)| 4.0 * det > 0.5 * psi * trace * trace && trace > -3.0 * psi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn identity_stretch_with_psi() {
        let m = modified_stretch(&Mat3::identity(), 0.05);
        let s = ((1.05f64.powi(2) + 2.0 * 0.975f64.powi(2)) / 3.0).sqrt();
        assert_relative_eq!(m.wrinkle.norm(), 1.05 / s, epsilon = 1e-12);
        // Û has unit RMS eigenvalue by construction.
        assert_relative_eq!(
            (m.stretch.transpose() * m.stretch).trace(),
            3.0,
            epsilon = 1e-12
        );
    }

    #[test]
    fn positive_stretch_test_is_sufficient_and_rarely_refuses() {
        // Random symmetric matrices around the identity: wherever the test passes, the
        // Jacobi eigenvalues of the ψ-modified stretch are all positive, and then Eq. 8's
        // solve returns the regularized rotation itself.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let r = *nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1).matrix();
        let (mut passed, mut near_identity) = (0, 0);
        for i in 0..20_000 {
            let spread = if i % 2 == 0 { 0.3 } else { 1.5 };
            let a = Mat3::from_fn(|_, _| rng.random_range(-spread..spread));
            let u = Mat3::identity() + 0.5 * (a + a.transpose());
            for psi in [0.05, 0.5, -0.3] {
                if !stretch_stays_positive(&u, psi) {
                    continue;
                }
                passed += 1;
                near_identity += usize::from(spread < 1.0);
                let e = sym_eigen3(&u);
                assert!(e.values[2] > 0.0, "{u}");
                let m = modified_stretch(&u, psi);
                let hat = sym_eigen3(&m.stretch);
                assert!(hat.values[2] > 0.0, "{u} ψ={psi}");
                let solved = crate::rotation::solve_rotation(&(r * u), &m.stretch, false);
                assert_relative_eq!(solved, r, epsilon = 1e-9);
            }
        }
        // Near the identity (spread 0.3: the stretches of a fit) it refuses only ψ = 0.5's
        // large shrink cases; far from it, it must also refuse indefinite matrices.
        assert!(near_identity > 25_000, "{near_identity}");
        assert!(passed < 60_000, "{passed}");
        // Refuses: an indefinite matrix, and a compression below ψ/2.
        let indefinite = Mat3::from_diagonal(&Vec3::new(5.0, -1.0, -1.0));
        assert!(!stretch_stays_positive(&indefinite, 0.05));
        let squashed = Mat3::from_diagonal(&Vec3::new(1.0, 1.0, 0.02));
        assert!(!stretch_stays_positive(&squashed, 0.05));
    }

    #[test]
    fn principal_direction_and_sign() {
        let u = Mat3::from_diagonal(&Vec3::new(1.0, 1.5, 0.9));
        let m = modified_stretch(&u, 0.0);
        let s = ((1.0 + 2.25 + 0.81) / 3.0f64).sqrt();
        assert_relative_eq!(m.wrinkle, Vec3::new(0.0, 1.5 / s, 0.0), epsilon = 1e-12);
        assert_relative_eq!(m.stretch, u / s, epsilon = 1e-12);
    }
}
