//! The PLY writer: binary (either endianness) or ASCII, with extra per-vertex `double`
//! properties.

use super::super::{write_atomically, write_to_stream, VertexProperty};
use super::record::{COLOR_NAMES, NORMAL_NAMES};
use super::{MeshData, PlyEncoding};
use crate::error::{FoldMatchError, Result};
use std::io::Write;
use std::path::Path;

/// Writes a PLY file atomically: binary little endian, or ASCII when `ascii`.
///
/// The header declares `double x y z`, then `double nx ny nz` (when `mesh.normals`),
/// `uchar red green blue` (when `mesh.colors`), then one `double NAME` per `extra` column;
/// a `face` element with `list uchar int vertex_indices` unless the mesh is a point cloud.
///
/// # Errors
/// [`FoldMatchError::Shape`], [`FoldMatchError::FaceIndex`] or [`FoldMatchError::Parameter`]
/// for inconsistent data (nothing is written), [`FoldMatchError::Io`] when writing fails.
pub fn write_ply(
    path: &Path,
    mesh: &MeshData,
    extra: &[VertexProperty],
    ascii: bool,
) -> Result<()> {
    let encoding = if ascii {
        PlyEncoding::Ascii
    } else {
        PlyEncoding::BinaryLittleEndian
    };
    write_ply_with_encoding(path, mesh, extra, encoding)
}

/// [`write_ply`] with an explicit encoding (including big endian).
///
/// # Errors
/// As [`write_ply`].
pub fn write_ply_with_encoding(
    path: &Path,
    mesh: &MeshData,
    extra: &[VertexProperty],
    encoding: PlyEncoding,
) -> Result<()> {
    check_writable(mesh, extra)?;
    write_atomically(path, |w| emit_ply(w, mesh, extra, encoding))
}

/// Writes PLY to any [`Write`] sink (not atomic; I/O errors name the path `<stream>`).
///
/// # Errors
/// As [`write_ply`].
pub fn write_ply_to<W: Write>(
    writer: &mut W,
    mesh: &MeshData,
    extra: &[VertexProperty],
    encoding: PlyEncoding,
) -> Result<()> {
    check_writable(mesh, extra)?;
    write_to_stream(writer, |w| emit_ply(w, mesh, extra, encoding))
}

const RESERVED: [&str; 9] = ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"];

fn check_writable(mesh: &MeshData, extra: &[VertexProperty]) -> Result<()> {
    mesh.check_consistency()?;
    if mesh.vertices.len() > i32::MAX as usize {
        return Err(FoldMatchError::shape(
            "vertices",
            format!(
                "{} vertices exceed the PLY int index range",
                mesh.vertices.len()
            ),
        ));
    }
    for (i, p) in extra.iter().enumerate() {
        let valid = !p.name.is_empty() && p.name.bytes().all(|b| b.is_ascii_graphic());
        if !valid {
            return Err(FoldMatchError::parameter(
                "extra property name",
                format!("{:?}", p.name),
                "must be non-empty printable ASCII without spaces",
            ));
        }
        if RESERVED.contains(&p.name.as_str()) || extra[..i].iter().any(|q| q.name == p.name) {
            return Err(FoldMatchError::parameter(
                "extra property name",
                &p.name,
                "clashes with a standard or an earlier property",
            ));
        }
        if p.values.len() != mesh.vertices.len() {
            return Err(FoldMatchError::shape(
                &format!("extra property '{}'", p.name),
                format!(
                    "{} values for {} vertices",
                    p.values.len(),
                    mesh.vertices.len()
                ),
            ));
        }
    }
    Ok(())
}

fn emit_ply<W: Write>(
    w: &mut W,
    mesh: &MeshData,
    extra: &[VertexProperty],
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    let n = mesh.vertices.len();
    writeln!(w, "ply")?;
    writeln!(w, "format {} 1.0", encoding.header_name())?;
    writeln!(
        w,
        "comment written by FoldMatch {}",
        env!("CARGO_PKG_VERSION")
    )?;
    writeln!(w, "element vertex {n}")?;
    for axis in ["x", "y", "z"] {
        writeln!(w, "property double {axis}")?;
    }
    if mesh.normals.is_some() {
        for axis in NORMAL_NAMES {
            writeln!(w, "property double {axis}")?;
        }
    }
    if mesh.colors.is_some() {
        for c in COLOR_NAMES[0] {
            writeln!(w, "property uchar {c}")?;
        }
    }
    for p in extra {
        writeln!(w, "property double {}", p.name)?;
    }
    if !mesh.faces.is_empty() {
        writeln!(w, "element face {}", mesh.faces.len())?;
        writeln!(w, "property list uchar int vertex_indices")?;
    }
    writeln!(w, "end_header")?;

    let normal = |i: usize| mesh.normals.as_ref().map(|n| n[i]);
    let color = |i: usize| mesh.colors.as_ref().map(|c| c[i]);
    match encoding {
        PlyEncoding::Ascii => {
            // `{:?}` prints the shortest string that parses back to the same f64.
            for i in 0..n {
                let v = mesh.vertices[i];
                write!(w, "{:?} {:?} {:?}", v[0], v[1], v[2])?;
                if let Some(nv) = normal(i) {
                    write!(w, " {:?} {:?} {:?}", nv[0], nv[1], nv[2])?;
                }
                if let Some(c) = color(i) {
                    write!(w, " {} {} {}", c[0], c[1], c[2])?;
                }
                for p in extra {
                    write!(w, " {:?}", p.values[i])?;
                }
                writeln!(w)?;
            }
            for f in &mesh.faces {
                writeln!(w, "3 {} {} {}", f[0], f[1], f[2])?;
            }
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let big = encoding == PlyEncoding::BinaryBigEndian;
            let f64b = |x: f64| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            };
            let i32b = |x: i32| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            };
            let mut record = Vec::with_capacity(8 * (6 + extra.len()) + 3);
            for i in 0..n {
                record.clear();
                for x in mesh.vertices[i] {
                    record.extend_from_slice(&f64b(x));
                }
                if let Some(nv) = normal(i) {
                    for x in nv {
                        record.extend_from_slice(&f64b(x));
                    }
                }
                if let Some(c) = color(i) {
                    record.extend_from_slice(&c);
                }
                for p in extra {
                    record.extend_from_slice(&f64b(p.values[i]));
                }
                w.write_all(&record)?;
            }
            for f in &mesh.faces {
                let mut rec = [3u8; 13];
                for (k, &v) in f.iter().enumerate() {
                    // In range: vertex count ≤ i32::MAX was checked.
                    rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&i32b(v as i32));
                }
                w.write_all(&rec)?;
            }
        }
    }
    Ok(())
}
