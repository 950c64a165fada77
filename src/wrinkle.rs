//! ψ-modified stretch and the wrinkle-vector field (paper Eq. 6–7, SPEC §2.8).
//!
//! The stretch tensor `U = Σ λ_i e_i e_iᵀ` (λ1 ≥ λ2 ≥ λ3; `C = Hᵀ H = U²`, Eq. 6) gets the
//! stretch coefficient ψ added along the principal direction e1 and half of it removed from
//! the other two, renormalized by
//! `s = (((λ1+ψ)² + (λ2−ψ/2)² + (λ3−ψ/2)²) / 3)^{½}`:
//! `λ̂1 = (λ1+ψ)/s, λ̂2 = (λ2−ψ/2)/s, λ̂3 = (λ3−ψ/2)/s`, `Û = Σ λ̂_i e_i e_iᵀ`.
//! The wrinkle vector is `v = λ̂1 e1` (Eq. 7), with e1's sign fixed so that its first
//! coordinate of magnitude above 1e-12 (x, then y, then z) is positive.

use crate::math::{sym_eigen3, Mat3, Vec3};

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
    fn principal_direction_and_sign() {
        let u = Mat3::from_diagonal(&Vec3::new(1.0, 1.5, 0.9));
        let m = modified_stretch(&u, 0.0);
        let s = ((1.0 + 2.25 + 0.81) / 3.0f64).sqrt();
        assert_relative_eq!(m.wrinkle, Vec3::new(0.0, 1.5 / s, 0.0), epsilon = 1e-12);
        assert_relative_eq!(m.stretch, u / s, epsilon = 1e-12);
    }
}
