//! Carrying the vertices without scan support (docs/method.md "Partial scans").

use super::*;
use crate::math::dist2;
use crate::synthetic::{sample_surface, SplitMix64};

/// An open tube of radius `r` and height 0.8 along y, `around` × `rows` vertices.
fn tube(r: impl Fn(f64) -> f64, around: usize, rows: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    for j in 0..rows {
        let y = 0.8 * j as f64 / (rows - 1) as f64;
        for i in 0..around {
            let t = std::f64::consts::TAU * i as f64 / around as f64;
            v.push([r(y) * t.cos(), y, r(y) * t.sin()]);
        }
    }
    let mut f = Vec::new();
    for j in 0..rows - 1 {
        for i in 0..around {
            let (a, b) = (
                (j * around + i) as u32,
                (j * around + (i + 1) % around) as u32,
            );
            let (c, d) = (a + around as u32, b + around as u32);
            f.push([a, b, d]);
            f.push([a, d, c]);
        }
    }
    (v, f)
}

/// A tube template, its flared truth and a scan of the truth's front half (x > 0), as one
/// camera side sees it.
/// Template, faces, truth and scan.
type HalfTube = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>);

fn half_tube_case() -> HalfTube {
    let (template, faces) = tube(|_| 0.3, 64, 25);
    let (truth, _) = tube(|y| 0.3 * (1.0 + 0.25 * y), 64, 25);
    let mut rng = SplitMix64::new(7);
    let scan: Vec<[f64; 3]> = sample_surface(&truth, &faces, 12000, &mut rng)
        .into_iter()
        .filter(|p| p[0] > 0.0)
        .collect();
    (template, faces, truth, scan)
}

fn rms(a: &[[f64; 3]], b: &[[f64; 3]], which: &[usize]) -> f64 {
    let s: f64 = which.iter().map(|&v| dist2(&a[v], &b[v])).sum();
    (s / which.len() as f64).sqrt()
}

#[test]
fn the_unscanned_back_of_a_half_scan_is_carried_not_collapsed() {
    let (template, faces, truth, scan) = half_tube_case();
    let back: Vec<usize> = (0..template.len())
        .filter(|&v| template[v][0] < -0.15)
        .collect();
    let fitted = |carry: f64| {
        let mut p = FitParams::default();
        p.schedule.carry_unsupported = carry;
        fit_simple(&template, &faces, &scan, None, &p).unwrap()
    };
    let attracted = fitted(0.0);
    let carried = fitted(ONE_SIDED_CARRY);
    let (e_attracted, e_carried) = (
        rms(&attracted.vertices, &truth, &back),
        rms(&carried.vertices, &truth, &back),
    );
    // The back stays behind the scanned front, near its true place; attracted, it is drawn
    // onto the front.
    let mean_x =
        |r: &FitResult| back.iter().map(|&v| r.vertices[v][0]).sum::<f64>() / back.len() as f64;
    assert!(
        e_carried < 0.5 * e_attracted,
        "back RMS carried {e_carried} vs attracted {e_attracted}"
    );
    assert!(
        mean_x(&carried) < -0.15 && mean_x(&carried) < 2.0 * mean_x(&attracted),
        "back at x {} carried, {} attracted",
        mean_x(&carried),
        mean_x(&attracted)
    );
    // The scanned front fits as well either way.
    let front: Vec<usize> = (0..template.len())
        .filter(|&v| template[v][0] > 0.15)
        .collect();
    assert!(
        rms(&carried.vertices, &truth, &front)
            < 1.5 * rms(&attracted.vertices, &truth, &front) + 0.005,
        "front RMS carried {} vs attracted {}",
        rms(&carried.vertices, &truth, &front),
        rms(&attracted.vertices, &truth, &front)
    );
}

#[test]
fn a_whole_scan_has_nothing_to_carry() {
    // Every vertex has its scan: the fit is the same with and without the setting.
    let (template, faces, truth, _) = half_tube_case();
    let mut rng = SplitMix64::new(8);
    let scan = sample_surface(&truth, &faces, 12000, &mut rng);
    let fitted = |carry: f64| {
        let mut p = FitParams::default();
        p.schedule.carry_unsupported = carry;
        fit_simple(&template, &faces, &scan, None, &p)
            .unwrap()
            .vertices
    };
    assert_eq!(fitted(0.0), fitted(ONE_SIDED_CARRY));
}

#[test]
fn carry_unsupported_is_refused_when_negative() {
    for bad in [-1.0, f64::NAN] {
        let mut p = FitParams::default();
        p.schedule.carry_unsupported = bad;
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("carry_unsupported"), "{e}");
    }
}
