//! The PLY reader and writer (Greg Turk's polygon file format).
//!
//! Reads `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0`; the scalar types
//! `char uchar short ushort int uint float double`, their aliases `int8 uint8 int16 uint16
//! int32 uint32 float32 float64`, and (as written by NumPy-based tools) `int64 uint64`.
//! From the `vertex` element it takes `x y z` (required), `nx ny nz` and `red green blue`
//! (or `diffuse_red …`) when all three of a group are present; from the `face` element the
//! `vertex_indices` (or `vertex_index`) list. Every other property and element is skipped,
//! but for one more scalar vertex property that [`read_ply_property`] is asked for (a
//! segmenter's `label`, a scanner's `confidence`), read as `f64` values.
//! Faces with fewer than three indices carry no area and are skipped; polygons are
//! fan-triangulated. Colors stored as integers are clamped to 0..=255; colors stored as
//! floats are taken as 0..=1 and scaled by 255.
//!
//! ASCII records are one per line (blank lines are tolerated), as every PLY writer emits
//! them; a line with too few or too many values is an error naming that line.

mod ascii;
mod binary;
mod header;
mod record;
#[cfg(test)]
mod tests;
mod write;

pub use write::{write_ply, write_ply_to, write_ply_with_encoding};

use super::{format_error, read_file, MeshData};
use crate::error::Result;
use ascii::read_ascii;
use binary::read_binary;
use header::{check_sizes, parse_header};
use record::Layout;
use std::path::Path;

/// The three PLY encodings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`: human-readable, about three times larger.
    Ascii,
    /// `format binary_little_endian 1.0` (the default, what most tools write).
    #[default]
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl PlyEncoding {
    fn header_name(self) -> &'static str {
        match self {
            Self::Ascii => "ascii",
            Self::BinaryLittleEndian => "binary_little_endian",
            Self::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// Reads a PLY file.
///
/// # Errors
/// [`FoldMatchError::Io`](crate::FoldMatchError::Io) when the file cannot be read, [`FoldMatchError::Format`](crate::FoldMatchError::Format) (naming the
/// file, the line and the reason) when its content is not a valid PLY mesh or point cloud.
pub fn read_ply(path: &Path) -> Result<MeshData> {
    let data = read_file(path)?;
    parse_ply(&data, &path.display().to_string())
}

/// Parses PLY bytes; `name` is used in error messages (a path, or e.g. `<memory>`).
///
/// # Errors
/// [`FoldMatchError::Format`](crate::FoldMatchError::Format) as for [`read_ply`].
pub fn parse_ply(data: &[u8], name: &str) -> Result<MeshData> {
    parse(data, name, None).map(|(mesh, _)| mesh)
}

/// Reads a PLY file and one more per-vertex scalar property of it, `property` (e.g. a
/// segmenter's `label` or a scanner's `confidence`), as `f64` values, one per vertex, in
/// vertex order. Any scalar type is accepted; any property of the `vertex` element may be
/// named, including those that [`MeshData`] already holds.
///
/// # Errors
/// As [`read_ply`]; a [`FoldMatchError::Format`](crate::FoldMatchError::Format) naming the file and the property when the
/// vertex element has no such property or when it is a list.
pub fn read_ply_property(path: &Path, property: &str) -> Result<(MeshData, Vec<f64>)> {
    let data = read_file(path)?;
    parse_ply_property(&data, &path.display().to_string(), property)
}

/// Parses PLY bytes as [`read_ply_property`] does; `name` is used in error messages.
///
/// # Errors
/// As [`read_ply_property`].
pub fn parse_ply_property(data: &[u8], name: &str, property: &str) -> Result<(MeshData, Vec<f64>)> {
    parse(data, name, Some(property)).map(|(mesh, values)| (mesh, values.unwrap_or_default()))
}

fn parse(data: &[u8], name: &str, property: Option<&str>) -> Result<(MeshData, Option<Vec<f64>>)> {
    let header = parse_header(data, name)?;
    let payload = &data[header.payload_start..];
    check_sizes(&header, payload.len(), name)?;
    let layout = Layout::new(&header, name, property)?;
    match header.encoding {
        PlyEncoding::Ascii => read_ascii(&header, &layout, payload, name),
        PlyEncoding::BinaryLittleEndian => read_binary(&header, &layout, payload, false, name),
        PlyEncoding::BinaryBigEndian => read_binary(&header, &layout, payload, true, name),
    }
}
