//! `foldmatch fit`, `eval` and `demo` end to end: output snapshots (snapbox; `[..]` stands for
//! timings and figures), the files written, and every error path with its message and exit
//! code. Inputs are generated into temporary folders.

mod cli_common;

use cli_common::{ascii_cloud, foldmatch, json, tree, write_case};
use foldmatch::io::read_mesh;
use snapbox::str;

#[test]
fn fit_writes_the_mesh_the_field_and_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let case = write_case(dir.path());
    foldmatch(dir.path())
        .args([
            "fit",
            "template.ply",
            "scan.ply",
            "-o",
            "out/fitted.ply",
            "--iterations",
            "5",
        ])
        .args(["--report", "out/report.json", "--gt", "gt.ply"])
        .assert()
        .code(0)
        .stdout_eq(str![""])
        .stderr_eq(str![[r#"
fitted scan.ply -> out/fitted.ply (5 iterations, [..] s, mean scan-to-fit [..])
...
"#]]);
    assert_eq!(
        tree(dir.path()),
        [
            "gt.ply",
            "out",
            "out/fitted.ply",
            "out/report.json",
            "scan.ply",
            "template.ply"
        ]
    );

    let template = read_mesh(&case.template).unwrap();
    let fitted = read_mesh(&dir.path().join("out/fitted.ply")).unwrap();
    assert_eq!(fitted.vertices.len(), template.vertices.len());
    assert_eq!(fitted.faces, template.faces);
    assert!(
        fitted.colors.is_some(),
        "viridis colors of the field's magnitude"
    );
    assert_ne!(fitted.vertices, template.vertices);
    let header = std::fs::read(dir.path().join("out/fitted.ply")).unwrap();
    let header = String::from_utf8_lossy(&header[..600]);
    for column in ["wvf_x", "wvf_y", "wvf_z", "wvf_magnitude", "red"] {
        assert!(
            header.contains(&format!(" {column}\n")),
            "{column} missing from\n{header}"
        );
    }

    let report = json(&dir.path().join("out/report.json"));
    assert_eq!(report["command"], "fit");
    assert_eq!(report["status"], "ok");
    assert_eq!(report["template"], "template.ply");
    assert_eq!(report["scan"], "scan.ply");
    assert_eq!(report["output"], "out/fitted.ply");
    assert_eq!(report["iterations"], 5);
    assert!(report["error"].is_null());
    assert!(report["seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(report["params"]["iterations"], 5);
    assert!(
        report["metrics"]["f_R"].as_f64().unwrap() > 0.0,
        "ground truth given"
    );
    assert!(report["metrics"]["scan_to_fit_mean"].as_f64().unwrap() > 0.0);
    assert_eq!(report["diagnostics"]["curvature"], "point_cloud");
}

#[test]
fn fit_takes_params_from_a_file_and_flags_and_writes_obj() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    std::fs::write(
        dir.path().join("p.json"),
        r#"{"iterations": 4, "method": "nrga", "psi": 0.3}"#,
    )
    .unwrap();
    foldmatch(dir.path())
        .args([
            "-q",
            "fit",
            "template.ply",
            "scan.ply",
            "-o",
            "fitted.obj",
            "--params",
            "p.json",
        ])
        .args(["--iterations", "3", "--report", "r.json", "--threads", "1"])
        .assert()
        .code(0)
        .stdout_eq(str![""])
        .stderr_eq(str![""]);
    let report = json(&dir.path().join("r.json"));
    assert_eq!(report["iterations"], 3, "the flag overrides the file");
    assert_eq!(report["params"]["method"], "nrga");
    assert_eq!(report["params"]["psi"], 0.3);
    let fitted = read_mesh(&dir.path().join("fitted.obj")).unwrap();
    assert_eq!(fitted.faces.len(), 2 * 14 * 14);
}

#[test]
fn fit_with_a_mesh_scan_uses_its_faces_for_curvature() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    foldmatch(dir.path())
        .args([
            "-q",
            "fit",
            "template.ply",
            "gt.ply",
            "-o",
            "fitted.ply",
            "--iterations",
            "2",
            "--report",
            "r.json",
        ])
        .assert()
        .code(0);
    assert_eq!(
        json(&dir.path().join("r.json"))["diagnostics"]["curvature"],
        "mesh"
    );
}

/// Every way `fit` can fail: exit code 1, one line naming the culprit and the reason, and no
/// output file.
#[test]
fn fit_error_paths() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    let d = dir.path();
    std::fs::write(
        d.join("cloud.ply"),
        ascii_cloud(&["0 0 0", "1 0 0", "0 1 0"], 3),
    )
    .unwrap();
    std::fs::write(
        d.join("truncated.ply"),
        ascii_cloud(&["0 0 0", "1 0 0"], 300),
    )
    .unwrap();
    std::fs::write(
        d.join("nan.ply"),
        ascii_cloud(&["0 0 0", "nan 0 0", "0 1 0"], 3),
    )
    .unwrap();
    std::fs::write(d.join("empty.ply"), "").unwrap();
    std::fs::write(d.join("bad.json"), "{\"iterations\": ").unwrap();
    let far: Vec<String> = (0..50)
        .map(|i| format!("{} 100 100", i as f64 * 0.01))
        .collect();
    let far: Vec<&str> = far.iter().map(String::as_str).collect();
    std::fs::write(d.join("far.ply"), ascii_cloud(&far, 50)).unwrap();

    let cases: &[(&[&str], &str)] = &[
        (
            &["fit", "missing.ply", "scan.ply", "-o", "o.ply"],
            "error: template: missing.ply: No such file or directory (os error 2)\n",
        ),
        (
            &["fit", "cloud.ply", "scan.ply", "-o", "o.ply"],
            "error: template cloud.ply: no faces (a point cloud); the template must be a triangle mesh\n",
        ),
        (
            &["fit", "template.ply", "missing.ply", "-o", "o.ply"],
            "error: missing.ply: No such file or directory (os error 2)\n",
        ),
        (
            &["fit", "template.ply", "truncated.ply", "-o", "o.ply"],
            "error: truncated.ply:3: header announces 300 vertices but the file holds at most [..]\n",
        ),
        (
            &["fit", "template.ply", "nan.ply", "-o", "o.ply"],
            "error: nan.ply: target: non-finite coordinate at row 1 (NaN)\n",
        ),
        (&["fit", "template.ply", "empty.ply", "-o", "o.ply"], "error: empty.ply:0: empty file\n"),
        (
            &["fit", "template.ply", "far.ply", "-o", "o.ply", "--prealign", "none"],
            "error: far.ply: the template's centroid is [..] target bounding-box diagonals from the scan's centroid: check units or pre-align it (prealign = \"rigid\")\n",
        ),
        (
            &["fit", "template.ply", "scan.ply", "-o", "o.ply", "--damping", "2"],
            "error: parameter damping = 2: must be in [0, 1]\n",
        ),
        (
            &["fit", "template.ply", "scan.ply", "-o", "o.ply", "--params", "missing.json"],
            "error: missing.json: No such file or directory (os error 2)\n",
        ),
        (
            &["fit", "template.ply", "scan.ply", "-o", "o.ply", "--params", "bad.json"],
            "error: bad.json: not valid JSON: EOF while parsing a value at line 1 column 15\n",
        ),
        (
            &["fit", "template.ply", "scan.ply", "-o", "o.ply", "--set", "wobble=3"],
            "error: parameter wobble = ?: unknown parameter; known: [..]\n",
        ),
        (&["fit", "template.ply", "scan.ply", "-o", "o.stl"], "error: the output o.stl must end in .ply or .obj\n"),
        (
            &["fit", "template.ply", "scan.ply", "-o", "scan.ply"],
            "error: the output scan.ply is the scan: choose another -o\n",
        ),
        (
            &["fit", "template.ply", "scan.ply", "-o", "o.ply", "--gt", "cloud.ply"],
            "error: ground truth cloud.ply: 3 vertices, but the template template.ply has 225\n",
        ),
    ];
    for (args, expected) in cases {
        foldmatch(d)
            .args(*args)
            .assert()
            .code(1)
            .stdout_eq(str![""])
            .stderr_eq(*expected);
    }
    assert!(!d.join("o.ply").exists() && !d.join("o.stl").exists());
    assert!(
        tree(d).iter().all(|n| !n.contains(".tmp.")),
        "{:?}",
        tree(d)
    );
}

#[test]
fn eval_prints_the_metrics_as_json() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    let d = dir.path();
    // The ground truth fits the scan: f_R is 0, f_H below 1.
    let out = foldmatch(d)
        .args([
            "eval",
            "template.ply",
            "gt.ply",
            "scan.ply",
            "--gt",
            "gt.ply",
            "-o",
            "m.json",
        ])
        .assert()
        .code(0)
        .get_output()
        .clone();
    let printed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(printed, json(&d.join("m.json")));
    assert_eq!(printed["f_R"], 0.0);
    assert_eq!(printed["f_F"], 0.0);
    assert!(printed["f_H"].as_f64().unwrap() < 1.0);
    assert_eq!(printed["num_faces"], 2 * 14 * 14);

    std::fs::write(
        d.join("cloud.ply"),
        ascii_cloud(&["0 0 0", "1 0 0", "0 1 0"], 3),
    )
    .unwrap();
    foldmatch(d)
        .args(["eval", "template.ply", "cloud.ply", "scan.ply"])
        .assert()
        .code(1)
        .stdout_eq(str![""])
        .stderr_eq(str![[r#"
error: fitted mesh cloud.ply has 3 vertices, but the template template.ply has 225 (vertex i must be template vertex i)

"#]]);
    foldmatch(d)
        .args(["eval", "template.ply", "gt.ply", "nope.obj"])
        .assert()
        .code(1)
        .stderr_eq(str![[r#"
error: scan: nope.obj: No such file or directory (os error 2)

"#]]);
}

#[test]
fn demo_writes_its_files_and_prints_before_and_after() {
    let dir = tempfile::tempdir().unwrap();
    foldmatch(dir.path())
        .args(["demo", "-o", "demo", "--size", "12", "--scan-points", "300", "--iterations", "5"])
        .assert()
        .code(0)
        .stdout_eq(str![[r#"
FoldMatch demo: a 12×12 sheet template (144 vertices, 242 faces) and a folded, rotated,
offset scan of it (300 points, noise 0.2% of the width).

                                   before        after
  RMSE to ground truth[..]→[..]
  f_R (RMSE / scan diagonal)[..]→[..]
  f_H (Hausdorff ratio)[..]1.00000  →[..]
  f_F (flipped faces)[..]0.00000  →[..]
  mean scan-to-fit distance[..]→[..]

  fitted in [..] s (5 iterations, method foldmatch)
  wrote demo: template.ply, scan.ply, ground_truth.ply, fitted.ply (wrinkle-vector field), preview.png, report.json

"#]])
        .stderr_eq(str![[r#"
demo: fitting demo/fitted.ply (5 iterations) …

"#]]);
    assert_eq!(
        tree(&dir.path().join("demo")),
        [
            "fitted.ply",
            "ground_truth.ply",
            "preview.png",
            "report.json",
            "scan.ply",
            "template.ply"
        ]
    );
    let report = json(&dir.path().join("demo/report.json"));
    assert_eq!(report["status"], "ok");
    assert!(report["metrics"]["f_R"].as_f64().unwrap() > 0.0);
}

#[test]
fn usage_errors_exit_with_1_and_help_with_0() {
    let dir = tempfile::tempdir().unwrap();
    foldmatch(dir.path()).args(["--help"]).assert().code(0);
    foldmatch(dir.path())
        .args(["--version"])
        .assert()
        .code(0)
        .stdout_eq(str![[r#"
foldmatch [..]

"#]]);
    foldmatch(dir.path())
        .args(["fit", "a.ply"])
        .assert()
        .code(1);
    foldmatch(dir.path())
        .args(["batch", "a.ply", "d", "-o", "o", "--jobs", "0"])
        .assert()
        .code(1);
    foldmatch(dir.path()).assert().code(1);
    assert!(tree(dir.path()).is_empty(), "nothing written");
}
