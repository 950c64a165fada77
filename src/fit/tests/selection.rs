//! The presets' schedules and schedule selection (docs/method.md "Schedule selection").

use super::*;

#[test]
fn fast_preset_is_one_schedule_between_the_given_and_the_sharp() {
    let fast = FitParams::preset("fast").unwrap();
    assert_eq!(fast, FitParams::fast());
    let default = FitParams::default();
    let sharp = default.sharp_schedule();
    // The sharp schedule's phases and constant softening, a two-way weight between the two,
    // 100 iterations, no refinement and no coherent candidate.
    assert_eq!(fast, {
        let mut p = sharp.clone();
        p.schedule.two_way = FAST_TWO_WAY;
        p.iterations = FAST_ITERATIONS;
        p.schedule.isometric_iterations = 0;
        p.schedule.isometric_hold = 0.0;
        p.schedule.coherent_gate = 0.0;
        p
    });
    assert!(
        sharp.schedule.two_way < fast.schedule.two_way
            && fast.schedule.two_way < default.schedule.two_way
    );
    assert_eq!(fast.candidate_schedules(), vec![fast.clone()]);
    // One run: no candidate figures, and a fit unlike either of the default's candidates.
    let (v, f, x) = small_grid_case();
    let run = |p: &FitParams| fit_simple(&v, &f, &x, None, p).unwrap();
    let alone = run(&fast);
    assert!(alone.diagnostics.candidate_scan_distances.is_empty());
    let d = mean_scan_distance(&x, &alone);
    let both = run(&default);
    for other in &both.diagnostics.candidate_scan_distances {
        assert!((other - d).abs() > 1e-9 * d, "{other} vs {d}");
    }
}

#[test]
fn accurate_preset_is_the_default_lengthened() {
    let accurate = FitParams::preset("accurate").unwrap();
    assert_eq!(accurate, FitParams::accurate());
    assert_eq!(
        {
            let mut p = accurate.clone();
            p.iterations = DEFAULT_ITERATIONS;
            p.schedule.unstretched_refinement = UnstretchedRefinement::Garments;
            p
        },
        FitParams::default()
    );
    assert_eq!(
        accurate.schedule.unstretched_refinement,
        UnstretchedRefinement::EveryFit
    );
    // Every phase keeps its share of the iterations: 45 rigid, 75 coarse, 30 FoldMatch (24,
    // 40 and 16 of the default's 80).
    assert_eq!(accurate.iterations, ACCURATE_ITERATIONS);
    assert_eq!(accurate.phase_iterations(), (45, 75));
    assert_eq!(FitParams::default().phase_iterations(), (24, 40));
}

#[test]
fn wide_selection_chooses_among_three_candidates() {
    let (v, f, x) = grid_case();
    let wide = {
        let mut p = FitParams {
            iterations: 20,
            ..FitParams::default()
        };
        // The schedules alone (the candidates are compared before the refinement).
        p.schedule.isometric_iterations = 0;
        p.schedule.selection = Selection::ScanDistanceWide;
        p.acceleration.rigid_sample = 1;
        p
    };
    let candidates = wide.candidate_schedules();
    assert_eq!(candidates.len(), SCHEDULE_NAMES.len());
    // Given, sharp, gentle: the gentle one differs from the given only in its weight and
    // its annealing's length.
    assert_eq!(candidates[1], wide.sharp_schedule());
    assert_eq!(candidates[2].schedule.two_way, wide.schedule.two_way / 1.5);
    assert_eq!(candidates[2].schedule.anneal_fraction, 0.8);
    assert_eq!(
        {
            let mut p = candidates[2].clone();
            p.schedule.two_way = wide.schedule.two_way;
            p.schedule.anneal_fraction = wide.schedule.anneal_fraction;
            p
        },
        candidates[0]
    );
    let chosen = fit_simple(&v, &f, &x, None, &wide).unwrap();
    let alone: Vec<FitResult> = candidates
        .iter()
        .map(|p| fit_simple(&v, &f, &x, None, p).unwrap())
        .collect();
    let dist = |r: &FitResult| mean_scan_distance(&x, r);
    let d: Vec<f64> = alone.iter().map(dist).collect();
    assert_eq!(chosen.diagnostics.candidate_scan_distances, d);
    let spreads = edge_spreads(&v, &f, &alone);
    assert_eq!(chosen.diagnostics.candidate_edge_spreads, spreads);
    let best = select_schedule(&d, &spreads, wide.schedule.selection_margin);
    assert_eq!(chosen.vertices, alone[best].vertices);
    assert_eq!(chosen.diagnostics.schedule, SCHEDULE_NAMES[best]);
    // One schedule for NRGa and for a single selection.
    for p in [
        {
            let mut p = wide.clone();
            p.method = Method::Nrga;
            p
        },
        FitParams::tracking(),
    ] {
        assert_eq!(p.candidate_schedules().len(), 1);
    }
}

#[test]
fn the_scan_order_changes_the_fit_only_by_round_off() {
    // The fit keeps the scan in Morton order; given in any other order, only the order of
    // the sums differs. The scan is a mesh (the folded vertices with noise, which breaks
    // the exact distance ties of a grid: those go to the lower index of the internal order),
    // fitted with its faces re-indexed (the mesh curvature follows its points) and without.
    let case = crate::synthetic::folded_sheet(&crate::synthetic::SheetSpec {
        nx: 24,
        ny: 24,
        noise: 0.002,
        ..Default::default()
    });
    let x = &case.scan;
    let n = x.len();
    // A scrambled order: position i holds point (i · 7919) mod n (7919 is prime to n).
    let perm: Vec<usize> = (0..n).map(|i| i * 7919 % n).collect();
    let mut inverse = vec![0u32; n];
    for (i, &j) in perm.iter().enumerate() {
        inverse[j] = i as u32;
    }
    let shuffled: Vec<[f64; 3]> = perm.iter().map(|&j| x[j]).collect();
    let faces = &case.faces;
    let shuffled_faces: Vec<[u32; 3]> = faces
        .iter()
        .map(|f| f.map(|j| inverse[j as usize]))
        .collect();
    let t = &case.template_vertices;
    for params in [FitParams::default(), FitParams::paper()] {
        let params = {
            let mut p = params;
            p.iterations = 40;
            p
        };
        for mesh in [false, true] {
            let (a, b) = if mesh {
                (
                    fit_simple(t, faces, x, Some(faces), &params).unwrap(),
                    fit_simple(t, faces, &shuffled, Some(&shuffled_faces), &params).unwrap(),
                )
            } else {
                (
                    fit_simple(t, faces, x, None, &params).unwrap(),
                    fit_simple(t, faces, &shuffled, None, &params).unwrap(),
                )
            };
            let moved = a
                .vertices
                .iter()
                .zip(t)
                .map(|(p, q)| (vec3(p) - vec3(q)).norm())
                .fold(0.0, f64::max);
            let apart = a
                .vertices
                .iter()
                .zip(&b.vertices)
                .map(|(p, q)| (vec3(p) - vec3(q)).norm())
                .fold(0.0, f64::max);
            assert!(moved > 0.01 && apart < 1e-9 * moved, "{apart} of {moved}");
        }
    }
}

#[test]
fn select_schedule_breaks_near_ties_by_the_edge_length_spread() {
    // Outside the margin the closest fit wins, whatever its spread.
    assert_eq!(select_schedule(&[1.0, 1.2], &[0.5, 0.1], 0.06), 0);
    assert_eq!(select_schedule(&[1.2, 1.0], &[0.1, 0.5], 0.06), 1);
    // Within it, the least spread.
    assert_eq!(select_schedule(&[1.0, 1.05], &[0.5, 0.1], 0.06), 1);
    assert_eq!(
        select_schedule(&[1.05, 1.0, 1.03], &[0.3, 0.5, 0.2], 0.06),
        2
    );
    // Margin 0: the closest alone (the earlier rule); equal spreads keep the earlier.
    assert_eq!(select_schedule(&[1.0, 1.05], &[0.5, 0.1], 0.0), 0);
    assert_eq!(select_schedule(&[1.0, 1.0], &[0.2, 0.2], 0.06), 0);
    assert_eq!(select_schedule(&[1.0, 1.0], &[0.2, 0.1], 0.0), 1);
    for bad in [-0.01, f64::NAN, f64::INFINITY] {
        assert_refused(
            &{
                let mut p = FitParams::default();
                p.schedule.selection_margin = bad;
                p
            },
            "selection_margin",
        );
    }
}

#[test]
fn early_selection_compares_there_and_runs_the_chosen_schedule_alone() {
    let (v, f, x) = grid_case();
    let params = {
        let mut p = FitParams {
            iterations: 20,
            ..FitParams::default()
        };
        // The schedules alone (the candidates are compared before the refinement).
        p.schedule.isometric_iterations = 0;
        p.schedule.selection_at = 0.5;
        p
    };
    let mut seen = Vec::new();
    let early = fit(&v, &f, &x, None, &params, &mut |p| {
        seen.push((p.iteration, p.iterations));
        true
    })
    .unwrap();
    assert_eq!(seen, (1..=20).map(|i| (i, 20)).collect::<Vec<_>>());
    let given = {
        let mut p = params.clone();
        p.schedule.selection = Selection::Single;
        p
    };
    let schedules = [given, params.sharp_schedule()];
    // Each candidate at iteration 10: its single run stopped there.
    let at_10: Vec<FitResult> = schedules
        .iter()
        .map(|p| fit(&v, &f, &x, None, p, &mut |p| p.iteration < 10).unwrap())
        .collect();
    let d: Vec<f64> = at_10.iter().map(|r| mean_scan_distance(&x, r)).collect();
    assert_eq!(early.diagnostics.candidate_scan_distances, d);
    let spreads = edge_spreads(&v, &f, &at_10);
    assert_eq!(early.diagnostics.candidate_edge_spreads, spreads);
    let k = select_schedule(&d, &spreads, params.schedule.selection_margin);
    assert_eq!(early.diagnostics.schedule, ["given", "sharp"][k]);
    // The chosen schedule then ran on alone: its single run's fit, bit for bit.
    let alone = fit_simple(&v, &f, &x, None, &schedules[k]).unwrap();
    assert_eq!(early.iterations, 20);
    assert_eq!(early.vertices, alone.vertices);
    assert_eq!(early.wvf_accumulated, alone.wvf_accumulated);
    for bad in [0.0, -0.1, 1.5, f64::NAN] {
        assert_refused(
            &{
                let mut p = FitParams::default();
                p.schedule.selection_at = bad;
                p
            },
            "selection_at",
        );
    }
}

#[test]
fn selection_chooses_between_the_given_and_the_sharp_schedule() {
    let (v, f, x) = grid_case();
    let mut params = FitParams {
        iterations: 20,
        ..FitParams::default()
    };
    // The schedules alone (the candidates are compared before the refinement).
    params.schedule.isometric_iterations = 0;
    let chosen = fit_simple(&v, &f, &x, None, &params).unwrap();
    let given = {
        let mut p = params.clone();
        p.schedule.selection = Selection::Single;
        p
    };
    let runs = [
        fit_simple(&v, &f, &x, None, &given).unwrap(),
        fit_simple(&v, &f, &x, None, &params.sharp_schedule()).unwrap(),
    ];
    let dist = |r: &FitResult| mean_scan_distance(&x, r);
    let d = chosen.diagnostics.candidate_scan_distances.clone();
    assert_eq!(d, vec![dist(&runs[0]), dist(&runs[1])]);
    let spreads = edge_spreads(&v, &f, &runs);
    assert_eq!(chosen.diagnostics.candidate_edge_spreads, spreads);
    let k = select_schedule(&d, &spreads, params.schedule.selection_margin);
    assert_eq!(chosen.vertices, runs[k].vertices);
    assert_eq!(chosen.diagnostics.schedule, ["given", "sharp"][k]);
    assert_eq!(chosen.params, params);
    // The runs advance in lockstep: progress counts ξ, with the given schedule's figures.
    let mut seen = Vec::new();
    fit(&v, &f, &x, None, &params, &mut |p| {
        seen.push((p.iteration, p.iterations, p.record));
        true
    })
    .unwrap();
    assert_eq!(
        seen,
        (1..=20)
            .map(|i| (i, 20, runs[0].history[i - 1]))
            .collect::<Vec<_>>()
    );
    // A stop applies to both runs: each candidate equals its single run stopped there.
    let stopped = |p: &FitParams| fit(&v, &f, &x, None, p, &mut |p| p.iteration < 7).unwrap();
    let both = stopped(&params);
    assert!(both.diagnostics.stopped_by_callback && both.iterations == 7);
    let alone = [stopped(&given), stopped(&params.sharp_schedule())];
    assert_eq!(
        both.diagnostics.candidate_scan_distances,
        vec![dist(&alone[0]), dist(&alone[1])]
    );
    // The sharp schedule differs from the given one only in its schedule fields.
    let sharp = params.sharp_schedule();
    assert_eq!(
        (
            sharp.schedule.two_way,
            sharp.schedule.coarse_fraction,
            sharp.schedule.anneal
        ),
        (1.0, 0.3, 1.0)
    );
    assert_eq!(sharp.schedule.selection, Selection::Single);
    assert_eq!(
        {
            let mut p = sharp;
            p.schedule.two_way = params.schedule.two_way;
            p.schedule.coarse_fraction = params.schedule.coarse_fraction;
            p.schedule.anneal = params.schedule.anneal;
            p.schedule.anneal_fraction = params.schedule.anneal_fraction;
            p.schedule.selection = params.schedule.selection;
            p
        },
        params
    );
}
