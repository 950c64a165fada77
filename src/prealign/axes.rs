//! Principal axes of a point set and the candidate rotations between two sets of axes: every
//! proper rotation that maps the template's principal axes onto the scan's, in any order and
//! with any signs (the 24 rotations of the cube's symmetry group, composed with the two frames).
//! A principal axis has no sign, and two shapes that differ by a non-rigid deformation (a
//! T-shirt draped or folded) need not have their axes in the same order, so the search tries
//! them all rather than the one pairing by sorted eigenvalues.

use crate::math::{sym_eigen3, vec3, Mat3, Vec3};

/// The centroid, the principal axes (columns of a proper rotation, by decreasing variance) and
/// the root-mean-square distance from the centroid of a point set.
#[derive(Clone, Copy, Debug)]
pub struct Axes {
    /// The mean point.
    pub centroid: Vec3,
    /// The eigenvectors of the covariance as columns, determinant +1.
    pub frame: Mat3,
    /// `sqrt(mean ‖p − centroid‖²)`.
    pub rms_radius: f64,
    /// The variances along the axes (the covariance's eigenvalues), the order of `frame`'s
    /// columns: decreasing.
    pub variances: Vec3,
}

/// The [`Axes`] of `points` (non-empty).
pub fn principal_axes(points: &[[f64; 3]]) -> Axes {
    let n = points.len().max(1) as f64;
    let centroid = points.iter().fold(Vec3::zeros(), |acc, p| acc + vec3(p)) / n;
    let mut cov = Mat3::zeros();
    for p in points {
        let d = vec3(p) - centroid;
        cov += d * d.transpose();
    }
    cov /= n;
    let eigen = sym_eigen3(&cov);
    let mut frame = eigen.vectors;
    if frame.determinant() < 0.0 {
        frame.set_column(2, &(-frame.column(2)));
    }
    Axes {
        centroid,
        frame,
        rms_radius: cov.trace().max(0.0).sqrt(),
        variances: eigen.values,
    }
}

/// The 24 proper rotations that permute the coordinate axes with signs (the rotation group of
/// the cube).
pub fn cube_rotations() -> Vec<Mat3> {
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(24);
    for perm in perms {
        for signs in 0..8u32 {
            let mut m = Mat3::zeros();
            for (row, &col) in perm.iter().enumerate() {
                m[(row, col)] = if signs >> row & 1 == 1 { -1.0 } else { 1.0 };
            }
            if m.determinant() > 0.0 {
                out.push(m);
            }
        }
    }
    out
}

/// The candidate rotations `R = F_scan · P · F_templateᵀ`, one per cube rotation `P`: each
/// maps the template's principal frame onto the scan's with one assignment of axes and signs.
pub fn candidate_rotations(template: &Axes, scan: &Axes) -> Vec<Mat3> {
    cube_rotations()
        .into_iter()
        .map(|p| scan.frame * p * template.frame.transpose())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Rotation3, Unit};

    #[test]
    fn the_cube_group_has_24_distinct_proper_rotations() {
        let all = cube_rotations();
        assert_eq!(all.len(), 24);
        for (i, a) in all.iter().enumerate() {
            assert_relative_eq!(a.determinant(), 1.0);
            assert_relative_eq!(a * a.transpose(), Mat3::identity());
            for b in &all[i + 1..] {
                assert!((a - b).norm() > 1.0);
            }
        }
    }

    #[test]
    fn one_candidate_is_the_rotation_between_two_rotated_copies() {
        // An anisotropic point set (distinct principal variances) and a rotated copy: one of
        // the candidates is the rotation itself.
        let points: Vec<[f64; 3]> = (0..200)
            .map(|i| {
                let t = i as f64 * 0.37;
                [3.0 * t.sin(), 1.5 * (1.7 * t).cos(), 0.4 * (2.3 * t).sin()]
            })
            .collect();
        let axis = Unit::new_normalize(Vec3::new(1.0, 2.0, -0.5));
        let r = *Rotation3::from_axis_angle(&axis, 1.2).matrix();
        let moved: Vec<[f64; 3]> = points.iter().map(|p| (r * vec3(p)).into()).collect();
        let (a, b) = (principal_axes(&points), principal_axes(&moved));
        assert_relative_eq!(a.rms_radius, b.rms_radius, epsilon = 1e-9);
        let best = candidate_rotations(&a, &b)
            .into_iter()
            .map(|c| (c - r).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(best < 1e-8, "closest candidate {best}");
    }
}
