use super::*;
use crate::synthetic::{grid_sheet, sample_surface, SplitMix64};

/// Template vertices, faces and scan points.
type Sheet = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 3]>);

/// A flat 1 × 1 sheet of `n × n` vertices and a dense scan of it (6 points per face).
fn sheet(n: usize) -> Sheet {
    let (v, f) = grid_sheet(n, n, 1.0, 1.0);
    let scan = sample_surface(&v, &f, 6 * f.len(), &mut SplitMix64::new(7));
    (v, f, scan)
}

fn run(y: &[[f64; 3]], f: &[[u32; 3]], fit: &[[f64; 3]], scan: &[[f64; 3]]) -> Assessment {
    let input = AssessInput {
        template_vertices: y,
        faces: f,
        fitted_vertices: fit,
        scan,
    };
    assess(&input, &VerdictThresholds::default()).unwrap()
}

#[test]
fn the_template_on_its_own_scan_is_ok() {
    let (y, f, scan) = sheet(21);
    let a = run(&y, &f, &y, &scan);
    let q = &a.quality;
    assert_eq!(q.verdict, Verdict::Ok, "{:?}", q.reasons);
    assert!(q.fit_to_scan < 0.01 && q.scan_to_fit < 1e-12, "{q:?}");
    assert_eq!(q.flipped_share, 0.0);
    assert_eq!(q.collapsed_share, 0.0);
    assert!((q.edge_distortion - 1.0).abs() < 1e-12);
    assert!(a.support.iter().all(|&s| s));
    // Correspondences are each vertex's nearest scan point; residuals their distances.
    for (v, (&j, &d)) in a.correspondences.iter().zip(&a.residuals).enumerate() {
        let direct = crate::math::dist2(&y[v], &scan[j as usize]).sqrt();
        assert_eq!(d, direct);
        let best = scan
            .iter()
            .map(|x| crate::math::dist2(&y[v], x).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert_eq!(d, best);
    }
}

#[test]
fn a_collapsed_face_is_counted() {
    let (y, f, scan) = sheet(9);
    // Vertex (4, 4) moved onto its +x neighbour: the two faces sharing that edge lose all area.
    let v = 4 * 9 + 4;
    let mut fit = y.clone();
    fit[v] = y[v + 1];
    let q = run(&y, &f, &fit, &scan).quality;
    assert!(
        (q.collapsed_share * f.len() as f64 - 2.0).abs() < 1e-9,
        "{q:?}"
    );
}

#[test]
fn a_flipped_face_is_counted_but_a_turned_sheet_is_not() {
    let (y, f, scan) = sheet(9);
    // Vertex (4, 4) pushed 1.5 edges along +x, past its neighbour: faces on that side fold over.
    let v = 4 * 9 + 4;
    let mut fit = y.clone();
    fit[v][0] += 1.5 / 8.0;
    let q = run(&y, &f, &fit, &scan).quality;
    let flipped = q.flipped_share * f.len() as f64;
    assert!((1.0..=6.0).contains(&flipped.round()), "flipped {flipped}");
    // The whole sheet turned upside down (a rotation by π about x) flips nothing.
    let turned: Vec<[f64; 3]> = y.iter().map(|p| [p[0], -p[1], -p[2]]).collect();
    let q = run(&y, &f, &turned, &scan).quality;
    assert_eq!(q.flipped_share, 0.0);
}

#[test]
fn edge_distortion_ignores_scale_and_measures_stretch() {
    let (y, f, scan) = sheet(11);
    let scaled: Vec<[f64; 3]> = y.iter().map(|p| p.map(|c| 1000.0 * c)).collect();
    let q = run(&y, &f, &scaled, &scan).quality;
    assert!((q.edge_distortion - 1.0).abs() < 1e-9);
    // Stretched ×3 along x: edge ratios 1 (vertical), √5 (diagonal), 3 (horizontal); the
    // median is √5, so the distortions are √5, 1 and 3/√5, and the 95th percentile √5.
    let stretched: Vec<[f64; 3]> = y.iter().map(|p| [3.0 * p[0], p[1], p[2]]).collect();
    let q = run(&y, &f, &stretched, &scan).quality;
    assert!((q.edge_distortion - 5f64.sqrt()).abs() < 1e-9, "{q:?}");
    let strict = VerdictThresholds {
        edge_distortion: 2.0,
        ..VerdictThresholds::default()
    };
    let edge_reason = |q: &Quality| q.reasons.iter().any(|r| r.contains("edge-length"));
    assert!(
        !edge_reason(&q),
        "√5 is within the default threshold: {:?}",
        q.reasons
    );
    let q = judged(q, &strict);
    assert_eq!(q.verdict, Verdict::Suspicious);
    assert!(edge_reason(&q), "{:?}", q.reasons);
    assert_eq!(q.thresholds, strict);
}

#[test]
fn a_half_scanned_template_has_half_support() {
    let (y, f, scan) = sheet(21);
    let half: Vec<[f64; 3]> = scan.iter().copied().filter(|p| p[0] < 0.0).collect();
    let a = run(&y, &f, &y, &half);
    let r = a.quality.support_radius;
    for (v, p) in y.iter().enumerate() {
        if p[0] <= 0.0 {
            assert!(a.support[v], "vertex {v} at {p:?} is on the scan");
        } else if p[0] > r {
            assert!(!a.support[v], "vertex {v} at {p:?} is beyond the scan");
        }
    }
    let share = a.quality.unsupported_share;
    assert!((0.3..0.5).contains(&share), "{share}");
    assert!(a.quality.asymmetry > 0.5, "{:?}", a.quality);
}

/// A closed tube around the y axis (radius 0.3, length 1), `n` around × `k` along.
fn tube(n: usize, k: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    for j in 0..k {
        for i in 0..n {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            v.push([
                0.3 * t.cos(),
                j as f64 / (k - 1) as f64 - 0.5,
                0.3 * t.sin(),
            ]);
        }
    }
    let mut f = Vec::new();
    for j in 0..k - 1 {
        for i in 0..n {
            let a = (j * n + i) as u32;
            let b = (j * n + (i + 1) % n) as u32;
            let (c, d) = (a + n as u32, b + n as u32);
            f.push([a, b, d]);
            f.push([a, d, c]);
        }
    }
    (v, f)
}

#[test]
fn a_fit_pulled_through_itself_is_flagged_and_a_good_one_passes() {
    let (y, f) = tube(48, 25);
    let scan = sample_surface(&y, &f, 20_000, &mut SplitMix64::new(3));
    // A good fit: the tube with a gentle ripple (2 mm on a 1 m tube).
    let good: Vec<[f64; 3]> = y
        .iter()
        .map(|p| {
            let s = 1.0 + 0.007 * (6.0 * p[1]).sin();
            [s * p[0], p[1], s * p[2]]
        })
        .collect();
    let q = run(&y, &f, &good, &scan).quality;
    assert_eq!(q.verdict, Verdict::Ok, "{:?}", q.reasons);
    // Back to front: the back half pulled through onto the front (z → |z|), the failure of a
    // template started facing away: the sides fold over, the scan's back is left uncovered
    // and the two layers claim the same scan points.
    let through: Vec<[f64; 3]> = y.iter().map(|p| [p[0], p[1], p[2].abs()]).collect();
    let a = run(&y, &f, &through, &scan);
    let q = &a.quality;
    assert_eq!(q.verdict, Verdict::Suspicious);
    assert!(q.asymmetry < -0.5, "{q:?}");
    assert!(q.unsupported_share > 0.2, "{q:?}");
    for label in ["unsupported", "flipped"] {
        assert!(
            q.reasons.iter().any(|r| r.contains(label)),
            "{:?}",
            q.reasons
        );
    }
}

#[test]
fn bad_inputs_are_refused_by_name() {
    let (y, f, scan) = sheet(5);
    let short = &y[..y.len() - 1];
    let input = AssessInput {
        template_vertices: &y,
        faces: &f,
        fitted_vertices: short,
        scan: &scan,
    };
    let e = assess(&input, &VerdictThresholds::default()).unwrap_err();
    assert!(e.to_string().contains("fitted_vertices"), "{e}");
    let bad = VerdictThresholds {
        asymmetry: f64::NAN,
        ..VerdictThresholds::default()
    };
    let input = AssessInput {
        fitted_vertices: &y,
        ..input
    };
    let e = assess(&input, &bad).unwrap_err();
    assert!(e.to_string().contains("asymmetry"), "{e}");
}
