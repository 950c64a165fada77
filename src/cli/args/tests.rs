//! Tests of the command line's grammar: every fit parameter has a flag that reaches it, the
//! documented defaults are `FitParams`'s, flags override `--params` files and presets, bad
//! values are named.

use super::*;

#[test]
fn the_grammar_is_consistent() {
    command().debug_assert();
}

#[test]
fn every_parameter_has_a_flag() {
    let defaults = serde_json::to_value(FitParams::default()).unwrap();
    let cmd = command();
    let fit = cmd.find_subcommand("fit").unwrap();
    let longs: Vec<String> = fit
        .get_arguments()
        .filter_map(|a| a.get_long())
        .map(|l| l.replace('-', "_"))
        .collect();
    for key in defaults.as_object().unwrap().keys() {
        let flag = match key.as_str() {
            "velocity_sync" => "no_velocity_sync".to_string(),
            "normalize" => "no_normalize".to_string(),
            "use_curvature" => "no_curvature".to_string(),
            "snapshot_every" => continue,
            k => k.to_string(),
        };
        assert!(longs.contains(&flag), "no flag for {key}");
    }
}

#[test]
fn generated_flags_reach_their_parameter() {
    let Some((key, default)) = generated_params().into_iter().find(|(_, v)| v.is_number()) else {
        return; // every parameter has a hand-written flag
    };
    let given = if default.is_u64() {
        Value::from(default.as_u64().unwrap() + 1)
    } else {
        Value::from(default.as_f64().unwrap() + 0.5)
    };
    let long = format!("--{}", key.replace('_', "-"));
    let cli = parse(["foldmatch", "demo", &long, &given.to_string()]).unwrap();
    let Command::Demo(demo) = cli.command else {
        panic!()
    };
    let p = serde_json::to_value(demo.params.to_params().unwrap()).unwrap();
    assert_eq!(p[&key], given, "{long}");
}

#[test]
fn no_flag_gives_the_defaults() {
    assert_eq!(
        ParamArgs::default().to_params().unwrap(),
        FitParams::default()
    );
}

/// Every `[default: X]` written in a parameter's help is the value of `FitParams::default()`,
/// and every field of `FitParams` (but `snapshot_every`) has a flag.
#[test]
fn documented_defaults_match_fit_params() {
    let defaults: Value = serde_json::from_str(&FitParams::default().to_json()).unwrap();
    let defaults = defaults.as_object().unwrap();
    let cmd = command();
    let fit = cmd.find_subcommand("fit").unwrap();
    let mut covered = vec!["velocity_sync", "normalize", "use_curvature"];
    for arg in fit.get_arguments() {
        let Some(help) = arg.get_help().map(|h| h.to_string()) else {
            continue;
        };
        let Some(start) = help.find("[default: ") else {
            continue;
        };
        let documented = &help[start + 10..help[start..].find(']').unwrap() + start];
        let key = arg.get_id().as_str().trim_start_matches("param.");
        let Some(value) = defaults.get(key) else {
            continue;
        };
        let actual = match value {
            Value::String(s) => s.clone(),
            other => other.to_string(),
        };
        let same = documented == actual
            || documented == actual.replace('_', "-")
            || documented.parse::<f64>().ok() == actual.parse::<f64>().ok()
                && documented.parse::<f64>().is_ok();
        assert!(
            same,
            "--{key}: help says {documented}, FitParams::default() has {actual}"
        );
        covered.push(defaults.get_key_value(key).unwrap().0.as_str());
    }
    for key in defaults.keys() {
        if key != "snapshot_every" {
            assert!(
                covered.contains(&key.as_str()),
                "no flag documents the default of {key}"
            );
        }
    }
}

#[test]
fn flags_override_the_params_file_and_the_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("p.json");
    std::fs::write(
        &file,
        r#"{"iterations": 7, "psi": 0.2, "damping_mode": "force"}"#,
    )
    .unwrap();
    let cli = Cli::try_parse_from([
        "foldmatch",
        "fit",
        "t.ply",
        "s.ply",
        "-o",
        "o.ply",
        "--params",
        file.to_str().unwrap(),
        "--psi",
        "-0.1",
        "--regularization",
        "log-euclidean",
        "--no-curvature",
        "--method",
        "nrga",
    ])
    .unwrap();
    let Command::Fit(fit) = cli.command else {
        panic!()
    };
    let p = fit.params.to_params().unwrap();
    assert_eq!(p.iterations, 7);
    assert_eq!(p.model.psi, -0.1);
    assert_eq!(p.model.nbody.damping_mode, crate::nbody::DampingMode::Force);
    assert_eq!(
        p.readings.regularization,
        crate::regularize::Regularization::LogEuclidean
    );
    assert!(!p.readings.use_curvature);
    assert_eq!(p.method, crate::fit::Method::Nrga);
}

#[test]
fn set_reaches_any_parameter() {
    let cli = Cli::try_parse_from([
        "foldmatch",
        "demo",
        "--set",
        "psi=0.2",
        "--set",
        "regularization=none",
        "--set",
        "k-max=32",
    ])
    .unwrap();
    let Command::Demo(demo) = cli.command else {
        panic!()
    };
    let p = demo.params.to_params().unwrap();
    assert_eq!((p.model.psi, p.model.k_max), (0.2, 32));
    assert_eq!(
        p.readings.regularization,
        crate::regularize::Regularization::None
    );
    let cli = Cli::try_parse_from(["foldmatch", "demo", "--set", "nonsense=1"]).unwrap();
    let Command::Demo(demo) = cli.command else {
        panic!()
    };
    assert!(demo.params.to_params().unwrap_err().contains("nonsense"));
    assert!(Cli::try_parse_from(["foldmatch", "demo", "--set", "psi"]).is_err());
}

#[test]
fn presets_are_the_starting_point() {
    let cli = parse([
        "foldmatch",
        "demo",
        "--preset",
        "paper",
        "--iterations",
        "9",
    ])
    .unwrap();
    let Command::Demo(demo) = cli.command else {
        panic!()
    };
    let p = demo.params.to_params().unwrap();
    assert_eq!(p, {
        let mut p = FitParams::preset("paper").unwrap();
        p.iterations = 9;
        p
    });
    let cli = parse(["foldmatch", "demo", "--preset", "fancy"]).unwrap();
    let Command::Demo(demo) = cli.command else {
        panic!()
    };
    assert!(demo.params.to_params().unwrap_err().contains("preset"));
}

#[test]
fn scan_weights_come_from_a_file_or_a_property_not_both() {
    let fit = |extra: &[&str]| {
        let mut argv = vec!["foldmatch", "fit", "t.ply", "s.ply", "-o", "o.ply"];
        argv.extend(extra);
        parse(argv)
    };
    let Command::Fit(cmd) = fit(&["--scan-weights", "w.npy"]).unwrap().command else {
        panic!()
    };
    assert_eq!(cmd.scan_weights, Some(PathBuf::from("w.npy")));
    assert_eq!(cmd.scan_weights_property, None);
    let Command::Fit(cmd) = fit(&["--scan-weights-property", "label"]).unwrap().command else {
        panic!()
    };
    assert_eq!(cmd.scan_weights_property.as_deref(), Some("label"));
    let both = fit(&[
        "--scan-weights",
        "w.npy",
        "--scan-weights-property",
        "label",
    ]);
    assert_eq!(
        both.unwrap_err().kind(),
        clap::error::ErrorKind::ArgumentConflict
    );
    // A folder of scans: only the property (one name for every file).
    for command in ["batch", "sequence"] {
        let folder = |extra: &[&str]| {
            let mut argv = vec!["foldmatch", command, "t.ply", "d", "-o", "o"];
            argv.extend(extra);
            parse(argv)
        };
        let cli = folder(&["--scan-weights-property", "confidence"]).unwrap();
        let property = match cli.command {
            Command::Batch(c) => c.scan_weights_property,
            Command::Sequence(c) => c.scan_weights_property,
            _ => panic!(),
        };
        assert_eq!(property.as_deref(), Some("confidence"));
        let file = folder(&["--scan-weights", "w.npy"]);
        assert_eq!(
            file.unwrap_err().kind(),
            clap::error::ErrorKind::UnknownArgument
        );
    }
}

#[test]
fn bad_values_are_named() {
    let args = ParamArgs {
        damping: Some(2.0),
        ..Default::default()
    };
    let err = args.to_params().unwrap_err();
    assert!(err.contains("damping"), "{err}");
    let args = ParamArgs {
        params: Some("/nonexistent/p.json".into()),
        ..Default::default()
    };
    let err = args.to_params().unwrap_err();
    assert!(err.contains("/nonexistent/p.json"), "{err}");
}
