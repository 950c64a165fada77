//! Landmarks on the command line: `fit --landmarks FILE` (JSON or CSV) places and holds the
//! landmark vertices, and every bad file is refused naming the file and the line.

mod cli_common;

use cli_common::{foldmatch, write_case};
use foldmatch::io::{read_mesh, write_mesh, MeshData};
use snapbox::str;

/// The template turned by 90° about z and moved: with four landmarks at the turned corners'
/// places (from a JSON and from a CSV file, the same fit) the fitted corners land there; the
/// turn is far outside what the scan alone would undo.
#[test]
fn landmark_files_place_and_hold_the_template() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let case = write_case(d);
    let template = read_mesh(&case.template).unwrap();
    let gt = read_mesh(&case.gt).unwrap().vertices;
    // The template turned by 90° about z and moved by 3 along x: far from the scan.
    let turned: Vec<[f64; 3]> = template
        .vertices
        .iter()
        .map(|p| [3.0 - p[1], p[0], p[2]])
        .collect();
    write_mesh(
        &d.join("turned.ply"),
        &MeshData::new(turned, template.faces.clone()),
        &[],
        false,
    )
    .unwrap();
    let corners = [0usize, 14, 210, 224];
    let json = format!(
        "{{\"vertices\": {:?}, \"positions\": {:?}}}",
        corners,
        corners.iter().map(|&c| gt[c]).collect::<Vec<_>>()
    );
    std::fs::write(d.join("lm.json"), json).unwrap();
    let csv: String = std::iter::once("# corners\nindex,x,y,z\n".to_string())
        .chain(corners.iter().map(|&c| {
            let p = gt[c];
            format!("{c}, {:?}, {:?}, {:?}\n", p[0], p[1], p[2])
        }))
        .collect();
    std::fs::write(d.join("lm.csv"), csv).unwrap();
    for (file, out) in [("lm.json", "a.ply"), ("lm.csv", "b.ply")] {
        foldmatch(d)
            .args(["-q", "fit", "turned.ply", "scan.ply", "-o", out])
            .args(["--iterations", "30", "--landmarks", file])
            .assert()
            .code(0)
            .stderr_eq(str![""]);
    }
    let a = read_mesh(&d.join("a.ply")).unwrap().vertices;
    let b = read_mesh(&d.join("b.ply")).unwrap().vertices;
    assert_eq!(a, b, "JSON and CSV give the same fit");
    for &c in &corners {
        let gap = foldmatch::math::dist2(&a[c], &gt[c]).sqrt();
        assert!(gap < 0.02, "corner {c} is {gap} from its landmark");
    }
}

#[test]
fn bad_landmark_files_are_refused_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d); // 15 × 15 = 225 template vertices
    let files = [
        ("range.csv", "index,x,y,z\n0,0,0,0\n225,0,0,0\n"),
        ("negative.csv", "-1,0,0,0\n"),
        ("twice.csv", "3,0,0,0\n# again\n3,1,1,1\n"),
        ("nan.csv", "3,0,nan,0\n"),
        ("short.csv", "3,0,0\n"),
        ("word.csv", "three,0,0,0\n"),
        ("empty.csv", "# nothing\n"),
        (
            "counts.json",
            "{\"vertices\": [1, 2], \"positions\": [[0, 0, 0]]}",
        ),
        (
            "shape.json",
            "{\"vertices\": [1],\n \"positions\": [[0, 0]]}",
        ),
    ];
    for (name, text) in files {
        std::fs::write(d.join(name), text).unwrap();
    }
    let cases: &[(&str, &str)] = &[
        ("range.csv", "error: landmarks range.csv:3: landmark 1: vertex 225 is out of range: the template has 225 vertices\n"),
        ("negative.csv", "error: landmarks negative.csv:1: landmark 0: vertex -1 is out of range: the template has 225 vertices\n"),
        ("twice.csv", "error: landmarks twice.csv:3: landmark 1: vertex 3 is already constrained by landmark 0\n"),
        ("nan.csv", "error: landmarks nan.csv:1: landmark 0: non-finite target coordinate (NaN) for vertex 3\n"),
        ("short.csv", "error: landmarks short.csv:1: expected 4 fields index,x,y,z, found 3\n"),
        ("word.csv", "error: landmarks word.csv:1: vertex index \"three\" is not a whole number\n"),
        ("empty.csv", "error: landmarks empty.csv:0: no landmarks (pass none instead of an empty list)\n"),
        ("counts.json", "error: landmarks counts.json:0: 2 vertex indices but 1 target positions (need one position per index)\n"),
        ("shape.json", "error: landmarks shape.json:2: invalid length 2, expected an array of length 3 (expected {\"vertices\": [i, ...], \"positions\": [[x, y, z], ...]})\n"),
        ("missing.csv", "error: landmarks missing.csv: No such file or directory (os error 2)\n"),
    ];
    for (file, expected) in cases {
        foldmatch(d)
            .args(["fit", "template.ply", "scan.ply", "-o", "o.ply"])
            .args(["--landmarks", file])
            .assert()
            .code(1)
            .stdout_eq(str![""])
            .stderr_eq(*expected);
    }
    assert!(!d.join("o.ply").exists());
}
