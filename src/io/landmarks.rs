//! Landmark files (`foldmatch fit --landmarks FILE`): template vertex indices and their target
//! positions on the scan, as JSON `{"vertices": [i, ...], "positions": [[x, y, z], ...]}` or
//! as CSV lines `index,x,y,z` (blank lines and `#` comments skipped, an optional header line
//! `index,x,y,z`). The extension decides (`.json`; anything else is read as CSV). Every error
//! names the file and the line ([`FoldMatchError::Format`]).

use crate::error::{FoldMatchError, Result};
use crate::landmarks::Landmarks;
use std::path::Path;

/// The pairs of a landmark file, in file order, with the 1-based line each landmark came
/// from (CSV; for JSON the line of the `"vertices"` key's array is not tracked: 0).
#[derive(Clone, Debug, PartialEq)]
pub struct LandmarkFile {
    /// Template vertex indices, as written (range-checked against a template by
    /// [`LandmarkFile::for_template`]).
    pub vertices: Vec<i64>,
    /// Target positions.
    pub positions: Vec<[f64; 3]>,
    /// The line of each landmark (0: not known).
    pub lines: Vec<usize>,
}

impl LandmarkFile {
    /// The landmarks validated against a template of `template_vertices` vertices; an error
    /// about one landmark names the file and its line.
    pub fn for_template(&self, path: &Path, template_vertices: usize) -> Result<Landmarks> {
        Landmarks::new(&self.vertices, &self.positions, template_vertices).map_err(|e| match e {
            FoldMatchError::Landmark { index, reason } => FoldMatchError::Format {
                path: path.display().to_string(),
                line: self.lines[index],
                reason: format!("landmark {index}: {reason}"),
            },
            FoldMatchError::Shape { reason, .. } => format_error(path, 0, reason),
            other => other,
        })
    }
}

fn format_error(path: &Path, line: usize, reason: impl Into<String>) -> FoldMatchError {
    FoldMatchError::Format {
        path: path.display().to_string(),
        line,
        reason: reason.into(),
    }
}

/// Reads a landmark file (JSON or CSV by extension).
pub fn read_landmarks(path: &Path) -> Result<LandmarkFile> {
    let text = std::fs::read_to_string(path).map_err(|source| FoldMatchError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if json {
        parse_json(path, &text)
    } else {
        parse_csv(path, &text)
    }
}

/// Parses the JSON form.
pub fn parse_json(path: &Path, text: &str) -> Result<LandmarkFile> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Form {
        vertices: Vec<i64>,
        positions: Vec<[f64; 3]>,
    }
    let form: Form = serde_json::from_str(text).map_err(|e| {
        let reason = e.to_string();
        let reason = reason.split(" at line ").next().unwrap_or(&reason);
        format_error(
            path,
            e.line(),
            format!(
                "{reason} (expected {{\"vertices\": [i, ...], \"positions\": [[x, y, z], ...]}})"
            ),
        )
    })?;
    let lines = vec![0; form.vertices.len()];
    Ok(LandmarkFile {
        vertices: form.vertices,
        positions: form.positions,
        lines,
    })
}

/// Parses the CSV form: `index,x,y,z` per line.
pub fn parse_csv(path: &Path, text: &str) -> Result<LandmarkFile> {
    let mut out = LandmarkFile {
        vertices: Vec::new(),
        positions: Vec::new(),
        lines: Vec::new(),
    };
    let mut seen_data = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        let header = fields.eq_ignore_ascii_case_all(&["index", "x", "y", "z"]);
        if header && !seen_data {
            seen_data = true;
            continue;
        }
        seen_data = true;
        if fields.len() != 4 {
            return Err(format_error(
                path,
                line,
                format!("expected 4 fields index,x,y,z, found {}", fields.len()),
            ));
        }
        let index: i64 = fields[0].parse().map_err(|_| {
            format_error(
                path,
                line,
                format!("vertex index {:?} is not a whole number", fields[0]),
            )
        })?;
        let mut p = [0.0; 3];
        for (k, f) in fields[1..].iter().enumerate() {
            p[k] = f.parse().map_err(|_| {
                format_error(path, line, format!("coordinate {f:?} is not a number"))
            })?;
        }
        out.vertices.push(index);
        out.positions.push(p);
        out.lines.push(line);
    }
    Ok(out)
}

/// Case-insensitive comparison of a row of fields with a header.
trait HeaderRow {
    fn eq_ignore_ascii_case_all(&self, header: &[&str]) -> bool;
}

impl HeaderRow for Vec<&str> {
    fn eq_ignore_ascii_case_all(&self, header: &[&str]) -> bool {
        self.len() == header.len()
            && self
                .iter()
                .zip(header)
                .all(|(a, b)| a.eq_ignore_ascii_case(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reason(e: FoldMatchError) -> (usize, String) {
        match e {
            FoldMatchError::Format { line, reason, .. } => (line, reason),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn csv_and_json_read_the_same_landmarks() {
        let p = Path::new("lm.csv");
        let csv = "# clicked on the scan\nindex,x,y,z\n3, 0.5, 1, -2\n\n7,1e-3,0,0  # cuff\n";
        let a = parse_csv(p, csv).unwrap();
        assert_eq!(a.vertices, vec![3, 7]);
        assert_eq!(a.positions, vec![[0.5, 1.0, -2.0], [1e-3, 0.0, 0.0]]);
        assert_eq!(a.lines, vec![3, 5]);
        let json = r#"{"vertices": [3, 7], "positions": [[0.5, 1, -2], [0.001, 0, 0]]}"#;
        let b = parse_json(Path::new("lm.json"), json).unwrap();
        assert_eq!((b.vertices, b.positions), (a.vertices, a.positions));
    }

    #[test]
    fn malformed_files_name_the_line() {
        let p = Path::new("lm.csv");
        let (line, why) = reason(parse_csv(p, "1,0,0,0\n2,0,0\n").unwrap_err());
        assert_eq!(line, 2);
        assert!(why.contains("expected 4 fields"), "{why}");
        let (line, why) = reason(parse_csv(p, "1,0,0,0\n\nx,0,0,0\n").unwrap_err());
        assert_eq!(line, 3);
        assert!(why.contains("\"x\" is not a whole number"), "{why}");
        let (line, why) = reason(parse_csv(p, "1,0,zero,0\n").unwrap_err());
        assert_eq!(line, 1);
        assert!(why.contains("\"zero\" is not a number"), "{why}");
        let (line, why) = reason(
            parse_json(
                Path::new("lm.json"),
                "{\"vertices\": [1],\n \"positions\": [[1, 2]]}",
            )
            .unwrap_err(),
        );
        assert_eq!(line, 2);
        assert!(why.contains("expected {\"vertices\""), "{why}");
    }

    #[test]
    fn landmarks_out_of_the_template_name_their_line() {
        let p = Path::new("lm.csv");
        let file = parse_csv(p, "index,x,y,z\n1,0,0,0\n5,0,0,nan\n1,1,1,1\n").unwrap();
        let (line, why) = reason(file.for_template(p, 10).unwrap_err());
        assert_eq!(line, 3);
        assert!(why.contains("landmark 1: non-finite"), "{why}");
        let (line, why) = reason(file.for_template(p, 3).unwrap_err());
        assert_eq!(line, 3);
        assert!(why.contains("vertex 5 is out of range"), "{why}");
        let file = parse_csv(p, "1,0,0,0\n1,1,1,1\n").unwrap();
        let (line, why) = reason(file.for_template(p, 10).unwrap_err());
        assert_eq!(line, 2);
        assert!(why.contains("already constrained by landmark 0"), "{why}");
        let (line, why) = reason(
            parse_csv(p, "# none\n")
                .unwrap()
                .for_template(p, 10)
                .unwrap_err(),
        );
        assert_eq!(line, 0);
        assert!(why.contains("no landmarks"), "{why}");
    }
}
