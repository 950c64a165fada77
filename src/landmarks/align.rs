//! The least-squares rigid or similarity motion between two point sets in correspondence,
//! for landmarks: Umeyama's closed form ([`crate::prealign::fit_pairs`], S. Umeyama,
//! "Least-squares estimation of transformation parameters between two point patterns", IEEE
//! TPAMI 13(4), 1991), with the centroids' translation alone where the pairs fix no rotation.
//! Landmarks use it as the global pre-alignment (docs/method.md "Landmarks").

use crate::math::{vec3, Mat3, Vec3};
pub use crate::prealign::Similarity;

/// Below this ratio of the source's second to first principal spread, its points lie on a
/// line (or a point) and fix no rotation.
const COLLINEAR: f64 = 1e-9;

/// Whether points in correspondence at `from` fix a rotation: three or more, not on a line.
pub fn fixes_rotation(from: &[[f64; 3]]) -> bool {
    if from.len() < 3 {
        return false;
    }
    let n = from.len() as f64;
    let centroid = from.iter().fold(Vec3::zeros(), |a, p| a + vec3(p)) / n;
    let mut spread = Mat3::zeros();
    for p in from {
        let a = vec3(p) - centroid;
        spread += a * a.transpose();
    }
    let mut eig = spread.symmetric_eigenvalues().as_slice().to_vec();
    eig.sort_by(|a, b| b.total_cmp(a));
    eig[0] > 0.0 && eig[1] > COLLINEAR * eig[0]
}

/// The motion minimizing `Σ ‖T(from_i) − to_i‖²` over rotations and translations (and, with
/// `scale`, uniform scales): Umeyama's closed form. With fewer than three pairs, or points of
/// `from` on a line, the rotation is undetermined and only the centroids' translation is
/// returned (scale 1). `from` and `to` must have the same, non-zero length.
pub fn fit_similarity(from: &[[f64; 3]], to: &[[f64; 3]], scale: bool) -> Similarity {
    assert_eq!(from.len(), to.len(), "pairs in correspondence");
    assert!(!from.is_empty(), "at least one pair");
    let n = from.len() as f64;
    let c_from = from.iter().fold(Vec3::zeros(), |a, p| a + vec3(p)) / n;
    let c_to = to.iter().fold(Vec3::zeros(), |a, p| a + vec3(p)) / n;
    let translation_only = Similarity {
        translation: c_to - c_from,
        ..Similarity::identity()
    };
    if !fixes_rotation(from) {
        return translation_only;
    }
    let pairs: Vec<([f64; 3], [f64; 3])> = from.iter().copied().zip(to.iter().copied()).collect();
    crate::prealign::fit_pairs(&pairs, scale).unwrap_or(translation_only)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Unit};

    fn points() -> Vec<[f64; 3]> {
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.2, -0.3],
            [0.1, 1.3, 0.4],
            [-0.7, 0.5, 1.1],
            [0.4, -0.9, 0.6],
        ]
    }

    #[test]
    fn recovers_a_known_similarity() {
        let axis = Unit::new_normalize(Vec3::new(0.3, -1.0, 0.5));
        let r = *Rotation3::from_axis_angle(&axis, 2.4).matrix();
        let truth = Similarity {
            rotation: r,
            scale: 2.5,
            translation: Vec3::new(3.0, -1.0, 0.25),
        };
        let from = points();
        let to = truth.apply_all(&from);
        let fitted = fit_similarity(&from, &to, true);
        assert!((fitted.rotation - r).norm() < 1e-12);
        assert!((fitted.scale - 2.5).abs() < 1e-12);
        assert!((fitted.translation - truth.translation).norm() < 1e-12);
        // Rigid: the rotation still, the scale left at 1.
        let rigid = fit_similarity(
            &from,
            &Similarity {
                scale: 1.0,
                ..truth
            }
            .apply_all(&from),
            false,
        );
        assert!((rigid.rotation - r).norm() < 1e-12);
        assert_eq!(rigid.scale, 1.0);
    }

    #[test]
    fn never_returns_a_reflection() {
        let from = points();
        let mirrored: Vec<[f64; 3]> = from.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let fitted = fit_similarity(&from, &mirrored, false);
        assert!((fitted.rotation.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn too_few_or_collinear_pairs_translate_only() {
        let from = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let to = [[0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.0, 3.0, 0.0]];
        for n in [1, 2, 3] {
            let fitted = fit_similarity(&from[..n], &to[..n], true);
            assert_eq!(fitted.rotation, Mat3::identity());
            assert_eq!(fitted.scale, 1.0);
            let mean = |p: &[[f64; 3]]| p.iter().fold(Vec3::zeros(), |a, q| a + vec3(q)) / n as f64;
            assert!((fitted.translation - (mean(&to[..n]) - mean(&from[..n]))).norm() < 1e-15);
        }
    }
}
