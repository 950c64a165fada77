//! Scan weights on the command line: `fit --scan-weights FILE.npy`, `--scan-weights-property
//! NAME` (also of `batch` and `sequence`), their report entries and every way they are refused.
//! Inputs (scans, masks, `.npy` files) are generated into temporary folders.

mod cli_common;

use cli_common::{
    foldmatch, json, npy_bytes, sheet, tree, write_case, write_labelled_cloud, write_npy_f64,
};
use foldmatch::io::{read_mesh, write_mesh, MeshData};
use serde_json::json;
use snapbox::str;
use std::path::Path;

/// `foldmatch -q fit template.ply SCAN -o OUT --iterations 8 --report OUT.json EXTRA` in `d`:
/// it succeeds and says nothing.
fn fit_quietly(d: &Path, scan: &str, out: &str, extra: &[&str]) {
    foldmatch(d)
        .args([
            "-q",
            "fit",
            "template.ply",
            scan,
            "-o",
            out,
            "--iterations",
            "8",
        ])
        .args(["--report", &format!("{out}.json")])
        .args(extra)
        .assert()
        .code(0)
        .stderr_eq(str![""]);
}

/// A "dressed" scan: the 400 garment points of `write_case`'s scan with 100 other points
/// interleaved (after every fourth garment point, 0.3 above it), and its 0/1 garment mask.
fn dressed(seed: u64) -> (Vec<[f64; 3]>, Vec<u8>) {
    let garment = sheet(15, 400, seed).scan;
    let mut points = Vec::new();
    let mut mask = Vec::new();
    for (k, p) in garment.iter().enumerate() {
        points.push(*p);
        mask.push(1);
        if k % 4 == 3 {
            points.push([p[0], p[1], p[2] + 0.3]);
            mask.push(0);
        }
    }
    (points, mask)
}

/// Writes `points` as a PLY or OBJ point cloud (the extension decides).
fn write_cloud(path: &Path, points: &[[f64; 3]]) {
    write_mesh(path, &MeshData::point_cloud(points.to_vec()), &[], false).unwrap();
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap()
}

/// A 0/1 mask (bool or uint8 `.npy`, or a `uchar label` PLY property) fits exactly as the
/// masked scan without weights: the same output file, byte for byte, and the same metrics.
#[test]
fn a_mask_fits_exactly_as_the_masked_scan() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let (points, mask) = dressed(1);
    assert_eq!(
        (points.len(), mask.iter().filter(|&&m| m == 0).count()),
        (500, 100)
    );
    write_cloud(&d.join("dressed.ply"), &points);
    std::fs::write(d.join("mask.npy"), npy_bytes("|b1", "(500,)", &mask)).unwrap();
    std::fs::write(d.join("mask_u8.npy"), npy_bytes("|u1", "(500, 1)", &mask)).unwrap();
    write_labelled_cloud(&d.join("labelled.ply"), &points, "label", &mask);
    let fit = |scan: &str, out: &str, extra: &[&str]| fit_quietly(d, scan, out, extra);
    fit("scan.ply", "plain.ply", &[]);
    fit("dressed.ply", "mask.ply", &["--scan-weights", "mask.npy"]);
    fit(
        "dressed.ply",
        "mask_u8.ply",
        &["--scan-weights", "mask_u8.npy"],
    );
    fit(
        "labelled.ply",
        "label.ply",
        &["--scan-weights-property", "label"],
    );
    let plain = read(&d.join("plain.ply"));
    for out in ["mask.ply", "mask_u8.ply", "label.ply"] {
        assert!(
            read(&d.join(out)) == plain,
            "{out} differs from the masked scan's fit"
        );
    }

    let plain = json(&d.join("plain.ply.json"));
    assert!(plain.get("scan_weights").is_none(), "no weights, no entry");
    let from_file = json(&d.join("mask.ply.json"));
    assert_eq!(
        from_file["scan_weights"],
        json!({"source": "file", "file": "mask.npy", "points": 500, "zero_weight": 100})
    );
    let from_property = json(&d.join("label.ply.json"));
    assert_eq!(
        from_property["scan_weights"],
        json!({"source": "property", "property": "label", "points": 500, "zero_weight": 100})
    );
    // The metrics are of the points of positive weight: the masked scan's.
    assert_eq!(from_file["metrics"], plain["metrics"]);
    assert_eq!(from_property["metrics"], plain["metrics"]);
}

/// Fractional weights (a scanner's confidence) change the fit; equal weights do not.
#[test]
fn fractional_weights_weigh_and_equal_weights_change_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let n = 400;
    let confidence: Vec<f64> = (0..n).map(|j| 0.2 + (j % 7) as f64 * 0.3).collect();
    write_npy_f64(&d.join("confidence.npy"), &confidence);
    let f32s: Vec<u8> = confidence
        .iter()
        .flat_map(|&w| (w as f32).to_le_bytes())
        .collect();
    std::fs::write(
        d.join("confidence32.npy"),
        npy_bytes("<f4", "(400,)", &f32s),
    )
    .unwrap();
    let threes: Vec<u8> = (0..n).flat_map(|_| 3i32.to_le_bytes()).collect();
    std::fs::write(d.join("threes.npy"), npy_bytes("<i4", "(400,)", &threes)).unwrap();
    let fit = |out: &str, extra: &[&str]| fit_quietly(d, "scan.ply", out, extra);
    fit("plain.ply", &[]);
    fit("weighted.ply", &["--scan-weights", "confidence.npy"]);
    fit("weighted32.ply", &["--scan-weights", "confidence32.npy"]);
    fit("equal.ply", &["--scan-weights", "threes.npy"]);
    let plain = read_mesh(&d.join("plain.ply")).unwrap();
    let weighted = read_mesh(&d.join("weighted.ply")).unwrap();
    let weighted32 = read_mesh(&d.join("weighted32.ply")).unwrap();
    assert_ne!(weighted.vertices, plain.vertices, "the weights act");
    assert_ne!(weighted32.vertices, plain.vertices, "the weights act");
    assert!(read(&d.join("equal.ply")) == read(&d.join("plain.ply")));
    let report = json(&d.join("weighted.ply.json"));
    assert_eq!(report["status"], "ok");
    assert_eq!(
        report["scan_weights"],
        json!({"source": "file", "file": "confidence.npy", "points": 400, "zero_weight": 0})
    );
}

/// Every way weights are refused: exit code 1, one clean line naming the file (and the index
/// of a bad weight), no output file; `--report` still records the failure and the weights.
#[test]
fn bad_weights_are_refused_with_a_clean_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let scan = read_mesh(&d.join("scan.ply")).unwrap();
    write_mesh(&d.join("scan.obj"), &scan, &[], false).unwrap();
    write_npy_f64(&d.join("short.npy"), &[1.0; 399]);
    let mut w = vec![1.0; 400];
    w[7] = -1.0;
    write_npy_f64(&d.join("negative.npy"), &w);
    w[7] = 1.0;
    w[3] = f64::NAN;
    write_npy_f64(&d.join("nan.npy"), &w);
    write_npy_f64(&d.join("zero.npy"), &[0.0; 400]);
    let payload: Vec<u8> = (0..400).flat_map(|_| 1.0f64.to_be_bytes()).collect();
    std::fs::write(d.join("big.npy"), npy_bytes(">f8", "(400,)", &payload)).unwrap();
    std::fs::write(
        d.join("cut.npy"),
        npy_bytes("<f8", "(400,)", &payload[..100]),
    )
    .unwrap();
    std::fs::write(d.join("table.npy"), npy_bytes("<f8", "(200, 2)", &payload)).unwrap();
    std::fs::write(d.join("text.npy"), "0 1 1 0\n").unwrap();

    let base = ["fit", "template.ply", "scan.ply", "-o", "o.ply"];
    let cases: &[(&[&str], &str)] = &[
        (
            &["--scan-weights", "short.npy"],
            "error: short.npy (the weights of scan.ply): parameter target_weights = 399 weights: need one weight per scan point (400)\n",
        ),
        (
            &["--scan-weights", "negative.npy"],
            "error: negative.npy (the weights of scan.ply): parameter target_weights[7] = -1: weights must be finite and >= 0\n",
        ),
        (
            &["--scan-weights", "nan.npy"],
            "error: nan.npy (the weights of scan.ply): parameter target_weights[3] = NaN: weights must be finite and >= 0\n",
        ),
        (
            &["--scan-weights", "zero.npy"],
            "error: zero.npy (the weights of scan.ply): parameter target_weights = all zero: at least one scan point needs a positive weight\n",
        ),
        (
            &["--scan-weights", "big.npy"],
            "error: big.npy:0: dtype '>f8' is big endian, which is not supported; accepted: float64, float32, int8..int64, uint8..uint64, bool (little endian)\n",
        ),
        (
            &["--scan-weights", "cut.npy"],
            "error: cut.npy:0: truncated file: shape (400,) of '<f8' needs 3200 bytes of data, the file holds 100\n",
        ),
        (
            &["--scan-weights", "table.npy"],
            "error: table.npy:0: shape (200, 2) is not (N,) or (N, 1): give one weight per scan point\n",
        ),
        (
            &["--scan-weights", "text.npy"],
            "error: text.npy:0: not a NumPy .npy file (it does not start with the NUMPY magic string; save the array with np.save)\n",
        ),
        (
            &["--scan-weights", "missing.npy"],
            "error: missing.npy: No such file or directory (os error 2)\n",
        ),
        (
            &["--scan-weights-property", "label"],
            "error: scan.ply:[..]: vertex element has no property 'label' (it has: x, y, z)\n",
        ),
    ];
    for (extra, expected) in cases {
        foldmatch(d)
            .args(base)
            .args(*extra)
            .assert()
            .code(1)
            .stdout_eq(str![""])
            .stderr_eq(*expected);
    }
    foldmatch(d)
        .args(["fit", "template.ply", "scan.obj", "-o", "o.ply"])
        .args(["--scan-weights-property", "label"])
        .assert()
        .code(1)
        .stderr_eq(str![[r#"
error: scan.obj: --scan-weights-property label needs a PLY scan (other formats have no per-vertex properties)

"#]]);
    // The two sources exclude each other (a usage error).
    foldmatch(d)
        .args(base)
        .args([
            "--scan-weights",
            "zero.npy",
            "--scan-weights-property",
            "label",
        ])
        .assert()
        .code(1)
        .stdout_eq(str![""])
        .stderr_eq(str![[r#"
error: the argument '--scan-weights <FILE.npy>' cannot be used with '--scan-weights-property <NAME>'
...
"#]]);
    assert!(!d.join("o.ply").exists());
    assert!(
        tree(d).iter().all(|n| !n.contains(".tmp.")),
        "{:?}",
        tree(d)
    );

    // The report of a refused file says why and where the weights came from.
    foldmatch(d)
        .args(base)
        .args(["--scan-weights", "short.npy", "--report", "r.json"])
        .assert()
        .code(1);
    let report = json(&d.join("r.json"));
    assert_eq!(report["status"], "error");
    assert!(report["error"].as_str().unwrap().contains("399 weights"));
    assert_eq!(
        report["scan_weights"],
        json!({"source": "file", "file": "short.npy", "points": 399, "zero_weight": 0})
    );
}

/// `batch --scan-weights-property` weighs every scan by its own property; a scan without it
/// (or not a PLY) fails alone, naming the file and the property.
#[test]
fn batch_and_sequence_take_a_property_of_every_scan() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    std::fs::create_dir_all(d.join("scans")).unwrap();
    let (points, mask) = dressed(1);
    write_labelled_cloud(&d.join("scans/a.ply"), &points, "label", &mask);
    let (points_b, mask_b) = dressed(2);
    write_labelled_cloud(&d.join("scans/b.ply"), &points_b, "label", &mask_b);
    write_labelled_cloud(&d.join("scans/c.ply"), &points, "segment", &mask);
    write_cloud(&d.join("scans/d.obj"), &points);
    foldmatch(d)
        .args(["-q", "fit", "template.ply", "scan.ply", "-o", "plain.ply"])
        .args(["--iterations", "8"])
        .assert()
        .code(0);
    let out = foldmatch(d)
        .args([
            "-q",
            "batch",
            "template.ply",
            "scans",
            "-o",
            "out",
            "--iterations",
            "8",
        ])
        .args(["--scan-weights-property", "label", "--jobs", "2"])
        .assert()
        .code(2)
        .get_output()
        .clone();
    let stderr = String::from_utf8_lossy(&out.stderr);
    for line in [
        "c.ply: scans/c.ply:3: vertex element has no property 'label' (it has: x, y, z, segment)\n",
        "d.obj: scans/d.obj: --scan-weights-property label needs a PLY scan (other formats have no per-vertex properties)\n",
        "error: 2 of 4 files failed: c.ply, d.obj\n",
    ] {
        assert!(stderr.contains(line), "{line:?} not in\n{stderr}");
    }
    assert!(!stderr.contains("panic"), "{stderr}");
    assert!(read(&d.join("out/a.ply")) == read(&d.join("plain.ply")));
    let report = json(&d.join("out/report.json"));
    let files = report["files"].as_array().unwrap();
    let status: Vec<&str> = files
        .iter()
        .map(|f| f["status"].as_str().unwrap())
        .collect();
    assert_eq!(status, ["ok", "ok", "error", "error"]);
    assert_eq!(
        files[0]["scan_weights"],
        json!({"source": "property", "property": "label", "points": 500, "zero_weight": 100})
    );

    // A sequence of the two labelled frames.
    std::fs::create_dir_all(d.join("frames")).unwrap();
    std::fs::copy(d.join("scans/a.ply"), d.join("frames/0.ply")).unwrap();
    std::fs::copy(d.join("scans/b.ply"), d.join("frames/1.ply")).unwrap();
    foldmatch(d)
        .args(["-q", "sequence", "template.ply", "frames", "-o", "tracked"])
        .args(["--iterations", "4", "--scan-weights-property", "label"])
        .assert()
        .code(0)
        .stderr_eq(str![""]);
    let report = json(&d.join("tracked/report.json"));
    for f in report["files"].as_array().unwrap() {
        assert_eq!(f["status"], "ok");
        assert_eq!(f["scan_weights"]["zero_weight"], 100);
    }
    // Only the property applies to a folder.
    foldmatch(d)
        .args([
            "batch",
            "template.ply",
            "scans",
            "-o",
            "o2",
            "--scan-weights",
            "w.npy",
        ])
        .assert()
        .code(1);
}

/// `eval` takes the fit's weights: on a dressed scan with its mask (a file or a PLY property)
/// it prints the metrics the fit's report holds, measured on the garment's points; without the
/// mask the other points count (the scan → fit distance grows). Bad weights are refused as
/// `fit` refuses them.
#[test]
fn eval_measures_the_points_the_weights_keep() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let (points, mask) = dressed(2);
    write_cloud(&d.join("dressed.ply"), &points);
    std::fs::write(d.join("mask.npy"), npy_bytes("|b1", "(500,)", &mask)).unwrap();
    write_labelled_cloud(&d.join("labelled.ply"), &points, "label", &mask);
    fit_quietly(
        d,
        "dressed.ply",
        "fitted.ply",
        &["--scan-weights", "mask.npy"],
    );
    let report = json(&d.join("fitted.ply.json"));
    let eval = |scan: &str, out: &str, extra: &[&str]| {
        foldmatch(d)
            .args(["-q", "eval", "template.ply", "fitted.ply", scan, "-o", out])
            .args(extra)
            .assert()
            .code(0);
        json(&d.join(out))
    };
    let masked = eval(
        "dressed.ply",
        "masked.json",
        &["--scan-weights", "mask.npy"],
    );
    let labelled = eval(
        "labelled.ply",
        "labelled.json",
        &["--scan-weights-property", "label"],
    );
    let whole = eval("dressed.ply", "whole.json", &[]);
    assert_eq!(masked, report["metrics"]);
    assert_eq!(labelled, report["metrics"]);
    let s2f = |m: &serde_json::Value| m["scan_to_fit_mean"].as_f64().unwrap();
    assert!(
        s2f(&whole) > 2.0 * s2f(&masked),
        "the 100 points 0.3 off the sheet count without the mask: {} vs {}",
        s2f(&whole),
        s2f(&masked)
    );
    write_npy_f64(&d.join("short.npy"), &[1.0; 499]);
    foldmatch(d)
        .args(["eval", "template.ply", "fitted.ply", "dressed.ply"])
        .args(["--scan-weights", "short.npy"])
        .assert()
        .code(1)
        .stdout_eq(str![""])
        .stderr_eq(str![[r#"
error: short.npy (the weights of dressed.ply): parameter target_weights = 499 weights: need one weight per scan point (500)

"#]]);
}

/// `fit --garment-mask FILE.npy` (and `batch` / `sequence --garment-masks`) writes the points
/// the fit took for the garment as a bool mask in the scan's order: on a scan with a "body" (a
/// far plane, so the scan is a scene) the sheet's points and not the body's; on the sheet alone
/// every point. The mask reads back as
/// `--scan-weights`; a name without `.npy` is refused before fitting.
#[test]
fn the_garment_mask_is_written_and_reads_back_as_weights() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let garment = sheet(15, 400, 1).scan;
    let mut points = garment.clone();
    for i in 0..20 {
        for j in 0..20 {
            let (x, y) = (-1.5 + 3.0 * i as f64 / 19.0, -1.5 + 3.0 * j as f64 / 19.0);
            points.push([x, y, -1.5]);
        }
    }
    write_cloud(&d.join("scene.ply"), &points);
    let read_mask = |name: &str| -> Vec<bool> {
        foldmatch::io::read_npy(&d.join(name))
            .unwrap()
            .iter()
            .map(|&w| w == 1.0)
            .collect()
    };
    fit_quietly(
        d,
        "scene.ply",
        "scene_fit.ply",
        &["--garment-mask", "scene_mask.npy"],
    );
    let mask = read_mask("scene_mask.npy");
    assert_eq!(mask.len(), points.len());
    let on_sheet = mask[..400].iter().filter(|&&m| m).count();
    assert!(on_sheet >= 380, "{on_sheet} of the 400 sheet points");
    assert!(mask[400..].iter().all(|&m| !m), "the body's points are out");
    let report = json(&d.join("scene_fit.ply.json"));
    assert_eq!(report["garment_mask"], "scene_mask.npy");
    assert_eq!(
        report["diagnostics"]["garment_refit_points"].as_u64(),
        Some(mask.iter().filter(|&&m| m).count() as u64)
    );
    // Fitted whole: every point.
    fit_quietly(
        d,
        "scan.ply",
        "plain.ply",
        &["--garment-mask", "plain_mask.npy"],
    );
    assert_eq!(read_mask("plain_mask.npy"), vec![true; 400]);
    // Back as weights.
    fit_quietly(
        d,
        "scene.ply",
        "again.ply",
        &["--scan-weights", "scene_mask.npy"],
    );
    // `batch --garment-masks` writes each file's next to its output; `sequence` each frame's.
    std::fs::create_dir_all(d.join("scans")).unwrap();
    std::fs::copy(d.join("scene.ply"), d.join("scans/scene.ply")).unwrap();
    std::fs::copy(d.join("scan.ply"), d.join("scans/plain.ply")).unwrap();
    for (command, out) in [("batch", "masks"), ("sequence", "frames")] {
        foldmatch(d)
            .args(["-q", command, "template.ply", "scans", "-o", out])
            .args(["--iterations", "8", "--garment-masks"])
            .assert()
            .code(0)
            .stderr_eq(str![""]);
        let report = json(&d.join(out).join("report.json"));
        for f in report["files"].as_array().unwrap() {
            let name = f["name"].as_str().unwrap().trim_end_matches(".ply");
            let mask_file = format!("{out}/{name}.garment.npy");
            assert_eq!(
                f["garment_mask"].as_str().map(|m| m.ends_with(&mask_file)),
                Some(true),
                "{f}"
            );
            let mask = read_mask(&mask_file);
            let expected = if name == "scene" { points.len() } else { 400 };
            assert_eq!(mask.len(), expected, "{mask_file}");
        }
        if command == "batch" {
            assert_eq!(
                read_mask("masks/scene.garment.npy"),
                read_mask("scene_mask.npy")
            );
        }
    }
    foldmatch(d)
        .args(["fit", "template.ply", "scan.ply", "-o", "o.ply"])
        .args(["--garment-mask", "mask.txt"])
        .assert()
        .code(1)
        .stderr_eq(str![[r#"
error: --garment-mask mask.txt: must end in .npy

"#]]);
    assert!(!d.join("o.ply").exists());
}
