//! The similarity's scale corrected by a fit (docs/method.md "Global pre-alignment"). The
//! least-squares similarity matches the template to the scan's *shape*; a garment that folds,
//! drapes or bunches occupies less room than its pattern, so that scale comes out small (a
//! folded sheet: 0.88 of the truth's). Cloth hardly stretches: the median ratio of a fit's
//! edge lengths to the placed template's says how much the fit had to stretch it, and the
//! template placed at that much more scale fits as cloth.

use crate::math::{vec3, Vec3};
use crate::metrics::{upper_median, EdgeLengths};

/// A fit's median edge stretch within this of 1 leaves the similarity's scale as it is.
pub const SCALE_SETTLED: f64 = 0.03;

/// Nor does one farther than this from 1: the similarity of a garment's shape is not that far
/// off its size (0.83–0.92 of it on the harness's folded and flattened garments); a fit that
/// stretched its template more was drawn by a drape's folds, which no scale reaches (a sheet
/// over a sphere: 1.45 from the size of its shape).
pub const SCALE_TRUSTED: f64 = 0.25;

/// The median, over the edges of `faces`, of the ratio of an edge's length in `fitted` to its
/// length in `placed` (1 when no edge has a length).
pub fn fitted_stretch(placed: &[[f64; 3]], fitted: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    let mut ratios = EdgeLengths::new(placed, faces).ratios(fitted);
    if ratios.is_empty() {
        return 1.0;
    }
    upper_median(&mut ratios)
}

/// `points` scaled by `factor` about their centroid.
pub fn scaled_about_centroid(points: &[[f64; 3]], factor: f64) -> Vec<[f64; 3]> {
    let centroid =
        points.iter().fold(Vec3::zeros(), |a, p| a + vec3(p)) / points.len().max(1) as f64;
    points
        .iter()
        .map(|p| (centroid + (vec3(p) - centroid) * factor).into())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::grid_sheet;

    #[test]
    fn the_stretch_of_a_uniformly_scaled_fit_is_its_scale() {
        let (v, f) = grid_sheet(7, 5, 2.0, 1.0);
        let bigger = scaled_about_centroid(&v, 1.1);
        assert!((fitted_stretch(&v, &bigger, &f) - 1.1).abs() < 1e-12);
        // The centroid stays.
        let c = |p: &[[f64; 3]]| p.iter().fold(Vec3::zeros(), |a, q| a + vec3(q)) / p.len() as f64;
        assert!((c(&bigger) - c(&v)).norm() < 1e-12);
        // A few stretched edges do not move the median; no edges: 1.
        let mut pulled = v.clone();
        pulled[0][2] += 5.0;
        assert!((fitted_stretch(&v, &pulled, &f) - 1.0).abs() < 1e-12);
        assert_eq!(fitted_stretch(&v, &bigger, &[]), 1.0);
    }
}
