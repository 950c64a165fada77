//! A similarity transform `p ↦ s R p + t` and its least-squares estimate from point pairs
//! (Umeyama 1991, "Least-squares estimation of transformation parameters between two point
//! patterns"; with the scale fixed to 1 it is the Kabsch fit).

use crate::math::{nearest_rotation, vec3, Mat3, Vec3};

/// `p ↦ scale · rotation · p + translation` (a rigid motion when `scale` is 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    /// A proper rotation (det +1).
    pub rotation: Mat3,
    /// The uniform scale (> 0).
    pub scale: f64,
    /// Added after rotating and scaling.
    pub translation: Vec3,
}

impl Similarity {
    /// The identity: the placement as given.
    pub fn identity() -> Self {
        Self {
            rotation: Mat3::identity(),
            scale: 1.0,
            translation: Vec3::zeros(),
        }
    }

    /// The transform of one point.
    #[inline]
    pub fn apply(&self, p: &[f64; 3]) -> [f64; 3] {
        (self.scale * (self.rotation * vec3(p)) + self.translation).into()
    }

    /// The transform of every point.
    pub fn apply_all(&self, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        points.iter().map(|p| self.apply(p)).collect()
    }

    /// The inverse transform `q ↦ Rᵀ (q − t) / s`.
    pub fn inverse(&self) -> Self {
        let rotation = self.rotation.transpose();
        Self {
            rotation,
            scale: 1.0 / self.scale,
            translation: -(rotation * self.translation) / self.scale,
        }
    }

    /// Whether this is exactly the identity.
    pub fn is_identity(&self) -> bool {
        *self == Self::identity()
    }

    /// The rotation angle in degrees (`acos((tr R − 1) / 2)`).
    pub fn angle_degrees(&self) -> f64 {
        ((self.rotation.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    /// The angle in degrees of the rotation that turns `other`'s orientation into this one's.
    pub fn turned_from(&self, other: &Self) -> f64 {
        Self {
            rotation: other.rotation.transpose() * self.rotation,
            ..Self::identity()
        }
        .angle_degrees()
    }
}

/// The least-squares similarity (or, with `scaled` false, rigid motion) mapping each
/// `pairs[i].0` onto `pairs[i].1`: `argmin Σ ‖s R aᵢ + t − bᵢ‖²` (Umeyama 1991, Eq. 40–42;
/// the reflection case resolved by the nearest proper rotation). `None` for fewer than three
/// pairs or a source set with no spread.
pub fn fit_pairs(pairs: &[([f64; 3], [f64; 3])], scaled: bool) -> Option<Similarity> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (mut ca, mut cb) = (Vec3::zeros(), Vec3::zeros());
    for (a, b) in pairs {
        ca += vec3(a);
        cb += vec3(b);
    }
    ca /= n;
    cb /= n;
    let mut cov = Mat3::zeros();
    let mut var_a = 0.0;
    for (a, b) in pairs {
        let (da, db) = (vec3(a) - ca, vec3(b) - cb);
        cov += db * da.transpose();
        var_a += da.norm_squared();
    }
    if !(var_a > 0.0 && var_a.is_finite()) {
        return None;
    }
    let rotation = nearest_rotation(&cov);
    // Umeyama's scale: tr(D S) / σ²_a, where tr(D S) = tr(Rᵀ Σ) for the chosen rotation.
    let scale = if scaled {
        (rotation.transpose() * cov).trace() / var_a
    } else {
        1.0
    };
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    Some(Similarity {
        rotation,
        scale,
        translation: cb - scale * (rotation * ca),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Rotation3, Unit};

    fn known() -> Similarity {
        let axis = Unit::new_normalize(Vec3::new(0.3, -1.0, 0.4));
        Similarity {
            rotation: *Rotation3::from_axis_angle(&axis, 2.1).matrix(),
            scale: 2.5,
            translation: Vec3::new(1.0, -2.0, 0.5),
        }
    }

    fn points() -> Vec<[f64; 3]> {
        (0..40)
            .map(|i| {
                let t = i as f64;
                [
                    (0.7 * t).sin(),
                    (1.3 * t).cos() * 0.5,
                    (0.37 * t).sin() * 0.2 + 0.01 * t,
                ]
            })
            .collect()
    }

    #[test]
    fn fit_pairs_recovers_a_known_similarity_and_a_known_rigid_motion() {
        let truth = known();
        let a = points();
        let pairs: Vec<_> = a.iter().map(|p| (*p, truth.apply(p))).collect();
        let got = fit_pairs(&pairs, true).unwrap();
        assert_relative_eq!(got.rotation, truth.rotation, epsilon = 1e-10);
        assert_relative_eq!(got.scale, truth.scale, epsilon = 1e-10);
        assert_relative_eq!(got.translation, truth.translation, epsilon = 1e-10);

        let rigid = Similarity {
            scale: 1.0,
            ..truth
        };
        let pairs: Vec<_> = a.iter().map(|p| (*p, rigid.apply(p))).collect();
        let got = fit_pairs(&pairs, false).unwrap();
        assert_relative_eq!(got.rotation, rigid.rotation, epsilon = 1e-10);
        assert_eq!(got.scale, 1.0);
        assert_relative_eq!(got.translation, rigid.translation, epsilon = 1e-10);
    }

    #[test]
    fn inverse_undoes_the_transform() {
        let t = known();
        let inv = t.inverse();
        for p in points() {
            let back = inv.apply(&t.apply(&p));
            assert_relative_eq!(vec3(&back), vec3(&p), epsilon = 1e-12);
        }
        assert!(Similarity::identity().is_identity());
        assert!(!t.is_identity());
        assert_relative_eq!(t.angle_degrees(), 2.1f64.to_degrees(), epsilon = 1e-9);
    }

    #[test]
    fn fit_pairs_rejects_degenerate_sources() {
        let p = [[1.0, 2.0, 3.0]; 5];
        let pairs: Vec<_> = p.iter().map(|a| (*a, *a)).collect();
        assert!(fit_pairs(&pairs, true).is_none());
        assert!(fit_pairs(&pairs[..2], false).is_none());
    }
}
