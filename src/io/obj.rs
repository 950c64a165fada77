//! The Wavefront OBJ reader and writer (geometry only).
//!
//! Read: `v x y z [w]` (the optional `w` is ignored) and `v x y z r g b` (vertex colors, as
//! written by MeshLab and trimesh: 0..1 floats, or 0..255 when any component exceeds 1);
//! `vn`; `f` with `v`, `v/vt`, `v//vn` and `v/vt/vn` corners, 1-based or negative (relative)
//! indices, polygons fan-triangulated. `vt`, `vp`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`,
//! free-form geometry and comments (`#` to the end of the line) are ignored; a trailing `\`
//! joins a line with the next. Vertex order and count are kept exactly (unreferenced vertices
//! included), so a point-cloud OBJ reads as a point cloud.
//!
//! Per-vertex normals: when faces reference `vn`, each vertex takes the normal of its first
//! reference; vertices that no face references take `vn` number i when the file has exactly
//! one `vn` per `v`, and zero otherwise. Without references, normals are taken in order when
//! their count equals the vertex count, and dropped otherwise. Colors are kept only when every
//! `v` line has them.

use super::{format_error, read_file, write_atomically, write_to_stream, MeshData};
use crate::error::{FoldMatchError, Result};
use crate::limits::{push, try_vec};
use std::io::Write;
use std::path::Path;

/// Reads an OBJ file.
///
/// # Errors
/// [`FoldMatchError::Io`] when the file cannot be read, [`FoldMatchError::Format`]
/// (naming the file, the line and the reason) when its content is malformed.
pub fn read_obj(path: &Path) -> Result<MeshData> {
    let data = read_file(path)?;
    parse_obj(&data, &path.display().to_string())
}

/// Parses OBJ bytes; `name` is used in error messages (a path, or e.g. `<memory>`).
///
/// # Errors
/// [`FoldMatchError::Format`] as for [`read_obj`].
pub fn parse_obj(data: &[u8], name: &str) -> Result<MeshData> {
    if data.is_empty() {
        return Err(format_error(name, 0, "empty file"));
    }
    let mut p = Parser {
        name,
        vertices: Vec::new(),
        colors: Vec::new(),
        normals: Vec::new(),
        faces: Vec::new(),
        normal_refs: Vec::new(),
        forward_ref: [None; 2],
        corners: Vec::new(),
    };
    let mut pos = 0usize;
    let mut lineno = 0usize;
    let mut joined = Vec::new();
    while pos < data.len() {
        let first_line = lineno + 1;
        // Gather one logical line (physical lines ending in '\' continue on the next).
        joined.clear();
        loop {
            let rest = &data[pos..];
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let mut line = &rest[..len];
            pos += len + 1;
            lineno += 1;
            line = line.strip_suffix(b"\r").unwrap_or(line);
            match line.strip_suffix(b"\\") {
                Some(head) if pos < data.len() => {
                    joined.extend_from_slice(head);
                    joined.push(b' ');
                }
                _ => {
                    joined.extend_from_slice(line);
                    break;
                }
            }
        }
        let line = match joined.iter().position(|&b| b == b'#') {
            Some(i) => &joined[..i],
            None => &joined[..],
        };
        p.line(line, first_line)?;
    }
    p.finish()
}

struct Parser<'a> {
    name: &'a str,
    vertices: Vec<[f64; 3]>,
    /// Colors of the `v` lines that had them (all or nothing is kept).
    colors: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    /// Every `(vertex, normal)` pair of a face corner with a normal, in file order (the first
    /// one of a vertex wins). Nothing is allocated per vertex *index* while reading: an index
    /// may refer forward, and is only known to be in range once the file ends, so the
    /// per-vertex table is built in [`Parser::finish`] from the vertex count.
    normal_refs: Vec<(u32, u32)>,
    /// Per [`Target`]: the largest positive index that referred past the entries defined so
    /// far, with its line (OBJ wants them defined first; we accept forward references and
    /// check them at the end).
    forward_ref: [Option<(usize, usize)>; 2],
    /// Scratch: one face's corners (vertex, normal).
    corners: Vec<(u32, Option<u32>)>,
}

const NONE: u32 = u32::MAX;

/// What a face-corner index refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Target {
    Vertex = 0,
    Normal = 1,
}

impl Target {
    fn name(self) -> &'static str {
        match self {
            Self::Vertex => "vertex",
            Self::Normal => "normal",
        }
    }
    fn plural(self) -> &'static str {
        match self {
            Self::Vertex => "vertices",
            Self::Normal => "normals",
        }
    }
}

impl Parser<'_> {
    fn err(&self, line: usize, reason: impl Into<String>) -> FoldMatchError {
        format_error(self.name, line, reason)
    }

    fn floats<const N: usize>(
        &self,
        tokens: &[&[u8]],
        line: usize,
        what: &str,
    ) -> Result<[f64; N]> {
        let mut out = [0.0; N];
        for (k, o) in out.iter_mut().enumerate() {
            let Some(tok) = tokens.get(k) else {
                return Err(self.err(
                    line,
                    format!("'{what}' needs {N} numbers, found {}", tokens.len()),
                ));
            };
            *o = std::str::from_utf8(tok)
                .ok()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| {
                    self.err(
                        line,
                        format!(
                            "'{what}': cannot parse '{}' as a number",
                            String::from_utf8_lossy(tok)
                        ),
                    )
                })?;
        }
        Ok(out)
    }

    fn line(&mut self, line: &[u8], lineno: usize) -> Result<()> {
        let mut it = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty());
        let Some(keyword) = it.next() else {
            return Ok(());
        };
        match keyword {
            b"v" => {
                let tokens: Vec<&[u8]> = it.take(7).collect();
                let xyz = self.floats::<3>(&tokens, lineno, "v")?;
                push(&mut self.vertices, xyz, self.name)?;
                // 3 or 4 numbers: x y z [w]; 6 or more: x y z r g b [...].
                if tokens.len() >= 6 {
                    let rgb = self.floats::<3>(&tokens[3..], lineno, "v")?;
                    if self.colors.len() == self.vertices.len() - 1 {
                        push(&mut self.colors, rgb, self.name)?;
                    }
                }
            }
            b"vn" => {
                let tokens: Vec<&[u8]> = it.take(3).collect();
                let n = self.floats::<3>(&tokens, lineno, "vn")?;
                push(&mut self.normals, n, self.name)?;
            }
            b"f" => {
                self.corners.clear();
                for tok in it {
                    let corner = self.corner(tok, lineno)?;
                    self.corners.push(corner);
                }
                if self.corners.len() < 3 {
                    return Err(self.err(
                        lineno,
                        format!(
                            "face {} has {} vertices, at least 3 are needed",
                            self.faces.len(),
                            self.corners.len()
                        ),
                    ));
                }
                for &(v, n) in &self.corners {
                    if let Some(n) = n {
                        push(&mut self.normal_refs, (v, n), self.name)?;
                    }
                }
                let a = self.corners[0].0;
                for w in self.corners[1..].windows(2) {
                    push(&mut self.faces, [a, w[0].0, w[1].0], self.name)?;
                }
            }
            _ => {} // vt, vp, o, g, s, usemtl, mtllib, l, p, curv, ...: not geometry we use
        }
        Ok(())
    }

    /// Parses one face corner `v`, `v/vt`, `v//vn` or `v/vt/vn` into 0-based indices.
    fn corner(&mut self, tok: &[u8], lineno: usize) -> Result<(u32, Option<u32>)> {
        let mut parts = tok.split(|&b| b == b'/');
        let v = parts.next().unwrap_or_default();
        let _vt = parts.next();
        let vn = parts.next().filter(|s| !s.is_empty());
        if parts.next().is_some() {
            return Err(self.err(
                lineno,
                format!(
                    "face corner '{}' has more than 3 parts",
                    String::from_utf8_lossy(tok)
                ),
            ));
        }
        let v = self.resolve(v, self.vertices.len(), lineno, Target::Vertex)?;
        let vn = match vn {
            Some(s) => Some(self.resolve(s, self.normals.len(), lineno, Target::Normal)?),
            None => None,
        };
        Ok((v, vn))
    }

    /// Turns a 1-based or negative OBJ index into a 0-based one.
    fn resolve(
        &mut self,
        tok: &[u8],
        defined: usize,
        lineno: usize,
        target: Target,
    ) -> Result<u32> {
        let face = self.faces.len();
        let what = target.name();
        let i: i64 = std::str::from_utf8(tok)
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| {
                self.err(
                    lineno,
                    format!(
                        "face {face}: cannot parse {what} index '{}'",
                        String::from_utf8_lossy(tok)
                    ),
                )
            })?;
        let idx = if i > 0 {
            let idx = (i - 1) as u64;
            if idx >= u64::from(NONE) {
                return Err(self.err(
                    lineno,
                    format!("face {face}: {what} index {i} is too large"),
                ));
            }
            let idx = idx as usize;
            let slot = &mut self.forward_ref[target as usize];
            if idx >= defined && slot.is_none_or(|(m, _)| idx > m) {
                *slot = Some((idx, lineno));
            }
            idx
        } else if i < 0 {
            let back = i.unsigned_abs();
            if back > defined as u64 {
                return Err(self.err(
                    lineno,
                    format!(
                        "face {face}: relative {what} index {i}, but only {defined} {} are defined",
                        target.plural()
                    ),
                ));
            }
            defined - back as usize
        } else {
            return Err(self.err(
                lineno,
                format!("face {face}: {what} index 0 (OBJ indices start at 1)"),
            ));
        };
        Ok(idx as u32)
    }

    fn finish(self) -> Result<MeshData> {
        let n = self.vertices.len();
        if n == 0 {
            return Err(self.err(0, "no vertices ('v' lines) found"));
        }
        // Check the forward references against the totals; afterwards every vertex index is
        // below `n` and every normal index below `self.normals.len()`.
        for target in [Target::Vertex, Target::Normal] {
            if let Some((idx, line)) = self.forward_ref[target as usize] {
                let total = match target {
                    Target::Vertex => n,
                    Target::Normal => self.normals.len(),
                };
                if idx >= total {
                    return Err(self.err(
                        line,
                        format!(
                            "{} index {} is out of range: the file defines {total} {}",
                            target.name(),
                            idx + 1,
                            target.plural()
                        ),
                    ));
                }
            }
        }
        let normals = if !self.normal_refs.is_empty() {
            // Every index is now known to be in range: the table has one entry per vertex.
            let mut normal_of_vertex = try_vec::<u32>(n, self.name)?;
            normal_of_vertex.resize(n, NONE);
            for &(v, k) in &self.normal_refs {
                let slot = &mut normal_of_vertex[v as usize];
                if *slot == NONE {
                    *slot = k;
                }
            }
            let in_order = self.normals.len() == n;
            let mut normals = try_vec::<[f64; 3]>(n, self.name)?;
            normals.extend(normal_of_vertex.iter().enumerate().map(|(i, &k)| {
                if k != NONE {
                    self.normals[k as usize]
                } else if in_order {
                    self.normals[i]
                } else {
                    [0.0; 3]
                }
            }));
            Some(normals)
        } else if self.normals.len() == n {
            Some(self.normals)
        } else {
            None
        };
        let colors = if self.colors.len() == n {
            let unit = self.colors.iter().flatten().all(|&c| c <= 1.0);
            let scale = if unit { 255.0 } else { 1.0 };
            let mut colors = try_vec::<[u8; 3]>(n, self.name)?;
            colors.extend(
                self.colors
                    .iter()
                    .map(|c| c.map(|x| (x * scale).round().clamp(0.0, 255.0) as u8)),
            );
            Some(colors)
        } else {
            None
        };
        Ok(MeshData {
            vertices: self.vertices,
            faces: self.faces,
            normals,
            colors,
        })
    }
}

/// Writes an OBJ file atomically: `v x y z` lines (`v x y z r g b` with colors as 0..1
/// floats when `mesh.colors`), `vn` lines when `mesh.normals`, and `f` lines (`f a//a b//b
/// c//c` with normals). Numbers are written in the shortest form that reads back exactly.
///
/// # Errors
/// [`FoldMatchError::Shape`] or [`FoldMatchError::FaceIndex`] for inconsistent
/// data (nothing is written), [`FoldMatchError::Io`] when writing fails.
pub fn write_obj(path: &Path, mesh: &MeshData) -> Result<()> {
    mesh.check_consistency()?;
    write_atomically(path, |w| emit_obj(w, mesh))
}

/// Writes OBJ to any [`Write`] sink (not atomic; I/O errors name the path `<stream>`).
///
/// # Errors
/// As [`write_obj`].
pub fn write_obj_to<W: Write>(writer: &mut W, mesh: &MeshData) -> Result<()> {
    mesh.check_consistency()?;
    write_to_stream(writer, |w| emit_obj(w, mesh))
}

fn emit_obj<W: Write>(w: &mut W, mesh: &MeshData) -> std::io::Result<()> {
    writeln!(w, "# written by FoldMatch {}", env!("CARGO_PKG_VERSION"))?;
    // `{:?}` prints the shortest string that parses back to the same f64.
    match &mesh.colors {
        Some(colors) => {
            for (v, c) in mesh.vertices.iter().zip(colors) {
                let [r, g, b] = c.map(|x| f64::from(x) / 255.0);
                writeln!(w, "v {:?} {:?} {:?} {r:?} {g:?} {b:?}", v[0], v[1], v[2])?;
            }
        }
        None => {
            for v in &mesh.vertices {
                writeln!(w, "v {:?} {:?} {:?}", v[0], v[1], v[2])?;
            }
        }
    }
    if let Some(normals) = &mesh.normals {
        for n in normals {
            writeln!(w, "vn {:?} {:?} {:?}", n[0], n[1], n[2])?;
        }
    }
    let with_normals = mesh.normals.is_some();
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| u64::from(i) + 1);
        if with_normals {
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        } else {
            writeln!(w, "f {a} {b} {c}")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{sample_mesh, TempDir};
    use super::*;

    fn parse(text: &str) -> Result<MeshData> {
        parse_obj(text.as_bytes(), "t.obj")
    }

    fn err_text(text: &str) -> String {
        match parse(text) {
            Ok(m) => panic!("expected an error, got {m:?}"),
            Err(e) => {
                assert!(matches!(e, FoldMatchError::Format { .. }), "{e:?}");
                e.to_string()
            }
        }
    }

    fn to_string(mesh: &MeshData) -> String {
        let mut buf = Vec::new();
        write_obj_to(&mut buf, mesh).unwrap();
        String::from_utf8(buf).unwrap()
    }

    #[test]
    fn round_trip() {
        let mut m = sample_mesh();
        assert_eq!(parse(&to_string(&m)).unwrap(), m);
        m.normals = Some(vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.5; 3],
            [0.25; 3],
        ]);
        m.colors = Some(vec![
            [0, 0, 0],
            [255, 255, 255],
            [1, 2, 3],
            [127, 128, 129],
            [9, 9, 9],
        ]);
        let text = to_string(&m);
        assert!(text.contains("f 1//1 2//2 3//3"), "{text}");
        assert_eq!(parse(&text).unwrap(), m);
        // Through a file.
        let dir = TempDir::new("obj");
        let p = dir.join("m.obj");
        write_obj(&p, &m).unwrap();
        assert_eq!(read_obj(&p).unwrap(), m);
        // A point cloud with normals.
        let mut pc = MeshData::point_cloud(vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        pc.normals = Some(vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(parse(&to_string(&pc)).unwrap(), pc);
    }

    #[test]
    fn polygons_negative_indices_and_corner_forms() {
        let text = "# a comment\r\n\
            mtllib x.mtl\no thing\ng group\ns 1\nusemtl red\n\
            v 0 0 0\nv 1 0 0 1.0\nv 1 1 0\nv 0 1 0 # trailing comment\n\
            vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nvn 0 0 -1\n\
            f 1 2 3 4\n\
            f -4/-3 -3/-2 -2/-1\n\
            f 1//2 3//2 \\\n 4//2\n\
            f 2/1/1 3/2/1 4/3/1\n\
            l 1 2\np 3\n";
        let m = parse(text).unwrap();
        assert_eq!(
            m.vertices,
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0]
            ]
        );
        assert_eq!(
            m.faces,
            vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [1, 2, 3]]
        );
        // First reference wins: vertex 0, 2, 3 get vn 2 (third face), vertex 1 gets vn 1.
        assert_eq!(
            m.normals.unwrap(),
            vec![
                [0.0, 0.0, -1.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, -1.0],
                [0.0, 0.0, -1.0]
            ]
        );
        assert!(m.colors.is_none());
    }

    #[test]
    fn normals_in_order_and_unreferenced_vertices() {
        let m = parse("v 0 0 0\nv 1 0 0\nvn 1 0 0\nvn 0 1 0\n").unwrap();
        assert_eq!(m.normals.unwrap(), vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        assert!(m.faces.is_empty());
        let m = parse("v 0 0 0\nv 1 0 0\nvn 1 0 0\n").unwrap();
        assert!(m.normals.is_none());
        // Vertex 3 unreferenced, counts differ: zero normal.
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nf 1//1 2//1 3//1\n").unwrap();
        assert_eq!(m.normals.unwrap()[3], [0.0; 3]);
    }

    #[test]
    fn colors() {
        let m = parse("v 0 0 0 1 0.5 0\nv 1 0 0 0 0 1\n").unwrap();
        assert_eq!(m.colors.unwrap(), vec![[255, 128, 0], [0, 0, 255]]);
        let m = parse("v 0 0 0 255 128 0\nv 1 0 0 0 0 1\n").unwrap();
        assert_eq!(m.colors.unwrap(), vec![[255, 128, 0], [0, 0, 1]]);
        let m = parse("v 0 0 0 1 0.5 0\nv 1 0 0\n").unwrap();
        assert!(m.colors.is_none(), "partial colors are dropped");
    }

    #[test]
    fn nan_is_read_as_is() {
        let m = parse("v nan 0 inf\n").unwrap();
        assert!(m.vertices[0][0].is_nan());
        assert_eq!(m.vertices[0][2], f64::INFINITY);
    }

    #[test]
    fn errors_name_the_line() {
        let cases: &[(&str, &str)] = &[
            ("", "t.obj:0: empty file"),
            ("# only a comment\n", "t.obj:0: no vertices"),
            (
                "v 0 0 0\nv 1 x 0\n",
                "t.obj:2: 'v': cannot parse 'x' as a number",
            ),
            ("v 0 0\n", "t.obj:1: 'v' needs 3 numbers, found 2"),
            ("v 0 0 0\nvn 0 1\n", "t.obj:2: 'vn' needs 3 numbers"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
                "t.obj:4: vertex index 4 is out of range: the file defines 3 vertices",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n",
                "t.obj:4: face 0: vertex index 0",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
                "t.obj:4: face 0: relative vertex index -4, but only 3",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n",
                "t.obj:5: face 0 has 2 vertices",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 a\n",
                "t.obj:5: face 1: cannot parse vertex index 'a'",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n",
                "t.obj:5: normal index 2 is out of range",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",
                "t.obj:4: face corner '1/1/1/1'",
            ),
            (
                "v 0 0 0\nf 99999999999 1 1\n",
                "t.obj:2: face 0: vertex index 99999999999 is too large",
            ),
        ];
        for (text, want) in cases {
            let e = err_text(text);
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn forward_references_within_range_are_accepted() {
        let m = parse("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2]]);
    }

    /// Issue 31, item 1: a corner's vertex index with a normal (`v//vn`, `v/vt/vn`) is checked
    /// against the file before anything is sized from it (it used to size a per-vertex table
    /// from the index: 4 GB for `f 1000000000//1 ...`). The normals of forward references
    /// still go to the right vertices.
    #[test]
    fn huge_corner_indices_with_normals_are_errors_before_allocating() {
        for corner in ["1000000000//1", "1000000000/1/1", "4000000000//1"] {
            let text = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf {corner} 2//1 3//1\n");
            let err = err_text(&text);
            assert!(err.starts_with("t.obj:5: "), "{err}");
            assert!(
                err.contains("out of range: the file defines 3 vertices"),
                "{err}"
            );
        }
        let err = err_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 5000000000//1 2//1 3//1\n");
        assert!(
            err.contains("vertex index 5000000000 is too large"),
            "{err}"
        );
        let err = err_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//9 2//1 3//1\n");
        assert!(err.contains("normal index 9 is out of range"), "{err}");
        // Forward references with normals: the first reference of a vertex gives its normal.
        let m = parse(
            "vn 1 0 0\nvn 0 1 0\nf 3//2 1//1 2//1\nf 3//1 2//2 1//2\nv 0 0 0\nv 1 0 0\nv 0 1 0\n",
        )
        .unwrap();
        assert_eq!(
            m.normals,
            Some(vec![[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        );
    }

    #[test]
    fn binary_garbage_is_an_error_not_a_panic() {
        let junk: Vec<u8> = (0..4096u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect();
        assert!(parse_obj(&junk, "junk.obj").is_err());
        // A PLY file renamed .obj has no 'v' lines.
        assert!(parse_obj(b"ply\nformat ascii 1.0\nend_header\n", "x.obj")
            .unwrap_err()
            .to_string()
            .contains("no vertices"));
    }
}
