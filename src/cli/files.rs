//! Finding the scans of a folder and naming their outputs.

use glob::{MatchOptions, Pattern};
use std::cmp::Ordering;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A scan found in the input folder.
#[derive(Clone, Debug)]
pub struct Found {
    /// Path relative to the folder, `/`-separated (the report's `name`).
    pub name: String,
    /// Full path.
    pub path: PathBuf,
}

/// Whether the file name has a mesh extension (.ply / .obj, any case).
fn is_mesh(path: &Path) -> bool {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .is_some_and(|e| e == "ply" || e == "obj")
}

/// Every `.ply` / `.obj` file of `dir` (and its subfolders when `recursive`), hidden entries
/// (name starting with `.`) and the subtree `exclude` left out, filtered by `pattern`, in
/// natural order of their relative names.
pub fn find_scans(
    dir: &Path,
    recursive: bool,
    pattern: Option<&str>,
    exclude: Option<&Path>,
) -> Result<Vec<Found>, String> {
    let pattern = pattern
        .map(|p| Pattern::new(p).map_err(|e| format!("--glob {p:?}: {e}")))
        .transpose()?;
    let options = MatchOptions {
        case_sensitive: true,
        require_literal_separator: true,
        require_literal_leading_dot: false,
    };
    let exclude = exclude.and_then(|p| p.canonicalize().ok());
    let mut found = Vec::new();
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((folder, prefix)) = stack.pop() {
        let entries =
            std::fs::read_dir(&folder).map_err(|e| format!("{}: {e}", folder.display()))?;
        for entry in entries {
            let entry = entry.map_err(|e| format!("{}: {e}", folder.display()))?;
            let file_name = entry.file_name().to_string_lossy().into_owned();
            if file_name.starts_with('.') {
                continue;
            }
            let path = entry.path();
            let name = format!("{prefix}{file_name}");
            let kind = entry
                .file_type()
                .map_err(|e| format!("{}: {e}", path.display()))?;
            if kind.is_dir() {
                let excluded = exclude
                    .as_ref()
                    .is_some_and(|x| path.canonicalize().is_ok_and(|p| &p == x));
                if recursive && !excluded {
                    stack.push((path, format!("{name}/")));
                }
                continue;
            }
            // Files, and symbolic links to files.
            if !is_mesh(&path) || !path.is_file() {
                continue;
            }
            if let Some(p) = &pattern {
                let subject = if p.as_str().contains('/') {
                    name.as_str()
                } else {
                    file_name.as_str()
                };
                if !p.matches_with(subject, options) {
                    continue;
                }
            }
            found.push(Found { name, path });
        }
    }
    found.sort_by(|a, b| natural_cmp(&a.name, &b.name));
    Ok(found)
}

/// The scans of a list of paths: each must be a `.ply` / `.obj` file; their names (the
/// report's `name`, and the outputs' relative paths) are their paths relative to the deepest
/// folder that holds them all, which is returned first. The order is kept; a path given twice
/// is an error.
pub fn named_files(paths: &[PathBuf]) -> Result<(PathBuf, Vec<Found>), String> {
    if paths.is_empty() {
        return Err("no scans given".into());
    }
    let mut absolute = Vec::with_capacity(paths.len());
    for path in paths {
        if !is_mesh(path) {
            return Err(format!("{}: not a .ply or .obj file", path.display()));
        }
        if !path.is_file() {
            return Err(match std::fs::metadata(path) {
                Err(e) => format!("{}: {e}", path.display()),
                Ok(_) => format!("{}: not a file", path.display()),
            });
        }
        let abs = std::path::absolute(path).map_err(|e| format!("{}: {e}", path.display()))?;
        if absolute.contains(&abs) {
            return Err(format!("{}: given twice", path.display()));
        }
        absolute.push(abs);
    }
    let mut root = absolute[0]
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    while !absolute.iter().all(|p| p.starts_with(&root)) {
        if !root.pop() {
            break;
        }
    }
    let found = paths
        .iter()
        .zip(&absolute)
        .map(|(path, abs)| {
            let relative = abs.strip_prefix(&root).unwrap_or(abs);
            let name = relative
                .components()
                .map(|c| c.as_os_str().to_string_lossy())
                .collect::<Vec<_>>()
                .join("/");
            Found {
                name,
                path: path.clone(),
            }
        })
        .collect();
    Ok((root, found))
}

/// The output path of every scan: `out_dir/<relative path with the format's extension>`; when
/// two scans would share an output (`a.ply` and `a.obj`), each of them keeps its own extension
/// before the new one (`a.ply.ply`, `a.obj.ply`).
pub fn output_paths(found: &[Found], out_dir: &Path, extension: &str) -> Vec<PathBuf> {
    let plain = |f: &Found| Path::new(&f.name).with_extension(extension);
    let mut count: HashMap<PathBuf, usize> = HashMap::new();
    for f in found {
        *count.entry(plain(f)).or_default() += 1;
    }
    found
        .iter()
        .map(|f| {
            let rel = plain(f);
            if count[&rel] > 1 {
                out_dir.join(format!("{}.{extension}", f.name))
            } else {
                out_dir.join(rel)
            }
        })
        .collect()
}

/// Natural order: runs of digits compare as numbers (`frame2` < `frame10`), the rest
/// case-insensitively, ties broken by the plain string order.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (ka, kb) = (chunks(a), chunks(b));
    for (x, y) in ka.iter().zip(&kb) {
        let o = match (x, y) {
            (Chunk::Number(p), Chunk::Number(q)) => {
                let (p, q) = (p.trim_start_matches('0'), q.trim_start_matches('0'));
                p.len().cmp(&q.len()).then_with(|| p.cmp(q))
            }
            (Chunk::Number(_), Chunk::Text(_)) => Ordering::Less,
            (Chunk::Text(_), Chunk::Number(_)) => Ordering::Greater,
            (Chunk::Text(p), Chunk::Text(q)) => p.to_lowercase().cmp(&q.to_lowercase()),
        };
        if o != Ordering::Equal {
            return o;
        }
    }
    ka.len().cmp(&kb.len()).then_with(|| a.cmp(b))
}

enum Chunk<'a> {
    Number(&'a str),
    Text(&'a str),
}

fn chunks(s: &str) -> Vec<Chunk<'_>> {
    let mut out = Vec::new();
    let mut start = 0;
    let bytes = s.as_bytes();
    while start < bytes.len() {
        let digit = bytes[start].is_ascii_digit();
        let mut end = start + 1;
        while end < bytes.len() && bytes[end].is_ascii_digit() == digit {
            end += 1;
        }
        // Digits are ASCII, so `start..end` always falls on character boundaries.
        let piece = &s[start..end];
        out.push(if digit {
            Chunk::Number(piece)
        } else {
            Chunk::Text(piece)
        });
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order() {
        let mut v = vec![
            "frame10.obj",
            "frame2.obj",
            "Frame1.obj",
            "frame02.obj",
            "a/b.ply",
            "10.obj",
            "9.obj",
        ];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(
            v,
            [
                "9.obj",
                "10.obj",
                "a/b.ply",
                "Frame1.obj",
                "frame02.obj",
                "frame2.obj",
                "frame10.obj"
            ]
        );
    }

    #[test]
    fn finds_scans_with_globs_and_excludes() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for name in [
            "a.ply",
            "b.OBJ",
            "c.txt",
            ".hidden.ply",
            "sub/d.ply",
            "sub/e.obj",
            "out/f.ply",
        ] {
            let p = root.join(name);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        }
        let names = |v: Vec<Found>| v.into_iter().map(|f| f.name).collect::<Vec<_>>();
        assert_eq!(
            names(find_scans(root, false, None, None).unwrap()),
            ["a.ply", "b.OBJ"]
        );
        assert_eq!(
            names(find_scans(root, true, None, Some(&root.join("out"))).unwrap()),
            ["a.ply", "b.OBJ", "sub/d.ply", "sub/e.obj"]
        );
        assert_eq!(
            names(find_scans(root, true, Some("*.ply"), None).unwrap()),
            ["a.ply", "out/f.ply", "sub/d.ply"]
        );
        assert_eq!(
            names(find_scans(root, true, Some("sub/*"), None).unwrap()),
            ["sub/d.ply", "sub/e.obj"]
        );
        assert!(find_scans(root, false, Some("[a"), None)
            .unwrap_err()
            .contains("--glob"));
        assert!(find_scans(&root.join("missing"), false, None, None)
            .unwrap_err()
            .contains("missing"));
    }

    #[test]
    fn listed_files_are_named_from_their_common_folder() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for name in ["a/x.ply", "a/b/y.obj", "a/notes.txt"] {
            let p = root.join(name);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        }
        let (common, found) = named_files(&[root.join("a/b/y.obj"), root.join("a/x.ply")]).unwrap();
        assert_eq!(common, std::path::absolute(root.join("a")).unwrap());
        let names: Vec<_> = found.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["b/y.obj", "x.ply"]);
        assert_eq!(found[0].path, root.join("a/b/y.obj"));
        let twice = named_files(&[root.join("a/x.ply"), root.join("a/x.ply")]);
        assert!(twice.unwrap_err().contains("given twice"));
        assert!(named_files(&[root.join("a/notes.txt")])
            .unwrap_err()
            .contains("not a .ply or .obj"));
        assert!(named_files(&[root.join("a/gone.ply")])
            .unwrap_err()
            .contains("gone.ply"));
        assert!(named_files(&[]).is_err());
    }

    #[test]
    fn outputs_do_not_collide() {
        let f = |n: &str| Found {
            name: n.into(),
            path: n.into(),
        };
        let out = output_paths(
            &[f("a.ply"), f("a.obj"), f("s/b.obj")],
            Path::new("o"),
            "ply",
        );
        assert_eq!(
            out,
            [
                PathBuf::from("o/a.ply.ply"),
                "o/a.obj.ply".into(),
                "o/s/b.ply".into()
            ]
        );
    }
}
