//! The tracker on generated sequences: rigidly moved copies of a folded sheet.

use super::*;
use crate::fit::fit_simple;
use crate::math::vec3;
use crate::math::Vec3;
use crate::quality::{assess, AssessInput, VerdictThresholds};
use crate::synthetic::{folded_sheet, SheetSpec};
use nalgebra::{Rotation3, Unit, Vector3};

/// One frame's points.
type Frame = Vec<[f64; 3]>;

/// A folded sheet (the template) and `frames` copies of it, each turned by a further 6° about
/// an oblique axis and moved by a further 6 % of its size: by the last frame the copy is far
/// beyond what one fit from the template can bridge.
fn moving_copies(frames: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<Frame>) {
    let case = folded_sheet(&SheetSpec {
        nx: 17,
        ny: 17,
        fold_amplitude: 0.08,
        rotation_degrees: 0.0,
        offset: [0.0; 3],
        ..Default::default()
    });
    let shape = case.ground_truth;
    let axis = Unit::new_normalize(Vector3::new(0.3, 1.0, 0.2));
    let copies = (0..frames)
        .map(|t| {
            let r = Rotation3::from_axis_angle(&axis, (6.0 * t as f64).to_radians());
            let shift = Vector3::new(0.06, 0.02, -0.03) * t as f64;
            shape.iter().map(|p| (r * vec3(p) + shift).into()).collect()
        })
        .collect();
    (shape, case.faces, copies)
}

fn rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (vec3(x) - vec3(y)).norm_squared())
        .sum();
    (sum / a.len() as f64).sqrt()
}

fn quick() -> TrackParams {
    let mut p = TrackParams::default();
    p.fit.iterations = 30;
    p
}

#[test]
fn tracks_rigidly_moved_copies_that_one_fit_from_the_template_cannot_reach() {
    let (template, faces, copies) = moving_copies(9);
    let mut tracker = Tracker::new(&template, &faces, quick()).unwrap();
    let size = crate::metrics::bbox_diagonal(&template);
    for (t, copy) in copies.iter().enumerate() {
        let frame = tracker.step(copy, None, None, &mut |_| true).unwrap();
        let error = rms(&frame.result.vertices, copy) / size;
        assert!(
            error < 0.01,
            "frame {t}: RMS to the moved copy {error:.4} of the diagonal"
        );
        assert_eq!(frame.figures.frame, t);
        assert_eq!(frame.figures.warm_started, t > 0);
        // The verdict's edge distortion is against the template, not the previous fit.
        let against_template = assess(
            &AssessInput {
                template_vertices: &template,
                faces: &faces,
                fitted_vertices: &frame.result.vertices,
                scan: copy,
            },
            &VerdictThresholds::default(),
        )
        .unwrap();
        assert_eq!(
            frame.figures.edge_distortion,
            against_template.quality.edge_distortion
        );
    }
    assert_eq!(tracker.frames(), copies.len());
    // The last copy, fitted from the template alone, is far off: the warm starts carried it.
    let last = copies.last().unwrap();
    let cold = fit_simple(&template, &faces, last, None, &quick().fit).unwrap();
    assert!(rms(&cold.vertices, last) / size > 0.05);
}

#[test]
fn an_anchored_fit_restores_the_rest_shape_a_warm_start_lost() {
    // The start is the template stretched by 25 % along x, on a scan of the template itself:
    // anchored to the template, the fit shrinks back; anchored to its start, it keeps more of
    // the stretch.
    let (template, faces, _) = moving_copies(1);
    let stretched: Vec<[f64; 3]> = template.iter().map(|p| [1.25 * p[0], p[1], p[2]]).collect();
    let params = quick().fit;
    let anchored = fit_anchored(
        &stretched,
        &template,
        &faces,
        &template,
        None,
        None,
        &params,
        &mut |_| true,
    )
    .unwrap();
    let loose = fit_simple(&stretched, &faces, &template, None, &params).unwrap();
    let distortion = |fitted: &[[f64; 3]]| {
        let input = AssessInput {
            template_vertices: &template,
            faces: &faces,
            fitted_vertices: fitted,
            scan: &template,
        };
        assess(&input, &VerdictThresholds::default())
            .unwrap()
            .quality
            .edge_distortion
    };
    let (a, l) = (distortion(&anchored.vertices), distortion(&loose.vertices));
    assert!(
        a < l - 0.02,
        "anchored {a:.3}, anchored to the start {l:.3}"
    );
    // The anchored fit's own verdict measures against the rest shape.
    assert_eq!(anchored.quality.edge_distortion, a);
}

#[test]
fn a_frame_that_jumps_is_flagged_suspicious() {
    let (template, faces, copies) = moving_copies(2);
    let mut p = quick();
    p.reanchor = false;
    let mut tracker = Tracker::new(&template, &faces, p).unwrap();
    tracker.step(&copies[0], None, None, &mut |_| true).unwrap();
    // The next scan is half the sheet, shifted a long way: the fit cannot explain it.
    let far: Vec<[f64; 3]> = copies[1]
        .iter()
        .filter(|q| q[0] > 0.0)
        .map(|q| [q[0] + 0.3, q[1], q[2] + 0.3])
        .collect();
    let frame = tracker.step(&far, None, None, &mut |_| true).unwrap();
    assert!(frame.figures.flagged);
    assert!(frame
        .figures
        .reasons
        .iter()
        .any(|r| r.starts_with("tracking:")));
    assert_eq!(frame.result.quality.verdict, Verdict::Suspicious);
}

#[test]
fn refuses_bad_settings_and_a_fit_of_another_vertex_count() {
    let (template, faces, _) = moving_copies(1);
    for (p, name) in [
        (
            TrackParams {
                prediction: 1.5,
                ..quick()
            },
            "prediction",
        ),
        (
            TrackParams {
                distortion_jump: 0.0,
                ..quick()
            },
            "distortion_jump",
        ),
        (
            TrackParams {
                distance_jump: 1.0,
                ..quick()
            },
            "distance_jump",
        ),
    ] {
        let err = Tracker::new(&template, &faces, p).err().unwrap();
        assert!(err.to_string().contains(name), "{err}");
    }
    let mut tracker = Tracker::new(&template, &faces, quick()).unwrap();
    let err = tracker.accept(&template[1..]).unwrap_err();
    assert!(matches!(err, FoldMatchError::Shape { .. }), "{err}");
    tracker.accept(&template).unwrap();
    assert_eq!(tracker.frames(), 1);
}

#[test]
fn reanchoring_keeps_the_refit_only_when_its_edges_are_truer() {
    // The jump of `a_frame_that_jumps_is_flagged_suspicious`, with and without re-anchoring:
    // the same first fit (the fit is deterministic), and the kept one never more distorted.
    let (template, faces, copies) = moving_copies(2);
    let far: Vec<[f64; 3]> = copies[1]
        .iter()
        .filter(|q| q[0] > 0.0)
        .map(|q| [q[0] + 0.3, q[1], q[2] + 0.3])
        .collect();
    let mut figures = Vec::new();
    for reanchor in [false, true] {
        let p = TrackParams {
            reanchor,
            ..quick()
        };
        let mut tracker = Tracker::new(&template, &faces, p).unwrap();
        tracker.step(&copies[0], None, None, &mut |_| true).unwrap();
        figures.push(
            tracker
                .step(&far, None, None, &mut |_| true)
                .unwrap()
                .figures,
        );
    }
    let (plain, reanchored) = (&figures[0], &figures[1]);
    assert!(!plain.reanchored);
    assert!(reanchored.edge_distortion <= plain.edge_distortion);
    if reanchored.reanchored {
        assert!(reanchored.edge_distortion < plain.edge_distortion);
    } else {
        assert_eq!(reanchored, plain);
    }
}

#[test]
fn a_tracker_restored_from_a_state_through_json_continues_bit_for_bit() {
    let (template, faces, copies) = moving_copies(4);
    let mut whole = Tracker::new(&template, &faces, quick()).unwrap();
    let mut fits = Vec::new();
    for copy in &copies {
        fits.push(whole.step(copy, None, None, &mut |_| true).unwrap());
    }
    // Frame by frame, each by a fresh tracker that only sees the state the last one left.
    let mut state = TrackerState::default();
    for (t, copy) in copies.iter().enumerate() {
        let mut fresh = Tracker::new(&template, &faces, quick()).unwrap();
        let json = serde_json::to_string(&state).unwrap();
        fresh.restore(serde_json::from_str(&json).unwrap()).unwrap();
        let frame = fresh.step(copy, None, None, &mut |_| true).unwrap();
        assert_eq!(frame.result.vertices, fits[t].result.vertices, "frame {t}");
        assert_eq!(frame.figures, fits[t].figures, "frame {t}");
        state = fresh.state();
    }
    assert_eq!(state.frames, copies.len());
    assert_eq!(state, whole.state());
    // A state of another template's vertex count is refused.
    let mut other = Tracker::new(&template, &faces, quick()).unwrap();
    let wrong = TrackerState {
        previous: vec![template[..5].to_vec()],
        ..TrackerState::default()
    };
    assert!(other.restore(wrong).is_err());
}

#[test]
fn the_first_frame_keeps_a_template_that_is_its_scan() {
    // The template is the first frame's shape: the first fit starts on it and keeps it (the
    // single fit's do-no-harm rule); with the rule off the fit is returned as it ends.
    let (template, faces, _) = moving_copies(1);
    // A scan of its surface: the vertices and the faces' centroids.
    let mut scan = template.clone();
    scan.extend(faces.iter().map(|f| {
        let c = f
            .iter()
            .fold(Vec3::zeros(), |a, &v| a + vec3(&template[v as usize]))
            / 3.0;
        [c.x, c.y, c.z]
    }));
    let mut tracker = Tracker::new(&template, &faces, quick()).unwrap();
    let frame = tracker.step(&scan, None, None, &mut |_| true).unwrap();
    assert!(frame.result.diagnostics.kept_start);
    assert!(rms(&frame.result.vertices, &template) < 1e-12);
    let off = TrackParams {
        first_keep_margin: 0.0,
        ..quick()
    };
    let mut tracker = Tracker::new(&template, &faces, off).unwrap();
    let frame = tracker.step(&scan, None, None, &mut |_| true).unwrap();
    assert!(!frame.result.diagnostics.kept_start);
    let bad = TrackParams {
        first_keep_margin: -1.0,
        ..quick()
    };
    assert!(Tracker::new(&template, &faces, bad).is_err());
}

#[test]
fn a_frame_that_moved_far_gets_more_iterations() {
    let (template, faces, _) = moving_copies(1);
    let edge = EdgeLengths::new(&template, &faces).mean_length();
    let shifted = |k: f64| -> Frame {
        template
            .iter()
            .map(|p| [p[0] + k * edge, p[1], p[2]])
            .collect()
    };
    // On its scan, or within the threshold: the schedule as set.
    assert_eq!(
        Tracker::far_frame_factor(&template, &template, None, edge),
        1.0
    );
    assert_eq!(
        Tracker::far_frame_factor(&template, &shifted(1.0), None, edge),
        1.0
    );
    // 4 edges away (every vertex): twice the iterations; far beyond, at most the cap.
    let four = Tracker::far_frame_factor(&template, &shifted(4.0), None, edge);
    assert!((four - 4.0 / FAR_FRAME_EDGES).abs() < 0.05, "{four}");
    let far = Tracker::far_frame_factor(&template, &shifted(40.0), None, edge);
    assert_eq!(far, MAX_ITERATION_FACTOR);
    // Points of weight 0 do not count: the scan's near copy is masked out.
    let mut both = template.clone();
    both.extend(shifted(4.0));
    let mask: Vec<f64> = (0..both.len())
        .map(|j| if j < template.len() { 0.0 } else { 1.0 })
        .collect();
    let masked = Tracker::far_frame_factor(&template, &both, Some(&mask), edge);
    assert!((masked - four).abs() < 1e-12);

    // In a sequence: the second frame, 4 edges from the first, is fitted with twice the
    // first frame's iterations.
    let mut tracker = Tracker::new(&template, &faces, quick()).unwrap();
    let first = tracker.step(&template, None, None, &mut |_| true).unwrap();
    let second = tracker
        .step(&shifted(4.0), None, None, &mut |_| true)
        .unwrap();
    assert_eq!(first.result.iterations, 30);
    let expected = (30.0 * four).round() as usize;
    assert_eq!(second.result.iterations, expected);
}
