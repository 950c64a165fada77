//! Analytic cases: a known rotation, translation and scale recovered on an asymmetric shape;
//! the placement as given kept on an aligned input.

use super::*;
use crate::math::{vec3, Mat3, Vec3};
use approx::assert_relative_eq;
use nalgebra::{Rotation3, Unit};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `p` with each coordinate moved by a uniform draw in ±`noise` / 2 (x, y, z in turn).
fn jittered(p: [f64; 3], noise: f64, rng: &mut ChaCha8Rng) -> [f64; 3] {
    p.map(|c| c + noise * (rng.random::<f64>() - 0.5))
}

/// `count` points on an asymmetric bent, bumped sheet (no symmetry of the cube group maps it
/// onto itself): 0.8 × 0.5, bent up along x, a bump off-centre, a flap on one corner.
fn asymmetric_surface(count: usize, noise: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let (u, v): (f64, f64) = (rng.random(), rng.random());
            let x = 0.8 * u;
            let y = 0.5 * v;
            let bump = 0.08 * (-((x - 0.55).powi(2) + (y - 0.15).powi(2)) / 0.01).exp();
            let flap = if u > 0.8 && v > 0.7 {
                0.3 * (u - 0.8)
            } else {
                0.0
            };
            let z = 0.25 * u * u + bump + flap;
            jittered([x, y, z], noise, &mut rng)
        })
        .collect()
}

/// A noisy scan of the surface of `asymmetric_surface(_, _, 10)` with folds along x (cloth
/// draped otherwise than its template), moved by 0.03 along x and scaled by `scale`.
fn folded_scan(scale: f64) -> Vec<[f64; 3]> {
    asymmetric_surface(3000, 0.002, 11)
        .into_iter()
        .map(|[x, y, z]| {
            let z = z + 0.08 * (std::f64::consts::TAU * x / 0.2).sin();
            [scale * (x + 0.03), scale * y, scale * z]
        })
        .collect()
}

fn rotation(axis: [f64; 3], degrees: f64) -> Mat3 {
    *Rotation3::from_axis_angle(&Unit::new_normalize(vec3(&axis)), degrees.to_radians()).matrix()
}

/// The rigid turn by `degrees` about the z axis through the origin.
fn turn_about_z(degrees: f64) -> Similarity {
    Similarity {
        rotation: rotation([0.0, 0.0, 1.0], degrees),
        scale: 1.0,
        translation: Vec3::zeros(),
    }
}

/// The rigid alignment of `template` onto `scan`, whose placement as given scores within
/// [`PLACED`] (asserted): by its score alone, the template looks placed.
fn align_looking_placed(template: &[[f64; 3]], scan: &[[f64; 3]]) -> Alignment {
    let got = align(template, scan, Motion::Rigid);
    let radius = principal_axes(scan).rms_radius;
    assert!(got.identity_score <= PLACED * radius, "{got:?}");
    got
}

fn angle_between(a: &Mat3, b: &Mat3) -> f64 {
    let at = |rotation: &Mat3| Similarity {
        rotation: *rotation,
        ..Similarity::identity()
    };
    at(b).turned_from(&at(a))
}

#[test]
fn a_rotated_shifted_copy_is_recovered_exactly() {
    let template = asymmetric_surface(3000, 0.0, 1);
    for (axis, degrees) in [
        ([0.2, 1.0, -0.4], 150.0),
        ([1.0, 0.0, 0.0], 90.0),
        ([1.0, 1.0, 1.0], 60.0),
    ] {
        let truth = Similarity {
            rotation: rotation(axis, degrees),
            scale: 1.0,
            translation: Vec3::new(0.9, -0.3, 0.4),
        };
        let scan = truth.apply_all(&template);
        let got = align(&template, &scan, Motion::Rigid);
        assert!(got.searched);
        assert!(
            (got.transform.rotation - truth.rotation).norm() < 1e-7,
            "{got:?}"
        );
        assert_relative_eq!(got.transform.translation, truth.translation, epsilon = 1e-7);
        assert_eq!(got.transform.scale, 1.0);
        assert!(got.score < 1e-7 && got.identity_score > 0.1, "{got:?}");
        // One orientation fits: the shape has no symmetry.
        assert_eq!(got.readings, 1, "{got:?}");
    }
}

#[test]
fn a_symmetric_template_reports_its_readings() {
    // A flat square grid turned 90° about an oblique axis and moved: its four turns about its
    // normal and their flips all fit the scan alike; the search says so.
    let square: Vec<[f64; 3]> = (0..900)
        .map(|i| [(i % 30) as f64 / 29.0, (i / 30) as f64 / 29.0, 0.0])
        .collect();
    let turned = Similarity {
        rotation: rotation([1.0, 2.0, -1.5], 90.0),
        scale: 1.0,
        translation: Vec3::new(3.0, -1.0, 2.0),
    };
    // Scanned with noise (an exact copy's one exact match scores 0, the others a hair above).
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let scan: Vec<[f64; 3]> = square
        .iter()
        .map(|p| p.map(|x| x + 0.004 * (rng.random::<f64>() - 0.5)))
        .collect();
    let got = align(&square, &turned.apply_all(&scan), Motion::Rigid);
    // On the grid within half its spacing.
    assert!(got.searched && got.score < 0.5 / 29.0, "{got:?}");
    assert!(got.readings >= 4, "{got:?}");
    // Placed already: kept as given.
    let placed = align(&square, &square, Motion::Rigid);
    assert!(
        placed.transform.is_identity() && placed.searched,
        "{placed:?}"
    );
}

#[test]
fn a_resampled_noisy_scan_turned_and_scaled_is_recovered() {
    let template = asymmetric_surface(2500, 0.0, 2);
    let truth = Similarity {
        rotation: rotation([0.5, -1.0, 0.3], 120.0),
        scale: 1000.0, // the template in metres, the scan in millimetres
        translation: Vec3::new(200.0, 50.0, -900.0),
    };
    // Another sample of the same surface, with noise of 0.5 % of its size.
    let scan = truth.apply_all(&asymmetric_surface(4000, 0.005, 3));
    let got = align(&template, &scan, Motion::Similarity);
    assert!(
        angle_between(&got.transform.rotation, &truth.rotation) < 1.0,
        "{got:?}"
    );
    assert_relative_eq!(got.transform.scale, truth.scale, max_relative = 0.01);
    // The template's points land within 1 % of its size (scan units) of the truth's.
    for p in template.iter().step_by(50) {
        let d = (vec3(&got.transform.apply(p)) - vec3(&truth.apply(p))).norm();
        assert!(d < 0.01 * 1000.0, "{d}");
    }
    // The rigid mode cannot change the scale.
    assert_eq!(align(&template, &scan, Motion::Rigid).transform.scale, 1.0);
}

#[test]
fn an_aligned_scan_keeps_the_placement_as_given() {
    let template = asymmetric_surface(2000, 0.0, 4);
    let scan = asymmetric_surface(3000, 0.004, 5);
    for motion in [Motion::Rigid, Motion::Similarity] {
        let got = align(&template, &scan, motion);
        assert!(got.transform.is_identity());
        assert_eq!(got.score, got.identity_score);
        // Searched all the same: nothing lies closer than the placement as given.
        assert!(
            got.searched && got.best_score > 0.5 * got.identity_score,
            "{got:?}"
        );
    }
    // Slightly off (3°, a small shift) is still "placed": the fit's own rigid phase finishes it.
    let nudged = Similarity {
        rotation: rotation([0.0, 0.0, 1.0], 3.0),
        scale: 1.0,
        translation: Vec3::new(0.01, 0.0, 0.0),
    };
    let got = align(&template, &nudged.apply_all(&scan), Motion::Rigid);
    assert!(got.transform.is_identity(), "{got:?}");
}

/// `count` points on a skirt-like tube about z (height 2, widening downwards) whose radius
/// varies about the axis as 1 + 0.1 cos 2θ + 0.1 sin 3θ: turned half a turn about its axis it
/// lies on itself within a few per cent of its radius (the cos 2θ part is symmetric), but no
/// rotation maps it onto itself.
fn skirt_tube(count: usize, noise: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let (u, v): (f64, f64) = (rng.random(), rng.random());
            let theta = std::f64::consts::TAU * u;
            let r = 1.0 + 0.1 * (2.0 * theta).cos() + 0.1 * (3.0 * theta).sin() + 0.2 * (1.0 - v);
            jittered([r * theta.cos(), r * theta.sin(), 2.0 * v], noise, &mut rng)
        })
        .collect()
}

#[test]
fn a_tube_turned_back_to_front_is_turned_back() {
    // Half a turn about its axis, the tube lies within `PLACED` of its scan as given (a skirt
    // whose front and back differ a little), but the search finds the placement that fits.
    let template = skirt_tube(2000, 0.0, 21);
    let half_turn = turn_about_z(180.0);
    let scan = half_turn.apply_all(&skirt_tube(3000, 0.004, 22));
    let got = align_looking_placed(&template, &scan);
    assert!(
        got.searched && got.score < 0.5 * got.identity_score,
        "{got:?}"
    );
    // Within the pre-alignment's resolution on these samples; the fit's rigid phase finishes it.
    assert_relative_eq!(got.transform.angle_degrees(), 180.0, epsilon = SAME_ANGLE);
    // Unturned, it stays as given.
    let placed = align(&template, &skirt_tube(3000, 0.004, 22), Motion::Rigid);
    assert!(placed.transform.is_identity(), "{placed:?}");
}

#[test]
fn degenerate_inputs_give_the_identity() {
    let scan = asymmetric_surface(100, 0.0, 6);
    let got = align(&scan[..2], &scan, Motion::Rigid);
    assert!(got.transform.is_identity() && !got.searched);
    let same = vec![[1.0, 1.0, 1.0]; 10];
    assert!(align(&same, &scan, Motion::Similarity)
        .transform
        .is_identity());
}

#[test]
fn a_template_on_part_of_a_larger_scene_keeps_its_placement() {
    // The surface inside a scene three times its size (a dressed body's other points): a
    // box of points around it. Two-sided, the scene's points are far from the template; the
    // template's own distance to the scan says it is placed.
    let template = asymmetric_surface(2000, 0.0, 7);
    let mut scan = asymmetric_surface(3000, 0.002, 8);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..6000 {
        let p: [f64; 3] = [rng.random(), rng.random(), rng.random()];
        scan.push([3.0 * p[0] - 1.1, 3.0 * p[1] - 1.2, 3.0 * p[2] - 1.3]);
    }
    let got = align(&template, &scan, Motion::Rigid);
    assert!(got.transform.is_identity() && !got.searched, "{got:?}");
    // Not by the two-sided score, which the scene's points dominate.
    let radius = principal_axes(&scan).rms_radius;
    assert!(got.identity_score > PLACED * radius, "{got:?}");
}

#[test]
fn a_roughly_placed_template_of_a_deformed_scan_is_left_to_the_fit() {
    // The scan is the surface with folds (cloth draped differently from its template) and
    // slightly moved: the placement as given is rough (above PLACED), and a rigid match of the
    // unfolded shape is no better placement than the one given.
    let template = asymmetric_surface(2000, 0.0, 10);
    let bent = folded_scan(1.0);
    let got = align(&template, &bent, Motion::Rigid);
    assert!(got.searched, "{got:?}");
    assert!(got.transform.is_identity(), "{got:?}");
    // The same scan turned by 90° about the vertical is found again: its placement as given
    // is not in the best basin.
    let turned = turn_about_z(90.0);
    let got = align(&template, &turned.apply_all(&bent), Motion::Rigid);
    assert!(
        angle_between(&got.transform.rotation, &turned.rotation) < 15.0,
        "{got:?}"
    );
}

#[test]
fn finalists_are_the_distinct_near_best_coarse_placements() {
    let at = |degrees: f64, x: f64| Similarity {
        rotation: rotation([0.0, 1.0, 0.0], degrees),
        scale: 1.0,
        translation: Vec3::new(x, 0.0, 0.0),
    };
    let coarse = [
        (at(30.0, 0.0), 1.2),
        (at(0.0, 0.0), 1.0),
        (at(0.5, 0.001), 1.01), // the same placement as the best
        (at(90.0, 0.0), 1.4),
        (at(0.0, 0.5), 1.45),  // moved: another placement
        (at(180.0, 0.0), 1.6), // beyond the coarse margin
    ];
    let got = finalists(&coarse, 1.0);
    let angles: Vec<f64> = got.iter().map(|t| t.angle_degrees().round()).collect();
    assert_eq!(angles, vec![0.0, 30.0, 90.0, 0.0]);
    assert_eq!(got[3].translation.x, 0.5);
}

#[test]
fn a_deformed_scan_in_other_units_is_rescaled_even_where_the_given_basin_ties() {
    // The folded scan of `a_roughly_placed_template_of_a_deformed_scan_is_left_to_the_fit`,
    // 1.5 times the size (other units): the basin of the placement as given, refined with the
    // scale free, ties with the best, but it rescales the template — the placement as given
    // was not right, and is not kept.
    let template = asymmetric_surface(2000, 0.0, 10);
    let bent = folded_scan(1.5);
    let got = align(&template, &bent, Motion::Similarity);
    assert!(got.searched && !got.transform.is_identity(), "{got:?}");
    assert!((got.transform.scale / 1.5 - 1.0).abs() < 0.2, "{got:?}");
}

#[test]
fn a_template_on_part_of_its_scan_twice_the_size_is_rescaled_with_the_similarity() {
    // A flat 0.8 × 0.5 template and the scan of the same sheet twice the size (other units),
    // sharing a corner: the template lies on a quarter of the scan. Rigidly that is a scene
    // and the placement is kept; with the scale free a larger scan is no scene, so the
    // similarity is searched and finds the scale.
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let mut sheet = |count: usize, size: f64, noise: f64| -> Vec<[f64; 3]> {
        (0..count)
            .map(|_| {
                let (u, v): (f64, f64) = (rng.random(), rng.random());
                let n = noise * (rng.random::<f64>() - 0.5);
                [size * 0.8 * u, size * 0.5 * v, n]
            })
            .collect()
    };
    let template = sheet(2000, 1.0, 0.0);
    let scan = sheet(6000, 2.0, 0.004);
    let rigid = align(&template, &scan, Motion::Rigid);
    assert!(
        !rigid.searched && rigid.transform.is_identity(),
        "{rigid:?}"
    );
    let got = align(&template, &scan, Motion::Similarity);
    assert!(got.searched && !got.transform.is_identity(), "{got:?}");
    assert!((got.transform.scale / 2.0 - 1.0).abs() < 0.15, "{got:?}");
}

#[test]
fn the_search_does_not_depend_on_the_scan_s_unit_or_position() {
    // A tube skirt folded sideways and turned 20° (not placed: searched), in other units and
    // moved elsewhere: the similarity's rotation is the same whatever the unit and position,
    // its scale and translation follow them. With the scale free, the template's own
    // orientation is a candidate placed as the principal-frame ones are (centroids and RMS
    // radii matched), not where the template happens to lie (as it lay, the search's results
    // were up to 5° apart).
    let template = skirt_tube(2000, 0.0, 21);
    let turn = Similarity {
        rotation: rotation([0.3, 1.0, -0.2], 20.0),
        ..Similarity::identity()
    };
    let folded: Vec<[f64; 3]> = skirt_tube(3000, 0.004, 22)
        .into_iter()
        .map(|[x, y, z]| [x + 0.2 * (3.0 * z).sin(), y, z])
        .collect();
    let scan = turn.apply_all(&folded);
    let moved = |unit: f64, shift: Vec3| -> Vec<[f64; 3]> {
        scan.iter()
            .map(|p| (unit * vec3(p) + shift).into())
            .collect()
    };
    let base = align(&template, &moved(2.0, Vec3::zeros()), Motion::Similarity);
    assert!(base.searched, "{base:?}");
    for unit in [0.5, 3.0, 8.0, 1000.0] {
        let got = align(&template, &moved(unit, Vec3::zeros()), Motion::Similarity);
        assert!(
            (got.transform.rotation - base.transform.rotation).norm() < 1e-9,
            "unit {unit}: {got:?} against {base:?}"
        );
        let ratio = unit / 2.0;
        assert_relative_eq!(
            got.transform.scale / ratio,
            base.transform.scale,
            max_relative = 1e-9
        );
        assert_relative_eq!(
            got.transform.translation / ratio,
            base.transform.translation,
            epsilon = 1e-9
        );
    }
    for shift in [Vec3::new(0.4, 3.0, 0.0), Vec3::new(-3.0, 5.0, 2.0)] {
        let got = align(&template, &moved(2.0, shift), Motion::Similarity);
        assert!(
            (got.transform.rotation - base.transform.rotation).norm() < 1e-9,
            "shift {shift:?}: {got:?} against {base:?}"
        );
        assert_relative_eq!(
            got.transform.translation - shift,
            base.transform.translation,
            epsilon = 1e-9
        );
    }
}

/// `count` points on a shirt-like surface: a round torso (radius 0.2, height 0.8, about z), two
/// sleeves along ±x at its top (radius 0.07; the left one 0.3 long, the right 0.22, so that no
/// rotation maps it onto itself), area-uniform.
fn sleeved_tube(count: usize, noise: f64, seed: u64) -> Vec<[f64; 3]> {
    use std::f64::consts::TAU;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // The three parts' areas: the torso, the left sleeve, the right sleeve.
    let areas = [TAU * 0.2 * 0.8, TAU * 0.07 * 0.3, TAU * 0.07 * 0.22];
    let total: f64 = areas.iter().sum();
    (0..count)
        .map(|_| {
            let (pick, u, v): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
            let theta = TAU * u;
            let p = if pick < areas[0] / total {
                [0.2 * theta.cos(), 0.2 * theta.sin(), 0.8 * v]
            } else {
                let (length, side) = if pick < (areas[0] + areas[1]) / total {
                    (0.3, -1.0)
                } else {
                    (0.22, 1.0)
                };
                [
                    side * (0.2 + length * v),
                    0.07 * theta.cos(),
                    0.7 + 0.07 * theta.sin(),
                ]
            };
            jittered(p, noise, &mut rng)
        })
        .collect()
}

#[test]
fn a_template_a_quarter_turn_from_its_scan_is_searched_though_its_score_looks_placed() {
    // Turned 90° about its axis, the round torso lies on itself and the trimmed score drops
    // the sleeves: by its score alone the template looks placed, and only its half turns would
    // be searched. Its principal axes (the sleeves' x, the depth y) are a quarter turn from the
    // scan's: the search runs over every reading and finds the turn.
    let template = sleeved_tube(3000, 0.0, 31);
    let turned = turn_about_z(90.0);
    let scan = turned.apply_all(&sleeved_tube(3000, 0.004, 32));
    let got = align_looking_placed(&template, &scan);
    assert!(!principal_axes(&template).agrees_with(&principal_axes(&scan)));
    assert!(
        angle_between(&got.transform.rotation, &turned.rotation) < SAME_ANGLE,
        "{got:?}"
    );
    // Unturned, its axes agree and it stays as given.
    let placed = align(&template, &sleeved_tube(3000, 0.004, 32), Motion::Rigid);
    assert!(placed.transform.is_identity(), "{placed:?}");
}
