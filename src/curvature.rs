//! Gaussian curvature κ_j of the target at every scan point (paper §2, the curvature term
//! α_kj of Eq. 2; docs/method.md "Curvature κ"). Precomputed once per fit, in the normalized frame.
//!
//! * Mesh targets: the angle deficit over the mixed Voronoi area (Meyer, Desbrun, Schröder and
//!   Barr, *Discrete differential-geometry operators for triangulated 2-manifolds*, 2003):
//!   `κ = (2π − Σ θ) / A_mixed`. Boundary vertices (an incident edge used by one face) and
//!   vertices with no face get κ = 0: their angle deficit measures the boundary, not the
//!   surface.
//! * Point clouds: a local quadric `z = a x² + b xy + c y² + d x + e y + f` fitted by least
//!   squares in the PCA frame of the point's k nearest neighbours; at the origin
//!   `κ = (4ac − b²) / (1 + d² + e²)²`. Neighbourhoods too small or too flat to fit get κ = 0.

use crate::knn::PointIndex;
use crate::math::{sym_eigen3, vec3, Mat3, SymEigen3, Vec3};
use nalgebra::{Matrix6, Vector6};
use rayon::prelude::*;
use std::collections::HashMap;
use std::f64::consts::PI;

/// Number of neighbours (the point included) used by the point-cloud quadric fit.
pub const POINT_CLOUD_NEIGHBOURS: usize = 16;

/// Gaussian curvature per vertex of a triangle mesh (angle deficit / mixed area).
pub fn gaussian_curvature_mesh(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<f64> {
    let n = vertices.len();
    let mut angle_sum = vec![0.0; n];
    let mut area = vec![0.0; n];
    let mut touched = vec![false; n];
    let mut edge_use: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 2);
    for f in faces {
        let p = [
            vec3(&vertices[f[0] as usize]),
            vec3(&vertices[f[1] as usize]),
            vec3(&vertices[f[2] as usize]),
        ];
        let tri_area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        if tri_area <= 0.0 {
            continue;
        }
        let mut angles = [0.0; 3];
        for i in 0..3 {
            let (a, b, c) = (p[i], p[(i + 1) % 3], p[(i + 2) % 3]);
            angles[i] = (b - a).angle(&(c - a));
        }
        let obtuse = angles.iter().position(|&t| t > PI / 2.0);
        for i in 0..3 {
            let v = f[i] as usize;
            touched[v] = true;
            angle_sum[v] += angles[i];
            area[v] += match obtuse {
                None => {
                    // Voronoi area: (|PR|² cot Q + |PQ|² cot R) / 8.
                    let (q, r) = ((i + 1) % 3, (i + 2) % 3);
                    let pr2 = (p[r] - p[i]).norm_squared();
                    let pq2 = (p[q] - p[i]).norm_squared();
                    (pr2 / angles[q].tan() + pq2 / angles[r].tan()) / 8.0
                }
                Some(o) if o == i => tri_area / 2.0,
                Some(_) => tri_area / 4.0,
            };
        }
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            *edge_use.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let mut boundary = vec![false; n];
    for (&(a, b), &uses) in &edge_use {
        if uses == 1 {
            boundary[a as usize] = true;
            boundary[b as usize] = true;
        }
    }
    (0..n)
        .map(|v| {
            if !touched[v] || boundary[v] || area[v] <= 0.0 {
                0.0
            } else {
                (2.0 * PI - angle_sum[v]) / area[v]
            }
        })
        .collect()
}

/// Gaussian curvature per point of a point cloud, by local quadric fits on the
/// [`POINT_CLOUD_NEIGHBOURS`] nearest neighbours.
pub fn gaussian_curvature_points(points: &[[f64; 3]], index: &PointIndex) -> Vec<f64> {
    let k = POINT_CLOUD_NEIGHBOURS.min(points.len());
    if k < 6 {
        return vec![0.0; points.len()];
    }
    points
        .par_iter()
        .map_init(
            || (vec![0u32; k], vec![0.0; k]),
            |(idx, d2), p| {
                index.nearest_into(p, idx, d2);
                quadric_curvature(points, p, idx)
            },
        )
        .collect()
}

/// The centroid of the points `neighbours` of `points` and the eigen-decomposition of their
/// scatter matrix (the PCA frame: `vectors.column(2)`, of the least eigenvalue, is the normal of
/// their best-fitting plane).
pub(crate) fn neighbourhood_frame(points: &[[f64; 3]], neighbours: &[u32]) -> (Vec3, SymEigen3) {
    let mut centroid = Vec3::zeros();
    for &j in neighbours {
        centroid += vec3(&points[j as usize]);
    }
    centroid /= neighbours.len() as f64;
    let mut cov = Mat3::zeros();
    for &j in neighbours {
        let d = vec3(&points[j as usize]) - centroid;
        cov += d * d.transpose();
    }
    (centroid, sym_eigen3(&cov))
}

/// Fits the quadric in the PCA frame of `neighbours` around `origin` and returns κ at origin.
fn quadric_curvature(points: &[[f64; 3]], origin: &[f64; 3], neighbours: &[u32]) -> f64 {
    let o = vec3(origin);
    let (_, frame) = neighbourhood_frame(points, neighbours);
    let (e1, e2, e3) = (
        frame.vectors.column(0),
        frame.vectors.column(1),
        frame.vectors.column(2),
    );
    let mut ata = Matrix6::<f64>::zeros();
    let mut atb = Vector6::<f64>::zeros();
    let mut scale2 = 0.0;
    for &j in neighbours {
        let d = vec3(&points[j as usize]) - o;
        scale2 += d.norm_squared();
    }
    let scale = (scale2 / neighbours.len() as f64).sqrt();
    if scale <= 0.0 {
        return 0.0;
    }
    // Fit in coordinates divided by `scale` for conditioning; rescale κ at the end.
    for &j in neighbours {
        let d = (vec3(&points[j as usize]) - o) / scale;
        let (x, y, z) = (d.dot(&e1), d.dot(&e2), d.dot(&e3));
        let row = Vector6::new(x * x, x * y, y * y, x, y, 1.0);
        ata += row * row.transpose();
        atb += row * z;
    }
    let Some(chol) = ata.cholesky() else {
        return 0.0;
    };
    let c = chol.solve(&atb);
    let (a, b, cc, d, e) = (c[0], c[1], c[2], c[3], c[4]);
    let kappa = (4.0 * a * cc - b * b) / (1.0 + d * d + e * e).powi(2);
    let kappa = kappa / (scale * scale);
    if kappa.is_finite() {
        kappa
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A latitude–longitude sphere mesh of radius r.
    fn uv_sphere(r: f64, n_lat: usize, n_lon: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut v = vec![[0.0, 0.0, r]];
        for i in 1..n_lat {
            let th = PI * i as f64 / n_lat as f64;
            for j in 0..n_lon {
                let ph = 2.0 * PI * j as f64 / n_lon as f64;
                v.push([
                    r * th.sin() * ph.cos(),
                    r * th.sin() * ph.sin(),
                    r * th.cos(),
                ]);
            }
        }
        v.push([0.0, 0.0, -r]);
        let south = (v.len() - 1) as u32;
        let ring = |i: usize, j: usize| (1 + (i - 1) * n_lon + j % n_lon) as u32;
        let mut f = Vec::new();
        for j in 0..n_lon {
            f.push([0, ring(1, j), ring(1, j + 1)]);
            f.push([south, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)]);
        }
        for i in 1..n_lat - 1 {
            for j in 0..n_lon {
                f.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
                f.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
            }
        }
        (v, f)
    }

    #[test]
    fn sphere_mesh_curvature_is_one_over_r_squared() {
        let r = 2.0;
        let (v, f) = uv_sphere(r, 40, 80);
        let k = gaussian_curvature_mesh(&v, &f);
        // Total curvature is exactly 4π (Gauss–Bonnet) for the angle deficits…
        let mut sorted = k.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        assert!(
            (median - 1.0 / (r * r)).abs() < 0.01 / (r * r),
            "median κ = {median}"
        );
    }

    #[test]
    fn flat_mesh_and_boundary_have_zero_curvature() {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
        ];
        let f = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]];
        let k = gaussian_curvature_mesh(&v, &f);
        assert!(k[0].abs() < 1e-12);
        assert_eq!(&k[1..], &[0.0; 4]);
    }

    #[test]
    fn sphere_point_cloud_curvature_is_one_over_r_squared() {
        // Fibonacci sphere.
        let (r, n) = (0.5, 4000);
        let golden = PI * (3.0 - 5f64.sqrt());
        let pts: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let rho = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                [r * rho * t.cos(), r * rho * t.sin(), r * z]
            })
            .collect();
        let index = PointIndex::new(&pts);
        let k = gaussian_curvature_points(&pts, &index);
        let mean = k.iter().sum::<f64>() / n as f64;
        assert!((mean - 4.0).abs() < 0.1, "mean κ = {mean}, want 1/r² = 4");
        let plane: Vec<[f64; 3]> = (0..400)
            .map(|i| [(i % 20) as f64 * 0.1, (i / 20) as f64 * 0.1, 0.0])
            .collect();
        let index = PointIndex::new(&plane);
        assert!(gaussian_curvature_points(&plane, &index)
            .iter()
            .all(|x| x.abs() < 1e-9));
    }
}
