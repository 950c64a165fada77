//! The quality verdict on the command line: `fit` warns when a fit looks wrong and its report
//! carries the verdict; `batch` lists the suspicious files in its report and its last lines.

mod cli_common;

use cli_common::{foldmatch, json, sheet, write_case};
use foldmatch::io::{write_mesh, MeshData};
use std::path::Path;

/// A scan of only a strip of the template's sheet (x below −0.3 of its unit width): the
/// default fit pulls the whole sheet onto the strip.
fn write_strip_scan(path: &Path) {
    let c = sheet(15, 2000, 5);
    let strip: Vec<[f64; 3]> = c
        .template_vertices
        .iter()
        .flat_map(|p| (0..4).map(move |k| [p[0] + 0.01 * k as f64, p[1] + 0.005 * k as f64, p[2]]))
        .filter(|p| p[0] < -0.3)
        .collect();
    write_mesh(path, &MeshData::point_cloud(strip), &[], false).unwrap();
}

#[test]
fn fit_warns_when_the_fit_looks_wrong_and_the_report_says_why() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    write_strip_scan(&dir.path().join("strip.ply"));
    let out = foldmatch(dir.path())
        .args(["fit", "template.ply", "strip.ply", "-o", "fitted.ply"])
        .args(["--report", "report.json"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "a suspicious fit is still written"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("warning: the fit looks wrong (quality verdict suspicious): "),
        "{stderr}"
    );
    let report = json(&dir.path().join("report.json"));
    assert_eq!(report["quality"]["verdict"], "suspicious");
    let reasons = report["quality"]["reasons"].as_array().unwrap();
    assert!(!reasons.is_empty());
    assert!(
        report["quality"]["unsupported_share"].as_f64().unwrap() > 0.0
            || report["quality"]["edge_distortion"].as_f64().unwrap() > 2.0,
        "{}",
        report["quality"]
    );

    // The template on its own folded scan: no warning, verdict ok, every figure in the report.
    let out = foldmatch(dir.path())
        .args(["fit", "template.ply", "scan.ply", "-o", "good.ply"])
        .args(["--report", "good.json"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("warning"), "{stderr}");
    let report = json(&dir.path().join("good.json"));
    assert_eq!(report["quality"]["verdict"], "ok", "{}", report["quality"]);
    for figure in [
        "fit_to_scan",
        "scan_to_fit",
        "asymmetry",
        "unsupported_share",
        "flipped_share",
        "collapsed_share",
        "edge_distortion",
        "pose_gap",
        "pose_turn",
    ] {
        assert!(
            report["quality"][figure].as_f64().unwrap().is_finite(),
            "{figure}"
        );
        assert!(
            report["quality"]["thresholds"][figure].is_number(),
            "{figure}"
        );
    }
}

#[test]
fn batch_lists_the_suspicious_files() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    std::fs::create_dir(dir.path().join("scans")).unwrap();
    std::fs::copy(dir.path().join("scan.ply"), dir.path().join("scans/a.ply")).unwrap();
    write_strip_scan(&dir.path().join("scans/b.ply"));
    let out = foldmatch(dir.path())
        .args(["batch", "template.ply", "scans", "-o", "out"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("warning: 1 of 2 fits look wrong (quality verdict suspicious; the report says why): b.ply"),
        "{stderr}"
    );
    let report = json(&dir.path().join("out/report.json"));
    assert_eq!(report["suspicious"], serde_json::json!(["b.ply"]));
    let files = report["files"].as_array().unwrap();
    let verdicts: Vec<&str> = files
        .iter()
        .map(|f| f["quality"]["verdict"].as_str().unwrap())
        .collect();
    assert_eq!(verdicts, ["ok", "suspicious"]);
}
