//! Every hostile input of `tests/hostile/cases.json` through the `foldmatch` binary: a clean,
//! located error (exit 1, the expected message, no panic text, no abort) or a documented
//! success (exit 0). tests/test_hostile.py runs the same cases through Python.

mod cli_common;

use cli_common::{bin, write_case};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn hostile_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/hostile")
}

/// The input a case names: a committed file, or one of the special names.
fn resolve(name: &str, scratch: &Path) -> PathBuf {
    match name {
        "@dev-zero" => scratch.join("zero.ply"),
        "@dev-urandom" => scratch.join("urandom.obj"),
        "@folder" => hostile_dir().join("files/folder.ply"),
        "@missing" => scratch.join("missing.ply"),
        file => hostile_dir().join("files").join(file),
    }
}

#[cfg(unix)]
#[test]
fn hostile_inputs_through_the_cli() {
    let text = std::fs::read_to_string(hostile_dir().join("cases.json")).unwrap();
    let cases: Value = serde_json::from_str(&text).unwrap();
    let cases = cases["cases"].as_array().unwrap();
    assert!(cases.len() >= 40, "{} cases", cases.len());
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let case = write_case(d);
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.ply")).unwrap();
    std::os::unix::fs::symlink("/dev/urandom", d.join("urandom.obj")).unwrap();
    let files = hostile_dir().join("files");
    let mut failures = Vec::new();
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let template = c["template"]
            .as_str()
            .map_or(case.template.clone(), |t| resolve(t, d));
        let scan = c["scan"]
            .as_str()
            .map_or(case.scan.clone(), |s| resolve(s, d));
        let out = d.join("out.ply");
        let _ = std::fs::remove_file(&out);
        let mut cmd = Command::new(bin());
        cmd.current_dir(d)
            .env("FOLDMATCH_NO_PROGRESS", "1")
            .arg("fit")
            .arg(&template)
            .arg(&scan)
            .arg("-o")
            .arg(&out);
        for key in ["args", "extra"] {
            for a in c[key].as_array().into_iter().flatten() {
                let a = a.as_str().unwrap();
                cmd.arg(
                    a.replace("{files}", &files.display().to_string())
                        .replace("{dev-zero}", &d.join("zero.ply").display().to_string()),
                );
            }
        }
        let output = cmd.output().unwrap();
        let all = format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
        let expect_ok = c["expect"] == "ok";
        let message = c["message"].as_str().unwrap();
        let code = output.status.code();
        let clean = !all.contains("panicked") && !all.contains("RUST_BACKTRACE");
        let good = if expect_ok {
            code == Some(0) && out.is_file()
        } else {
            code == Some(1) && all.contains(message) && !out.exists()
        };
        if !(good && clean) {
            failures.push(format!(
                "{name}: exit {code:?}, expected {message:?}:\n{all}"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
