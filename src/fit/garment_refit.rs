//! The garment refit on a scan that holds more than the garment (docs/method.md "Scans of
//! dressed people"): the fit's own segmentation of the scan. A dressed-body scan's skin and
//! hair continue the garment's surface past its hems, cuffs and collar, where a garment-only scan
//! ends; the first fit, which has to ignore them by its trust radius and rim rules, leaves the
//! garment's rim without the scan edge that places it. The points that this first fit explains —
//! within one trust unit of a fitted vertex, and not outward of the fit's rim (Turk & Levoy's
//! boundary rule, 1994) — are taken as the garment, and the template is fitted again from its
//! start onto those points alone, as onto a garment-only scan.

use super::attraction::trust_unit;
use crate::knn::PointIndex;
use crate::math::{vec3, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// The scan points of positive weight and which of them a fit explains ([`explain`]).
pub(super) struct Explanation {
    /// The indices of the scan points of positive weight (the given weight; all without one).
    pub(super) live: Vec<usize>,
    /// Those points.
    pub(super) scan: Vec<[f64; 3]>,
    /// Per live point: its nearest fitted vertex and the squared distance to it.
    pub(super) nearest: Vec<(u32, f64)>,
    /// Per live point: whether the fit explains it.
    pub(super) explained: Vec<bool>,
}

impl Explanation {
    /// Per scan point: its given weight (1 when none) where `keep(p)` holds for its index `p`
    /// among the live points, 0 elsewhere.
    pub(super) fn weights(
        &self,
        n: usize,
        weights: Option<&[f64]>,
        keep: impl Fn(usize) -> bool,
    ) -> Vec<f64> {
        let mut out = vec![0.0; n];
        for (p, &j) in self.live.iter().enumerate() {
            if keep(p) {
                out[j] = weights.map_or(1.0, |w| w[j]);
            }
        }
        out
    }
}

/// The points that `fitted` explains. A point is explained when its nearest fitted vertex is
/// within `radius_multiple ×` the larger of the median vertex-to-scan distance and the mean
/// edge length ([`garment_refit`](crate::fit::Schedule::garment_refit)), and, when that vertex
/// lies on the template's boundary, the point is not outward of it (on the far side of the plane
/// through the vertex normal to its outward direction in the surface). Points of weight 0 are
/// left out.
pub(super) fn explain(
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    fitted: &[[f64; 3]],
    faces: &[[u32; 3]],
    radius_multiple: f64,
) -> Explanation {
    let live: Vec<usize> = (0..target.len())
        .filter(|&j| weights.map_or(1.0, |w| w[j]) > 0.0)
        .collect();
    let scan: Vec<[f64; 3]> = live.iter().map(|&j| target[j]).collect();
    let radius = radius_multiple * trust_unit(fitted, faces, &scan);
    let outward = rim_outward(fitted, faces);
    let fitted_index = PointIndex::new(fitted);
    let nearest: Vec<(u32, f64)> = scan
        .par_iter()
        .map(|p| fitted_index.nearest_one(p))
        .collect();
    let explained = scan
        .iter()
        .zip(&nearest)
        .map(|(p, &(v, d2))| {
            let v = v as usize;
            d2 <= radius * radius && (vec3(p) - vec3(&fitted[v])).dot(&vec3(&outward[v])) <= 0.0
        })
        .collect();
    Explanation {
        live,
        scan,
        nearest,
        explained,
    }
}

/// The refit's weights of the scan points: the given weight (1 when none) on the points that
/// `fitted` explains ([`explain`]), 0 elsewhere.
pub(super) fn garment_weights(
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    fitted: &[[f64; 3]],
    faces: &[[u32; 3]],
    radius_multiple: f64,
) -> Vec<f64> {
    let e = explain(target, weights, fitted, faces, radius_multiple);
    e.weights(target.len(), weights, |p| e.explained[p])
}

/// How many scan points weigh more than 0.
pub(super) fn garment_points(weights: &[f64]) -> usize {
    weights.iter().filter(|&&w| w > 0.0).count()
}

/// Every vertex's distance in edges (rings) from the boundary of the mesh: 0 on it;
/// `u32::MAX` in a component without boundary.
pub(super) fn rim_rings(faces: &[[u32; 3]], n_vertices: usize) -> Vec<u32> {
    let ring = crate::rings::adjacency(faces, n_vertices);
    let mut rings = vec![u32::MAX; n_vertices];
    let mut queue: std::collections::VecDeque<u32> =
        crate::mesh::boundary_vertices(faces, n_vertices).into();
    for &v in &queue {
        rings[v as usize] = 0;
    }
    while let Some(v) = queue.pop_front() {
        for &u in ring.of(v as usize) {
            if rings[u as usize] == u32::MAX {
                rings[u as usize] = rings[v as usize] + 1;
                queue.push_back(u);
            }
        }
    }
    rings
}

/// Every vertex's outward direction on the boundary of the mesh `(vertices, faces)`: in the
/// surface, normal to the boundary — the unit vector from the centroid of the vertex's
/// one-ring to the vertex, less its component along the boundary (the direction between its
/// two boundary neighbours); zero off the boundary.
pub(super) fn rim_outward(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let m = vertices.len();
    // Every edge, with its face count and its direction in its first face.
    let mut edges: HashMap<(u32, u32), (u32, (u32, u32))> = HashMap::new();
    for f in faces {
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            edges.entry((a.min(b), a.max(b))).or_insert((0, (a, b))).0 += 1;
        }
    }
    let mut ring_sum = vec![Vec3::zeros(); m];
    let mut ring_count = vec![0usize; m];
    let mut keys: Vec<(u32, u32)> = edges.keys().copied().collect();
    keys.sort_unstable();
    for (a, b) in keys {
        ring_sum[a as usize] += vec3(&vertices[b as usize]);
        ring_sum[b as usize] += vec3(&vertices[a as usize]);
        ring_count[a as usize] += 1;
        ring_count[b as usize] += 1;
    }
    // Along the boundary: the boundary edges in their faces' direction, which runs around each
    // boundary loop one way on a consistently oriented mesh (at a vertex: next − previous).
    let mut along = vec![Vec3::zeros(); m];
    let mut on_rim = vec![false; m];
    let mut rim: Vec<(u32, u32)> = edges
        .values()
        .filter(|(n, _)| *n == 1)
        .map(|&(_, e)| e)
        .collect();
    rim.sort_unstable();
    for (a, b) in rim {
        let d = vec3(&vertices[b as usize]) - vec3(&vertices[a as usize]);
        along[a as usize] += d;
        along[b as usize] += d;
        on_rim[a as usize] = true;
        on_rim[b as usize] = true;
    }
    (0..m)
        .map(|v| {
            if !on_rim[v] || ring_count[v] == 0 {
                return [0.0; 3];
            }
            let mut d = vec3(&vertices[v]) - ring_sum[v] / ring_count[v] as f64;
            let t = along[v].try_normalize(0.0);
            if let Some(t) = t {
                d -= d.dot(&t) * t;
            }
            d.try_normalize(0.0).map_or([0.0; 3], Into::into)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{fit_anchored, fit_scan, fit_simple, FitParams, ScanExtras};
    use crate::synthetic::grid_sheet;

    /// A 1 × 1 sheet in z = 0 (9 × 9 vertices, edge 0.125).
    fn sheet() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        grid_sheet(9, 9, 1.0, 1.0)
    }

    #[test]
    fn the_garment_is_what_the_fit_explains_and_not_past_its_rim() {
        let (fitted, faces) = sheet();
        let mut scan = Vec::new();
        let mut expected = Vec::new();
        // On the sheet: a 20 × 20 grid strictly inside it, 0.01 above it.
        for i in 0..20 {
            for j in 0..20 {
                let (x, y) = (-0.475 + 0.05 * i as f64, -0.475 + 0.05 * j as f64);
                scan.push([x, y, 0.01]);
                expected.push(true);
            }
        }
        // Its continuation past the edge x = 0.5 (skin past a hem), within the radius.
        for j in 0..10 {
            scan.push([0.56, -0.45 + 0.1 * j as f64, 0.0]);
            expected.push(false);
        }
        // Far away (another part of the body).
        for j in 0..10 {
            scan.push([0.1 * j as f64, 0.0, -1.5]);
            expected.push(false);
        }
        let mut weights = vec![1.0; scan.len()];
        weights[3] = 0.5; // kept, with its weight
        weights[5] = 0.0; // removed by the user: stays removed
        let w = garment_weights(&scan, Some(&weights), &fitted, &faces, 1.0);
        for (j, (&wj, &garment)) in w.iter().zip(&expected).enumerate() {
            let want = if garment { weights[j] } else { 0.0 };
            assert_eq!(wj, want, "point {j} at {:?}", scan[j]);
        }
        // Without weights every explained point weighs 1; a larger radius takes no point past the
        // rim either.
        let w = garment_weights(&scan, None, &fitted, &faces, 3.0);
        assert_eq!(w.iter().filter(|&&x| x > 0.0).count(), 400);
    }

    /// A template (vertices, faces) and a scan.
    type Case = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 3]>);

    /// A sheet template and a scan of it bent up along x (the garment) continued past its edge
    /// x = 0.5 by a flat strip (skin past a hem) and a far plane (the rest of a body).
    fn dressed_sheet() -> Case {
        let (template, faces) = sheet();
        let bend = |x: f64| 0.15 * (std::f64::consts::PI * x).cos();
        let mut scan = Vec::new();
        for i in 0..41 {
            for j in 0..41 {
                let (x, y) = (-0.5 + 0.025 * i as f64, -0.5 + 0.025 * j as f64);
                scan.push([x, y, bend(x)]);
            }
        }
        for i in 1..13 {
            for j in 0..41 {
                scan.push([0.5 + 0.025 * i as f64, -0.5 + 0.025 * j as f64, bend(0.5)]);
            }
        }
        let (body, _) = grid_sheet(25, 25, 3.0, 3.0);
        scan.extend(body.iter().map(|p| [p[0], p[1], -1.5]));
        (template, faces, scan)
    }

    /// The fits of [`dressed_sheet`]: 40 iterations, the sheet as placed (the search would
    /// turn it onto the bend).
    fn sheet_params() -> FitParams {
        FitParams {
            iterations: 40,
            prealign: crate::fit::Prealign::None,
            ..FitParams::default()
        }
    }

    /// The driver's first fit (the refit off, and the strain limit, docs/method.md "Strain
    /// limiting"; the isometric refinement as given) and its second fit (the refit and the
    /// do-no-harm comparison off: the first fit made it).
    fn first_and_second(params: &FitParams) -> (FitParams, FitParams) {
        let mut second = params.clone();
        second.schedule.garment_refit = 0.0;
        second.schedule.keep_margin = 0.0;
        let mut first = params.clone();
        first.schedule.garment_refit = 0.0;
        first.schedule.strain_limit = 0.0;
        (first, second)
    }

    #[test]
    fn the_first_fit_of_a_dressed_scan_ends_with_the_refinement() {
        let (template, faces, scan) = dressed_sheet();
        let mut params = sheet_params();
        params.schedule.garment_cut = 0.0;
        assert!(params.schedule.isometric_iterations > 0);
        let (once, _) = first_and_second(&params);
        let refit = fit_simple(&template, &faces, &scan, None, &params).unwrap();
        let explained = |first: &FitParams| {
            let fitted = fit_simple(&template, &faces, &scan, None, first).unwrap();
            garment_points(&garment_weights(&scan, None, &fitted.vertices, &faces, 1.0))
        };
        // The refit's points are those the refined first fit explains, not the unrefined one's.
        assert_eq!(refit.diagnostics.garment_refit_points, explained(&once));
        let mut unrefined = once.clone();
        unrefined.schedule.isometric_iterations = 0;
        assert_ne!(
            refit.diagnostics.garment_refit_points,
            explained(&unrefined)
        );
    }

    #[test]
    fn a_dressed_scan_is_fitted_again_onto_the_points_the_first_fit_explains() {
        let (template, faces, scan) = dressed_sheet();
        let mut params = sheet_params();
        // The refit alone (the garment cut's third fit: garment_cut.rs).
        params.schedule.garment_cut = 0.0;
        // The passes without the refinement, whose garment passes differ from a plain fit
        // onto the same weights (no pull beyond the rim: isometric/tests.rs).
        params.schedule.isometric_iterations = 0;
        let (once, second) = first_and_second(&params);
        let refit = fit_simple(&template, &faces, &scan, None, &params).unwrap();
        let first = fit_simple(&template, &faces, &scan, None, &once).unwrap();
        assert_eq!(first.diagnostics.garment_refit_points, 0);
        // The second fit is the fit of the first's explained points, from the same start.
        let weights = garment_weights(&scan, None, &first.vertices, &faces, 1.0);
        let garment = weights.iter().filter(|&&w| w > 0.0).count();
        assert_eq!(refit.diagnostics.garment_refit_points, garment);
        // The result names those points (indices into the scan as given).
        let taken: Vec<u32> = (0..scan.len() as u32)
            .filter(|&j| weights[j as usize] > 0.0)
            .collect();
        assert_eq!(refit.garment_points, taken);
        assert!(first.garment_points.is_empty());
        assert!(
            garment < 41 * 41 + 41 * 6,
            "{garment}: the strip past the edge is left out"
        );
        assert!(
            weights[41 * 41 + 41 * 12..].iter().all(|&w| w == 0.0),
            "the far plane"
        );
        let again = fit_scan(
            &template,
            &faces,
            &scan,
            &ScanExtras {
                weights: Some(&weights),
                ..ScanExtras::default()
            },
            &second,
            &mut |_| true,
        )
        .unwrap();
        assert_eq!(refit.vertices, again.vertices);
        // The observer saw one run of the iterations, each pass counting half.
        let mut seen = Vec::new();
        let observed = crate::fit::fit(&template, &faces, &scan, None, &params, &mut |p| {
            seen.push((p.iteration, p.iterations));
            true
        })
        .unwrap();
        assert_eq!(observed.vertices, refit.vertices);
        assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
        assert_eq!(seen.last(), Some(&(40, 40)));
    }

    #[test]
    fn an_anchored_fit_is_refitted_with_its_rest_shape() {
        // A warm start of another shape than the rest (bent the other way from the scan),
        // anchored to the template: the refit keeps the template as the rest shape, as the
        // first fit had it.
        let (template, faces, scan) = dressed_sheet();
        let mut params = FitParams {
            iterations: 30,
            ..sheet_params()
        };
        params.schedule.garment_cut = 0.0;
        // Without the refinement (see above).
        params.schedule.isometric_iterations = 0;
        let start: Vec<[f64; 3]> = template
            .iter()
            .map(|p| [p[0], p[1], -0.1 * (std::f64::consts::PI * p[0]).cos()])
            .collect();
        let anchored = |weights: Option<&[f64]>, params: &FitParams| {
            fit_anchored(
                &start,
                &template,
                &faces,
                &scan,
                None,
                weights,
                params,
                &mut |_| true,
            )
            .unwrap()
        };
        let (once, second) = first_and_second(&params);
        let first = anchored(None, &once);
        let refit = anchored(None, &params);
        let weights = garment_weights(&scan, None, &first.vertices, &faces, 1.0);
        assert_eq!(
            refit.diagnostics.garment_refit_points,
            weights.iter().filter(|&&w| w > 0.0).count()
        );
        assert_eq!(refit.vertices, anchored(Some(&weights), &second).vertices);
    }

    #[test]
    fn the_garment_cut_fits_a_third_time_onto_the_cut_of_the_refit() {
        let (template, faces, scan) = dressed_sheet();
        let mut params = sheet_params();
        // Without the refinement (see above).
        params.schedule.isometric_iterations = 0;
        let mut refit_only = params.clone();
        refit_only.schedule.garment_cut = 0.0;
        let refit = fit_simple(&template, &faces, &scan, None, &refit_only).unwrap();
        let full = fit_simple(&template, &faces, &scan, None, &params).unwrap();
        let cut = crate::fit::garment_cut::garment_cut_weights(
            &scan,
            None,
            &refit.vertices,
            &faces,
            1.0,
            params.schedule.garment_cut,
        );
        assert_eq!(full.diagnostics.garment_refit_points, garment_points(&cut));
        assert!(full
            .garment_points
            .iter()
            .all(|&j| cut[j as usize] > 0.0 && j < 41 * 41 + 41 * 12));
        assert!(
            cut[41 * 41 + 41 * 12..].iter().all(|&w| w == 0.0),
            "the far plane is the body's"
        );
        let (_, second) = first_and_second(&params);
        let third = fit_scan(
            &template,
            &faces,
            &scan,
            &ScanExtras {
                weights: Some(&cut),
                ..ScanExtras::default()
            },
            &second,
            &mut |_| true,
        )
        .unwrap();
        // The cut again from the third fit: fitted a fourth time only if more than 1 % of the
        // points changed side.
        let again = crate::fit::garment_cut::garment_cut_weights(
            &scan,
            None,
            &third.vertices,
            &faces,
            1.0,
            params.schedule.garment_cut,
        );
        if crate::fit::garment_cut::settled(&cut, &again) {
            assert_eq!(full.vertices, third.vertices);
        } else {
            let fourth = fit_scan(
                &template,
                &faces,
                &scan,
                &ScanExtras {
                    weights: Some(&again),
                    ..ScanExtras::default()
                },
                &second,
                &mut |_| true,
            )
            .unwrap();
            assert_eq!(full.vertices, fourth.vertices);
        }
        // The observer saw one run of the iterations over the three passes.
        let mut seen = Vec::new();
        crate::fit::fit(&template, &faces, &scan, None, &params, &mut |p| {
            seen.push(p.iteration);
            true
        })
        .unwrap();
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
        assert_eq!(seen.last(), Some(&40));
    }
}
