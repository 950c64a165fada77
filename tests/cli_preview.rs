//! `--preview`: the PNG that `fit`, `batch` and `demo` draw of a fit, decoded and checked —
//! its size, that it is not blank, and that the mesh's pixels in the wrinkle-field row carry
//! the field's colors (viridis, shaded) while the distance row's do not.

mod cli_common;

use cli_common::{batch, foldmatch, json, tree, write_case, write_case_and_scans};
use foldmatch::io::colormap_viridis;
use std::collections::HashSet;
use std::path::Path;

/// A decoded 8-bit RGB PNG and its `tEXt` chunks.
struct Png {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
    text: Vec<(String, String)>,
}

impl Png {
    fn read(path: &Path) -> Self {
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut rgb).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        rgb.truncate(info.buffer_size());
        let text = reader
            .info()
            .uncompressed_latin1_text
            .iter()
            .map(|t| (t.keyword.clone(), t.text.clone()))
            .collect();
        Self {
            width: info.width as usize,
            height: info.height as usize,
            rgb,
            text,
        }
    }

    fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * self.width + x);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// The pixels of the panel at (`row`, `col`) of the 320-pixel grid that are neither
    /// background nor gray (text, scan points and separators are gray).
    fn colored_in_panel(&self, row: usize, col: usize) -> Vec<[u8; 3]> {
        let mut out = Vec::new();
        for y in row * 320..(row + 1) * 320 {
            for x in col * 320..(col + 1) * 320 {
                let p = self.pixel(x, y);
                let spread = p.iter().max().unwrap() - p.iter().min().unwrap();
                if spread > 24 {
                    out.push(p);
                }
            }
        }
        out
    }
}

/// How far `p` is from the nearest viridis color shaded by a factor in [0.3, 1], and the
/// index of that color.
fn off_viridis(p: [u8; 3]) -> (f64, usize) {
    let table = colormap_viridis(&(0..256).map(f64::from).collect::<Vec<_>>(), 0.0, 255.0);
    let p = p.map(f64::from);
    table
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let c = c.map(f64::from);
            let cc: f64 = c.iter().map(|v| v * v).sum();
            let s = (p.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>() / cc).clamp(0.3, 1.0);
            let d2: f64 = p.iter().zip(&c).map(|(a, b)| (a - s * b).powi(2)).sum();
            (d2.sqrt(), i)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap()
}

/// The picture of a fit with a scan: 3 views × (scan, wrinkle field, distance) rows of 320
/// pixels plus the 96-pixel color-bar column.
fn check_fit_picture(png: &Png) {
    assert_eq!((png.width, png.height), (3 * 320 + 96, 3 * 320));
    let distinct: HashSet<[u8; 3]> = (0..png.height)
        .flat_map(|y| (0..png.width).map(move |x| (x, y)))
        .map(|(x, y)| png.pixel(x, y))
        .collect();
    assert!(distinct.len() > 500, "{} distinct colors", distinct.len());
    let white = png.rgb.chunks(3).filter(|p| p == &[255, 255, 255]).count();
    let share = white as f64 / (png.width * png.height) as f64;
    assert!(share > 0.2 && share < 0.95, "background {share}");

    for col in 0..3 {
        // The mesh covers a good part of each field panel, in viridis colors (shaded), and
        // with a range of them: the field is drawn, not one flat color.
        let field = png.colored_in_panel(1, col);
        assert!(field.len() > 320 * 320 / 20, "{} mesh pixels", field.len());
        let matched: Vec<(f64, usize)> = field.iter().map(|&p| off_viridis(p)).collect();
        let near = matched.iter().filter(|m| m.0 < 12.0).count();
        assert!(
            near as f64 > 0.95 * field.len() as f64,
            "view {col}: {near} of {} pixels on viridis",
            field.len()
        );
        let used: HashSet<usize> = matched.iter().map(|m| m.1 / 16).collect();
        assert!(used.len() >= 5, "view {col}: viridis bands used {used:?}");
        // The distance row is painted with another scale: mostly off viridis.
        let distance = png.colored_in_panel(2, col);
        assert!(distance.len() > 320 * 320 / 20);
        let on = distance
            .iter()
            .filter(|&&p| off_viridis(p).0 < 12.0)
            .count();
        assert!(
            (on as f64) < 0.5 * distance.len() as f64,
            "view {col}: {on} of {} distance pixels on viridis",
            distance.len()
        );
    }
    // The scan row is drawn in grays only.
    assert!(png.colored_in_panel(0, 0).is_empty());
    assert!(png
        .text
        .iter()
        .any(|(k, v)| k == "foldmatch:wrinkle_range" && v.starts_with("viridis of |w|")));
}

#[test]
fn fit_preview_draws_the_scan_the_field_and_the_distance() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    foldmatch(dir.path())
        .args(["fit", "template.ply", "scan.ply", "-o", "out/fitted.ply"])
        .args(["--iterations", "30", "--preview", "out/fit.png"])
        .args(["--report", "out/report.json"])
        .assert()
        .code(0);
    assert_eq!(
        tree(&dir.path().join("out")),
        ["fit.png", "fitted.ply", "report.json"]
    );
    check_fit_picture(&Png::read(&dir.path().join("out/fit.png")));
    assert_eq!(
        json(&dir.path().join("out/report.json"))["preview"],
        "out/fit.png"
    );
}

#[test]
fn fit_preview_must_be_a_png() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path());
    for preview in ["fit.jpg", "fit"] {
        let message = format!("--preview {preview}: must end in .png");
        let out = foldmatch(dir.path())
            .args(["fit", "template.ply", "scan.ply", "-o", "fitted.ply"])
            .args(["--preview", preview])
            .assert()
            .code(1)
            .get_output()
            .clone();
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert!(stderr.contains(&message), "{stderr}");
    }
    assert_eq!(tree(dir.path()), ["gt.ply", "scan.ply", "template.ply"]);
}

#[test]
fn batch_preview_writes_one_picture_per_scan_next_to_its_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case_and_scans(d, 2);
    batch(d, &["--iterations", "5", "--preview"])
        .assert()
        .code(0);
    // Committed like the meshes: no staged file is left behind.
    assert_eq!(
        tree(&d.join("out")),
        [
            ".foldmatch.lock",
            "report.json",
            "s0.ply",
            "s0.png",
            "s1.ply",
            "s1.png"
        ]
    );
    let report = json(&d.join("out/report.json"));
    for (i, file) in report["files"].as_array().unwrap().iter().enumerate() {
        assert_eq!(file["preview"], format!("out/s{i}.png"));
        let png = Png::read(&d.join(format!("out/s{i}.png")));
        assert_eq!((png.width, png.height), (3 * 320 + 96, 3 * 320));
    }
    // Previews are drawn locally only.
    let out = batch(d, &["--preview", "--scheduler", "local"])
        .assert()
        .code(1)
        .get_output()
        .clone();
    assert!(String::from_utf8(out.stderr)
        .unwrap()
        .contains("--scheduler"));
}

#[test]
fn demo_writes_a_preview() {
    let dir = tempfile::tempdir().unwrap();
    foldmatch(dir.path())
        .args([
            "demo",
            "-o",
            "demo",
            "--size",
            "21",
            "--scan-points",
            "1500",
        ])
        .assert()
        .code(0);
    check_fit_picture(&Png::read(&dir.path().join("demo/preview.png")));
}
