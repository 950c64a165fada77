//! `foldmatch batch` end to end: a folder of good scans and every kind of bad file, the report,
//! the exit code of a partial failure, bounded memory, `--resume`, recursion and globs, and a
//! clean stop on Ctrl-C. Inputs are generated into temporary folders.

mod cli_common;

use cli_common::{
    ascii_cloud, batch, foldmatch, json, tree, write_case, write_case_and_scans, write_scan,
};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

/// The folder of the acceptance test: three good scans (binary PLY, ASCII PLY, OBJ) and five
/// bad files.
fn scan_folder(dir: &Path) {
    let scans = dir.join("scans");
    std::fs::create_dir_all(&scans).unwrap();
    write_scan(&scans.join("good_a.ply"), 2);
    write_scan(&scans.join("good_b.obj"), 3);
    // An ASCII PLY (write_scan writes binary PLY; rewrite one as text).
    let cloud = foldmatch::io::read_mesh(&scans.join("good_a.ply")).unwrap();
    foldmatch::io::write_mesh(&scans.join("good_c.ply"), &cloud, &[], true).unwrap();
    // Truncated: the first 2000 bytes of a binary PLY of 400 points.
    let bytes = std::fs::read(scans.join("good_a.ply")).unwrap();
    std::fs::write(scans.join("truncated.ply"), &bytes[..2000]).unwrap();
    // A header announcing 10⁹ vertices.
    std::fs::write(
        scans.join("huge_header.ply"),
        ascii_cloud(&["0 0 0", "1 1 1"], 1_000_000_000),
    )
    .unwrap();
    // A binary file renamed .ply (the test binary itself, 64 KB of it).
    let exe = std::fs::read(std::env::current_exe().unwrap()).unwrap();
    std::fs::write(
        scans.join("renamed_binary.ply"),
        &exe[..65536.min(exe.len())],
    )
    .unwrap();
    std::fs::write(scans.join("empty.ply"), "").unwrap();
    std::fs::write(
        scans.join("nan_coords.ply"),
        ascii_cloud(&["0 0 0", "0.1 0.2 nan", "0.3 0 0"], 3),
    )
    .unwrap();
    // Not a mesh: ignored.
    std::fs::write(scans.join("notes.txt"), "not a scan").unwrap();
}

fn entries(report: &Value) -> BTreeMap<String, Value> {
    report["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| (f["name"].as_str().unwrap().to_string(), f.clone()))
        .collect()
}

fn mtimes(dir: &Path, names: &[&str]) -> Vec<SystemTime> {
    names
        .iter()
        .map(|n| std::fs::metadata(dir.join(n)).unwrap().modified().unwrap())
        .collect()
}

/// Peak resident memory of the children this test process has waited for, in MB.
#[cfg(unix)]
fn children_peak_mb() -> f64 {
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage only writes into the struct it is given.
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) };
    assert_eq!(rc, 0);
    // ru_maxrss is in kilobytes on Linux, in bytes on macOS.
    let kb = if cfg!(target_os = "macos") {
        usage.ru_maxrss as f64 / 1024.0
    } else {
        usage.ru_maxrss as f64
    };
    kb / 1024.0
}

#[test]
fn good_scans_are_fitted_bad_ones_reported_and_resume_redoes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    scan_folder(d);
    let before = tree(&d.join("scans"));

    let out = batch(d, &["--iterations", "4", "--jobs", "2"])
        .assert()
        .code(2)
        .stdout_eq("")
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();

    // Every good scan fitted, nothing else written, nothing written outside -o.
    assert_eq!(
        tree(&d.join("out")),
        [
            ".foldmatch.lock",
            "good_a.ply",
            "good_b.ply",
            "good_c.ply",
            "report.json"
        ]
    );
    assert_eq!(tree(&d.join("scans")), before);
    let report = json(&d.join("out/report.json"));
    assert_eq!(report["state"], "complete");
    assert_eq!(report["command"], "batch");
    // Independent scans start from the default preset (schedule selection on).
    assert_eq!(report["params"]["selection"], "scan_distance");
    assert_eq!(
        report["summary"],
        serde_json::json!({"total": 8, "ok": 3, "error": 5, "skipped": 0, "interrupted": 0, "pending": 0})
    );
    let files = entries(&report);
    for good in ["good_a.ply", "good_b.obj", "good_c.ply"] {
        let f = &files[good];
        assert_eq!(f["status"], "ok", "{f}");
        assert!(f["error"].is_null());
        assert_eq!(f["iterations"], 4);
        assert!(f["seconds"].as_f64().unwrap() > 0.0);
        assert!(f["metrics"]["scan_to_fit_mean"].as_f64().unwrap() > 0.0);
        assert!(f["diagnostics"].is_object());
    }
    // Every bad file reported by name with its reason, in the report and on stderr.
    let reasons = [
        ("truncated.ply", "truncated.ply:"),
        (
            "huge_header.ply",
            "header announces 1000000000 vertices but the file holds at most",
        ),
        ("renamed_binary.ply", "not a PLY file"),
        ("empty.ply", "empty file"),
        ("nan_coords.ply", "non-finite coordinate at row 1"),
    ];
    for (name, reason) in reasons {
        let f = &files[name];
        assert_eq!(f["status"], "error", "{f}");
        let error = f["error"].as_str().unwrap();
        assert!(error.contains(&format!("scans/{name}")), "{error}");
        assert!(error.contains(reason), "{name}: {error}");
        assert!(stderr.contains(&format!("] {name}: {error}\n")), "{stderr}");
    }
    assert!(
        stderr.contains("batch: 3 ok, 5 failed, 0 skipped in "),
        "{stderr}"
    );
    assert!(stderr.contains("error: 5 of 8 files failed: "), "{stderr}");
    #[cfg(unix)]
    {
        let peak = children_peak_mb();
        assert!(peak < 400.0, "peak memory of the CLI {peak:.0} MB");
    }

    // --resume: nothing done is redone (outputs untouched), the bad files are tried again.
    let outputs = ["out/good_a.ply", "out/good_b.ply", "out/good_c.ply"];
    let stamps = mtimes(d, &outputs);
    std::thread::sleep(Duration::from_millis(20));
    let out = batch(d, &["--iterations", "4", "--resume", "--jobs", "1"])
        .assert()
        .code(2)
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains("batch: 8 scans in scans, 5 to fit"),
        "{stderr}"
    );
    assert!(
        stderr.contains("batch: 0 ok, 5 failed, 3 skipped"),
        "{stderr}"
    );
    assert_eq!(
        mtimes(d, &outputs),
        stamps,
        "--resume rewrote a finished output"
    );
    let report = json(&d.join("out/report.json"));
    let files = entries(&report);
    for good in ["good_a.ply", "good_b.obj", "good_c.ply"] {
        assert_eq!(files[good]["status"], "skipped");
        assert!(
            files[good]["metrics"].is_object(),
            "the earlier figures are kept"
        );
    }
    // A second resume still skips them; a removed output is fitted again.
    std::fs::remove_file(d.join("out/good_b.ply")).unwrap();
    let out = foldmatch(d)
        .args([
            "-v",
            "batch",
            "template.ply",
            "scans",
            "-o",
            "out",
            "--iterations",
            "4",
            "--resume",
            "--glob",
            "good*",
        ])
        .assert()
        .code(0)
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains("batch: 3 scans in scans, 1 to fit"),
        "{stderr}"
    );
    assert!(
        stderr.contains("skipped good_a.ply (done by an earlier run)"),
        "{stderr}"
    );
    assert!(
        stderr.contains("ok      good_b.obj -> out/good_b.ply"),
        "{stderr}"
    );
    assert_eq!(
        mtimes(d, &["out/good_a.ply", "out/good_c.ply"]),
        [stamps[0], stamps[2]]
    );
    assert!(
        tree(d).iter().all(|n| !n.contains(".tmp.")),
        "{:?}",
        tree(d)
    );
}

#[test]
fn recursive_glob_collisions_and_the_output_inside_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let scans = d.join("scans");
    for name in [
        "a.ply",
        "a.obj",
        "sub/b.ply",
        "sub/deeper/c.obj",
        "sub/skip.obj",
    ] {
        let p = scans.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        write_scan(&p, name.len() as u64);
    }
    // The output folder inside the input folder is not scanned (a second run finds the same).
    for _ in 0..2 {
        foldmatch(d)
            .args([
                "-q",
                "batch",
                "template.ply",
                "scans",
                "-o",
                "scans/out",
                "-r",
                "--glob",
                "[abc].*",
            ])
            .args(["--iterations", "2", "--format", "obj"])
            .assert()
            .code(0)
            .stdout_eq("")
            .stderr_eq("");
    }
    assert_eq!(
        tree(&scans.join("out")),
        [
            ".foldmatch.lock",
            "a.obj.obj",
            "a.ply.obj",
            "report.json",
            "sub",
            "sub/b.obj",
            "sub/deeper",
            "sub/deeper/c.obj"
        ]
    );
    let report = json(&scans.join("out/report.json"));
    let names: Vec<&str> = report["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["a.obj", "a.ply", "sub/b.ply", "sub/deeper/c.obj"]);
    // The same folder as input and output is refused.
    foldmatch(d)
        .args(["batch", "template.ply", "scans", "-o", "scans/"])
        .assert()
        .code(1)
        .stderr_eq("error: the output folder scans/ is the input folder: choose another -o\n");
}

#[test]
fn fatal_errors_exit_with_1_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    std::fs::create_dir(d.join("none")).unwrap();
    std::fs::write(d.join("none/readme.txt"), "").unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["batch", "template.ply", "missing", "-o", "o"],
            "error: missing: No such file or directory (os error 2)\n",
        ),
        (
            &["batch", "template.ply", "scan.ply", "-o", "o"],
            "error: scan.ply: not a folder\n",
        ),
        (
            &["batch", "template.ply", "none", "-o", "o"],
            "error: none: no .ply or .obj files\n",
        ),
        (
            &["batch", "template.ply", "none", "-o", "o", "--glob", "x*"],
            "error: none: no .ply or .obj files matching \"x*\"\n",
        ),
        (
            &["batch", "nope.obj", "none", "-o", "o"],
            "error: template: nope.obj: No such file or directory (os error 2)\n",
        ),
        (
            &["sequence", "template.ply", "none", "-o", "o"],
            "error: none: no .ply or .obj files\n",
        ),
    ];
    for (args, expected) in cases {
        foldmatch(d)
            .args(*args)
            .assert()
            .code(1)
            .stdout_eq("")
            .stderr_eq(*expected);
    }
    assert!(!d.join("o").exists());
}

/// Ctrl-C (SIGINT) stops a running batch: exit code 130, no half-written output and no
/// temporary file, a valid report that says so.
#[cfg(unix)]
#[test]
fn ctrl_c_stops_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case_and_scans(d, 3);
    let mut child = std::process::Command::new(cli_common::bin())
        .current_dir(d)
        .env("FOLDMATCH_NO_PROGRESS", "1")
        .args([
            "batch",
            "template.ply",
            "scans",
            "-o",
            "out",
            "--iterations",
            "1000000",
            "--jobs",
            "2",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    while !d.join("out/report.json").exists() {
        assert!(Instant::now() < deadline, "the batch never started");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    let status = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let started = Instant::now();
    let code = child.wait().unwrap().code();
    assert_eq!(code, Some(130));
    assert!(started.elapsed() < Duration::from_secs(10), "slow to stop");
    assert_eq!(
        tree(&d.join("out")),
        [".foldmatch.lock", "report.json"],
        "no partial output, no temporary file"
    );
    let report = json(&d.join("out/report.json"));
    assert_eq!(report["state"], "interrupted");
    let statuses: Vec<&str> = report["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["status"].as_str().unwrap())
        .collect();
    // The first scan was being fitted; on a busy machine the second job may not have started.
    assert_eq!(statuses[0], "interrupted");
    assert!(
        statuses
            .iter()
            .all(|s| *s == "interrupted" || *s == "pending"),
        "{statuses:?}"
    );
    assert_eq!(statuses[2], "pending");
}

/// Starts `foldmatch batch template.ply scans -o out ARGS` in `d` without waiting.
fn spawn_batch(d: &Path, args: &[&str]) -> std::process::Child {
    std::process::Command::new(cli_common::bin())
        .current_dir(d)
        .env("FOLDMATCH_NO_PROGRESS", "1")
        .args(["batch", "template.ply", "scans", "-o", "out"])
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap()
}

/// The fitted outputs in `out` (not the report, the lock or staged files).
fn outputs(d: &Path) -> Vec<String> {
    if !d.join("out").is_dir() {
        return Vec::new();
    }
    tree(&d.join("out"))
        .into_iter()
        .filter(|n| n.ends_with(".ply") && !n.starts_with('.'))
        .collect()
}

/// Issue 31, items 6 and 7: after `kill -9` mid-batch, every output in the folder is recorded
/// as done by the report (written before the output is renamed into place), and `--resume`
/// fits none of them again (not even one killed between its report and its rename); the
/// killed run's lock is stale and taken over.
#[cfg(unix)]
#[test]
fn kill_9_mid_batch_then_resume_fits_nothing_twice() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 6;
    write_case_and_scans(d, n as u64);
    let args = ["--iterations", "60", "--jobs", "1"];
    let mut child = spawn_batch(d, &args);
    let deadline = Instant::now() + Duration::from_secs(60);
    while outputs(d).len() < 2 {
        assert!(Instant::now() < deadline, "the batch wrote no output");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let written = outputs(d);
    assert!(written.len() < n, "the batch finished before the kill");
    let report = json(&d.join("out/report.json"));
    let files = entries(&report);
    for name in &written {
        let scan = name.clone();
        assert_eq!(
            files[&scan]["status"], "ok",
            "{name} is not recorded: {report}"
        );
    }
    // Simulate a kill between the report and the rename for the first output: recorded, but
    // still under its staged name.
    let first = written[0].clone();
    std::fs::rename(
        d.join("out").join(&first),
        d.join("out").join(format!(".{first}.staged.ply")),
    )
    .unwrap();
    let staged = format!(".{first}.staged.ply");
    // And a kill in the middle of writing the last output's staged file: its temporary file.
    let torn = format!("..{}.staged.ply.tmp.99999.0", written[written.len() - 1]);
    std::fs::write(d.join("out").join(&torn), b"ply\nformat ascii 1.0\n").unwrap();
    let stamps = mtimes(&d.join("out"), &[staged.as_str()]);
    let others: Vec<&str> = written[1..].iter().map(String::as_str).collect();
    let other_stamps = mtimes(&d.join("out"), &others);
    let recorded = files.values().filter(|f| f["status"] == "ok").count();
    std::thread::sleep(Duration::from_millis(20));

    let out = batch(d, &["--resume", "-v"])
        .args(args)
        .assert()
        .success()
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains(&format!(
            "batch: {n} scans in scans, {} to fit",
            n - recorded
        )),
        "{stderr}"
    );
    assert!(stderr.contains("taking over the lock"), "{stderr}");
    assert_eq!(outputs(d).len(), n);
    assert_eq!(
        mtimes(&d.join("out"), &[first.as_str()]),
        stamps,
        "refitted {first}"
    );
    assert_eq!(
        mtimes(&d.join("out"), &others),
        other_stamps,
        "refitted an output"
    );
    assert!(!d.join("out").join(&staged).exists());
    assert!(!d.join("out").join(&torn).exists(), "{torn} left behind");
    let report = json(&d.join("out/report.json"));
    assert_eq!(report["state"], "complete");
    assert_eq!(report["summary"]["skipped"], recorded);
    assert_eq!(report["summary"]["ok"], n - recorded);
}

/// Issue 31, item 6: two runs never write into one folder (the second is refused, naming the
/// first one's pid), and `--resume` with other parameters refuses instead of mixing.
#[cfg(unix)]
#[test]
fn one_run_per_folder_and_resume_never_mixes_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case_and_scans(d, 2);
    let mut first = spawn_batch(d, &["--iterations", "1000000", "--jobs", "1"]);
    let deadline = Instant::now() + Duration::from_secs(30);
    while !d.join("out/report.json").exists() {
        assert!(Instant::now() < deadline, "the first batch never started");
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = batch(d, &["--iterations", "3"])
        .assert()
        .code(1)
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains(&format!(
            "out: another foldmatch run (pid {}) is writing into this folder",
            first.id()
        )),
        "{stderr}"
    );
    first.kill().unwrap();
    first.wait().unwrap();

    batch(d, &["--iterations", "3"]).assert().success();
    let stamps = mtimes(d, &["out/s0.ply", "out/s1.ply"]);
    let out = batch(d, &["--resume"])
        .args(["--iterations", "4", "--psi", "0.1"])
        .assert()
        .code(1)
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains("--resume: out/report.json was written with other settings (")
            && stderr.contains("iterations 3 -> 4")
            && stderr.contains("psi 0.05 -> 0.1"),
        "{stderr}"
    );
    assert_eq!(mtimes(d, &["out/s0.ply", "out/s1.ply"]), stamps);
    assert_eq!(json(&d.join("out/report.json"))["params"]["iterations"], 3);
    // The same parameters resume (nothing to do).
    let out = foldmatch(d)
        .args(["batch", "template.ply", "scans", "-o", "out", "--resume"])
        .args(["--iterations", "3"])
        .assert()
        .success()
        .get_output()
        .clone();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("2 scans in scans, 0 to fit"), "{stderr}");
    assert_eq!(mtimes(d, &["out/s0.ply", "out/s1.ply"]), stamps);
}
