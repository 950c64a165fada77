//! Shared by the CLI integration tests: the binary, and small generated meshes (nothing is
//! committed: every test writes its own inputs into a temporary folder).
#![allow(dead_code)]

use foldmatch::io::{write_mesh, MeshData};
use foldmatch::synthetic::{folded_sheet, SheetSpec};
use std::path::{Path, PathBuf};

/// The `foldmatch` binary built for this test run.
pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_foldmatch")
}

/// A `foldmatch` command running in `dir`, without progress bars and with a fixed terminal
/// width (so that output is stable).
pub fn foldmatch(dir: &Path) -> snapbox::cmd::Command {
    snapbox::cmd::Command::new(bin())
        .current_dir(dir)
        .env("FOLDMATCH_NO_PROGRESS", "1")
        .env("COLUMNS", "100")
}

/// A small generated case: a `n × n` sheet template and a folded scan of `points` samples.
pub struct Case {
    /// Template (mesh).
    pub template: PathBuf,
    /// Scan (point cloud).
    pub scan: PathBuf,
    /// Ground truth (mesh, same vertex order as the template).
    pub gt: PathBuf,
}

/// The generated sheet case with a given seed (different seeds give different scans).
pub fn sheet(n: usize, points: usize, seed: u64) -> foldmatch::synthetic::Case {
    folded_sheet(&SheetSpec {
        nx: n,
        ny: n,
        scan_points: points,
        noise: 0.001,
        seed,
        ..SheetSpec::default()
    })
}

/// Writes `template.ply`, `scan.ply` and `gt.ply` of a 15 × 15 sheet into `dir`.
pub fn write_case(dir: &Path) -> Case {
    let c = sheet(15, 400, 1);
    let case = Case {
        template: dir.join("template.ply"),
        scan: dir.join("scan.ply"),
        gt: dir.join("gt.ply"),
    };
    write_mesh(
        &case.template,
        &MeshData::new(c.template_vertices.clone(), c.faces.clone()),
        &[],
        false,
    )
    .unwrap();
    write_mesh(
        &case.scan,
        &MeshData::point_cloud(c.scan.clone()),
        &[],
        false,
    )
    .unwrap();
    write_mesh(
        &case.gt,
        &MeshData::new(c.ground_truth.clone(), c.faces.clone()),
        &[],
        false,
    )
    .unwrap();
    case
}

/// Writes a scan of the sheet with a given seed (a point cloud; binary PLY or OBJ) to `path`.
pub fn write_scan(path: &Path, seed: u64) {
    let c = sheet(15, 400, seed);
    write_mesh(path, &MeshData::point_cloud(c.scan), &[], false).unwrap();
}

/// Writes the case of `write_case` and a folder `scans/` of `n` scans `s0.ply`, `s1.ply`, …
/// (`s{i}.ply` of seed `i`).
pub fn write_case_and_scans(dir: &Path, n: u64) {
    write_case(dir);
    std::fs::create_dir(dir.join("scans")).unwrap();
    for i in 0..n {
        write_scan(&dir.join(format!("scans/s{i}.ply")), i);
    }
}

/// `foldmatch batch template.ply scans -o out ARGS` running in `dir` (as `foldmatch` runs).
pub fn batch(dir: &Path, args: &[&str]) -> snapbox::cmd::Command {
    foldmatch(dir)
        .args(["batch", "template.ply", "scans", "-o", "out"])
        .args(args)
}

/// An ASCII PLY point cloud with the given rows, written as is (for broken inputs).
pub fn ascii_cloud(rows: &[&str], announced: usize) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {announced}\nproperty double x\nproperty double y\nproperty double z\nend_header\n"
    );
    for r in rows {
        s.push_str(r);
        s.push('\n');
    }
    s
}

/// Names of the entries of `dir` (recursively, `/`-separated, sorted).
pub fn tree(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((d, prefix)) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let e = e.unwrap();
            let name = format!("{prefix}{}", e.file_name().to_string_lossy());
            if e.file_type().unwrap().is_dir() {
                stack.push((e.path(), format!("{name}/")));
            }
            out.push(name);
        }
    }
    out.sort();
    out
}

/// Reads a JSON file.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// An `.npy` file as `np.save` writes it (format 1.0, header padded to 64 bytes): `descr` e.g.
/// `<f8` or `|b1`, `shape` e.g. `(400,)`, `payload` the little-endian data.
pub fn npy_bytes(descr: &str, shape: &str, payload: &[u8]) -> Vec<u8> {
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    let used = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat((64 - used % 64) % 64));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((dict.len() as u16).to_le_bytes());
    out.extend(dict.as_bytes());
    out.extend(payload);
    out
}

/// Writes `values` as a `float64` `.npy` array of shape `(N,)`.
pub fn write_npy_f64(path: &Path, values: &[f64]) {
    let payload: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let shape = format!("({},)", values.len());
    std::fs::write(path, npy_bytes("<f8", &shape, &payload)).unwrap();
}

/// Writes a binary PLY point cloud with `double x y z` and a `uchar NAME` per vertex, as a
/// segmenter writes its labels.
pub fn write_labelled_cloud(path: &Path, points: &[[f64; 3]], name: &str, labels: &[u8]) {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\n\
         property double y\nproperty double z\nproperty uchar {name}\nend_header\n",
        points.len()
    )
    .into_bytes();
    for (p, &l) in points.iter().zip(labels) {
        for c in p {
            out.extend(c.to_le_bytes());
        }
        out.push(l);
    }
    std::fs::write(path, out).unwrap();
}
