//! Scan weights (`ScanExtras::weights`, issue "Scans of dressed people"), the two-way trust radius and
//! the rim rule, against cases whose answer is known exactly.

use foldmatch::fit::{fit_scan, fit_simple, FitParams, FitResult, ScanExtras};
use foldmatch::nbody::{
    gravitational_force, pair_force, weighted_gravitational_force, NBodyParams, ReverseAttraction,
    TwoWay, TwoWayPull,
};
use foldmatch::synthetic::grid_sheet;
use foldmatch::FoldMatchError;
use nalgebra::Vector3;

/// Template vertices, its faces and a scan.
type Case = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 3]>);

/// A 13 × 13 sheet and a wavy, lifted scan of it with more points than vertices.
fn case() -> Case {
    let (v, f) = grid_sheet(13, 13, 1.0, 1.0);
    let (dense, _) = grid_sheet(21, 21, 1.1, 1.1);
    let scan = dense
        .iter()
        .map(|p| [p[0], p[1], 0.04 * (5.0 * p[0]).sin() + 0.03])
        .collect();
    (v, f, scan)
}

fn params() -> FitParams {
    {
        let mut p = FitParams::default();
        p.iterations = 30;
        p
    }
}

fn weighted(w: Option<&[f64]>) -> foldmatch::Result<FitResult> {
    let (v, f, x) = case();
    let extras = ScanExtras {
        weights: w,
        ..ScanExtras::default()
    };
    fit_scan(&v, &f, &x, &extras, &params(), &mut |_| true)
}

#[test]
fn a_zero_one_mask_fits_exactly_as_the_masked_scan() {
    let (v, f, x) = case();
    let mask: Vec<f64> = (0..x.len()).map(|j| f64::from(j % 3 != 0)).collect();
    let masked: Vec<[f64; 3]> = x
        .iter()
        .zip(&mask)
        .filter(|(_, &w)| w > 0.0)
        .map(|(p, _)| *p)
        .collect();
    let with_mask = weighted(Some(&mask)).unwrap();
    let subset = fit_simple(&v, &f, &masked, None, &params()).unwrap();
    assert_eq!(with_mask.vertices, subset.vertices);
}

#[test]
fn equal_weights_fit_exactly_as_no_weights() {
    let n = case().2.len();
    let none = weighted(None).unwrap();
    for c in [1.0, 0.25, 7.0] {
        assert_eq!(weighted(Some(&vec![c; n])).unwrap().vertices, none.vertices);
    }
}

#[test]
fn unequal_weights_change_the_fit() {
    let n = case().2.len();
    let w: Vec<f64> = (0..n).map(|j| 1.0 + (j % 2) as f64).collect();
    assert_ne!(
        weighted(Some(&w)).unwrap().vertices,
        weighted(None).unwrap().vertices
    );
}

#[test]
fn bad_weights_are_refused_with_the_culprit_named() {
    let n = case().2.len();
    let message = |w: &[f64]| match weighted(Some(w)) {
        Err(e @ FoldMatchError::Parameter { .. }) => e.to_string(),
        other => panic!(
            "expected a parameter error, got {:?}",
            other.map(|r| r.iterations)
        ),
    };
    assert!(message(&[1.0; 3]).contains("one weight per scan point"));
    let mut w = vec![1.0; n];
    w[5] = -1.0;
    assert!(message(&w).contains("target_weights[5]"));
    w[5] = f64::NAN;
    assert!(message(&w).contains("target_weights[5]"));
    w[5] = f64::INFINITY;
    assert!(message(&w).contains("target_weights[5]"));
    assert!(message(&vec![0.0; n]).contains("all zero"));
}

#[test]
fn the_weighted_force_is_the_weighted_mean_of_the_pair_forces() {
    let p = NBodyParams::default();
    let target = [
        [0.1, 0.0, 0.0],
        [0.0, 0.2, 0.1],
        [-0.1, -0.1, 0.0],
        [0.3, 0.1, -0.2],
    ];
    let kappa = [0.5, -1.0, 0.0, 2.0];
    let w = [2.0, 0.0, 0.5, 1.5];
    let y = Vector3::new(0.05, 0.02, 0.3);
    let all = [0u32, 1, 2, 3];
    let got = weighted_gravitational_force(&y, &all, &target, &kappa, Some(&w), None, &p);
    let mut want = Vector3::zeros();
    for j in 0..4 {
        want += w[j] * pair_force(&y, &Vector3::from(target[j]), kappa[j], &p);
    }
    want /= w.iter().sum::<f64>();
    assert!((got - want).norm() < 1e-14 * want.norm());
    // No weights is the plain mean; all neighbours of weight 0 pull nothing.
    let plain = weighted_gravitational_force(&y, &all, &target, &kappa, None, None, &p);
    assert_eq!(plain, gravitational_force(&y, &all, &target, &kappa, &p));
    let zero = weighted_gravitational_force(&y, &[1], &target, &kappa, Some(&w), None, &p);
    assert_eq!(zero, Vector3::zeros());
    // The rim: with the outward direction +x and margin 0.05, the neighbours at x = 0.1 and
    // 0.3 (beyond y's x = 0.05 by 0.05 + ...) weigh 0: the force is the weighted mean of the
    // other two.
    let o = Vector3::new(1.0, 0.0, 0.0);
    let rim =
        weighted_gravitational_force(&y, &all, &target, &kappa, Some(&w), Some((o, 0.04)), &p);
    let kept = weighted_gravitational_force(&y, &[1, 2], &target, &kappa, Some(&w), None, &p);
    assert!((rim - kept).norm() < 1e-14 * kept.norm());
}

/// The two-way pulls on two template points from four scan points: three near the first, one
/// far from both.
fn two_way(trust_radius: f64, rim: Option<(&[[f64; 3]], f64)>) -> [Vector3<f64>; 2] {
    let template = [[0.0; 3], [1.0, 0.0, 0.0]];
    let scan = [
        [0.05, 0.0, 0.0],
        [0.0, 0.05, 0.0],
        [-0.05, 0.0, 0.0],
        [3.0, 0.0, 0.0],
    ];
    let kappa = [0.0; 4];
    let mut reverse = ReverseAttraction::new(2, 4, false);
    let forward = foldmatch::knn::TargetNeighbours {
        indices: &[0, 0],
        dist2: &[0.0, 0.0],
        k: 1,
        exact: true,
    };
    let settings = TwoWay {
        weight: 1.0,
        pull: TwoWayPull::Coverage,
        trust_radius,
        rim,
        weights: None,
    };
    let mut out = [[0.0; 3]; 2];
    let p = NBodyParams::default();
    reverse.compute(&template, &scan, &kappa, forward, &settings, &p, &mut out);
    out.map(Vector3::from)
}

#[test]
fn scan_points_beyond_the_trust_radius_or_the_rim_pull_nothing() {
    let p = NBodyParams::default();
    let far = pair_force(
        &Vector3::new(1.0, 0.0, 0.0),
        &Vector3::new(3.0, 0.0, 0.0),
        0.0,
        &p,
    );
    let all = two_way(f64::INFINITY, None);
    // Every point pulls: the far point pulls the second template point (share M / N = 2 / 4).
    assert!((all[1] - 0.5 * far).norm() < 1e-14 * far.norm());
    // Within a radius of 1, the far point pulls nothing, and the three near ones are the whole
    // scan weight: share 2 / 3.
    let trusted = two_way(1.0, None);
    assert_eq!(trusted[1], Vector3::zeros());
    assert!((trusted[0] - all[0] * (4.0 / 3.0)).norm() < 1e-14 * all[0].norm());
    // The rim: the second point's outward direction +x; the far point lies beyond it.
    let outward = [[0.0; 3], [1.0, 0.0, 0.0]];
    let rim = two_way(f64::INFINITY, Some((&outward, 0.5)));
    assert_eq!(rim[1], Vector3::zeros());
    assert_eq!(rim[0], trusted[0]);
}

#[test]
fn a_garment_inside_a_larger_scan_is_fitted_in_its_own_frame() {
    // The sheet's scan plus a distant clutter twice as wide: the frame is the sheet's (its
    // scale about the sheet scan's diagonal), and the clutter does not drag the fit away.
    let (v, f, x) = case();
    let clutter: Vec<[f64; 3]> = (0..600)
        .map(|i| {
            let t = i as f64 / 600.0;
            [-1.5 + 4.0 * t, 2.0 - 0.5 * (13.0 * t).sin(), -0.8]
        })
        .collect();
    let whole: Vec<[f64; 3]> = x.iter().chain(&clutter).copied().collect();
    let alone = fit_simple(&v, &f, &x, None, &params()).unwrap();
    let dressed = fit_simple(&v, &f, &whole, None, &params()).unwrap();
    let scale = |r: &FitResult| r.diagnostics.frame.unwrap().scale;
    assert!((scale(&dressed) / scale(&alone) - 1.0).abs() < 0.1);
    let rms = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        (a.iter()
            .zip(b)
            .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>())
            .sum::<f64>()
            / a.len() as f64)
            .sqrt()
    };
    let untrusted = {
        let mut p = params();
        p.schedule.two_way_trust = 0.0;
        p
    };
    let dragged = fit_simple(&v, &f, &whole, None, &untrusted).unwrap();
    let off = rms(&dressed.vertices, &alone.vertices);
    assert!(
        off < 0.25 * rms(&dragged.vertices, &alone.vertices),
        "with the trust radius {off}, without {}",
        rms(&dragged.vertices, &alone.vertices)
    );
}
