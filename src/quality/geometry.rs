//! Point-to-triangle distance for the scan→fit figure.

use crate::math::{vec3, Vec3};

/// The distance from `p` to the closest point of the triangle `tri` (its interior, an edge
/// or a corner), by the Voronoi-region walk of Ericson, *Real-Time Collision Detection*
/// (2004), §5.1.5. A degenerate triangle gives the distance to its nearest corner or edge.
pub fn point_triangle_distance(p: &[f64; 3], tri: &[[f64; 3]; 3]) -> f64 {
    (vec3(p) - closest_point(vec3(p), tri.map(|c| vec3(&c)))).norm()
}

fn closest_point(p: Vec3, [a, b, c]: [Vec3; 3]) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE {
        // Degenerate (collinear) triangle: the nearest of its three edges.
        return [(a, b), (b, c), (c, a)]
            .into_iter()
            .map(|(s, e)| closest_on_segment(p, s, e))
            .min_by(|x, y| (p - x).norm_squared().total_cmp(&(p - y).norm_squared()))
            .unwrap_or(a);
    }
    let (v, w) = (vb / denom, vc / denom);
    a + ab * v + ac * w
}

fn closest_on_segment(p: Vec3, s: Vec3, e: Vec3) -> Vec3 {
    let d = e - s;
    let len2 = d.norm_squared();
    if len2 == 0.0 {
        return s;
    }
    s + d * ((p - s).dot(&d) / len2).clamp(0.0, 1.0)
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
}
