//! Point-to-triangle distance for the scan→fit figure.

use crate::math::{vec3, Vec3};

/// The distance from `p` to the closest point of the triangle `tri` (its interior, an edge
/// or a corner), by the Voronoi-region walk of Ericson, *Real-Time Collision Detection*
/// (2004), §5.1.5. A degenerate triangle gives the distance to its nearest corner or edge.
pub fn point_triangle_distance(p: &[f64; 3], tri: &[[f64; 3]; 3]) -> f64 {
    let corners = tri.map(|c| vec3(&c));
    let w = closest_barycentric(&vec3(p), &corners);
    (vec3(p) - (w[0] * corners[0] + w[1] * corners[1] + w[2] * corners[2])).norm()
}

/// The barycentric coordinates of the point of the triangle `[a, b, c]` closest to `p` (its
/// interior, an edge or a corner), by the same walk; a degenerate triangle gives the closest
/// point of its nearest edge.
pub fn closest_barycentric(p: &Vec3, [a, b, c]: &[Vec3; 3]) -> [f64; 3] {
    let (a, b, c) = (*a, *b, *c);
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE {
        // Degenerate (collinear) triangle: the nearest of its three edges.
        return [(0, 1), (1, 2), (2, 0)]
            .into_iter()
            .map(|(i, j)| {
                let corners = [a, b, c];
                let t = along_segment(p, corners[i], corners[j]);
                let mut w = [0.0; 3];
                w[i] = 1.0 - t;
                w[j] = t;
                let q = (1.0 - t) * corners[i] + t * corners[j];
                ((p - q).norm_squared(), w)
            })
            .min_by(|x, y| x.0.total_cmp(&y.0))
            .map_or([1.0, 0.0, 0.0], |(_, w)| w);
    }
    let (v, w) = (vb / denom, vc / denom);
    [1.0 - v - w, v, w]
}

/// The parameter in [0, 1] of the point of the segment from `s` to `e` closest to `p`.
fn along_segment(p: &Vec3, s: Vec3, e: Vec3) -> f64 {
    let d = e - s;
    let len2 = d.norm_squared();
    if len2 == 0.0 {
        return 0.0;
    }
    ((p - s).dot(&d) / len2).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn above_the_interior_is_the_height() {
        assert!((point_triangle_distance(&[0.2, 0.2, 0.5], &TRI) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn beyond_a_corner_and_an_edge() {
        let corner = point_triangle_distance(&[-3.0, -4.0, 0.0], &TRI);
        assert!((corner - 5.0).abs() < 1e-12);
        // Beyond the hypotenuse: distance to the line x + y = 1.
        let edge = point_triangle_distance(&[1.0, 1.0, 0.0], &TRI);
        assert!((edge - 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn degenerate_triangle_is_its_segment() {
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!((point_triangle_distance(&[1.5, 2.0, 0.0], &line) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn the_closest_point_of_a_triangle() {
        let t = [
            Vec3::zeros(),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let at = |p: [f64; 3]| closest_barycentric(&Vec3::new(p[0], p[1], p[2]), &t);
        // Inside, above the face: its own barycentric coordinates.
        let w = at([0.25, 0.25, 0.7]);
        assert!((w[0] - 0.5).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12);
        // Beyond a corner, beyond an edge.
        assert_eq!(at([-1.0, -1.0, 0.0]), [1.0, 0.0, 0.0]);
        assert_eq!(at([2.0, -0.5, 0.0]), [0.0, 1.0, 0.0]);
        let e = at([0.5, -1.0, 0.3]);
        assert!((e[0] - 0.5).abs() < 1e-12 && (e[1] - 0.5).abs() < 1e-12 && e[2] == 0.0);
        let h = at([1.0, 1.0, 0.0]);
        assert!(h[0] == 0.0 && (h[1] - 0.5).abs() < 1e-12);
    }
}
