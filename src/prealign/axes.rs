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

/// Two principal variances within this fraction of the larger do not fix the axes of their
/// plane (a square sheet, a round tube, a scan as wide as it is long): any turn about the third
/// axis is as principal. The cube rotations sample that circle every 90° only.
pub const TIED_VARIANCES: f64 = 0.1;

/// The turns (degrees) about the distinct axis of a frame whose other two axes tie
/// ([`TIED_VARIANCES`]) given to the best cube candidate's basin: with the cube's own quarter
/// turns, the circle is sampled every 30°.
pub const TIED_TURNS: [f64; 4] = [30.0, 60.0, -30.0, -60.0];

/// A frame's largest (smallest) principal axis is distinct when the middle variance lies below
/// (above) it by more than this fraction: a garment's depth, a sheet's normal, a tall or wide
/// shape's long axis.
pub const DISTINCT_VARIANCES: f64 = 0.3;

/// Two frames agree when each distinct axis that both have lies within this angle (degrees,
/// either sign) of the other's: half the quarter turn between two cube candidates.
pub const AGREEING_AXES_DEGREES: f64 = 45.0;

impl Axes {
    /// Whether `other`'s largest and smallest principal axes lie within
    /// `AGREEING_AXES_DEGREES` (45°) of this frame's, wherever both frames have that axis distinct
    /// (`DISTINCT_VARIANCES`, 30 %): a shape and a quarter-turned copy of it do not agree, a
    /// shape and its deformed or noisy copy do (their tied axes are not compared).
    pub fn agrees_with(&self, other: &Axes) -> bool {
        let distinct = |a: &Axes, k: usize| {
            let v = a.variances;
            if k == 0 {
                v[1] < (1.0 - DISTINCT_VARIANCES) * v[0]
            } else {
                v[2] < (1.0 - DISTINCT_VARIANCES) * v[1]
            }
        };
        let cos = AGREEING_AXES_DEGREES.to_radians().cos();
        [0, 2].into_iter().all(|k| {
            !(distinct(self, k) && distinct(other, k))
                || self.frame.column(k).dot(&other.frame.column(k)).abs() >= cos
        })
    }

    /// The principal axis whose variance stands apart when the other two tie within
    /// `TIED_VARIANCES` (10 %); `None` when no two tie, or all three do.
    pub fn tied_turn_axis(&self) -> Option<Vec3> {
        let v = self.variances;
        let tie =
            |i: usize, j: usize| (v[i] - v[j]).abs() <= TIED_VARIANCES * v[i].abs().max(v[j].abs());
        let mut apart = [(0, 1, 2), (0, 2, 1), (1, 2, 0)]
            .into_iter()
            .filter(|&(i, j, _)| tie(i, j))
            .map(|(_, _, k)| k);
        match (apart.next(), apart.next()) {
            (Some(k), None) => Some(self.frame.column(k).into_owned()),
            _ => None,
        }
    }
}

/// The rotations `base` turned about the distinct axis of each of the two frames whose other
/// axes tie in a plane ([`Axes::tied_turn_axis`]) by [`TIED_TURNS`] (the template's turn
/// applied first, the scan's last); empty when neither frame ties. A folded square sheet's
/// best placement can lie 30° from every cube candidate, out of trimmed ICP's reach from them
/// (docs/method.md "Global pre-alignment").
pub fn tied_turns(template: &Axes, scan: &Axes, base: &[Mat3]) -> Vec<Mat3> {
    let turns = |axis: Vec3| {
        let axis = nalgebra::Unit::new_normalize(axis);
        TIED_TURNS.map(|t| *nalgebra::Rotation3::from_axis_angle(&axis, t.to_radians()).matrix())
    };
    let mut out = Vec::new();
    if let Some(axis) = template.tied_turn_axis() {
        for q in turns(axis) {
            out.extend(base.iter().map(|r| r * q));
        }
    }
    if let Some(axis) = scan.tied_turn_axis() {
        for q in turns(axis) {
            out.extend(base.iter().map(|r| q * r));
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

    /// A grid of `nx` × `ny` points of spacing 1 in the plane z = 0, turned by `r`.
    fn grid(nx: usize, ny: usize, r: &Mat3) -> Vec<[f64; 3]> {
        (0..nx * ny)
            .map(|i| (r * Vec3::new((i % nx) as f64, (i / nx) as f64, 0.0)).into())
            .collect()
    }

    #[test]
    fn frames_agree_unless_a_distinct_axis_turned_past_45_degrees() {
        let turn = |degrees: f64| {
            *Rotation3::from_axis_angle(&Vec3::z_axis(), degrees.to_radians()).matrix()
        };
        // A 1 × 2 sheet: its long axis (largest) and normal (smallest) are distinct.
        let strip = principal_axes(&grid(11, 21, &Mat3::identity()));
        assert!(strip.agrees_with(&strip));
        assert!(strip.agrees_with(&principal_axes(&grid(11, 21, &turn(40.0)))));
        assert!(!strip.agrees_with(&principal_axes(&grid(11, 21, &turn(50.0)))));
        assert!(!strip.agrees_with(&principal_axes(&grid(11, 21, &turn(90.0)))));
        // Half a turn flips the axes' signs only: they agree.
        assert!(strip.agrees_with(&principal_axes(&grid(11, 21, &turn(180.0)))));
        // A square sheet's in-plane axes tie: only its normal is compared, which a turn about
        // it keeps; tipped onto its side, the normal disagrees.
        let square = principal_axes(&grid(21, 21, &Mat3::identity()));
        assert!(square.agrees_with(&principal_axes(&grid(21, 21, &turn(45.0)))));
        let tipped = *Rotation3::from_axis_angle(&Vec3::x_axis(), 90f64.to_radians()).matrix();
        assert!(!square.agrees_with(&principal_axes(&grid(21, 21, &tipped))));
    }

    #[test]
    fn a_square_sheet_s_frame_is_tied_about_its_normal_and_gets_turned_candidates() {
        let r = *Rotation3::from_axis_angle(&Unit::new_normalize(Vec3::new(1.0, 2.0, -1.5)), 0.9)
            .matrix();
        let square = principal_axes(&grid(21, 21, &r));
        let axis = square
            .tied_turn_axis()
            .expect("a square's in-plane axes tie");
        assert_relative_eq!(axis.dot(&(r * Vec3::z())).abs(), 1.0, epsilon = 1e-9);
        // A 1 × 2 sheet's axes are all fixed; a cube of points ties all three (no turn helps).
        let strip = principal_axes(&grid(11, 21, &r));
        assert!(strip.tied_turn_axis().is_none());
        let cube: Vec<[f64; 3]> = (0..1000)
            .map(|i| [(i % 10) as f64, (i / 10 % 10) as f64, (i / 100) as f64])
            .collect();
        assert!(principal_axes(&cube).tied_turn_axis().is_none());
        let base = candidate_rotations(&square, &strip);
        let turned = tied_turns(&square, &strip, &base);
        assert_eq!(turned.len(), 24 * TIED_TURNS.len());
        // Each is a cube candidate turned by one of the turns about the square's normal.
        let normal = r * Vec3::z();
        for (k, t) in turned.iter().enumerate() {
            let turn = Rotation3::from_matrix_unchecked(base[k % 24].transpose() * t);
            assert_relative_eq!(
                turn.angle().to_degrees(),
                TIED_TURNS[k / 24].abs(),
                epsilon = 1e-9
            );
            let axis = turn.axis().expect("a turn");
            assert_relative_eq!(axis.dot(&normal).abs(), 1.0, epsilon = 1e-9);
        }
        assert!(tied_turns(&strip, &strip, &candidate_rotations(&strip, &strip)).is_empty());
    }
}
