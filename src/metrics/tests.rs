use super::*;
use approx::assert_relative_eq;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn edge_length_spread_counts_each_edge_once_and_ignores_similarities() {
    // A unit square as two triangles sharing the diagonal 0–2: five unique edges.
    let square = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let faces = [[0, 1, 2], [0, 2, 3]];
    // Stretched ×2 along x: edge ratios 2 (0–1), 1 (1–2), √(5/2) (0–2), 2 (2–3), 1 (3–0).
    let stretched: Vec<[f64; 3]> = square.iter().map(|p| [2.0 * p[0], p[1], p[2]]).collect();
    let logs = [2f64.ln(), 0.0, 2.5f64.sqrt().ln(), 2f64.ln(), 0.0];
    let mean = logs.iter().sum::<f64>() / 5.0;
    let want = (logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / 5.0).sqrt();
    assert_relative_eq!(
        edge_length_spread(&square, &stretched, &faces),
        want,
        max_relative = 1e-14
    );
    // A rotation, a uniform scale and a translation change no ratio's logarithm but by a
    // constant: spread 0.
    let (c, s) = (0.6f64, 0.8f64);
    let similar: Vec<[f64; 3]> = square
        .iter()
        .map(|p| {
            [
                3.0 * (c * p[0] - s * p[1]) + 5.0,
                3.0 * (s * p[0] + c * p[1]),
                -2.0,
            ]
        })
        .collect();
    assert!(edge_length_spread(&square, &similar, &faces) < 1e-14);
    // A collapsed edge is finite (ratio 1e-12); no face, no edge: 0.
    let collapsed = [square[0], square[0], square[2], square[3]];
    assert!(edge_length_spread(&square, &collapsed, &faces).is_finite());
    assert_eq!(edge_length_spread(&square, &stretched, &[]), 0.0);
}

// ---------- brute-force references (O(N·M), written independently) ----------

/// The stretch field's spread: 0 for a similarity; a regional stretch (one half of a sheet
/// 20 % longer) keeps most of its spread through the smoothing, edge-scale noise of the same
/// per-edge spread averages out.
#[test]
fn stretch_field_spread_keeps_regional_stretch_and_averages_out_noise() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (flat, faces) = crate::synthetic::grid_sheet(41, 41, 1.0, 1.0);
    let lengths = EdgeLengths::new(&flat, &faces);
    let similar: Vec<[f64; 3]> = flat
        .iter()
        .map(|p| [2.0 * p[1], -2.0 * p[0], 2.0 * p[2] + 1.0])
        .collect();
    assert!(lengths.stretch_field_spread(&similar, 40) < 1e-12);
    // Half the sheet (x > 0) stretched along x by 20 %.
    let regional: Vec<[f64; 3]> = flat
        .iter()
        .map(|p| [if p[0] > 0.0 { 1.2 * p[0] } else { p[0] }, p[1], p[2]])
        .collect();
    // Noise across the sheet, scaled to the same per-edge spread.
    let jitter: Vec<[f64; 3]> = flat
        .iter()
        .map(|_| {
            [
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                0.0,
            ]
        })
        .collect();
    let noisy = |a: f64| -> Vec<[f64; 3]> {
        flat.iter()
            .zip(&jitter)
            .map(|(p, j)| [p[0] + a * j[0], p[1] + a * j[1], p[2]])
            .collect()
    };
    let target = lengths.spread(&regional);
    let (mut lo, mut hi) = (0.0, 0.1);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if lengths.spread(&noisy(mid)) < target {
            lo = mid
        } else {
            hi = mid
        }
    }
    let noise = noisy(lo);
    assert_relative_eq!(lengths.spread(&noise), target, max_relative = 1e-3);
    let (kept, averaged) = (
        lengths.stretch_field_spread(&regional, 40),
        lengths.stretch_field_spread(&noise, 40),
    );
    assert!(kept > 0.5 * target, "{kept:.4} of {target:.4}");
    assert!(averaged < 0.2 * kept, "{averaged:.5} against {kept:.4}");
    // Without smoothing rounds the two are of one order.
    assert!(
        lengths.stretch_field_spread(&noise, 0) > 0.3 * lengths.stretch_field_spread(&regional, 0)
    );
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn brute_nearest(from: &[[f64; 3]], to: &[[f64; 3]]) -> Vec<f64> {
    from.iter()
        .map(|p| to.iter().map(|q| dist(p, q)).fold(f64::INFINITY, f64::min))
        .collect()
}

fn brute_hausdorff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let ab = brute_nearest(a, b).into_iter().fold(0.0, f64::max);
    let ba = brute_nearest(b, a).into_iter().fold(0.0, f64::max);
    ab.max(ba)
}

fn brute_percentile(v: &[f64], p: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let h = (s.len() - 1) as f64 * p / 100.0;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(s.len() - 1);
    s[lo] + (h - lo as f64) * (s[hi] - s[lo])
}

fn tri_area_normal(p: &[[f64; 3]], f: &[u32; 3]) -> (f64, [f64; 3]) {
    let a = p[f[0] as usize];
    let b = p[f[1] as usize];
    let c = p[f[2] as usize];
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    (0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt(), n)
}

/// Returns (f_S, f_E, f_F, degenerate count) by a plain loop.
fn brute_faces(
    y: &[[f64; 3]],
    yh: &[[f64; 3]],
    faces: &[[u32; 3]],
    p: &MetricsParams,
) -> (f64, f64, f64, usize) {
    let diag = {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for q in y {
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        dist(&lo, &hi)
    };
    let (mut s, mut e, mut fl, mut deg, mut n) = (0, 0, 0, 0, 0);
    for f in faces {
        let (a, na) = tri_area_normal(y, f);
        if a <= p.degenerate_area_rel * diag * diag {
            deg += 1;
            continue;
        }
        n += 1;
        let (b, nb) = tri_area_normal(yh, f);
        s += usize::from(b / a < p.tau_s);
        e += usize::from(b / a > p.tau_e);
        fl += usize::from(na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2] < 0.0);
    }
    let frac = |k: usize| if n == 0 { 0.0 } else { k as f64 / n as f64 };
    (frac(s), frac(e), frac(fl), deg)
}

fn random_points(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<[f64; 3]> {
    (0..n)
        .map(|_| {
            [
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
            ]
        })
        .collect()
}

/// A (nx × ny) grid in the xy-plane with a little z noise, triangulated.
fn grid_mesh(rng: &mut ChaCha8Rng, nx: usize, ny: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            v.push([
                i as f64 / (nx - 1) as f64,
                j as f64 / (ny - 1) as f64,
                rng.random_range(-0.02..0.02),
            ]);
        }
    }
    let mut f = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let b = a + 1;
            let c = a + nx as u32;
            let d = c + 1;
            f.push([a, b, d]);
            f.push([a, d, c]);
        }
    }
    (v, f)
}

fn input<'a>(
    y: &'a [[f64; 3]],
    f: &'a [[u32; 3]],
    yh: &'a [[f64; 3]],
    x: &'a [[f64; 3]],
    g: Option<&'a [[f64; 3]]>,
) -> MetricsInput<'a> {
    MetricsInput {
        template_vertices: y,
        faces: f,
        fitted_vertices: yh,
        target: x,
        ground_truth: g,
    }
}

fn single_triangle() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    (
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
}

// ---------- helpers vs brute force ----------

#[test]
fn nearest_distances_match_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for &(n, m) in &[(1, 1), (7, 3), (200, 150), (500, 40), (33, 700)] {
        let a = random_points(&mut rng, n, 1.0);
        let b = random_points(&mut rng, m, 2.0);
        let got = nearest_distances(&a, &b);
        let want = brute_nearest(&a, &b);
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert_relative_eq!(g, w, max_relative = 1e-12, epsilon = 1e-15);
        }
    }
}

#[test]
fn nearest_distances_with_duplicates_and_flat_axes() {
    // Many points on an axis-aligned plane and many exact duplicates (hard for k-d trees).
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let mut b: Vec<[f64; 3]> = (0..300)
        .map(|_| {
            [
                rng.random_range(0..5) as f64,
                rng.random_range(0..5) as f64,
                0.0,
            ]
        })
        .collect();
    b.extend(std::iter::repeat_n([0.5, 0.5, 0.0], 100));
    let a = random_points(&mut rng, 200, 3.0);
    let got = nearest_distances(&a, &b);
    let want = brute_nearest(&a, &b);
    for (g, w) in got.iter().zip(&want) {
        assert_relative_eq!(g, w, max_relative = 1e-12, epsilon = 1e-15);
    }
    // A point of the set is at distance exactly 0.
    assert_eq!(nearest_distances(&b, &b), vec![0.0; b.len()]);
}

#[test]
fn nearest_distances_empty_sets() {
    let a = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]];
    assert_eq!(nearest_distances(&a, &[]), vec![f64::INFINITY; 2]);
    assert!(nearest_distances(&[], &a).is_empty());
}

#[test]
fn hausdorff_matches_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    for &(n, m) in &[(1, 1), (10, 90), (250, 180)] {
        let a = random_points(&mut rng, n, 1.0);
        let b = random_points(&mut rng, m, 1.5);
        let h = hausdorff(&a, &b);
        assert_relative_eq!(h, brute_hausdorff(&a, &b), max_relative = 1e-12);
        assert_eq!(h, hausdorff(&b, &a), "symmetric");
    }
}

#[test]
fn hausdorff_known_values_and_conventions() {
    let a = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let b = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 3.0, 4.0]];
    // a ⊂ b: directed a→b = 0, b→a = 5.
    assert_relative_eq!(hausdorff(&a, &b), 5.0);
    assert_eq!(hausdorff(&a, &a), 0.0);
    assert_eq!(hausdorff(&[], &[]), 0.0);
    assert_eq!(hausdorff(&a, &[]), f64::INFINITY);
    assert_eq!(hausdorff(&[], &a), f64::INFINITY);
}

#[test]
fn percentile_matches_numpy_linear() {
    let v: Vec<f64> = (0..=100).rev().map(f64::from).collect();
    assert_eq!(percentile_linear(&v, 95.0), 95.0);
    assert_relative_eq!(percentile_linear(&[0.0, 10.0], 95.0), 9.5);
    assert_eq!(percentile_linear(&[3.0], 95.0), 3.0);
    assert_eq!(percentile_linear(&[4.0, 1.0, 3.0], 100.0), 4.0);
    assert_eq!(percentile_linear(&[4.0, 1.0, 3.0], 0.0), 1.0);
    assert!(percentile_linear(&[], 95.0).is_nan());
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    for n in [2usize, 3, 19, 20, 21, 101, 997] {
        let v: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
        assert_relative_eq!(
            percentile_linear(&v, 95.0),
            brute_percentile(&v, 95.0),
            max_relative = 1e-14
        );
    }
}

// ---------- evaluate vs brute force ----------

#[test]
fn evaluate_matches_brute_force_on_random_meshes() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let params = MetricsParams::default();
    let mut seen = [0usize; 3];
    for trial in 0..6 {
        let (mut y, mut faces) = grid_mesh(&mut rng, 9 + trial, 7);
        // A repeated-index face and a collinear face (first row, flattened): degenerate.
        for p in &mut y[..3] {
            p[2] = 0.0;
        }
        faces.push([0, 0, 1]);
        faces.push([0, 1, 2]);
        // Large noise so that collapsed / expanded / flipped faces all occur.
        let amp = 0.05 + 0.05 * trial as f64;
        let mut yh: Vec<[f64; 3]> = y
            .iter()
            .map(|p| {
                [
                    p[0] + rng.random_range(-amp..amp),
                    p[1] + rng.random_range(-amp..amp),
                    p[2] + rng.random_range(-amp..amp),
                ]
            })
            .collect();
        // Snap a few fitted vertices onto a grid neighbour: faces sharing that edge collapse.
        for k in [10 + trial, 20 + 2 * trial, 30] {
            yh[k] = yh[k + 1];
        }
        let x = random_points(&mut rng, 150 + 37 * trial, 0.8);
        let g: Vec<[f64; 3]> = y
            .iter()
            .map(|p| [p[0] + 0.01, p[1] - 0.02, p[2] + rng.random_range(-0.1..0.1)])
            .collect();
        let m = evaluate(&input(&y, &faces, &yh, &x, Some(&g)), &params).unwrap();

        let x_to_fit = brute_nearest(&x, &yh);
        let fit_to_x = brute_nearest(&yh, &x);
        let before = brute_hausdorff(&x, &y);
        let after = brute_hausdorff(&x, &yh);
        let s2f = x_to_fit.iter().sum::<f64>() / x.len() as f64;
        let f2s = fit_to_x.iter().sum::<f64>() / yh.len() as f64;
        let (fs, fe, ff, deg) = brute_faces(&y, &yh, &faces, &params);
        let rmse = (yh
            .iter()
            .zip(&g)
            .map(|(a, b)| dist(a, b).powi(2))
            .sum::<f64>()
            / y.len() as f64)
            .sqrt();
        let diag_x = {
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for q in &x {
                for k in 0..3 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
            dist(&lo, &hi)
        };

        let tol = 1e-12;
        assert_relative_eq!(m.hausdorff_before, before, max_relative = tol);
        assert_relative_eq!(m.hausdorff_after, after, max_relative = tol);
        assert_relative_eq!(m.f_h, after / before, max_relative = tol);
        assert_relative_eq!(m.scan_to_fit_mean, s2f, max_relative = tol);
        assert_relative_eq!(m.fit_to_scan_mean, f2s, max_relative = tol);
        assert_relative_eq!(m.chamfer, 0.5 * (s2f + f2s), max_relative = tol);
        assert_relative_eq!(
            m.scan_to_fit_p95,
            brute_percentile(&x_to_fit, 95.0),
            max_relative = tol
        );
        assert_eq!((m.f_s, m.f_e, m.f_f), (fs, fe, ff));
        assert_eq!(m.num_degenerate_faces, deg);
        assert_eq!(deg, 2);
        assert_eq!(m.num_faces, faces.len());
        assert_eq!(m.num_evaluated_faces, faces.len() - 2);
        assert_relative_eq!(m.rmse.unwrap(), rmse, max_relative = tol);
        assert_relative_eq!(m.target_diagonal, diag_x, max_relative = tol);
        assert_relative_eq!(m.f_r.unwrap(), rmse / diag_x, max_relative = tol);
        assert_eq!(m.f_lambda_terms, ["f_H", "f_S", "f_E", "f_F", "f_R"]);
        assert_relative_eq!(
            m.f_lambda,
            (after / before + fs + fe + ff + rmse / diag_x) / 5.0,
            max_relative = tol
        );
        seen[0] += m.num_collapsed_faces;
        seen[1] += m.num_expanded_faces;
        seen[2] += m.num_flipped_faces;
    }
    // The trials exercise every face class.
    assert!(seen.iter().all(|&k| k > 0), "{seen:?}");
}

#[test]
fn evaluate_is_deterministic_across_thread_counts() {
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    let (y, faces) = grid_mesh(&mut rng, 60, 50);
    let yh: Vec<[f64; 3]> = y
        .iter()
        .map(|p| {
            [
                p[0] * 1.1,
                p[1] + rng.random_range(-0.01..0.01),
                p[2] + 0.3 * p[0] * p[1],
            ]
        })
        .collect();
    let x = random_points(&mut rng, 7000, 1.0);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                evaluate(
                    &input(&y, &faces, &yh, &x, Some(&y)),
                    &MetricsParams::default(),
                )
                .unwrap()
            })
    };
    let one = run(1);
    for t in [2, 3, 8] {
        assert_eq!(run(t), one, "{t} threads");
    }
}

// ---------- analytic cases ----------

#[test]
fn scaled_triangle_is_expanded() {
    let (y, f) = single_triangle();
    let yh: Vec<[f64; 3]> = y.iter().map(|p| p.map(|c| 3.0 * c)).collect();
    let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
    // Area ratio 9 > 2.
    assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 1.0, 0.0));
    assert_eq!(m.num_expanded_faces, 1);
}

#[test]
fn shrunk_triangle_is_collapsed() {
    let (y, f) = single_triangle();
    let yh: Vec<[f64; 3]> = y.iter().map(|p| p.map(|c| 0.1 * c)).collect();
    let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
    // Area ratio 0.01 < 0.02.
    assert_eq!((m.f_s, m.f_e, m.f_f), (1.0, 0.0, 0.0));
    // A custom threshold below the ratio no longer counts it.
    let p = MetricsParams {
        tau_s: 0.005,
        ..MetricsParams::default()
    };
    assert_eq!(
        evaluate(&input(&y, &f, &yh, &y, None), &p).unwrap().f_s,
        0.0
    );
}

#[test]
fn mirrored_triangle_is_flipped() {
    let (y, f) = single_triangle();
    let yh: Vec<[f64; 3]> = y.iter().map(|p| [-p[0], p[1], p[2]]).collect();
    let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
    // Same area, normal reversed.
    assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 1.0));
}

#[test]
fn fully_collapsed_fitted_face_is_collapsed_not_flipped() {
    let (y, f) = single_triangle();
    let yh = vec![[0.2, 0.2, 0.2]; 3];
    let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
    assert_eq!((m.f_s, m.f_e, m.f_f), (1.0, 0.0, 0.0));
}

#[test]
fn identical_fit_and_template() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (y, f) = grid_mesh(&mut rng, 8, 6);
    let x = random_points(&mut rng, 100, 2.0);
    let m = evaluate(&input(&y, &f, &y, &x, None), &MetricsParams::default()).unwrap();
    assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 0.0));
    assert_eq!(m.f_h, 1.0);
    assert_eq!(m.hausdorff_before, m.hausdorff_after);
    assert_eq!(m.f_r, None);
    assert_eq!(m.rmse, None);
    assert_eq!(m.f_lambda_terms, ["f_H", "f_S", "f_E", "f_F"]);
    assert_relative_eq!(m.f_lambda, 0.25);
}

#[test]
fn fit_onto_target_vertices_gives_zero_distances() {
    let mut rng = ChaCha8Rng::seed_from_u64(32);
    let (y, f) = grid_mesh(&mut rng, 6, 6);
    let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0] + 0.5, p[1], p[2]]).collect();
    let m = evaluate(&input(&y, &f, &yh, &yh, None), &MetricsParams::default()).unwrap();
    assert_eq!(m.f_h, 0.0);
    assert_eq!(
        (
            m.chamfer,
            m.scan_to_fit_mean,
            m.scan_to_fit_p95,
            m.fit_to_scan_mean
        ),
        (0.0, 0.0, 0.0, 0.0)
    );
    assert_relative_eq!(m.hausdorff_before, 0.5, max_relative = 1e-12);
    assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 0.0));
}

#[test]
fn weights_leave_out_the_points_of_weight_zero() {
    // The fit lies on its scan's garment points; two "body" points lie 2 above it. Weighted 0,
    // they are out: the figures are those of the garment points alone (distances 0, the
    // garment's diagonal), whatever positive weight the others carry.
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let (y, f) = grid_mesh(&mut rng, 6, 6);
    let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0] + 0.5, p[1], p[2]]).collect();
    let mut x = yh.clone();
    x.push([yh[0][0], yh[0][1], yh[0][2] + 2.0]);
    x.push([yh[7][0], yh[7][1], yh[7][2] + 2.0]);
    let g = Some(&yh[..]);
    let params = MetricsParams::default();
    let mut w: Vec<f64> = (0..yh.len()).map(|j| 0.5 + (j % 3) as f64).collect();
    w.extend([0.0, 0.0]);
    let masked = evaluate_weighted(&input(&y, &f, &yh, &x, g), Some(&w), &params).unwrap();
    let garment = evaluate(&input(&y, &f, &yh, &yh, g), &params).unwrap();
    assert_eq!(masked, garment);
    assert_eq!((masked.scan_to_fit_mean, masked.f_h), (0.0, 0.0));
    // Without the weights the two points count: each at most 2 from the fitted surface (2
    // from their vertex; the jittered grid is nearly flat).
    let whole = evaluate_weighted(&input(&y, &f, &yh, &x, g), None, &params).unwrap();
    let two_points = 4.0 / x.len() as f64;
    assert!(
        (0.9 * two_points..=two_points).contains(&whole.scan_to_fit_mean),
        "{}",
        whole.scan_to_fit_mean
    );
    assert!(whole.target_diagonal > garment.target_diagonal);
    // Refused as a fit refuses them, naming the point.
    let bad = |w: &[f64]| {
        evaluate_weighted(&input(&y, &f, &yh, &x, g), Some(w), &params)
            .unwrap_err()
            .to_string()
    };
    assert!(bad(&w[1..]).contains("need one weight per scan point"));
    w[4] = f64::NAN;
    assert!(bad(&w).contains("target_weights[4]"));
    assert!(bad(&vec![0.0; x.len()]).contains("all zero"));
}

#[test]
fn zero_hausdorff_before() {
    let (y, f) = single_triangle();
    // Template already equals the target; fit stays → f_H = 0.
    let m = evaluate(&input(&y, &f, &y, &y, None), &MetricsParams::default()).unwrap();
    assert_eq!(m.hausdorff_before, 0.0);
    assert_eq!(m.f_h, 0.0);
    assert_eq!(m.f_lambda, 0.0);
    // Fit moves away → f_H = +∞, and so is f_λ.
    let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0], p[1], p[2] + 0.1]).collect();
    let m = evaluate(&input(&y, &f, &yh, &y, None), &MetricsParams::default()).unwrap();
    assert_eq!(m.f_h, f64::INFINITY);
    assert_eq!(m.f_lambda, f64::INFINITY);
}

#[test]
fn ground_truth_rmse_is_normalized_by_target_diagonal() {
    let (y, f) = single_triangle();
    // Target spans the unit cube: diagonal √3.
    let x = vec![[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, 0.9, 0.1]];
    let g: Vec<[f64; 3]> = y.iter().map(|p| [p[0] + 2.0, p[1], p[2]]).collect();
    // Fitted = ground truth + a constant offset (0, 0.3, 0.4) of length 0.5: RMSE = 0.5.
    let yh: Vec<[f64; 3]> = g.iter().map(|p| [p[0], p[1] + 0.3, p[2] + 0.4]).collect();
    let m = evaluate(&input(&y, &f, &yh, &x, Some(&g)), &MetricsParams::default()).unwrap();
    assert_relative_eq!(m.rmse.unwrap(), 0.5, max_relative = 1e-12);
    assert_relative_eq!(m.target_diagonal, 3f64.sqrt(), max_relative = 1e-12);
    assert_relative_eq!(m.f_r.unwrap(), 0.5 / 3f64.sqrt(), max_relative = 1e-12);
    assert_eq!(m.f_lambda_terms.last().unwrap(), "f_R");
    // Fit equal to the ground truth: f_R = 0.
    let m = evaluate(&input(&y, &f, &g, &x, Some(&g)), &MetricsParams::default()).unwrap();
    assert_eq!(m.f_r, Some(0.0));
    // A single-point target has zero diagonal: 0 / 0 = 0, x / 0 = +∞.
    let x1 = [[0.0, 0.0, 0.0]];
    let m = evaluate(&input(&y, &f, &g, &x1, Some(&g)), &MetricsParams::default()).unwrap();
    assert_eq!(m.f_r, Some(0.0));
    let m = evaluate(
        &input(&y, &f, &yh, &x1, Some(&g)),
        &MetricsParams::default(),
    )
    .unwrap();
    assert_eq!(m.f_r, Some(f64::INFINITY));
}

#[test]
fn degenerate_and_missing_faces() {
    let y = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let yh: Vec<[f64; 3]> = y.iter().map(|p| [p[0], p[1] * 10.0, p[2]]).collect();
    // [0,1,2] collinear, [1,1,3] repeated index: both degenerate; [0,1,3] expands ×10.
    let faces = vec![[0, 1, 2], [1, 1, 3], [0, 1, 3]];
    let m = evaluate(&input(&y, &faces, &yh, &y, None), &MetricsParams::default()).unwrap();
    assert_eq!(
        (m.num_faces, m.num_degenerate_faces, m.num_evaluated_faces),
        (3, 2, 1)
    );
    assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 1.0, 0.0));
    // All faces degenerate, or none at all: face terms 0 and out of f_λ.
    for faces in [vec![[0, 1, 2], [1, 1, 3]], vec![]] {
        let m = evaluate(&input(&y, &faces, &yh, &y, None), &MetricsParams::default()).unwrap();
        assert_eq!(m.num_evaluated_faces, 0);
        assert_eq!((m.f_s, m.f_e, m.f_f), (0.0, 0.0, 0.0));
        assert_eq!(m.f_lambda_terms, ["f_H"]);
        assert_eq!(m.f_lambda, m.f_h);
    }
}

// ---------- errors ----------

#[test]
fn shape_and_value_errors() {
    let (y, f) = single_triangle();
    let p = MetricsParams::default();
    let short = &y[..2];
    let shape_name = |r: Result<Metrics>| match r {
        Err(FoldMatchError::Shape { name, .. }) => name,
        other => panic!("expected Shape error, got {other:?}"),
    };
    assert_eq!(
        shape_name(evaluate(&input(&y, &f, short, &y, None), &p)),
        "fitted_vertices"
    );
    assert_eq!(
        shape_name(evaluate(&input(&y, &f, &y, &y, Some(short)), &p)),
        "ground_truth"
    );
    assert_eq!(
        shape_name(evaluate(&input(&y, &f, &y, &[], None), &p)),
        "target"
    );
    assert_eq!(
        shape_name(evaluate(&input(&[], &[], &[], &y, None), &p)),
        "template_vertices"
    );

    let bad = [[0.0, 0.0, 0.0], [1.0, f64::NAN, 0.0], [0.0, 1.0, 0.0]];
    match evaluate(&input(&y, &f, &bad, &y, None), &p) {
        Err(FoldMatchError::NonFinite { name, row, .. }) => {
            assert_eq!((name.as_str(), row), ("fitted_vertices", 1))
        }
        other => panic!("{other:?}"),
    }
    match evaluate(&input(&y, &[[0, 1, 3]], &y, &y, None), &p) {
        Err(FoldMatchError::FaceIndex {
            face,
            vertex,
            count,
            ..
        }) => assert_eq!((face, vertex, count), (0, 3, 3)),
        other => panic!("{other:?}"),
    }
    for bad in [
        MetricsParams { tau_s: -0.1, ..p },
        MetricsParams { tau_e: 0.0, ..p },
        MetricsParams {
            tau_e: f64::NAN,
            ..p
        },
        MetricsParams {
            degenerate_area_rel: f64::INFINITY,
            ..p
        },
    ] {
        assert!(matches!(
            evaluate(&input(&y, &f, &y, &y, None), &bad),
            Err(FoldMatchError::Parameter { .. })
        ));
    }
}

#[test]
fn serializes_with_paper_names() {
    let (y, f) = single_triangle();
    let m = evaluate(
        &input(&y, &f, &y, &[[0.0, 0.0, 1.0]], None),
        &MetricsParams::default(),
    )
    .unwrap();
    let json = serde_json::to_value(&m).unwrap();
    for key in [
        "f_H",
        "f_S",
        "f_E",
        "f_F",
        "f_R",
        "f_lambda",
        "f_lambda_terms",
        "chamfer",
        "scan_to_fit_mean",
        "scan_to_fit_p95",
        "fit_to_scan_mean",
        "hausdorff_before",
        "hausdorff_after",
        "num_faces",
        "num_degenerate_faces",
    ] {
        assert!(json.get(key).is_some(), "missing {key}");
    }
    assert!(json["f_R"].is_null());
}
