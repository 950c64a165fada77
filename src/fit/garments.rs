//! Several garments in one template (the paper's Fig. 1: an upper and a lower garment fitted
//! onto one scan of a dressed person; docs/method.md "Several garments"). Each garment — a
//! connected component of the template holding at least [`GARMENT_MIN_SHARE`] of its
//! vertices, with the smaller components nearest to it (sleeves cut loose, buttons, pockets) —
//! is fitted on its own onto the whole scan, as one garment on a dressed-body scan, and the fits
//! are put back together. Fitted together, each garment's rim and the other garment's scan pull
//! on one another (a shirt's hem onto the skirt's waistband under it); fitted apart, the other
//! garment is scan that this garment does not explain, like the skin.

use super::attraction::explained_points;
use super::result::{component_figures, Diagnostics, FitResult, IterationRecord, Progress};
use super::{fit_from, FitParams, FitRole};
use crate::error::Result;
use crate::knn::PointIndex;
use crate::landmarks::Landmarks;

/// The smallest share of the template's vertices that a connected component needs to be a
/// garment of its own.
pub const GARMENT_MIN_SHARE: f64 = 0.25;

/// One garment of the template: its vertices (increasing), its faces in its own numbering, and
/// the index of each of those faces in the template.
struct Garment {
    vertices: Vec<u32>,
    faces: Vec<[u32; 3]>,
    face_index: Vec<usize>,
}

/// The garments of the template `(vertices, faces)`, or `None` when it has fewer than two
/// components of at least [`GARMENT_MIN_SHARE`] of its vertices. Every other component (and
/// every vertex in no face) goes with the garment that has the vertex nearest to it.
fn garments(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Option<Vec<Garment>> {
    let m = vertices.len();
    let (label, count) = crate::mesh::connected_components(faces, m);
    let mut size = vec![0usize; count];
    for &c in &label {
        size[c as usize] += 1;
    }
    let mut garment_of = vec![usize::MAX; count];
    let mut garments = 0;
    for c in 0..count {
        if size[c] as f64 >= GARMENT_MIN_SHARE * m as f64 {
            garment_of[c] = garments;
            garments += 1;
        }
    }
    if garments < 2 {
        return None;
    }
    // The small components: with the garment of the garment vertex nearest to any of theirs.
    let anchors: Vec<u32> = (0..m as u32)
        .filter(|&v| garment_of[label[v as usize] as usize] != usize::MAX)
        .collect();
    let anchor_points: Vec<[f64; 3]> = anchors.iter().map(|&v| vertices[v as usize]).collect();
    let index = PointIndex::new(&anchor_points);
    let mut nearest = vec![(f64::INFINITY, usize::MAX); count];
    for v in 0..m {
        let c = label[v] as usize;
        if garment_of[c] == usize::MAX {
            let (i, d2) = index.nearest_one(&vertices[v]);
            if d2 < nearest[c].0 {
                let anchor = anchors[i as usize] as usize;
                nearest[c] = (d2, garment_of[label[anchor] as usize]);
            }
        }
    }
    for c in 0..count {
        if garment_of[c] == usize::MAX {
            garment_of[c] = nearest[c].1;
        }
    }
    let mut out: Vec<Garment> = (0..garments)
        .map(|_| Garment {
            vertices: Vec::new(),
            faces: Vec::new(),
            face_index: Vec::new(),
        })
        .collect();
    let mut local = vec![0u32; m];
    for v in 0..m {
        let g = &mut out[garment_of[label[v] as usize]];
        local[v] = g.vertices.len() as u32;
        g.vertices.push(v as u32);
    }
    // A face's vertices share one component, so one garment.
    for (i, f) in faces.iter().enumerate() {
        let g = &mut out[garment_of[label[f[0] as usize] as usize]];
        g.faces.push(f.map(|v| local[v as usize]));
        g.face_index.push(i);
    }
    Some(out)
}

/// [`fit_from`] of a template that holds several garments: the template placed as a whole
/// (landmarks or pre-alignment), then each garment fitted on its own from there (its landmarks,
/// its rest shape) onto the whole scan, the results put back together in the template's
/// numbering; a template of one garment is fitted as it is. A garment with no scan near it
/// ([`PRESENT_SHARE`]) is not fitted, unless none has (then each fit refuses a template far
/// from its scan, [`FoldMatchError::FarAway`](crate::error::FoldMatchError::FarAway), or finds
/// it). The observer sees the garments' iterations as one count;
/// when it stops the fit, the garments not reached keep their placed positions. The verdict
/// and the per-component figures are those of the whole fit.
#[allow(clippy::too_many_arguments)]
pub(super) fn fit_garments(
    template_vertices: &[[f64; 3]],
    rest: Option<&[[f64; 3]]>,
    template_faces: &[[u32; 3]],
    target: &[[f64; 3]],
    target_faces: Option<&[[u32; 3]]>,
    target_weights: Option<&[f64]>,
    target_normals: Option<&[[f64; 3]]>,
    landmarks: Option<&Landmarks>,
    params: &FitParams,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<FitResult> {
    crate::mesh::validate_points("template_vertices", template_vertices)?;
    crate::mesh::validate_faces("template_faces", template_faces, template_vertices.len())?;
    let split = garments(template_vertices, template_faces);
    let Some(garments) = split else {
        return fit_from(
            template_vertices,
            rest,
            template_faces,
            target,
            target_faces,
            target_weights,
            target_normals,
            landmarks,
            FitRole::default(),
            params,
            observer,
        );
    };
    if let Some(r) = rest {
        crate::mesh::validate_points("rest", r)?;
        if r.len() != template_vertices.len() {
            return Err(crate::error::FoldMatchError::shape(
                "rest",
                format!(
                    "has {} vertices, the template {}",
                    r.len(),
                    template_vertices.len()
                ),
            ));
        }
    }
    crate::mesh::validate_points("target", target)?;
    if let Some(w) = target_weights {
        super::validate_weights(w, target.len())?;
    }
    // The scan points that remain (weight > 0), with their indices where some weigh 0.
    let kept: Option<Vec<usize>> = target_weights
        .filter(|w| w.contains(&0.0))
        .map(|w| (0..w.len()).filter(|&j| w[j] > 0.0).collect());
    let live = super::kept_points(target, kept.as_deref());
    let live: &[[f64; 3]] = &live;
    // Placed as a whole: the pre-alignment (or the landmarks' rigid fit) moves every garment
    // by one motion, and each garment's fit starts from there.
    let placed = placed_whole(
        template_vertices,
        target,
        kept.as_deref(),
        live,
        landmarks,
        params,
    )?;
    let mut each = params.clone();
    each.prealign = super::Prealign::None;
    let live_index = PointIndex::new(live);
    let pick = |g: &Garment, all: &[[f64; 3]]| -> Vec<[f64; 3]> {
        g.vertices.iter().map(|&v| all[v as usize]).collect()
    };
    let mut present: Vec<bool> = garments
        .iter()
        .map(|g| has_scan(&pick(g, &placed), &live_index))
        .collect();
    // None near the scan: the template is elsewhere, and each fit says so (or finds it).
    if !present.contains(&true) {
        present.fill(true);
    }
    let parts = garments.len();
    let mut fits: Vec<Option<FitResult>> = Vec::with_capacity(parts);
    for (i, g) in garments.iter().enumerate() {
        if !present[i] {
            fits.push(None);
            continue;
        }
        let vertices = pick(g, &placed);
        let rest = rest.map(|r| pick(g, r));
        let landmarks = landmarks.and_then(|l| garment_landmarks(l, &g.vertices));
        let mut observed = |p: &Progress| observer(&p.of_parts(i, parts, params.iterations));
        let fit = fit_from(
            &vertices,
            rest.as_deref(),
            &g.faces,
            target,
            target_faces,
            target_weights,
            target_normals,
            landmarks.as_ref(),
            FitRole {
                several: true,
                ..FitRole::default()
            },
            &each,
            &mut observed,
        )?;
        let stopped = fit.diagnostics.stopped_by_callback;
        fits.push(Some(fit));
        if stopped {
            break;
        }
    }
    assemble(
        &placed,
        rest.unwrap_or(&placed),
        template_faces,
        target,
        (live, kept.as_deref()),
        params,
        &garments,
        fits,
    )
}

/// The share of a garment's vertices that must lie within [`ABSENT_DISTANCE`] of the scan for
/// it to be fitted: a garment of several farther from the scan than that (one the person does
/// not wear, or the scanner did not see) keeps its place instead of being drawn onto another
/// garment's scan.
pub const PRESENT_SHARE: f64 = 0.25;

/// The distance, as a fraction of the garment's bounding-box diagonal, within which a vertex
/// counts as on the scan for [`PRESENT_SHARE`].
pub const ABSENT_DISTANCE: f64 = 0.1;

/// Whether at least [`PRESENT_SHARE`] of `vertices` lie within [`ABSENT_DISTANCE`] of their
/// diagonal from a scan point.
fn has_scan(vertices: &[[f64; 3]], scan: &PointIndex) -> bool {
    let radius = ABSENT_DISTANCE * crate::normalize::Frame::of_target(vertices).scale;
    let near = vertices
        .iter()
        .filter(|p| scan.nearest_one(p).1 <= radius * radius)
        .count();
    near as f64 >= PRESENT_SHARE * vertices.len() as f64
}

/// The template moved as a whole by the landmarks' rigid (or similarity) fit, else by the
/// pre-alignment ([`FitParams::prealign`]: the centroid onto the live scan's, or the global
/// search of [`crate::prealign`]); as given when there is none.
fn placed_whole(
    template_vertices: &[[f64; 3]],
    target: &[[f64; 3]],
    kept: Option<&[usize]>,
    live: &[[f64; 3]],
    landmarks: Option<&Landmarks>,
    params: &FitParams,
) -> Result<Vec<[f64; 3]>> {
    let scaled = params.prealign == super::Prealign::Similarity;
    if let Some(l) = landmarks {
        return Ok(
            super::landmark_placement(template_vertices, target, kept, l, params, scaled)
                .apply_all(template_vertices),
        );
    }
    if params.prealign == super::Prealign::Centroid {
        let mean = |p: &[[f64; 3]]| {
            p.iter()
                .fold(crate::math::Vec3::zeros(), |a, q| a + crate::math::vec3(q))
                / p.len().max(1) as f64
        };
        let offset = mean(live) - mean(template_vertices);
        return Ok(template_vertices
            .iter()
            .map(|p| (crate::math::vec3(p) + offset).into())
            .collect());
    }
    Ok(super::prealigned(template_vertices, target, kept, params)?
        .0
        .unwrap_or_else(|| template_vertices.to_vec()))
}

/// The landmarks on the garment's vertices (`vertices`, increasing), in its numbering.
fn garment_landmarks(landmarks: &Landmarks, vertices: &[u32]) -> Option<Landmarks> {
    let mut out = Landmarks {
        vertices: Vec::new(),
        positions: Vec::new(),
    };
    for (&v, p) in landmarks.vertices.iter().zip(&landmarks.positions) {
        if let Ok(local) = vertices.binary_search(&v) {
            out.vertices.push(local as u32);
            out.positions.push(*p);
        }
    }
    (!out.vertices.is_empty()).then_some(out)
}

/// The garments' fits (`fits`, in `garments` order, `None` for a garment without scan; fewer
/// when the observer stopped) as one fit of the whole template; the garments not fitted stay
/// where `placed` has them.
#[allow(clippy::too_many_arguments)]
fn assemble(
    placed: &[[f64; 3]],
    rest: &[[f64; 3]],
    faces: &[[u32; 3]],
    target: &[[f64; 3]],
    (live, kept): (&[[f64; 3]], Option<&[usize]>),
    params: &FitParams,
    garments: &[Garment],
    fits: Vec<Option<FitResult>>,
) -> Result<FitResult> {
    let m = placed.len();
    let mut vertices = placed.to_vec();
    let mut wvf = vec![[0.0; 3]; m];
    let mut wvf_accumulated = vec![[0.0; 3]; m];
    let fitted: Vec<(&Garment, &FitResult)> = garments
        .iter()
        .zip(&fits)
        .filter_map(|(g, f)| f.as_ref().map(|f| (g, f)))
        .collect();
    let mut diagnostics = Diagnostics {
        converged: true,
        kept_start: true,
        ..fitted
            .first()
            .map(|f| f.1.diagnostics.clone())
            .unwrap_or_default()
    };
    diagnostics.degenerate_faces.clear();
    diagnostics.duplicate_faces.clear();
    diagnostics.isolated_vertices = 0;
    diagnostics.garment_refit_points = 0;
    diagnostics.dressed = false;
    diagnostics.stage_seconds = Default::default();
    diagnostics.wall_seconds = [0.0; 3];
    diagnostics.knn_queries = 0;
    diagnostics.two_way_queries = 0;
    diagnostics.candidate_scan_distances.clear();
    diagnostics.candidate_edge_spreads.clear();
    let mut schedules = Vec::new();
    let mut refinements = Vec::new();
    let mut ring_sizes = 0.0;
    for &(g, fit) in &fitted {
        for (i, &v) in g.vertices.iter().enumerate() {
            vertices[v as usize] = fit.vertices[i];
            wvf[v as usize] = fit.wvf[i];
            wvf_accumulated[v as usize] = fit.wvf_accumulated[i];
        }
        let d = &fit.diagnostics;
        let global = |fs: &[usize]| fs.iter().map(|&f| g.face_index[f]).collect::<Vec<_>>();
        diagnostics
            .degenerate_faces
            .extend(global(&d.degenerate_faces));
        diagnostics
            .duplicate_faces
            .extend(global(&d.duplicate_faces));
        diagnostics.isolated_vertices += d.isolated_vertices;
        diagnostics.target_neighbours = diagnostics.target_neighbours.max(d.target_neighbours);
        diagnostics.coarse_rings = diagnostics.coarse_rings.max(d.coarse_rings);
        ring_sizes += d.mean_ring_size * g.vertices.len() as f64;
        diagnostics.converged &= d.converged;
        diagnostics.stopped_by_callback |= d.stopped_by_callback;
        diagnostics.kept_start &= d.kept_start;
        diagnostics.garment_refit_points += d.garment_refit_points;
        diagnostics.dressed |= d.dressed;
        diagnostics.stage_seconds.add(&d.stage_seconds);
        for (total, part) in diagnostics.wall_seconds.iter_mut().zip(d.wall_seconds) {
            *total += part;
        }
        diagnostics.knn_queries += d.knn_queries;
        diagnostics.two_way_queries += d.two_way_queries;
        schedules.push(d.schedule.clone());
        refinements.push(d.refinement.clone());
    }
    diagnostics.degenerate_faces.sort_unstable();
    diagnostics.duplicate_faces.sort_unstable();
    diagnostics.mean_ring_size = ring_sizes / m as f64;
    diagnostics.schedule = schedules.join(" + ");
    diagnostics.refinement = refinements.join(" + ");
    let iterations = fitted.iter().map(|f| f.1.iterations).max().unwrap_or(0);
    let history = merged_history(&fitted, iterations);
    let snapshots = merged_snapshots(&fitted, &vertices);
    // The verdict of the whole fit, against the scan points of positive weight that the
    // template explains where the scan holds more than the garments.
    let assessed: Option<Vec<usize>> = match explained_points(live, &vertices, faces, params, false)
    {
        Some(e) => Some(
            e.iter()
                .map(|&j| kept.map_or(j as usize, |k| k[j as usize]))
                .collect(),
        ),
        None => kept.map(<[usize]>::to_vec),
    };
    let assessment = crate::quality::assess_points(
        rest,
        faces,
        &vertices,
        target,
        assessed.as_deref(),
        &crate::quality::VerdictThresholds::default(),
    )?;
    diagnostics.components = component_figures(
        faces,
        &assessment.residuals,
        &assessment.support,
        assessment.quality.scan_diagonal,
    );
    // Each garment's fit indexes the whole scan: their points together.
    let mut garment_points: Vec<u32> = fitted
        .iter()
        .flat_map(|(_, f)| f.garment_points.iter().copied())
        .collect();
    garment_points.sort_unstable();
    garment_points.dedup();
    Ok(FitResult {
        vertices,
        wvf,
        wvf_accumulated,
        iterations,
        history,
        snapshots,
        params: params.clone(),
        diagnostics,
        quality: assessment.quality,
        correspondences: assessment.correspondences,
        residuals: assessment.residuals,
        support: assessment.support,
        garment_points,
    })
}

/// Per iteration, the garments' figures together: the vertex-weighted mean displacement of
/// the garments still iterating, the largest displacement, the degenerate gradients summed.
fn merged_history(fitted: &[(&Garment, &FitResult)], iterations: usize) -> Vec<IterationRecord> {
    (0..iterations)
        .map(|i| {
            let mut record = IterationRecord {
                iteration: i + 1,
                ..IterationRecord::default()
            };
            let mut weight = 0.0;
            for (g, fit) in fitted {
                if let Some(r) = fit.history.get(i) {
                    let w = g.vertices.len() as f64;
                    record.mean_displacement += w * r.mean_displacement;
                    weight += w;
                    record.max_displacement = record.max_displacement.max(r.max_displacement);
                    record.degenerate_gradients += r.degenerate_gradients;
                }
            }
            if weight > 0.0 {
                record.mean_displacement /= weight;
            }
            record
        })
        .collect()
}

/// Snapshots of the whole template at every iteration any garment took one: each garment at
/// its latest snapshot up to that iteration (its first before it has one), garments without
/// snapshots where `vertices` (the fit) has them.
fn merged_snapshots(
    fitted: &[(&Garment, &FitResult)],
    vertices: &[[f64; 3]],
) -> Vec<(usize, Vec<[f64; 3]>)> {
    let mut at: Vec<usize> = fitted
        .iter()
        .flat_map(|f| f.1.snapshots.iter().map(|s| s.0))
        .collect();
    at.sort_unstable();
    at.dedup();
    at.into_iter()
        .map(|it| {
            let mut vertices = vertices.to_vec();
            for (g, fit) in fitted {
                let snapshot = fit
                    .snapshots
                    .iter()
                    .rev()
                    .find(|s| s.0 <= it)
                    .or(fit.snapshots.first());
                if let Some((_, s)) = snapshot {
                    for (i, &v) in g.vertices.iter().enumerate() {
                        vertices[v as usize] = s[i];
                    }
                }
            }
            (it, vertices)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{fit, fit_scan, ScanExtras};
    use crate::synthetic::grid_sheet;

    /// Two `n × n` sheets of 1 × 1 side by side (x ∈ [−1.3, −0.3] and [0.3, 1.3]) as one
    /// template.
    fn two_sheets(n: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let (sheet, faces) = grid_sheet(n, n, 1.0, 1.0);
        let k = sheet.len() as u32;
        let mut v: Vec<[f64; 3]> = sheet.iter().map(|p| [p[0] - 0.8, p[1], 0.0]).collect();
        v.extend(sheet.iter().map(|p| [p[0] + 0.8, p[1], 0.0]));
        let mut f = faces.clone();
        f.extend(faces.iter().map(|t| t.map(|i| i + k)));
        (v, f)
    }

    /// The left sheet lifted by 0.05 and the right one lowered by 0.05, densely sampled, and a
    /// far "body" plane 1.5 below, 6 × 6 wide.
    fn dressed_scan() -> Vec<[f64; 3]> {
        let (dense, _) = grid_sheet(21, 21, 1.0, 1.0);
        let mut x: Vec<[f64; 3]> = dense.iter().map(|p| [p[0] - 0.8, p[1], 0.05]).collect();
        x.extend(dense.iter().map(|p| [p[0] + 0.8, p[1], -0.05]));
        let (body, _) = grid_sheet(25, 25, 6.0, 6.0);
        x.extend(body.iter().map(|p| [p[0], p[1], -1.5]));
        x
    }

    #[test]
    fn garments_are_the_large_components_with_the_small_ones_nearest_them() {
        let (mut v, mut f) = two_sheets(9);
        // A small triangle just right of the right sheet, and a vertex in no face by the left.
        let m = v.len() as u32;
        v.extend([
            [1.4, 0.0, 0.0],
            [1.5, 0.0, 0.0],
            [1.4, 0.1, 0.0],
            [-1.4, 0.0, 0.0],
        ]);
        f.push([m, m + 1, m + 2]);
        let g = garments(&v, &f).expect("two garments");
        assert_eq!(g.len(), 2);
        let left: Vec<u32> = (0..81).chain([m + 3]).collect();
        let right: Vec<u32> = (81..m + 3).collect();
        assert_eq!((&g[0].vertices, &g[1].vertices), (&left, &right));
        // Every face once, in its garment's numbering.
        assert_eq!(g[0].faces.len() + g[1].faces.len(), f.len());
        assert_eq!(g[1].faces.last(), Some(&[81, 82, 83]));
        assert_eq!(g[1].face_index.last(), Some(&(f.len() - 1)));
        // A body with two small sleeves (12.5 % each, as the generated shirts) is one garment.
        let (body, body_faces) = grid_sheet(8, 12, 1.0, 1.5);
        let (sleeve, sleeve_faces) = grid_sheet(4, 4, 0.3, 0.3);
        let mut v = body.clone();
        let mut f = body_faces;
        for dx in [-0.8, 0.8] {
            let k = v.len() as u32;
            v.extend(sleeve.iter().map(|p| [p[0] + dx, p[1], 0.0]));
            f.extend(sleeve_faces.iter().map(|t| t.map(|i| i + k)));
        }
        assert!(garments(&v, &f).is_none());
    }

    #[test]
    fn each_garment_is_fitted_onto_its_own_scan() {
        let (v, f) = two_sheets(9);
        let x = dressed_scan();
        let mut seen = Vec::new();
        let r = fit(&v, &f, &x, None, &FitParams::default(), &mut |p| {
            seen.push((p.iteration, p.iterations));
            true
        })
        .unwrap();
        for (range, z) in [(0..81, 0.05), (81..162, -0.05)] {
            for p in &r.vertices[range] {
                assert!((p[2] - z).abs() < 0.02, "{p:?} should be near z = {z}");
            }
        }
        assert_eq!(r.diagnostics.components.len(), 2);
        assert_eq!(r.history.len(), r.iterations);
        // The observer counts both garments' iterations as one fit's.
        assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
        let n = FitParams::default().iterations;
        assert_eq!(seen.last(), Some(&(n, n)));
        // Stopped during the first garment, the second stays where it started.
        let r = fit(&v, &f, &x, None, &FitParams::default(), &mut |p| {
            p.iteration < 10
        })
        .unwrap();
        assert!(r.diagnostics.stopped_by_callback);
        assert_eq!(&r.vertices[81..], &v[81..]);
    }

    #[test]
    fn a_template_of_garments_far_from_the_scan_is_refused_as_one_garment_is() {
        let (v, f) = two_sheets(9);
        let far: Vec<[f64; 3]> = v.iter().map(|p| [p[0] + 50.0, p[1], p[2]]).collect();
        let params = FitParams {
            prealign: super::super::Prealign::None,
            ..FitParams::default()
        };
        let err = fit(&far, &f, &dressed_scan(), None, &params, &mut |_| true);
        assert!(
            matches!(err, Err(crate::error::FoldMatchError::FarAway { .. })),
            "{err:?}"
        );
    }

    #[test]
    fn a_garments_landmarks_reach_it_in_its_own_numbering() {
        let (v, f) = two_sheets(9);
        let x = dressed_scan();
        // Vertex 81 + 40 is the right sheet's centre: pulled 0.1 along y off its scan position.
        let target = [0.8, 0.1, -0.05];
        let l = Landmarks::new(&[121], &[target], v.len()).unwrap();
        let params = FitParams::default();
        let extras = ScanExtras {
            landmarks: Some(&l),
            ..ScanExtras::default()
        };
        let r = fit_scan(&v, &f, &x, &extras, &params, &mut |_| true).unwrap();
        let gap = crate::math::dist2(&r.vertices[121], &target).sqrt();
        assert!(gap < 0.02, "landmark vertex {:?}", r.vertices[121]);
        let free = fit(&v, &f, &x, None, &params, &mut |_| true).unwrap();
        assert!(crate::math::dist2(&free.vertices[121], &target).sqrt() > 0.05);
    }
}
