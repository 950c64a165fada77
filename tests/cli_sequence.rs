//! `foldmatch sequence`: natural frame order, warm starts, a failing frame, `--resume`, and the
//! DiffCloth wind sequence of `../shared/data` (skipped, with the reason, when it is absent).

mod cli_common;

use cli_common::{foldmatch, json, tree, write_case};
use foldmatch::io::{read_mesh, write_mesh, MeshData};
use foldmatch::math::vec3;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn names(report: &Value) -> Vec<String> {
    report["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap().to_string())
        .collect()
}

fn field(report: &Value, key: &str) -> Vec<Value> {
    report["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f[key].clone())
        .collect()
}

/// Frames of a sheet folding a little more each time (scans of growing fold amplitude).
fn write_frames(dir: &Path, names: &[&str]) {
    std::fs::create_dir_all(dir).unwrap();
    for (i, name) in names.iter().enumerate() {
        let spec = foldmatch::synthetic::SheetSpec {
            nx: 15,
            ny: 15,
            scan_points: 400,
            fold_amplitude: 0.02 * (i + 1) as f64,
            seed: i as u64,
            ..Default::default()
        };
        let c = foldmatch::synthetic::folded_sheet(&spec);
        write_mesh(&dir.join(name), &MeshData::point_cloud(c.scan), &[], false).unwrap();
    }
}

#[test]
fn frames_in_natural_order_each_from_the_previous_fit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    write_frames(
        &d.join("frames"),
        &["f1.ply", "f2.ply", "f10.ply", "f3.obj"],
    );
    foldmatch(d)
        .args([
            "sequence",
            "template.ply",
            "frames",
            "-o",
            "out",
            "--iterations",
            "3",
        ])
        .assert()
        .code(0)
        .stdout_eq("")
        .stderr_eq(
            "\
sequence: 4 frames in frames (f1.ply … f10.ply) -> out
[1/4] ok      f1.ply -> out/f1.ply (3 it, [..] s, scan-to-fit [..])
[2/4] ok      f2.ply -> out/f2.ply (3 it, [..] s, scan-to-fit [..])
[3/4] ok      f3.obj -> out/f3.ply (3 it, [..] s, scan-to-fit [..])
...
[4/4] ok      f10.ply -> out/f10.ply (3 it, [..] s, scan-to-fit [..])
...
sequence: 4 ok, 0 failed, 0 skipped in [..] s; report: out/report.json
...
",
        );
    let report = json(&d.join("out/report.json"));
    assert_eq!(report["command"], "sequence");
    assert_eq!(report["state"], "complete");
    // Warm-started frames start from the tracking preset: one schedule, constant softening.
    assert_eq!(report["params"]["anneal"], 1.0);
    assert_eq!(report["params"]["selection"], "single");
    assert_eq!(names(&report), ["f1.ply", "f2.ply", "f3.obj", "f10.ply"]);
    // Every frame carries its tracking figures, numbered in order; the first is not warm-started.
    let tracking = field(&report, "tracking");
    for (i, t) in tracking.iter().enumerate() {
        assert_eq!(t["frame"], i);
        assert_eq!(t["warm_started"], i > 0);
        assert!(t["edge_distortion"].as_f64().unwrap() >= 1.0);
    }
    // The tracking preset anchors every frame to the template's metric.
    assert_eq!(report["params"]["rest_rigidity"], 0.15);
    assert_eq!(report["params"]["isometric_iterations"], 60);
    assert_eq!(
        field(&report, "warm_start"),
        [
            Value::Null,
            "f1.ply".into(),
            "f2.ply".into(),
            "f3.obj".into()
        ]
    );
    // Frame 2 started where frame 1 ended: its fit is not the fit of frame 2 from the template.
    let seq2 = read_mesh(&d.join("out/f2.ply")).unwrap();
    foldmatch(d)
        .args([
            "-q",
            "fit",
            "template.ply",
            "frames/f2.ply",
            "-o",
            "cold.ply",
            "--iterations",
            "3",
        ])
        .assert()
        .code(0);
    assert_ne!(
        seq2.vertices,
        read_mesh(&d.join("cold.ply")).unwrap().vertices
    );

    // --resume redoes nothing and still chains the warm starts.
    let stamps: Vec<_> = ["f1.ply", "f10.ply"]
        .iter()
        .map(|n| {
            std::fs::metadata(d.join("out").join(n))
                .unwrap()
                .modified()
                .unwrap()
        })
        .collect();
    foldmatch(d)
        .args(["sequence", "template.ply", "frames", "-o", "out", "--iterations", "3", "--resume"])
        .assert()
        .code(0)
        .stderr_eq("sequence: 4 frames in frames (f1.ply … f10.ply) -> out\nsequence: 0 ok, 0 failed, 4 skipped in [..] s; report: out/report.json\n...\n");
    let again: Vec<_> = ["f1.ply", "f10.ply"]
        .iter()
        .map(|n| {
            std::fs::metadata(d.join("out").join(n))
                .unwrap()
                .modified()
                .unwrap()
        })
        .collect();
    assert_eq!(stamps, again);
    assert_eq!(
        field(&json(&d.join("out/report.json")), "status"),
        ["skipped"; 4]
    );
}

#[test]
fn a_failing_frame_is_reported_and_the_next_starts_from_the_last_good_fit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    write_frames(&d.join("frames"), &["1.ply", "2.ply", "4.ply"]);
    std::fs::write(
        d.join("frames/3.ply"),
        "ply\nformat ascii 1.0\nelement vertex 5\n",
    )
    .unwrap();
    foldmatch(d)
        .args([
            "-q",
            "sequence",
            "template.ply",
            "frames",
            "-o",
            "out",
            "--iterations",
            "2",
        ])
        .assert()
        .code(2)
        .stderr_eq("error: [3/4] 3.ply: frames/3.ply:[..]\nerror: 1 of 4 files failed: 3.ply\n");
    let report = json(&d.join("out/report.json"));
    assert_eq!(field(&report, "status"), ["ok", "ok", "error", "ok"]);
    assert_eq!(field(&report, "warm_start")[3], "2.ply");
    assert_eq!(
        tree(&d.join("out")),
        [".foldmatch.lock", "1.ply", "2.ply", "4.ply", "report.json"]
    );
}

fn diffcloth() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/diffcloth/tshirt1000_wind_sim/iter0");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipping the DiffCloth sequence test: {} not found (../shared is absent)",
            dir.display()
        );
        None
    }
}

fn rmse(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(x, y)| (vec3(x) - vec3(y)).norm_squared())
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

/// The DiffCloth wind sequence (26 frames of a T-shirt blown by wind, `../shared/data`): every
/// frame is tracked from the previous one and reported. The template is frame 0 itself: the
/// rest mesh `tshirt1000-tri.obj` is frame 0 scaled by 1/0.5275 and turned by 180° (see the
/// data README), a rigid offset the N-body model cannot bridge. Frames share the template's
/// vertex order, so each frame is its own ground truth (`--gt-dir`).
#[test]
fn tracks_the_diffcloth_wind_sequence() {
    let Some(frames) = diffcloth() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let template = frames.join("0.obj");
    let f = |p: &Path| p.to_str().unwrap().to_string();
    foldmatch(d)
        .args([
            "-q",
            "sequence",
            &f(&template),
            &f(&frames),
            "-o",
            "out",
            "--iterations",
            "8",
            "--gt-dir",
            &f(&frames),
        ])
        .assert()
        .code(0)
        .stderr_eq("");
    let report = json(&d.join("out/report.json"));
    let expected: Vec<String> = (0..=250).step_by(10).map(|i| format!("{i}.obj")).collect();
    assert_eq!(names(&report), expected, "all 26 frames, in natural order");
    assert!(field(&report, "status").iter().all(|s| s == "ok"));
    let warm = field(&report, "warm_start");
    for i in 1..expected.len() {
        assert_eq!(warm[i], expected[i - 1].as_str());
    }
    // 26 frames, the report and the folder's lock file.
    let outputs = tree(&d.join("out"));
    assert_eq!(outputs.len(), 28);
    // Tracking follows the cloth: on the last frame the fit is well below the error of the
    // template left where it was.
    let last = &report["files"][25];
    let f_r = last["metrics"]["f_R"].as_f64().unwrap();
    let t = read_mesh(&template).unwrap().vertices;
    let g = read_mesh(&frames.join("250.obj")).unwrap().vertices;
    let diag = last["metrics"]["target_diagonal"].as_f64().unwrap();
    let f_r_template = rmse(&t, &g) / diag;
    assert!(
        f_r < 0.5 * f_r_template,
        "f_R {f_r:.4} vs template left in place {f_r_template:.4}"
    );
}
