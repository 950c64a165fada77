//! Whether two readings of a template are one shape: the template turned from one placement
//! to the other, registered onto itself by ICP (Besl & McKay 1992), lies on itself — an exact
//! symmetry (a flat square sheet turned 90°, a generated tube skirt turned about its axis) —
//! or not (a real T-shirt turned back to front differs at its neckline and drape). Readings of
//! one shape are the same fit with other correspondences, which no scan distance can tell
//! apart; readings of two shapes are fitted both and compared (docs/method.md "Global
//! pre-alignment").

use super::axes::{candidate_rotations, Axes};
use super::matching::spread_sample;
use super::transform::{fit_pairs, Similarity};
use crate::knn::PointIndex;
use crate::metrics::upper_median;
use rayon::prelude::*;

/// Template points the test registers (spread over the template).
const SAMPLE: usize = 2048;
/// ICP iterations of the self-registration.
const ITERATIONS: usize = 30;
/// A residual below this share of the template's point spacing is a symmetry: an exact
/// symmetry of a mesh maps vertices onto vertices (0); the real garments of the harness leave
/// 0.5–3.6 spacings (`bench/prealign.py`'s templates, turned 180° about each principal axis).
pub const SYMMETRIC: f64 = 0.25;

/// The relative motion from placement `a` to placement `b` of the same template, in the
/// template's own coordinates: `p ↦ a⁻¹(b(p))`.
pub fn relative(a: &Similarity, b: &Similarity) -> Similarity {
    let inv = a.inverse();
    Similarity {
        rotation: inv.rotation * b.rotation,
        scale: inv.scale * b.scale,
        translation: crate::math::vec3(&inv.apply(&b.translation.into())),
    }
}

/// Whether `template` moved by `motion` (rigid part only) and registered back onto itself by
/// ICP lies on itself within [`SYMMETRIC`] of its point spacing; `index` holds every template
/// point, `axes` are the template's principal axes (both as the search made them).
pub fn maps_onto_itself(
    template: &[[f64; 3]],
    index: &PointIndex,
    axes: &Axes,
    motion: &Similarity,
) -> bool {
    if template.len() < 3 {
        return true;
    }
    let sample = spread_sample(template, SAMPLE);
    // The mean distance of `points` from their nearest template point, and those points.
    let nearest = |points: &[[f64; 3]]| -> (f64, Vec<[f64; 3]>) {
        let found: Vec<(f64, [f64; 3])> = points
            .par_iter()
            .map(|p| {
                let (j, d2) = index.nearest_one(p);
                (d2.sqrt(), *index.point(j))
            })
            .collect();
        let mean = found.iter().map(|f| f.0).sum::<f64>() / found.len() as f64;
        (mean, found.into_iter().map(|f| f.1).collect())
    };
    let mut spacing: Vec<f64> = sample
        .par_iter()
        .map(|p| {
            let (mut idx, mut d2) = ([0u32; 2], [0.0; 2]);
            index.nearest_into(p, &mut idx, &mut d2);
            d2[1].sqrt()
        })
        .collect();
    let threshold = SYMMETRIC * upper_median(&mut spacing);
    // Started from the symmetry of the template's principal frame nearest to `motion` (the
    // readings come from those frames, refined on a deformed scan: a few degrees off a
    // symmetry, from which ICP on a regular grid stalls between vertices).
    let turn = Similarity {
        scale: 1.0,
        ..*motion
    };
    let mut current = candidate_rotations(axes, axes)
        .into_iter()
        .map(|rotation| Similarity {
            rotation,
            scale: 1.0,
            translation: axes.centroid - rotation * axes.centroid,
        })
        .min_by(|a, b| a.turned_from(&turn).total_cmp(&b.turned_from(&turn)))
        .unwrap_or(turn);
    for _ in 0..ITERATIONS {
        let (residual, targets) = nearest(&current.apply_all(&sample));
        if residual < threshold {
            return true;
        }
        let pairs: Vec<([f64; 3], [f64; 3])> = sample.iter().copied().zip(targets).collect();
        match fit_pairs(&pairs, false) {
            Some(next) => current = next,
            None => break,
        }
    }
    nearest(&current.apply_all(&sample)).0 < threshold
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{vec3, Mat3, Vec3};
    use nalgebra::{Rotation3, Unit};

    fn turn(axis: [f64; 3], degrees: f64, about: Vec3) -> Similarity {
        let rotation: Mat3 =
            *Rotation3::from_axis_angle(&Unit::new_normalize(vec3(&axis)), degrees.to_radians())
                .matrix();
        Similarity {
            rotation,
            scale: 1.0,
            translation: about - rotation * about,
        }
    }

    /// A flat square grid (x, y in [0, 1]) and the same grid with a bump off-centre and one
    /// corner lifted: no rotation maps the second onto itself.
    fn grids() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let n = 31;
        let flat: Vec<[f64; 3]> = (0..n * n)
            .map(|i| [(i % n) as f64 / 30.0, (i / n) as f64 / 30.0, 0.0])
            .collect();
        let bumped = flat
            .iter()
            .map(|&[x, y, _]| {
                let bump = 0.2 * (-((x - 0.7f64).powi(2) + (y - 0.3f64).powi(2)) / 0.02).exp();
                [x, y, bump + 0.3 * (x * y).powi(3)]
            })
            .collect();
        (flat, bumped)
    }

    fn maps(template: &[[f64; 3]], motion: &Similarity) -> bool {
        let axes = super::super::axes::principal_axes(template);
        maps_onto_itself(template, &PointIndex::new(template), &axes, motion)
    }

    #[test]
    fn a_square_sheet_turned_near_a_symmetry_maps_onto_itself_a_bumped_one_does_not() {
        let (flat, bumped) = grids();
        let centre = Vec3::new(0.5, 0.5, 0.0);
        // Readings refined on a scan come a few degrees off the symmetry.
        for (axis, degrees) in [
            ([0.0, 0.0, 1.0], 176.0),
            ([0.0, 0.0, 1.0], 93.0),
            ([1.0, 0.0, 0.0], 184.0),
        ] {
            assert!(
                maps(&flat, &turn(axis, degrees, centre)),
                "{axis:?} {degrees}"
            );
            assert!(
                !maps(&bumped, &turn(axis, degrees, centre)),
                "{axis:?} {degrees}"
            );
        }
        // The identity is a symmetry of everything.
        assert!(maps(&bumped, &Similarity::identity()));
    }

    #[test]
    fn relative_takes_one_placement_to_the_other() {
        let a = turn([1.0, 2.0, 0.5], 40.0, Vec3::new(0.3, -0.2, 1.0));
        let b = turn([0.0, 1.0, -1.0], 110.0, Vec3::new(-1.0, 0.5, 0.2));
        let r = relative(&a, &b);
        let p = [0.4, -0.7, 1.3];
        // a(r(p)) = b(p)
        let lhs = vec3(&a.apply(&r.apply(&p)));
        let rhs = vec3(&b.apply(&p));
        assert!((lhs - rhs).norm() < 1e-12, "{lhs} {rhs}");
    }
}
