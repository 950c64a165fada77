//! The isometric refinement on sheets whose answer is known: a cylinder patch slid along
//! itself, a flat sheet stretched in its plane, a fit already at its scan, a tight fold.

use super::*;
use crate::fit::{DEFAULT_ISOMETRIC_WEIGHT as WEIGHT, TRACKING_ISOMETRIC_ITERATIONS as ITERATIONS};
use crate::metrics::bbox_diagonal;
use crate::synthetic::{grid_sheet, sample_surface, SplitMix64};
use nalgebra::Rotation3;

/// A grid bent onto a cylinder of radius 1 about the y axis (a 120° arc): sliding it about the
/// axis keeps it on its own surface, which only its rim and its metric can tell.
fn cylinder_patch() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (flat, faces) = grid_sheet(25, 13, 2.0 * std::f64::consts::PI / 3.0, 1.0);
    let bent = flat
        .iter()
        .map(|p| [p[0].sin(), p[1], p[0].cos()])
        .collect();
    (bent, faces)
}

/// `points` turned by `degrees` about the y axis.
fn turned(points: &[[f64; 3]], degrees: f64) -> Vec<[f64; 3]> {
    let (s, c) = degrees.to_radians().sin_cos();
    points
        .iter()
        .map(|p| [c * p[0] + s * p[2], p[1], -s * p[0] + c * p[2]])
        .collect()
}

fn rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(x, y)| dist2(x, y)).sum();
    (sum / a.len() as f64).sqrt()
}

/// The largest `|ℓ / ℓ⁰ − 1|` over the mesh's edges.
fn worst_strain(v: &[[f64; 3]], rest: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    faces
        .iter()
        .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
        .map(|(a, b)| {
            let (a, b) = (a as usize, b as usize);
            let l = (vec3(&v[a]) - vec3(&v[b])).norm();
            let l0 = (vec3(&rest[a]) - vec3(&rest[b])).norm();
            (l / l0 - 1.0).abs()
        })
        .fold(0.0, f64::max)
}

/// [`IsometricRefine`] of `fit` onto `scan`, `steps` steps at the default weight, the fit → scan
/// plane's normal `plane`.
fn refine(
    plane: PlaneNormal,
    rest: &[[f64; 3]],
    faces: &[[u32; 3]],
    scan: &[[f64; 3]],
    weights: Option<&[f64]>,
    fit: &mut [[f64; 3]],
    steps: usize,
) {
    let incidence = VertexFaces::new(faces, rest.len());
    IsometricRefine::new(rest, faces, &incidence, scan, weights)
        .with_plane_normal(plane)
        .run(fit, steps, springs(WEIGHT, SpringScale::Rest));
}

/// Springs of `weight` at `scale`, no hold.
fn springs(weight: f64, scale: SpringScale) -> Springs {
    Springs {
        weight,
        hold: 0.0,
        scale,
        hold_where: HoldWhere::Everywhere,
    }
}

fn scan_of(v: &[[f64; 3]], faces: &[[u32; 3]], count: usize) -> Vec<[f64; 3]> {
    sample_surface(v, faces, count, &mut SplitMix64::new(7))
}

#[test]
fn a_patch_slid_along_its_own_surface_is_brought_back() {
    // With either plane normal: the fit's own normals (tracking) still bring it back.
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 4000);
    for plane in [PlaneNormal::Scan, PlaneNormal::Fit] {
        let mut fit = turned(&truth, 8.0);
        let before = rms(&fit, &truth);
        refine(plane, &truth, &faces, &scan, None, &mut fit, ITERATIONS);
        let after = rms(&fit, &truth);
        assert!(
            after < 0.2 * before,
            "{plane:?}: slid {before:.4}, refined {after:.4} from the truth"
        );
    }
}

#[test]
fn a_stretched_sheet_gets_its_rest_lengths_back() {
    let (rest, faces) = grid_sheet(21, 21, 1.0, 1.0);
    let scan = scan_of(&rest, &faces, 3000);
    // Stretched by 15 % along x about its middle: still on the scan's plane.
    let mut fit: Vec<[f64; 3]> = rest.iter().map(|p| [1.15 * p[0], p[1], p[2]]).collect();
    let strained = worst_strain(&fit, &rest, &faces);
    refine(
        PlaneNormal::Scan,
        &rest,
        &faces,
        &scan,
        None,
        &mut fit,
        ITERATIONS,
    );
    let strain = worst_strain(&fit, &rest, &faces);
    assert!(
        strained > 0.14 && strain < 0.03,
        "strain {strained:.3} -> {strain:.3}"
    );
    assert!(
        rms(&fit, &rest) < 0.01,
        "{:.4} from the rest shape",
        rms(&fit, &rest)
    );
}

#[test]
fn a_fit_at_its_scan_stays_there() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 6000);
    let mut fit = truth.clone();
    refine(
        PlaneNormal::Scan,
        &truth,
        &faces,
        &scan,
        None,
        &mut fit,
        ITERATIONS,
    );
    let moved = rms(&fit, &truth) / bbox_diagonal(&truth);
    assert!(moved < 2e-3, "moved {moved:.5} of the diagonal");
}

#[test]
fn scaling_every_weight_changes_nothing() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 2000);
    let weights: Vec<f64> = (0..scan.len()).map(|j| 1.0 + (j % 3) as f64).collect();
    let doubled: Vec<f64> = weights.iter().map(|w| 2.0 * w).collect();
    let start = turned(&truth, 5.0);
    let (mut a, mut b) = (start.clone(), start);
    refine(
        PlaneNormal::Scan,
        &truth,
        &faces,
        &scan,
        Some(&weights),
        &mut a,
        20,
    );
    refine(
        PlaneNormal::Scan,
        &truth,
        &faces,
        &scan,
        Some(&doubled),
        &mut b,
        20,
    );
    assert!(rms(&a, &b) < 1e-9, "{:e}", rms(&a, &b));
    // The weights matter: uniform ones give another fit.
    let mut c = turned(&truth, 5.0);
    refine(PlaneNormal::Scan, &truth, &faces, &scan, None, &mut c, 20);
    assert!(rms(&a, &c) > 1e-6);
}

#[test]
fn the_same_result_for_any_thread_count() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 3000);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut fit = turned(&truth, 6.0);
            refine(PlaneNormal::Scan, &truth, &faces, &scan, None, &mut fit, 15);
            fit
        })
    };
    assert_eq!(run(1), run(3));
}

/// A vertex no face uses has no springs, only its scan point's tangent plane (a rank-one
/// block): it moves onto that plane and no farther, at any spring weight, and with spring
/// weight 0 no vertex is sent away along its tangent plane. The sheet is tilted so that no
/// block is diagonal (a rank-one block then factors with round-off pivots).
#[test]
fn a_vertex_without_springs_only_moves_onto_its_scan_plane() {
    let (flat, faces) = grid_sheet(15, 15, 1.0, 1.0);
    let tilt = Rotation3::from_euler_angles(0.4, -0.7, 0.3);
    let truth: Vec<[f64; 3]> = flat.iter().map(|p| (tilt * vec3(p)).into()).collect();
    let normal = tilt * Vec3::z();
    let scan = scan_of(&truth, &faces, 2000);
    let mut rest = truth.clone();
    // Off the sheet's middle, above it.
    let lone_start = tilt * Vec3::new(0.03, 0.02, 0.05);
    rest.push(lone_start.into());
    let incidence = VertexFaces::new(&faces, rest.len());
    let refine = IsometricRefine::new(&rest, &faces, &incidence, &scan, None);
    for weight in [0.0, 3.0, 10.0] {
        let mut fit = rest.clone();
        refine.run(&mut fit, 30, springs(weight, SpringScale::Rest));
        assert!(
            fit.iter().flatten().all(|x| x.is_finite()),
            "weight {weight}"
        );
        let step = vec3(&fit[truth.len()]) - lone_start;
        let along = step - step.dot(&normal) * normal;
        let height = vec3(&fit[truth.len()]).dot(&normal);
        assert!(
            height.abs() < 2e-3,
            "weight {weight}: {height} off the plane"
        );
        assert!(
            along.norm() < 1e-6,
            "weight {weight}: moved {along:?} along the plane"
        );
        let moved = rms(&fit[..truth.len()], &truth);
        assert!(moved < 0.02, "weight {weight}: the sheet moved {moved:.4}");
    }
}

/// The springs hold the rest shape's proportions at the fit's own scale: a template placed at
/// 0.6 × its scan's size, fitted onto the scan, is not pulled back to the template's size.
#[test]
fn a_template_at_another_scale_keeps_the_fit_s_size() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 4000);
    let small: Vec<[f64; 3]> = truth.iter().map(|p| p.map(|x| 0.6 * x)).collect();
    let incidence = VertexFaces::new(&faces, small.len());
    let refine = IsometricRefine::new(&small, &faces, &incidence, &scan, None);
    let mut fit = turned(&truth, 3.0);
    let before = rms(&fit, &truth);
    refine.run(&mut fit, ITERATIONS, springs(WEIGHT, SpringScale::Fit));
    let after = rms(&fit, &truth);
    assert!(after < 0.5 * before, "from {before:.4} to {after:.4}");
    let strain = worst_strain(&fit, &truth, &faces);
    assert!(
        strain < 0.05,
        "strain against the scan's own size {strain:.3}"
    );
    // At the rest lengths themselves the same fit shrinks towards the template's size.
    let mut shrunk = turned(&truth, 3.0);
    refine.run(&mut shrunk, ITERATIONS, springs(WEIGHT, SpringScale::Rest));
    assert!(worst_strain(&shrunk, &truth, &faces) > 0.2);
}

/// The hold keeps the edge vectors of the start: held strongly, a slid patch keeps its shape
/// (it may only translate), where the free refinement brings it back.
#[test]
fn a_strong_hold_keeps_the_start_s_shape() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 4000);
    let incidence = VertexFaces::new(&faces, truth.len());
    let refine = IsometricRefine::new(&truth, &faces, &incidence, &scan, None);
    let start = turned(&truth, 8.0);
    let run = |hold: f64| {
        let mut fit = start.clone();
        let springs = Springs {
            weight: WEIGHT,
            hold,
            scale: SpringScale::Rest,
            hold_where: HoldWhere::Everywhere,
        };
        refine.run(&mut fit, ITERATIONS, springs);
        fit
    };
    let held = run(1e4);
    let shift: Vec3 = held
        .iter()
        .zip(&start)
        .map(|(a, b)| vec3(a) - vec3(b))
        .sum::<Vec3>()
        / held.len() as f64;
    let unshifted: Vec<[f64; 3]> = held.iter().map(|p| (vec3(p) - shift).into()).collect();
    assert!(
        rms(&unshifted, &start) < 1e-3,
        "{:.5}",
        rms(&unshifted, &start)
    );
    assert!(rms(&run(0.0), &truth) < 0.2 * rms(&start, &truth));
}

/// Held only where the scan has no points ([`HoldWhere::Unsupported`]): with a hole in the scan,
/// the patch slid along itself comes back further where the scan sees it than under the hold
/// everywhere, while the edges in the hole keep their vectors better than without a hold.
#[test]
fn the_hold_over_a_hole_keeps_its_edges_and_frees_the_rest() {
    let (truth, faces) = cylinder_patch();
    let centre = truth[truth.len() / 2];
    let in_hole = |p: &[f64; 3]| dist2(p, &centre).sqrt() < 0.3;
    let scan: Vec<[f64; 3]> = scan_of(&truth, &faces, 4000)
        .into_iter()
        .filter(|p| !in_hole(p))
        .collect();
    let incidence = VertexFaces::new(&faces, truth.len());
    let refine = IsometricRefine::new(&truth, &faces, &incidence, &scan, None);
    let start = turned(&truth, 8.0);
    let run = |hold: f64, hold_where: HoldWhere| {
        let mut fit = start.clone();
        let springs = Springs {
            weight: WEIGHT,
            hold,
            scale: SpringScale::Rest,
            hold_where,
        };
        refine.run(&mut fit, ITERATIONS, springs);
        fit
    };
    // The vertices deep in the hole (none of their ring's scan points is near them) and the
    // largest change of one of their edges' vectors.
    let deep: Vec<usize> = (0..truth.len())
        .filter(|&v| dist2(&truth[v], &centre).sqrt() < 0.15)
        .collect();
    assert!(deep.len() >= 4);
    let edge_change = |fit: &[[f64; 3]]| {
        faces
            .iter()
            .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
            .filter(|&(a, b)| deep.contains(&(a as usize)) && deep.contains(&(b as usize)))
            .map(|(a, b)| {
                let (a, b) = (a as usize, b as usize);
                let now = vec3(&fit[a]) - vec3(&fit[b]);
                let then = vec3(&start[a]) - vec3(&start[b]);
                (now - then).norm()
            })
            .fold(0.0, f64::max)
    };
    let hold = crate::fit::DEFAULT_ISOMETRIC_HOLD;
    let everywhere = run(hold, HoldWhere::Everywhere);
    let unsupported = run(hold, HoldWhere::Unsupported);
    let free = run(0.0, HoldWhere::Everywhere);
    let seen: Vec<usize> = (0..truth.len()).filter(|&v| !in_hole(&truth[v])).collect();
    let rms_over = |fit: &[[f64; 3]], of: &[usize]| {
        (of.iter().map(|&v| dist2(&fit[v], &truth[v])).sum::<f64>() / of.len() as f64).sqrt()
    };
    // The seen part comes back further than under the hold everywhere; the edges in the hole
    // change less than with no hold at all.
    let (held, freed) = (rms_over(&everywhere, &seen), rms_over(&unsupported, &seen));
    assert!(rms_over(&free, &seen) < held);
    assert!(freed < 0.6 * held, "{freed:.4} against {held:.4}");
    let (kept, loose) = (edge_change(&unsupported), edge_change(&free));
    assert!(kept < 0.75 * loose, "{kept:.5} against {loose:.5}");
}

/// Anchors (a fit's landmark vertices) hold their vertices where they are told: the patch slid
/// along itself, which the refinement alone brings back, stays slid where four of its vertices
/// are anchored at their slid places; an index past the mesh is ignored.
#[test]
fn anchored_vertices_stay_at_their_anchors() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 4000);
    let slid = turned(&truth, 8.0);
    let chosen: [u32; 5] = [26, 48, 276, 298, 10_000];
    let at: Vec<[f64; 3]> = chosen
        .iter()
        .map(|&v| slid.get(v as usize).copied().unwrap_or([0.0; 3]))
        .collect();
    let incidence = VertexFaces::new(&faces, truth.len());
    let run = |anchor_weight: f64| {
        let mut fit = slid.clone();
        IsometricRefine::new(&truth, &faces, &incidence, &scan, None)
            .with_anchors(&chosen, &at, anchor_weight)
            .run(&mut fit, ITERATIONS, springs(WEIGHT, SpringScale::Rest));
        fit
    };
    let gap = |fit: &[[f64; 3]]| {
        chosen[..4]
            .iter()
            .zip(&at)
            .map(|(&v, z)| dist2(&fit[v as usize], z).sqrt())
            .fold(0.0, f64::max)
    };
    let slide = rms(&slid, &truth);
    let (free, held) = (run(0.0), run(100.0));
    assert!(
        gap(&free) > 0.5 * slide,
        "free: {:.4} of {slide:.4}",
        gap(&free)
    );
    assert!(
        gap(&held) < 0.05 * slide,
        "anchored: {:.4} of {slide:.4}",
        gap(&held)
    );
    // The rest of the patch follows its anchors (the rim pulls it back in between).
    assert!(
        rms(&held, &slid) < 0.4 * rms(&free, &slid),
        "the anchored patch stays slid: {:.4} from it (free: {:.4})",
        rms(&held, &slid),
        rms(&free, &slid)
    );
}

/// The largest x of `rest` (a sheet's rim at x = max).
fn x_max(rest: &[[f64; 3]]) -> f64 {
    rest.iter().map(|p| p[0]).fold(f64::MIN, f64::max)
}

/// A scan of the plane of the sheet `(rest, faces)` with 30 % more of it past its rim at
/// x = max.
fn scan_past_the_rim(rest: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let x_max = x_max(rest);
    let wide: Vec<[f64; 3]> = rest
        .iter()
        .map(|p| [p[0] + 0.3 * (p[0] - x_max + 1.0), p[1], p[2]])
        .collect();
    scan_of(&wide, faces, 4000)
}

/// Scan beyond the fit's rim pulls the rim outward (the fit slides towards it), unless
/// [`IsometricRefine::without_rim_pull`] (a garment pass on a dressed-body scan, whose points
/// beyond the rim are mostly skin).
#[test]
fn without_the_rim_pull_the_scan_beyond_the_rim_does_not_move_the_fit() {
    let (rest, faces) = grid_sheet(21, 21, 1.0, 1.0);
    let scan = scan_past_the_rim(&rest, &faces);
    let incidence = VertexFaces::new(&faces, rest.len());
    let shift = |refine: IsometricRefine| {
        let mut fit = rest.clone();
        refine.run(&mut fit, ITERATIONS, springs(WEIGHT, SpringScale::Rest));
        fit.iter().zip(&rest).map(|(a, b)| a[0] - b[0]).sum::<f64>() / rest.len() as f64
    };
    let pulled = shift(IsometricRefine::new(&rest, &faces, &incidence, &scan, None));
    let held =
        shift(IsometricRefine::new(&rest, &faces, &incidence, &scan, None).without_rim_pull());
    assert!(
        pulled > 0.02,
        "the rim follows the scan past it: {pulled:.4}"
    );
    assert!(
        held.abs() < 0.1 * pulled,
        "without the rim pull: {held:.4} (with: {pulled:.4})"
    );
}

/// Without the rim pull, the faces on a free edge ([`IsometricRefine::with_free_edges`]) are
/// still pulled by the scan past them: the sheet of the test above slides on towards the scan
/// past its rim at x = max when that rim's faces are flagged, and not when the other rim's are.
#[test]
fn a_free_edge_keeps_its_pull_without_the_rim_pull() {
    let (rest, faces) = grid_sheet(21, 21, 1.0, 1.0);
    let scan = scan_past_the_rim(&rest, &faces);
    let x_max = x_max(&rest);
    let incidence = VertexFaces::new(&faces, rest.len());
    let on_rim = |x: f64| -> Vec<bool> {
        faces
            .iter()
            .map(|f| f.iter().any(|&v| (rest[v as usize][0] - x).abs() < 1e-9))
            .collect()
    };
    let shift = |free: Vec<bool>| {
        let mut fit = rest.clone();
        IsometricRefine::new(&rest, &faces, &incidence, &scan, None)
            .without_rim_pull()
            .with_free_edges(free)
            .run(&mut fit, ITERATIONS, springs(WEIGHT, SpringScale::Rest));
        fit.iter().zip(&rest).map(|(a, b)| a[0] - b[0]).sum::<f64>() / rest.len() as f64
    };
    let free = shift(on_rim(x_max));
    let other = shift(on_rim(-x_max));
    assert!(
        free > 0.02,
        "the free edge follows the scan past it: {free:.4}"
    );
    assert!(
        other.abs() < 0.1 * free,
        "the other rim's flag does not pull this one: {other:.4} (free: {free:.4})"
    );
}

/// A 2 × 1 grid folded into a hairpin about the y axis: a half circle of radius `r` between
/// two parallel legs.
fn hairpin(r: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (flat, faces) = grid_sheet(41, 11, 2.0, 1.0);
    let bend = std::f64::consts::FRAC_PI_2 * r;
    let folded = flat
        .iter()
        .map(|p| {
            let s = p[0];
            if s.abs() <= bend {
                let a = s / r;
                [r * a.sin(), p[1], r * (1.0 - a.cos())]
            } else {
                [r * s.signum(), p[1], r + s.abs() - bend]
            }
        })
        .collect();
    (folded, faces)
}

#[test]
fn the_fit_s_own_normals_keep_a_fit_at_a_sparse_scan_of_a_fold_in_place() {
    // About one scan point per vertex on a tight fold: the plane of a point's 12 nearest
    // points spans the fold and tilts against the surface, which pushes a fit lying on the
    // truth along itself; the fit's own normals move each vertex across the surface only.
    for r in [0.1, 0.15] {
        let (truth, faces) = hairpin(r);
        let scan = scan_of(&truth, &faces, truth.len());
        let moved = |plane| {
            let mut fit = truth.clone();
            refine(plane, &truth, &faces, &scan, None, &mut fit, ITERATIONS);
            rms(&fit, &truth)
        };
        let (by_scan, by_fit) = (moved(PlaneNormal::Scan), moved(PlaneNormal::Fit));
        assert!(
            by_fit < 0.7 * by_scan,
            "moved {by_scan:.4} with the scan's planes, {by_fit:.4} with the fit's normals"
        );
    }
}

/// A garment pass's refinement (no rim pull, the hold on) brings a patch slid along its own
/// curved surface back where the scan past its free edge says it ends: the slide turns every
/// edge, which the hold resists, and the pull of the points past the free edge
/// ([`FREE_EDGE_WEIGHT`]) carries it back the more (at one point's weight, half of it).
#[test]
fn the_scan_past_a_free_edge_carries_the_garment_against_the_hold() {
    let (truth, faces) = cylinder_patch();
    let scan = scan_of(&truth, &faces, 4000);
    let incidence = VertexFaces::new(&faces, truth.len());
    let start = turned(&truth, -8.0);
    // The rim the slide drew back from the scan's end: the largest angle about the y axis.
    let angle = |p: &[f64; 3]| p[0].atan2(p[2]);
    let rim_angle = start.iter().map(angle).fold(f64::MIN, f64::max);
    let free: Vec<bool> = faces
        .iter()
        .map(|f| {
            f.iter()
                .any(|&v| angle(&start[v as usize]) > rim_angle - 1e-9)
        })
        .collect();
    let mut fit = start.clone();
    IsometricRefine::new(&truth, &faces, &incidence, &scan, None)
        .without_rim_pull()
        .with_free_edges(free)
        .run(
            &mut fit,
            crate::fit::DEFAULT_ISOMETRIC_ITERATIONS,
            Springs {
                weight: WEIGHT,
                hold: crate::fit::DEFAULT_ISOMETRIC_HOLD,
                scale: SpringScale::Rest,
                hold_where: HoldWhere::Everywhere,
            },
        );
    let (before, after) = (rms(&start, &truth), rms(&fit, &truth));
    // 0.36 of the slide is left; at one point's weight 0.52.
    assert!(
        after < 0.45 * before,
        "slid {before:.4}, refined {after:.4} from the truth"
    );
}

#[test]
fn a_region_without_scan_under_it_keeps_its_shape() {
    // The cylinder patch at its truth, scanned on one side of x = 0 only (a one-sided rig):
    // the unseen side's vertices near the scan's edge match points of the seen side, whose
    // planes bend the unseen side towards them; marked as without scan under them (the region
    // a fit carried), they keep their place.
    let (truth, faces) = cylinder_patch();
    let scan: Vec<[f64; 3]> = scan_of(&truth, &faces, 4000)
        .into_iter()
        .filter(|p| p[0] > 0.0)
        .collect();
    let unseen: Vec<bool> = truth.iter().map(|p| p[0] < -0.05).collect();
    let incidence = VertexFaces::new(&faces, truth.len());
    let run = |mark: bool| {
        let mut fit = truth.clone();
        let mut refine = IsometricRefine::new(&truth, &faces, &incidence, &scan, None);
        if mark {
            refine = refine.without_scan_under(&unseen);
        }
        refine.run(&mut fit, ITERATIONS, springs(WEIGHT, SpringScale::Rest));
        fit
    };
    let moved = |fit: &[[f64; 3]]| {
        let which: Vec<usize> = (0..truth.len()).filter(|&v| unseen[v]).collect();
        let s: f64 = which.iter().map(|&v| dist2(&fit[v], &truth[v])).sum();
        (s / which.len() as f64).sqrt()
    };
    let (matched, marked) = (run(false), run(true));
    assert!(moved(&matched) > 1e-3, "matched: {:.5}", moved(&matched));
    assert!(
        moved(&marked) < 0.2 * moved(&matched),
        "marked {:.5}, matched {:.5}",
        moved(&marked),
        moved(&matched)
    );
    // A mask of another length, or with nothing marked, changes nothing.
    let mut fit = truth.clone();
    IsometricRefine::new(&truth, &faces, &incidence, &scan, None)
        .without_scan_under(&unseen[1..])
        .run(&mut fit, ITERATIONS, springs(WEIGHT, SpringScale::Rest));
    assert_eq!(fit, matched);
}
