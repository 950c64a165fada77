//! The template's rotational symmetries in the rigid phase (docs/method.md "Rigid phase").
//!
//! A rotation about an axis the template is symmetric about — a tube (a skirt) turned about
//! its own axis, a round sheet turned in its plane — moves every surface point along the
//! surface and every rim point along the rim. No distance to the scan sees it, yet the
//! tangential parts of the scan's pulls add up to a torque about that axis, and the rigid
//! phase's Kabsch fit turns the template by it. The stability analysis of point-to-plane ICP
//! (Gelfand, Ikemoto, Rusinkiewicz, Levoy 2003, "Geometrically stable sampling for the ICP
//! algorithm") finds such axes: a rotation ω moves a surface point `r` (from the centroid) with
//! normal `n` off the surface by `ω · (r × n)`, and a rim point with in-surface rim normal `b`
//! off the rim by `ω · (r × b)`. The ratio λ(ω) = ωᵀAω / ωᵀBω of that motion's energy to the
//! whole motion's (A and B below, surface and rim each normalized to unit weight) lies in
//! [0, 1]; the generalized eigenvectors of (A, B) with λ under [`SYMMETRY_STIFFNESS`] are the
//! template's free axes, and the rigid phase's rotation keeps no part about them
//! ([`RigidSymmetry::hold`]).

use crate::math::{vec3, Mat3, Vec3};
use nalgebra as na;

/// The largest λ (the share of a rotation's motion that leaves the surface or the rim) of an
/// axis the rigid phase treats as a symmetry of the template: a tube's turn about its axis has
/// λ = 0 up to its polygonal discretization, a square sheet's turn in its plane 0.125 (its rim
/// holds it), a T-shirt's about any axis well above this.
pub(super) const SYMMETRY_STIFFNESS: f64 = 0.02;

/// The template's boundary edges, each with the third vertex of its face, for the rim's part
/// of the symmetry analysis; present only when the template, as placed, has a free axis.
#[derive(Debug, Clone)]
pub(super) struct RigidSymmetry {
    rim: Vec<[u32; 3]>,
    /// How many free axes the template has as placed (1: a tube; 3: a sphere).
    axes: usize,
}

impl RigidSymmetry {
    /// The analysis for `faces` at `pos` (the placed template), or `None` when the template
    /// has no free axis there (most garments): the rigid phase is then left as it is.
    pub(super) fn new(pos: &[[f64; 3]], faces: &[[u32; 3]]) -> Option<Self> {
        let boundary: std::collections::HashSet<(u32, u32)> =
            crate::mesh::boundary_edges(faces).into_iter().collect();
        let rim = faces
            .iter()
            .flat_map(|f| [[f[0], f[1], f[2]], [f[1], f[2], f[0]], [f[2], f[0], f[1]]])
            .filter(|e| boundary.contains(&(e[0].min(e[1]), e[0].max(e[1]))))
            .collect();
        let mut symmetry = Self { rim, axes: 0 };
        symmetry.axes = symmetry.free_axes(pos, faces).iter().flatten().count();
        (symmetry.axes > 0).then_some(symmetry)
    }

    /// How many free axes the template has as placed (1: a tube, 3: a sphere).
    pub(super) fn axes(&self) -> usize {
        self.axes
    }

    /// `r`, the rigid phase's rotation of the template at `pos`, without its part about the
    /// template's free axes (the rotation vector projected off them).
    pub(super) fn hold(&self, r: &Mat3, pos: &[[f64; 3]], faces: &[[u32; 3]]) -> Mat3 {
        let mut omega = na::Rotation3::from_matrix_unchecked(*r).scaled_axis();
        let mut basis: [Vec3; 3] = [Vec3::zeros(); 3];
        let mut n = 0;
        for axis in self.free_axes(pos, faces).into_iter().flatten() {
            // Gram–Schmidt: the free axes span a subspace; ω loses its part in it.
            let mut w = axis;
            for b in &basis[..n] {
                w -= b * b.dot(&w);
            }
            let norm = w.norm();
            if norm > 1e-9 {
                basis[n] = w / norm;
                n += 1;
            }
        }
        for b in &basis[..n] {
            omega -= b * b.dot(&omega);
        }
        na::Rotation3::new(omega).into_inner()
    }

    /// The generalized eigenvectors of (A, B) with eigenvalue under [`SYMMETRY_STIFFNESS`],
    /// unit length: A sums the surface's `area · (r × n)(r × n)ᵀ` and the rim's
    /// `length · (r × b)(r × b)ᵀ`, B their `|r|² I − r rᵀ`, each part divided by the trace of
    /// its B (module docs).
    fn free_axes(&self, pos: &[[f64; 3]], faces: &[[u32; 3]]) -> [Option<Vec3>; 3] {
        let mut area = 0.0;
        let mut centroid = Vec3::zeros();
        let face_centroid =
            |f: &[u32; 3]| f.iter().map(|&v| vec3(&pos[v as usize])).sum::<Vec3>() / 3.0;
        for f in faces {
            let w = 0.5 * crate::mesh::face_area_normal(pos, f).norm();
            area += w;
            centroid += w * face_centroid(f);
        }
        if area <= 0.0 {
            return [None; 3];
        }
        centroid /= area;
        let inertia = |r: &Vec3| Mat3::identity() * r.norm_squared() - r * r.transpose();
        let (mut a_s, mut b_s) = (Mat3::zeros(), Mat3::zeros());
        for f in faces {
            let cross = crate::mesh::face_area_normal(pos, f);
            let norm = cross.norm();
            if norm <= 0.0 {
                continue;
            }
            let r = face_centroid(f) - centroid;
            let moment = r.cross(&(cross / norm));
            a_s += 0.5 * norm * moment * moment.transpose();
            b_s += 0.5 * norm * inertia(&r);
        }
        let (mut a_r, mut b_r) = (Mat3::zeros(), Mat3::zeros());
        for e in &self.rim {
            let [a, b, o] = e.map(|v| vec3(&pos[v as usize]));
            let edge = b - a;
            let length = edge.norm();
            let across = edge.cross(&edge.cross(&(o - a)));
            if length <= 0.0 || across.norm() <= 0.0 {
                continue;
            }
            let r = 0.5 * (a + b) - centroid;
            let moment = r.cross(&across.normalize());
            a_r += length * moment * moment.transpose();
            b_r += length * inertia(&r);
        }
        let (mut a_m, mut b_m) = (a_s / b_s.trace(), b_s / b_s.trace());
        if b_r.trace() > 0.0 {
            a_m += a_r / b_r.trace();
            b_m += b_r / b_r.trace();
        }
        // λ of ω = B^{-1/2} u, u an eigenvector of B^{-1/2} A B^{-1/2}.
        let eb = na::SymmetricEigen::new(b_m);
        if eb.eigenvalues.min() <= 1e-12 * eb.eigenvalues.max() {
            return [None; 3];
        }
        let inv_sqrt = eb.eigenvectors
            * Mat3::from_diagonal(&eb.eigenvalues.map(|l| 1.0 / l.sqrt()))
            * eb.eigenvectors.transpose();
        let es = na::SymmetricEigen::new(inv_sqrt * a_m * inv_sqrt);
        std::array::from_fn(|i| {
            (es.eigenvalues[i] < SYMMETRY_STIFFNESS)
                .then(|| (inv_sqrt * es.eigenvectors.column(i)).normalize())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tube of radius 1 along z: `rings` circles of `around` vertices.
    fn tube(around: usize, rings: usize, height: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for j in 0..rings {
            for i in 0..around {
                let t = i as f64 / around as f64 * std::f64::consts::TAU;
                pos.push([t.cos(), t.sin(), height * j as f64 / (rings - 1) as f64]);
            }
        }
        let mut faces = Vec::new();
        for j in 0..rings - 1 {
            for i in 0..around {
                let (a, b) = (
                    (j * around + i) as u32,
                    (j * around + (i + 1) % around) as u32,
                );
                let (c, d) = (a + around as u32, b + around as u32);
                faces.push([a, b, d]);
                faces.push([a, d, c]);
            }
        }
        (pos, faces)
    }

    fn turn(axis: Vec3, angle: f64) -> Mat3 {
        na::Rotation3::new(axis.normalize() * angle).into_inner()
    }

    #[test]
    fn a_tube_is_free_about_its_axis_only() {
        let (pos, faces) = tube(48, 6, 1.5);
        let symmetry = RigidSymmetry::new(&pos, &faces).expect("a tube has a free axis");
        assert_eq!(symmetry.axes(), 1);
        let axes: Vec<Vec3> = symmetry
            .free_axes(&pos, &faces)
            .into_iter()
            .flatten()
            .collect();
        assert_eq!(axes.len(), 1);
        assert!(axes[0].z.abs() > 0.999, "{:?}", axes[0]);
        // A turn about the axis is dropped, a tilt kept, a mix loses its turn.
        let held = symmetry.hold(&turn(Vec3::z(), 0.1), &pos, &faces);
        assert!((held - Mat3::identity()).norm() < 1e-12);
        let tilt = turn(Vec3::x(), 0.1);
        assert!((symmetry.hold(&tilt, &pos, &faces) - tilt).norm() < 1e-12);
        let mixed = turn(Vec3::new(1.0, 0.0, 1.0), 0.1);
        let omega =
            na::Rotation3::from_matrix_unchecked(symmetry.hold(&mixed, &pos, &faces)).scaled_axis();
        assert!(omega.z.abs() < 1e-12 && (omega.x - 0.1 / 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn a_square_sheet_is_held_by_its_rim_and_a_bent_tube_has_no_free_axis() {
        let sheet = crate::synthetic::grid_sheet(12, 12, 1.0, 1.0);
        assert!(RigidSymmetry::new(&sheet.0, &sheet.1).is_none());
        // The same tube with its cross-section squashed to an ellipse: no turn leaves it.
        let (mut pos, faces) = tube(48, 6, 1.5);
        for p in &mut pos {
            p[1] *= 0.6;
        }
        assert!(RigidSymmetry::new(&pos, &faces).is_none());
    }
}
