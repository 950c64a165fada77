//! The fit on generated cases: phases, samples, presets, rest-shape rigidity, the parameters' keys,
//! dressed-scan rigid parts, do no harm; schedule selection in `selection`.

use super::params::Internal;
use super::phases::{annealed, rest_ring_placement};
use super::refinement::turned_over_share;
use super::*;
use crate::math::{vec3, Vec3};
use crate::rings::n_rings;
use crate::rotation::ring_centroids;

mod selection;
mod support;

#[test]
fn turned_over_share_counts_the_faces_whose_normal_reversed() {
    // Two triangles of a unit square; the second folded past flat turns over, the first only
    // tilts.
    let faces = [[0, 1, 2], [0, 2, 3]];
    // The square with its corners 1 and 3 at `a` and `b`.
    let square = |a: [f64; 3], b: [f64; 3]| [[0.0, 0.0, 0.0], a, [1.0, 1.0, 0.0], b];
    let before = square([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let tilted = square([1.0, 0.0, 0.5], [0.0, 1.0, 0.0]);
    assert_eq!(turned_over_share(&before, &tilted, &faces), 0.0);
    let folded = square([1.0, 0.0, 0.0], [1.5, 0.5, 0.0]);
    assert_eq!(turned_over_share(&before, &folded, &faces), 0.5);
    assert_eq!(turned_over_share(&before, &before, &[]), 0.0);
}

#[test]
fn softening_anneals_linearly_over_its_fraction_of_the_iterations() {
    let mut p = {
        let mut p = FitParams::default();
        p.schedule.anneal = 3.0;
        p.schedule.anneal_fraction = 0.5;
        p.iterations = 10;
        p
    };
    let eps = p.model.nbody.softening;
    let at = |p: &FitParams, it| annealed(p, it).softening / eps;
    assert!((at(&p, 1) - 3.0).abs() < 1e-15);
    // Span 5 iterations: at iteration 3, 2/5 of the way from 3 down to 1.
    assert!((at(&p, 3) - 2.2).abs() < 1e-15);
    for it in 6..=10 {
        assert_eq!(at(&p, it), 1.0, "iteration {it}");
    }
    // Same schedule, in fractions, whatever ξ is.
    p.iterations = 100;
    assert!((at(&p, 21) - 2.2).abs() < 1e-15);
    for off in [
        {
            let mut p = p.clone();
            p.schedule.anneal = 1.0;
            p
        },
        {
            let mut p = p.clone();
            p.schedule.anneal_fraction = 0.0;
            p
        },
        FitParams::paper(),
    ] {
        assert!((1..=100).all(|it| at(&off, it) == 1.0));
    }
}

/// A sheet (vertices, faces) and a wavy copy of its vertices lifted by `lift` as the scan.
type Case = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 3]>);

fn wavy_grid_case(side: usize, lift: f64) -> Case {
    let (v, f) = crate::synthetic::grid_sheet(side, side, 1.0, 1.0);
    let target = v
        .iter()
        .map(|p| [p[0], p[1], 0.05 * (4.0 * p[0]).sin() + lift])
        .collect();
    (v, f, target)
}

/// Schedule selection's first figure for a fit: the mean distance from every scan point
/// to its nearest fitted vertex.
fn mean_scan_distance(x: &[[f64; 3]], r: &FitResult) -> f64 {
    let d = crate::metrics::nearest_distances(x, &r.vertices);
    d.iter().sum::<f64>() / d.len() as f64
}

/// Schedule selection's tie-break for each fit: its edge-length spread.
fn edge_spreads(v: &[[f64; 3]], f: &[[u32; 3]], runs: &[FitResult]) -> Vec<f64> {
    runs.iter()
        .map(|r| crate::metrics::edge_length_spread(v, &r.vertices, f))
        .collect()
}

/// A 13 × 13 sheet and its scan.
fn grid_case() -> Case {
    wavy_grid_case(13, 0.02)
}

/// An 8×8 grid (64 vertices, graph diameter 14) and a scan above it.
fn small_grid_case() -> Case {
    wavy_grid_case(8, 0.1)
}

/// The default with only a rigid phase, `iterations` long, one schedule.
fn rigid_only(iterations: usize) -> FitParams {
    {
        let mut p = FitParams {
            iterations,
            // From the placement as given.
            prealign: Prealign::None,
            ..FitParams::default()
        };
        p.schedule.rigid_fraction = 1.0;
        p.schedule.coarse_fraction = 0.0;
        p.schedule.selection = Selection::Single;
        // The rigid phase alone, without the end-of-fit comparison with the start, a refit or
        // the isometric refinement.
        p.schedule.keep_margin = 0.0;
        p.schedule.garment_refit = 0.0;
        p.schedule.isometric_iterations = 0;
        p
    }
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (vec3(a) - vec3(b)).norm()
}

/// The largest distance between corresponding points.
fn max_apart(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    (0..a.len()).map(|i| dist(&a[i], &b[i])).fold(0.0, f64::max)
}

/// `moved` keeps every pairwise distance of `start`: one rigid motion.
fn assert_rigidly_moved(start: &[[f64; 3]], moved: &[[f64; 3]]) {
    for i in 0..start.len() {
        for j in 0..i {
            assert!((dist(&moved[i], &moved[j]) - dist(&start[i], &start[j])).abs() < 1e-12);
        }
    }
}

/// `params` fail validation with an error naming `field`.
fn assert_refused(params: &FitParams, field: &str) {
    let err = params.validate().unwrap_err().to_string();
    assert!(err.contains(field), "{err}");
}

#[test]
fn automatic_coarse_radius_grows_with_the_square_root_of_the_template_and_is_clamped() {
    let auto = FitParams::default();
    assert_eq!(auto.schedule.coarse_rings, 0);
    // 8 rings up to the reference size, √M above it, at most 12.
    for (m, want) in [
        (10, 8),
        (1_700, 8),
        (1_921, 9),  // 8 √(1921 / 1700) = 8.50
        (3_845, 12), // 12.03
        (3_509, 11), // 11.49
        (6_561, 12), // 15.7, clamped
        (100_489, 12),
    ] {
        assert_eq!(auto.coarse_radius(m), want, "M = {m}");
    }
    // A given radius is used as given, whatever the size.
    let given = {
        let mut p = FitParams::default();
        p.schedule.coarse_rings = 5;
        p
    };
    assert_eq!(given.coarse_radius(100_489), 5);
    assert_refused(
        &{
            let mut p = FitParams::default();
            p.schedule.coarse_rings = 33;
            p
        },
        "coarse_rings",
    );
    // The automatic radius is the given one for that size: the same fit, bit for bit, and
    // the diagnostics report it (a 50 × 50 grid: 2,500 vertices, radius 10).
    let (v, f) = crate::synthetic::grid_sheet(50, 50, 1.0, 1.0);
    let x: Vec<[f64; 3]> = v
        .iter()
        .map(|p| [p[0], p[1], 0.1 * (3.0 * p[0]).sin() + 0.05])
        .collect();
    let base = {
        let mut p = FitParams {
            iterations: 10,
            ..FitParams::default()
        };
        p.schedule.selection = Selection::Single;
        p
    };
    let auto_fit = fit_simple(&v, &f, &x, None, &base).unwrap();
    let given = |coarse_rings| {
        let params = {
            let mut p = base.clone();
            p.schedule.coarse_rings = coarse_rings;
            p
        };
        fit_simple(&v, &f, &x, None, &params).unwrap().vertices
    };
    assert_eq!(auto_fit.diagnostics.coarse_rings, 10);
    assert_eq!(auto_fit.vertices, given(10));
    assert_ne!(auto_fit.vertices, given(8));
}

#[test]
fn coarse_levels_shrink_the_radius_and_stop_at_one_ring() {
    let (v, f, x) = grid_case();
    let base = {
        let mut p = FitParams {
            iterations: 12,
            ..FitParams::default()
        };
        p.schedule.selection = Selection::Single;
        p.schedule.coarse_rings = 1;
        p
    };
    let one = fit_simple(&v, &f, &x, None, &base).unwrap();
    // Radius max(1, 1 >> l) = 1 at every level: the same fit, bit for bit.
    let three = fit_simple(&v, &f, &x, None, &{
        let mut p = base.clone();
        p.schedule.coarse_levels = 3;
        p
    });
    assert_eq!(one.vertices, three.unwrap().vertices);
    // From 4 rings, a second level (2 rings) changes the coarse phase.
    let wide = {
        let mut p = base.clone();
        p.schedule.coarse_rings = 4;
        p
    };
    let a = fit_simple(&v, &f, &x, None, &wide).unwrap();
    let b = fit_simple(&v, &f, &x, None, &{
        let mut p = wide;
        p.schedule.coarse_levels = 2;
        p
    })
    .unwrap();
    assert_ne!(a.vertices, b.vertices);
    for bad in [0, 5] {
        assert_refused(
            &{
                let mut p = base.clone();
                p.schedule.coarse_levels = bad;
                p
            },
            "coarse_levels",
        );
    }
}

#[test]
fn rigid_sample_moves_the_template_rigidly_by_the_sample_fit() {
    let (v, f, x) = small_grid_case();
    let rigid_only = rigid_only(6);
    let with = |rigid_sample| {
        fit_simple(&v, &f, &x, None, &{
            let mut p = rigid_only.clone();
            p.acceleration.rigid_sample = rigid_sample;
            p
        })
        .unwrap()
        .vertices
    };
    // A quarter of the vertices drives the fit: the template still moves rigidly (every
    // pairwise distance kept), but not as the fit driven by every vertex does.
    let (quarter, full) = (with(4), with(1));
    assert_rigidly_moved(&v, &quarter);
    let apart = max_apart(&quarter, &full);
    assert!(apart > 1e-9, "{apart}");
    // 64 ≥ M: the sample is vertex 0 alone, whose Kabsch fit has no rotation, so every
    // vertex moves by the same translation, the one the N-body step proposes for vertex 0.
    let one = with(64);
    let shift = vec3(&one[0]) - vec3(&v[0]);
    assert!(shift.norm() > 1e-6);
    for i in 0..v.len() {
        assert!((vec3(&one[i]) - vec3(&v[i]) - shift).norm() < 1e-12);
    }
    for bad in [0, 65] {
        assert_refused(
            &{
                let mut p = rigid_only.clone();
                p.acceleration.rigid_sample = bad;
                p
            },
            "rigid_sample",
        );
    }
}

#[test]
fn rigid_scan_sample_strides_only_dense_scans() {
    let default = FitParams::default();
    // Paper-sized: 14,400 points under 3,307 rigid-phase vertices: every point pulls.
    assert_eq!(default.rigid_scan_stride(13_225, 14_400), 1);
    // The large case: 1M points under 25,123 vertices, 8 per vertex → every 4th.
    assert_eq!(default.rigid_scan_stride(100_489, 1_000_000), 4);
    let every_vertex = {
        let mut p = default.clone();
        p.acceleration.rigid_sample = 1;
        p
    };
    assert_eq!(every_vertex.rigid_scan_stride(100_489, 1_000_000), 1);
    let given = {
        let mut p = default.clone();
        p.acceleration.rigid_scan_sample = 3;
        p
    };
    assert_eq!(given.rigid_scan_stride(100_489, 14_400), 3);
    assert_refused(
        &{
            let mut p = default;
            p.acceleration.rigid_scan_sample = 65;
            p
        },
        "rigid_scan_sample",
    );

    // An 8×8 template over a 40×40-point scan: 16 rigid-phase vertices, stride 12.
    let (v, f, _) = small_grid_case();
    let (_, _, x) = wavy_grid_case(40, 0.1);
    let rigid_only = rigid_only(6);
    assert_eq!(rigid_only.rigid_scan_stride(v.len(), x.len()), 12);
    let with = |rigid_scan_sample| {
        let params = {
            let mut p = rigid_only.clone();
            p.acceleration.rigid_scan_sample = rigid_scan_sample;
            p
        };
        fit_simple(&v, &f, &x, None, &params).unwrap().vertices
    };
    let (auto, twelve, every) = (with(0), with(12), with(1));
    assert_eq!(auto, twelve);
    // Still one rigid motion, not the one every scan point drives, but close to it.
    assert_rigidly_moved(&v, &auto);
    let (apart, moved) = (max_apart(&auto, &every), max_apart(&every, &v));
    assert!(apart > 1e-9 && apart < 0.2 * moved, "{apart} vs {moved}");
}

#[test]
fn coarse_scan_sample_halves_only_scans_of_eight_points_a_vertex() {
    let default = FitParams::default();
    // Paper-sized (1.1 points a vertex) and a dense scan (3.5): the whole scan.
    assert_eq!(default.coarse_scan_stride(13_225, 14_400), 1);
    assert_eq!(default.coarse_scan_stride(1_426, 5_000), 1);
    // From 8 points a vertex every 2nd, and never more by itself.
    assert_eq!(default.coarse_scan_stride(1_000, 7_999), 1);
    assert_eq!(default.coarse_scan_stride(1_000, 8_000), 2);
    assert_eq!(default.coarse_scan_stride(100_489, 1_000_000), 2);
    assert_eq!(default.coarse_scan_stride(1_426, 60_000), 2);
    // The rigid phase's automatic stride keeps its own rule.
    assert_eq!(default.rigid_scan_stride(100_489, 1_000_000), 4);
    for given in [1, 3, 64] {
        let params = {
            let mut p = default.clone();
            p.acceleration.coarse_scan_sample = given;
            p
        };
        assert_eq!(params.coarse_scan_stride(1_000, 1_000_000), given);
    }
    assert_refused(
        &{
            let mut p = default.clone();
            p.acceleration.coarse_scan_sample = 65;
            p
        },
        "coarse_scan_sample",
    );

    // A coarse-only fit of an 8×8 template on a 40×40-point scan (25 points a vertex):
    // the automatic stride is the explicit 2, and it changes the fit by a fraction of the
    // motion.
    let (v, f, _) = small_grid_case();
    let (_, _, x) = wavy_grid_case(40, 0.1);
    let coarse_only = {
        let mut p = default;
        p.iterations = 6;
        p.prealign = Prealign::None;
        p.schedule.rigid_fraction = 0.0;
        p.schedule.coarse_fraction = 1.0;
        p.schedule.selection = Selection::Single;
        p
    };
    assert_eq!(coarse_only.coarse_scan_stride(v.len(), x.len()), 2);
    let with = |coarse_scan_sample| {
        let params = {
            let mut p = coarse_only.clone();
            p.acceleration.coarse_scan_sample = coarse_scan_sample;
            p
        };
        fit_simple(&v, &f, &x, None, &params).unwrap().vertices
    };
    let (auto, two, every) = (with(0), with(2), with(1));
    assert_eq!(auto, two);
    let (apart, moved) = (max_apart(&auto, &every), max_apart(&every, &v));
    assert!(apart > 1e-9 && apart < 0.2 * moved, "{apart} vs {moved}");
}

#[test]
fn coarse_sample_with_whole_mesh_rings_is_the_rigid_sample() {
    // Coarse rings reaching the whole 8×8 grid (graph diameter 14 < 32): every vertex's
    // sampled ring is the whole sample, so a coarse-only fit on every 4th vertex is the
    // rigid-only fit on every 4th vertex, up to the order of the sums.
    let (v, f, x) = small_grid_case();
    let base = {
        let mut p = FitParams {
            iterations: 6,
            prealign: Prealign::None,
            ..FitParams::default()
        };
        p.schedule.coarse_rings = 32;
        p.schedule.selection = Selection::Single;
        p
    };
    let run = |p: FitParams| fit_simple(&v, &f, &x, None, &p).unwrap().vertices;
    let coarse = run({
        let mut p = base.clone();
        p.schedule.rigid_fraction = 0.0;
        p.schedule.coarse_fraction = 1.0;
        p.acceleration.coarse_sample = 4;
        p
    });
    let rigid = run({
        let mut p = base.clone();
        p.schedule.rigid_fraction = 1.0;
        p.schedule.coarse_fraction = 0.0;
        p.acceleration.rigid_sample = 4;
        p
    });
    let every = run({
        let mut p = base.clone();
        p.schedule.rigid_fraction = 0.0;
        p.schedule.coarse_fraction = 1.0;
        p
    });
    let gap = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| (vec3(p) - vec3(q)).norm())
            .fold(0.0, f64::max)
    };
    assert!(gap(&coarse, &rigid) < 1e-12, "{}", gap(&coarse, &rigid));
    assert!(gap(&coarse, &every) > 1e-9, "the sample changed nothing");
    for (bad, rings, levels) in [(0, 8, 1), (65, 8, 1), (2, 4, 2), (2, 2, 1)] {
        assert_refused(
            &{
                let mut p = base.clone();
                p.acceleration.coarse_sample = bad;
                p.schedule.coarse_rings = rings;
                p.schedule.coarse_levels = levels;
                p
            },
            "coarse_sample",
        );
    }
}

#[test]
fn rest_ring_placement_recovers_a_rigid_motion_of_the_rest_shape() {
    // Proposed = R · rest + t on every ring: each vertex goes to R · rest[v] + t exactly.
    let (rest, f) = crate::synthetic::grid_sheet(6, 5, 1.0, 0.8);
    let rest: Vec<[f64; 3]> = rest
        .iter()
        .map(|p| [p[0], p[1], 0.3 * p[0] * p[1]])
        .collect();
    let rings = n_rings(&f, rest.len(), 2);
    let r = nalgebra::Rotation3::from_scaled_axis(Vec3::new(0.3, -0.5, 0.9)).into_inner();
    let t = Vec3::new(0.2, -1.0, 0.4);
    let moved = |p: &[f64; 3]| r * vec3(p) + t;
    let proposed: Vec<[f64; 3]> = rest.iter().map(|p| moved(p).into()).collect();
    for fast in [true, false] {
        for v in 0..rest.len() {
            let ring = rings.of(v);
            let (c_rest, c) = ring_centroids(ring, &rest, &proposed);
            let placed = rest_ring_placement(ring, v, &rest, &c_rest, &proposed, &c, fast);
            assert!((placed - moved(&rest[v])).norm() < 1e-12, "vertex {v}");
        }
    }
}

#[test]
fn rest_rigidity_keeps_the_template_edge_lengths_over_a_scan_hole() {
    // A flat sheet onto a wavy scan with a hole: the rest-shape term keeps the edge lengths
    // closer to the template's; 0 is the update without it, and out-of-range values fail.
    let (v, f, x) = wavy_grid_case(17, 0.03);
    let x: Vec<[f64; 3]> = x
        .into_iter()
        .filter(|p| (p[0] - 0.6).hypot(p[1] - 0.4) > 0.2)
        .collect();
    let spread = |params: &FitParams| {
        let r = fit_simple(&v, &f, &x, None, params).unwrap();
        crate::metrics::edge_length_spread(&v, &r.vertices, &f)
    };
    let with_rigidity = {
        let mut p = FitParams {
            iterations: 40,
            ..FitParams::default()
        };
        p.schedule.coarse_fraction = 0.2;
        p.schedule.selection = Selection::Single;
        p
    };
    assert_eq!(with_rigidity.schedule.rest_rigidity, 0.65);
    let with = spread(&with_rigidity);
    let without = spread(&{
        let mut p = with_rigidity.clone();
        p.schedule.rest_rigidity = 0.0;
        p
    });
    assert!(
        with < 0.8 * without,
        "edge-length spread {with} vs {without}"
    );
    for bad in [-0.1, 1.5, f64::NAN] {
        assert_refused(
            &{
                let mut p = FitParams::default();
                p.schedule.rest_rigidity = bad;
                p
            },
            "rest_rigidity",
        );
    }
}

#[test]
fn every_flat_key_round_trips_and_unknown_keys_are_refused_by_name() {
    // The groups are flattened: one flat object, every key at the top level.
    let paper = FitParams::paper();
    let json: serde_json::Value = serde_json::from_str(&paper.to_json()).unwrap();
    let keys = json.as_object().unwrap();
    for key in [
        "iterations",
        "rho",
        "psi",
        "damping_mode",
        "regularization",
        "two_way",
    ] {
        assert!(keys.contains_key(key), "{key}");
    }
    for key in [
        "rigid_sample",
        "knn_slack",
        "model",
        "schedule",
        "acceleration",
    ] {
        assert_eq!(
            keys.contains_key(key),
            !["model", "schedule", "acceleration"].contains(&key)
        );
    }
    assert_eq!(FitParams::from_json(&paper.to_json()).unwrap(), paper);
    // The round-off-only speed switches are not settings.
    for key in ["matrix_series", "knn_cache", "nonsense"] {
        let err = FitParams::from_json(&format!("{{\"{key}\": false}}")).unwrap_err();
        assert!(err.to_string().contains(key), "{err}");
    }
    let err = FitParams::from_json(r#"{"anneal": 0.5}"#)
        .unwrap_err()
        .to_string();
    assert!(err.contains("anneal") && err.contains("[1, 1e6]"), "{err}");
}

/// The default and the paper preset, 30 iterations, exact neighborhoods throughout.
fn exact_neighbourhood_presets() -> Vec<FitParams> {
    [FitParams::default(), FitParams::paper()]
        .into_iter()
        .map(|mut p| {
            p.iterations = 30;
            p.acceleration.knn_slack = 0.0;
            p
        })
        .collect()
}

#[test]
fn the_fast_paths_change_the_fit_only_by_round_off() {
    let (v, f, x) = grid_case();
    for fast in exact_neighbourhood_presets() {
        let mut exact = fast.clone();
        exact.internal = Internal {
            matrix_series: false,
            knn_cache: false,
            ..Internal::default()
        };
        let (a, b) = (
            fit_simple(&v, &f, &x, None, &fast).unwrap(),
            fit_simple(&v, &f, &x, None, &exact).unwrap(),
        );
        assert!(max_apart(&v, &a.vertices) > 1e-3, "the fit moved");
        assert!(max_apart(&a.vertices, &b.vertices) < 1e-9);
        let field = |r: &FitResult| r.wvf_accumulated.clone();
        assert!(max_apart(&field(&a), &field(&b)) < 1e-9);
        assert!(max_apart(&a.wvf, &b.wvf) < 1e-9);
        // The cache spared fresh queries.
        assert!(a.diagnostics.knn_queries < b.diagnostics.knn_queries);
    }
}

/// Two 9 × 9 sheets side by side (x ∈ [−1.3, −0.3] and [0.3, 1.3]) as one template, and a scan of
/// the left one lifted by `dz` and the right one lowered by `dz`.
fn two_sheets_case(dz: f64) -> Case {
    let (sheet, faces) = crate::synthetic::grid_sheet(9, 9, 1.0, 1.0);
    let n = sheet.len() as u32;
    let mut v: Vec<[f64; 3]> = sheet.iter().map(|p| [p[0] - 0.8, p[1], 0.0]).collect();
    v.extend(sheet.iter().map(|p| [p[0] + 0.8, p[1], 0.0]));
    let mut f = faces.clone();
    f.extend(faces.iter().map(|t| t.map(|i| i + n)));
    let x = v
        .iter()
        .map(|p| [p[0], p[1], if p[0] < 0.0 { dz } else { -dz }])
        .collect();
    (v, f, x)
}

#[test]
fn rigid_phase_moves_each_piece_by_its_own_rigid_motion_on_a_dressed_scan() {
    // One rigid motion cannot lift one sheet and lower the other: it would tilt both about the
    // y axis. On a scan that holds more than the template (here a far "body" plane 1.5 below,
    // 6 × 6 wide), one motion per connected component (docs/method.md "Rigid phase") moves
    // each sheet straight to its own scan, keeping each sheet's shape. (Fitted through `fit`,
    // two sheets this size are two garments, each fitted on its own (`garments`); a template
    // whose second piece is smaller, a sleeve cut loose, is fitted whole, as here.)
    let (v, f, garments) = two_sheets_case(0.05);
    let (body, _) = crate::synthetic::grid_sheet(25, 25, 6.0, 6.0);
    let mut x = garments.clone();
    x.extend(body.iter().map(|p| [p[0], p[1], -1.5]));
    let whole = |x: &[[f64; 3]]| {
        let params = rigid_only(30);
        super::fit_from(
            &v,
            None,
            &f,
            x,
            None,
            None,
            None,
            None,
            super::FitRole::default(),
            &params,
            &mut |_| true,
        )
        .unwrap()
    };
    let r = whole(&x);
    assert!(
        r.diagnostics.frame.unwrap().scale < 3.0,
        "the garment frame is in use"
    );
    let half = v.len() / 2;
    for (range, sign) in [(0..half, 1.0), (half..v.len(), -1.0)] {
        assert_rigidly_moved(&v[range.clone()], &r.vertices[range.clone()]);
        let z: Vec<f64> = r.vertices[range].iter().map(|p| p[2]).collect();
        let (lo, hi) = z
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &z| (a.min(z), b.max(z)));
        // Each sheet reached its own scan's height and stayed level.
        assert!(sign * lo > 0.03 && sign * hi < 0.07, "{lo} {hi}");
        assert!(hi - lo < 0.01, "a sheet tilted: z from {lo} to {hi}");
    }
    // The same template on the garments alone: its components are taken as pieces of one
    // garment and move by one rigid motion, which tilts them.
    let one = whole(&garments);
    assert_rigidly_moved(&v, &one.vertices);
    let z: Vec<f64> = one.vertices[..half].iter().map(|p| p[2]).collect();
    let spread =
        z.iter().fold(f64::MIN, |a, &b| a.max(b)) - z.iter().fold(f64::MAX, |a, &b| a.min(b));
    assert!(spread > 0.02, "{spread}");
}

#[test]
fn rigid_parts_are_the_components_with_small_pieces_joined_to_the_largest() {
    let (v, mut f, _) = two_sheets_case(0.05);
    let m = v.len();
    // A lone triangle (3 vertices < MIN_RIGID_PART) and an unused vertex.
    f.push([m as u32, m as u32 + 1, m as u32 + 2]);
    let parts = super::setup::rigid_parts(&f, m + 4);
    assert_eq!(parts.vertices.len(), 2);
    let first: Vec<u32> = (0..81).chain(m as u32..m as u32 + 4).collect();
    assert_eq!(parts.vertices[0], first);
    // The largest is the first of the two equal sheets; the small pieces join it.
    assert!((m..m + 4).all(|v| parts.of[v] == 0));
    assert!((81..m).all(|v| parts.of[v] == 1));
    // One sheet alone (plus small pieces) is one part: the whole-template fit.
    let one: Vec<[u32; 3]> = f
        .iter()
        .copied()
        .filter(|t| t[0] < 81 || t[0] >= m as u32)
        .collect();
    assert!(super::setup::rigid_parts(&one, m + 4).vertices.is_empty());
}

#[test]
fn the_start_is_kept_only_within_the_keep_margin() {
    assert!(keeps_start(1.09, 1.0, 0.1));
    assert!(keeps_start(0.9, 1.0, 0.1));
    assert!(!keeps_start(1.11, 1.0, 0.1));
    // Margin 0: the rule is off, even where the start is the closer one.
    assert!(!keeps_start(0.5, 1.0, 0.0));
    for bad in [-0.01, f64::NAN, f64::INFINITY] {
        let mut p = FitParams::default();
        p.schedule.keep_margin = bad;
        assert_refused(&p, "keep_margin");
    }
}

#[test]
fn the_do_no_harm_distance_is_the_weighted_median() {
    // Scan points at distances 0, 1, 2, 3 and 10 from the one vertex at the origin.
    let scan = [
        [0.0; 3],
        [1.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [0.0, 0.0, 3.0],
        [10.0, 0.0, 0.0],
    ];
    let vertex = [[0.0; 3]];
    let d = |w: Option<&[f64]>, g: Option<&[usize]>| {
        super::schedule::median_scan_distance(&scan, w, g, &vertex)
    };
    assert_eq!(d(None, None), 2.0);
    // The far point weighs most: half the weight lies at 10.
    assert_eq!(d(Some(&[1.0, 1.0, 1.0, 1.0, 4.0]), None), 3.0);
    assert_eq!(d(Some(&[1.0, 1.0, 1.0, 1.0, 5.0]), None), 10.0);
    // Weight 0 removes a point; the garment's points alone when given.
    assert_eq!(d(Some(&[0.0, 0.0, 1.0, 1.0, 1.0]), None), 3.0);
    assert_eq!(d(None, Some(&[0, 1])), 0.0);
}
