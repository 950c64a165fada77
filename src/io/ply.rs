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

use super::{format_error, read_file, write_atomically, write_to_stream, MeshData, VertexProperty};
use crate::error::{FoldMatchError, Result};
use crate::limits::{push, try_vec};
use std::io::Write;
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
/// [`FoldMatchError::Io`] when the file cannot be read, [`FoldMatchError::Format`] (naming the
/// file, the line and the reason) when its content is not a valid PLY mesh or point cloud.
pub fn read_ply(path: &Path) -> Result<MeshData> {
    let data = read_file(path)?;
    parse_ply(&data, &path.display().to_string())
}

/// Parses PLY bytes; `name` is used in error messages (a path, or e.g. `<memory>`).
///
/// # Errors
/// [`FoldMatchError::Format`] as for [`read_ply`].
pub fn parse_ply(data: &[u8], name: &str) -> Result<MeshData> {
    parse(data, name, None).map(|(mesh, _)| mesh)
}

/// Reads a PLY file and one more per-vertex scalar property of it, `property` (e.g. a
/// segmenter's `label` or a scanner's `confidence`), as `f64` values, one per vertex, in
/// vertex order. Any scalar type is accepted; any property of the `vertex` element may be
/// named, including those that [`MeshData`] already holds.
///
/// # Errors
/// As [`read_ply`]; a [`FoldMatchError::Format`] naming the file and the property when the
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

// ------------------------------------------------------------------------------------------
// Header
// ------------------------------------------------------------------------------------------

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "int64" => Self::I64,
            "uint64" => Self::U64,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::I64 | Self::U64 | Self::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    fn name(self) -> &'static str {
        match self {
            Self::I8 => "char",
            Self::U8 => "uchar",
            Self::I16 => "short",
            Self::U16 => "ushort",
            Self::I32 => "int",
            Self::U32 => "uint",
            Self::I64 => "int64",
            Self::U64 => "uint64",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }
}

/// A property's type: one scalar, or a list (count type, item type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
    /// Header line of the `element` statement (for error messages).
    line: usize,
}

impl Element {
    /// What the count counts, for messages: "vertices", "faces", or "'edge' elements".
    fn plural(&self) -> String {
        match self.name.as_str() {
            "vertex" => "vertices".into(),
            "face" => "faces".into(),
            other => format!("'{other}' elements"),
        }
    }

    /// Smallest possible size of one record in bytes: fixed sizes (binary), or one character
    /// plus one separator per value (ASCII; a list has at least its count).
    fn min_record_size(&self, encoding: PlyEncoding) -> usize {
        self.props
            .iter()
            .map(|p| match (encoding, p.kind) {
                (PlyEncoding::Ascii, _) => 2,
                (_, Kind::Scalar(s)) => s.size(),
                (_, Kind::List(c, _)) => c.size(),
            })
            .sum()
    }

    /// Record size when every property is a scalar (binary only).
    fn fixed_size(&self) -> Option<usize> {
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => Some(s.size()),
                Kind::List(..) => None,
            })
            .sum()
    }
}

#[derive(Debug)]
struct Header {
    encoding: PlyEncoding,
    elements: Vec<Element>,
    /// Byte offset of the first payload byte.
    payload_start: usize,
    /// Number of header lines (the payload's first line is `lines + 1`).
    lines: usize,
}

fn parse_header(data: &[u8], name: &str) -> Result<Header> {
    let err = |line: usize, reason: String| format_error(name, line, reason);
    if data.is_empty() {
        return Err(err(0, "empty file".into()));
    }
    let magic_ok = data.starts_with(b"ply")
        && matches!(
            data.get(3),
            Some(b'\n') | Some(b'\r') | Some(b' ') | Some(b'\t')
        );
    if !magic_ok {
        return Err(err(1, "not a PLY file (missing 'ply' magic)".into()));
    }
    let mut pos = 0usize;
    let mut lineno = 0usize;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(nl) = data[pos..].iter().position(|&b| b == b'\n') else {
            return Err(err(
                lineno + 1,
                "header is not terminated by 'end_header'".into(),
            ));
        };
        let raw = &data[pos..pos + nl];
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        pos += nl + 1;
        lineno += 1;
        let text = String::from_utf8_lossy(raw);
        let mut tokens = text.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue; // blank header line
        };
        let rest: Vec<&str> = tokens.collect();
        match keyword {
            "ply" if lineno == 1 => {}
            "comment" | "obj_info" => {}
            "format" => {
                if encoding.is_some() {
                    return Err(err(lineno, "second 'format' line".into()));
                }
                encoding = Some(match rest.first().copied() {
                    Some("ascii") => PlyEncoding::Ascii,
                    Some("binary_little_endian") => PlyEncoding::BinaryLittleEndian,
                    Some("binary_big_endian") => PlyEncoding::BinaryBigEndian,
                    other => {
                        return Err(err(
                            lineno,
                            format!(
                                "unknown format '{}' (expected ascii, binary_little_endian \
                                 or binary_big_endian)",
                                other.unwrap_or("")
                            ),
                        ))
                    }
                });
            }
            "element" => {
                let [ename, count] = rest[..] else {
                    return Err(err(lineno, "expected 'element NAME COUNT'".into()));
                };
                let count: usize = count.parse().map_err(|_| {
                    err(
                        lineno,
                        format!("element '{ename}': invalid count '{count}'"),
                    )
                })?;
                if (ename == "vertex" || ename == "face")
                    && elements.iter().any(|e| e.name == ename)
                {
                    return Err(err(lineno, format!("second '{ename}' element")));
                }
                elements.push(Element {
                    name: ename.into(),
                    count,
                    props: Vec::new(),
                    line: lineno,
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(err(lineno, "'property' before any 'element'".into()));
                };
                let ty = |s: &str| {
                    Scalar::from_name(s)
                        .ok_or_else(|| err(lineno, format!("unknown property type '{s}'")))
                };
                let (kind, pname) = match rest[..] {
                    ["list", count, item, pname] => {
                        let count = ty(count)?;
                        if !count.is_integer() {
                            return Err(err(
                                lineno,
                                format!(
                                    "list '{pname}': count type '{}' is not an integer type",
                                    count.name()
                                ),
                            ));
                        }
                        (Kind::List(count, ty(item)?), pname)
                    }
                    [scalar, pname] if scalar != "list" => (Kind::Scalar(ty(scalar)?), pname),
                    _ => {
                        return Err(err(
                            lineno,
                            "expected 'property TYPE NAME' or 'property list COUNT_TYPE \
                             ITEM_TYPE NAME'"
                                .into(),
                        ))
                    }
                };
                element.props.push(Property {
                    name: pname.into(),
                    kind,
                });
            }
            "end_header" => break,
            other => {
                return Err(err(
                    lineno,
                    format!("unexpected header line starting with '{other}'"),
                ))
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(err(lineno, "header has no 'format' line".into()));
    };
    Ok(Header {
        encoding,
        elements,
        payload_start: pos,
        lines: lineno,
    })
}

/// Rejects headers announcing more records than the payload can hold, before any allocation.
fn check_sizes(header: &Header, payload_len: usize, name: &str) -> Result<()> {
    // An ASCII file's last value may lack its trailing newline.
    let mut remaining = match header.encoding {
        PlyEncoding::Ascii => payload_len + 1,
        _ => payload_len,
    };
    for e in &header.elements {
        let min = e.min_record_size(header.encoding);
        if min == 0 {
            continue; // no properties: occupies nothing
        }
        let at_most = remaining / min;
        if e.count > at_most {
            return Err(format_error(
                name,
                e.line,
                format!(
                    "header announces {} {} but the file holds at most {}",
                    e.count,
                    e.plural(),
                    at_most
                ),
            ));
        }
        remaining -= e.count * min;
    }
    Ok(())
}

/// Where the vertex and face data live in the header.
struct Layout {
    vertex: usize,
    /// For each vertex property: the slot it fills (0..3 xyz, 3..6 normal, 6..9 color).
    slots: Vec<Option<usize>>,
    has_normals: bool,
    has_colors: bool,
    /// Whether color properties are floats (0..1) rather than integers.
    float_colors: bool,
    /// The face element and its index-list property.
    face: Option<(usize, usize)>,
    /// The vertex property asked for besides the mesh (read into slot [`EXTRA_SLOT`]).
    extra: Option<usize>,
}

/// Where a vertex record's values go: 0..3 xyz, 3..6 normal, 6..9 color, 9 the extra property.
const EXTRA_SLOT: usize = 9;

const NORMAL_NAMES: [&str; 3] = ["nx", "ny", "nz"];
const COLOR_NAMES: [[&str; 3]; 2] = [
    ["red", "green", "blue"],
    ["diffuse_red", "diffuse_green", "diffuse_blue"],
];

impl Layout {
    fn new(header: &Header, name: &str, property: Option<&str>) -> Result<Self> {
        let Some(vertex) = header.elements.iter().position(|e| e.name == "vertex") else {
            return Err(format_error(
                name,
                header.lines,
                "no 'vertex' element in the header",
            ));
        };
        let ve = &header.elements[vertex];
        let find = |pname: &str| -> Result<Option<usize>> {
            match ve.props.iter().position(|p| p.name == pname) {
                None => Ok(None),
                Some(i) => match ve.props[i].kind {
                    Kind::Scalar(_) => Ok(Some(i)),
                    Kind::List(..) => Err(format_error(
                        name,
                        ve.line,
                        format!("vertex property '{pname}' is a list, expected a number"),
                    )),
                },
            }
        };
        let mut slots = vec![None; ve.props.len()];
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let Some(i) = find(axis)? else {
                return Err(format_error(
                    name,
                    ve.line,
                    format!("vertex element has no '{axis}' property"),
                ));
            };
            slots[i] = Some(k);
        }
        let group = |names: &[&str; 3]| -> Result<Option<[usize; 3]>> {
            Ok(match (find(names[0])?, find(names[1])?, find(names[2])?) {
                (Some(a), Some(b), Some(c)) => Some([a, b, c]),
                _ => None,
            })
        };
        let normals = group(&NORMAL_NAMES)?;
        if let Some(idx) = normals {
            for (k, i) in idx.into_iter().enumerate() {
                slots[i] = Some(3 + k);
            }
        }
        let mut colors = None;
        for names in &COLOR_NAMES {
            if let Some(idx) = group(names)? {
                colors = Some(idx);
                break;
            }
        }
        let mut float_colors = false;
        if let Some(idx) = colors {
            for (k, i) in idx.into_iter().enumerate() {
                slots[i] = Some(6 + k);
                if let Kind::Scalar(s) = ve.props[i].kind {
                    float_colors |= !s.is_integer();
                }
            }
        }
        let extra = match property {
            None => None,
            Some(pname) => match ve.props.iter().position(|p| p.name == pname) {
                Some(i) if matches!(ve.props[i].kind, Kind::Scalar(_)) => Some(i),
                Some(_) => {
                    return Err(format_error(
                        name,
                        ve.line,
                        format!(
                            "vertex property '{pname}' is a list, expected one number per vertex"
                        ),
                    ))
                }
                None => {
                    let known: Vec<&str> = ve.props.iter().map(|p| p.name.as_str()).collect();
                    return Err(format_error(
                        name,
                        ve.line,
                        format!(
                            "vertex element has no property '{pname}' (it has: {})",
                            known.join(", ")
                        ),
                    ));
                }
            },
        };
        let face = match header.elements.iter().position(|e| e.name == "face") {
            None => None,
            Some(fi) => {
                let fe = &header.elements[fi];
                let Some(pi) = fe
                    .props
                    .iter()
                    .position(|p| p.name == "vertex_indices" || p.name == "vertex_index")
                else {
                    return Err(format_error(
                        name,
                        fe.line,
                        "face element has no 'vertex_indices' (or 'vertex_index') property",
                    ));
                };
                match fe.props[pi].kind {
                    Kind::List(_, item) if item.is_integer() => {}
                    Kind::List(_, item) => {
                        return Err(format_error(
                            name,
                            fe.line,
                            format!(
                                "face '{}' items have type '{}', expected an integer type",
                                fe.props[pi].name,
                                item.name()
                            ),
                        ))
                    }
                    Kind::Scalar(_) => {
                        return Err(format_error(
                            name,
                            fe.line,
                            format!("face property '{}' is not a list", fe.props[pi].name),
                        ))
                    }
                }
                Some((fi, pi))
            }
        };
        Ok(Self {
            vertex,
            slots,
            has_normals: normals.is_some(),
            has_colors: colors.is_some(),
            float_colors,
            face,
            extra,
        })
    }
}

/// Collects vertex and face data while the payload is decoded.
struct Builder {
    n_vertices: usize,
    vertices: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    colors: Vec<[u8; 3]>,
    faces: Vec<[u32; 3]>,
    /// The extra property's values, when one was asked for.
    extra: Vec<f64>,
    float_colors: bool,
    /// Scratch list of one face's indices.
    polygon: Vec<i64>,
}

impl Builder {
    fn new(header: &Header, layout: &Layout, payload_len: usize, name: &str) -> Result<Self> {
        // Counts were checked against the payload size (`check_sizes`), so the vertex
        // reservations are at most ~8× the file size (3 one-byte coordinates → 24 bytes). A
        // face record can be a single byte (an empty list), so the triangle reservation is
        // capped by what the payload can hold as triangles (≥ 4 bytes each) and grows beyond
        // that only as triangles are actually read.
        let n = header.elements[layout.vertex].count;
        let n_faces = layout
            .face
            .map_or(0, |(fi, _)| header.elements[fi].count)
            .min(payload_len / 4);
        // The reservations can still fail on a machine with less memory than the file needs:
        // a typed error then, not an abort.
        Ok(Self {
            n_vertices: n,
            vertices: try_vec(n, name)?,
            normals: try_vec(if layout.has_normals { n } else { 0 }, name)?,
            colors: try_vec(if layout.has_colors { n } else { 0 }, name)?,
            faces: try_vec(n_faces, name)?,
            extra: try_vec(if layout.extra.is_some() { n } else { 0 }, name)?,
            float_colors: layout.float_colors,
            polygon: Vec::new(),
        })
    }

    /// Stores one vertex (the vectors were reserved for the header's count, which the payload
    /// was checked to hold, so these pushes do not allocate).
    fn push_vertex(&mut self, values: &[f64; 10], layout: &Layout) {
        self.vertices.push([values[0], values[1], values[2]]);
        if layout.extra.is_some() {
            self.extra.push(values[EXTRA_SLOT]);
        }
        if layout.has_normals {
            self.normals.push([values[3], values[4], values[5]]);
        }
        if layout.has_colors {
            let c = |v: f64| {
                let v = if self.float_colors {
                    (v * 255.0).round()
                } else {
                    v
                };
                v.clamp(0.0, 255.0) as u8 // NaN maps to 0
            };
            self.colors.push([c(values[6]), c(values[7]), c(values[8])]);
        }
    }

    /// Fan-triangulates `self.polygon` (face number `face`), checking its indices; a face of
    /// fewer than 3 indices is an error, as OBJ's `f 1 2`.
    fn push_polygon(&mut self, face: usize, name: &str, line: usize) -> Result<()> {
        if self.polygon.len() < 3 {
            return Err(format_error(
                name,
                line,
                format!(
                    "face {face} has {} vertices, at least 3 are needed",
                    self.polygon.len()
                ),
            ));
        }
        for &v in &self.polygon {
            if v < 0 || v as u64 >= self.n_vertices as u64 {
                return Err(format_error(
                    name,
                    line,
                    format!(
                        "face {face} refers to vertex {v}, but there are only {} vertices",
                        self.n_vertices
                    ),
                ));
            }
        }
        let a = self.polygon[0] as u32;
        for w in self.polygon[1..].windows(2) {
            push(&mut self.faces, [a, w[0] as u32, w[1] as u32], name)?;
        }
        Ok(())
    }

    fn finish(self, layout: &Layout) -> (MeshData, Option<Vec<f64>>) {
        let mesh = MeshData {
            vertices: self.vertices,
            faces: self.faces,
            normals: layout.has_normals.then_some(self.normals),
            colors: layout.has_colors.then_some(self.colors),
        };
        (mesh, layout.extra.is_some().then_some(self.extra))
    }
}

// ------------------------------------------------------------------------------------------
// Binary payload
// ------------------------------------------------------------------------------------------

/// A decoded number: integers stay exact (indices, counts), floats as they are.
#[derive(Clone, Copy, Debug)]
enum Num {
    Int(i64),
    Float(f64),
}

impl Num {
    fn as_f64(self) -> f64 {
        match self {
            Self::Int(i) => i as f64,
            Self::Float(f) => f,
        }
    }
    fn as_int(self) -> Option<i64> {
        match self {
            Self::Int(i) => Some(i),
            Self::Float(f) if f.fract() == 0.0 && f.abs() < 9.0e18 => Some(f as i64),
            Self::Float(_) => None,
        }
    }
}

/// Binary cursor over the payload.
struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
    big: bool,
}

impl Cursor<'_> {
    #[inline]
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let bytes: [u8; N] = self.data.get(self.pos..self.pos + N)?.try_into().ok()?;
        self.pos += N;
        Some(bytes)
    }

    #[inline]
    fn skip(&mut self, n: usize) -> Option<()> {
        let end = self.pos.checked_add(n)?;
        if end > self.data.len() {
            return None;
        }
        self.pos = end;
        Some(())
    }

    #[inline]
    fn read(&mut self, ty: Scalar) -> Option<Num> {
        macro_rules! get {
            ($t:ty, $n:literal) => {{
                let b = self.take::<$n>()?;
                if self.big {
                    <$t>::from_be_bytes(b)
                } else {
                    <$t>::from_le_bytes(b)
                }
            }};
        }
        Some(match ty {
            Scalar::I8 => Num::Int(i64::from(get!(i8, 1))),
            Scalar::U8 => Num::Int(i64::from(get!(u8, 1))),
            Scalar::I16 => Num::Int(i64::from(get!(i16, 2))),
            Scalar::U16 => Num::Int(i64::from(get!(u16, 2))),
            Scalar::I32 => Num::Int(i64::from(get!(i32, 4))),
            Scalar::U32 => Num::Int(i64::from(get!(u32, 4))),
            Scalar::I64 => Num::Int(get!(i64, 8)),
            Scalar::U64 => Num::Int(i64::try_from(get!(u64, 8)).unwrap_or(i64::MAX)),
            Scalar::F32 => Num::Float(f64::from(get!(f32, 4))),
            Scalar::F64 => Num::Float(get!(f64, 8)),
        })
    }

    /// Reads a list count (an integer type, checked in the header).
    fn read_count(&mut self, ty: Scalar) -> Option<std::result::Result<usize, i64>> {
        let c = self.read(ty)?.as_int().unwrap_or(-1);
        Some(usize::try_from(c).map_err(|_| c))
    }
}

fn read_binary(
    header: &Header,
    layout: &Layout,
    payload: &[u8],
    big: bool,
    name: &str,
) -> Result<(MeshData, Option<Vec<f64>>)> {
    let mut cur = Cursor {
        data: payload,
        pos: 0,
        big,
    };
    let mut b = Builder::new(header, layout, payload.len(), name)?;
    let truncated = |e: &Element, i: usize| {
        format_error(
            name,
            0,
            format!(
                "truncated file: {} record {} of {} extends past the end of the data",
                e.name, i, e.count
            ),
        )
    };
    let bad_count = |e: &Element, i: usize, c: i64| {
        format_error(
            name,
            0,
            format!("{} record {i}: negative list count {c}", e.name),
        )
    };
    for (ei, e) in header.elements.iter().enumerate() {
        if e.props.is_empty() {
            continue;
        }
        if ei == layout.vertex {
            let mut values = [0.0f64; 10];
            for i in 0..e.count {
                for (pi, (p, slot)) in e.props.iter().zip(&layout.slots).enumerate() {
                    match p.kind {
                        Kind::Scalar(s) => {
                            let v = cur.read(s).ok_or_else(|| truncated(e, i))?;
                            if let Some(k) = *slot {
                                values[k] = v.as_f64();
                            }
                            if layout.extra == Some(pi) {
                                values[EXTRA_SLOT] = v.as_f64();
                            }
                        }
                        Kind::List(c, item) => {
                            let n = cur
                                .read_count(c)
                                .ok_or_else(|| truncated(e, i))?
                                .map_err(|c| bad_count(e, i, c))?;
                            let bytes =
                                n.checked_mul(item.size()).ok_or_else(|| truncated(e, i))?;
                            cur.skip(bytes).ok_or_else(|| truncated(e, i))?;
                        }
                    }
                }
                b.push_vertex(&values, layout);
            }
        } else if let Some((_, pi)) = layout.face.filter(|&(fi, _)| fi == ei) {
            for i in 0..e.count {
                for (k, p) in e.props.iter().enumerate() {
                    match p.kind {
                        Kind::Scalar(s) => {
                            cur.skip(s.size()).ok_or_else(|| truncated(e, i))?;
                        }
                        Kind::List(c, item) => {
                            let n = cur
                                .read_count(c)
                                .ok_or_else(|| truncated(e, i))?
                                .map_err(|c| bad_count(e, i, c))?;
                            if k == pi {
                                b.polygon.clear();
                                for _ in 0..n {
                                    let v = cur.read(item).ok_or_else(|| truncated(e, i))?;
                                    push(&mut b.polygon, v.as_int().unwrap_or(-1), name)?;
                                }
                                b.push_polygon(i, name, 0)?;
                            } else {
                                let bytes =
                                    n.checked_mul(item.size()).ok_or_else(|| truncated(e, i))?;
                                cur.skip(bytes).ok_or_else(|| truncated(e, i))?;
                            }
                        }
                    }
                }
            }
        } else if let Some(size) = e.fixed_size() {
            // Checked in `check_sizes`: count * size fits in the payload.
            cur.skip(e.count * size)
                .ok_or_else(|| truncated(e, e.count))?;
        } else {
            for i in 0..e.count {
                for p in &e.props {
                    let bytes = match p.kind {
                        Kind::Scalar(s) => s.size(),
                        Kind::List(c, item) => cur
                            .read_count(c)
                            .ok_or_else(|| truncated(e, i))?
                            .map_err(|c| bad_count(e, i, c))?
                            .checked_mul(item.size())
                            .ok_or_else(|| truncated(e, i))?,
                    };
                    cur.skip(bytes).ok_or_else(|| truncated(e, i))?;
                }
            }
        }
    }
    Ok(b.finish(layout))
}

// ------------------------------------------------------------------------------------------
// ASCII payload
// ------------------------------------------------------------------------------------------

/// Iterates over the payload's non-blank lines with their 1-based line numbers.
struct Lines<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Lines<'a> {
    fn next_record(&mut self) -> Option<(usize, &'a [u8])> {
        while self.pos < self.data.len() {
            let rest = &self.data[self.pos..];
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let line = &rest[..len];
            self.pos += len + 1;
            self.line += 1;
            if line.iter().any(|b| !b.is_ascii_whitespace()) {
                return Some((self.line, line));
            }
        }
        None
    }
}

fn parse_ascii_num(token: &[u8], ty: Scalar) -> Option<Num> {
    let s = std::str::from_utf8(token).ok()?;
    if ty.is_integer() {
        if let Ok(i) = s.parse::<i64>() {
            return Some(Num::Int(i));
        }
        // Tolerate "3.0" for integer properties; reject "3.5".
        let f: f64 = s.parse().ok()?;
        return Num::Float(f).as_int().map(Num::Int);
    }
    s.parse::<f64>().ok().map(Num::Float)
}

fn read_ascii(
    header: &Header,
    layout: &Layout,
    payload: &[u8],
    name: &str,
) -> Result<(MeshData, Option<Vec<f64>>)> {
    let mut lines = Lines {
        data: payload,
        pos: 0,
        line: header.lines,
    };
    let mut b = Builder::new(header, layout, payload.len(), name)?;
    let mut values = [0.0f64; 10];
    for (ei, e) in header.elements.iter().enumerate() {
        if e.props.is_empty() {
            continue;
        }
        let face_prop = layout.face.filter(|&(fi, _)| fi == ei).map(|(_, pi)| pi);
        for i in 0..e.count {
            let Some((line, text)) = lines.next_record() else {
                return Err(format_error(
                    name,
                    lines.line,
                    format!(
                        "truncated file: expected {} {}, found {}",
                        e.count,
                        e.plural(),
                        i
                    ),
                ));
            };
            let mut tokens = text
                .split(|b| b.is_ascii_whitespace())
                .filter(|t| !t.is_empty());
            let what = || format!("{} {i}", e.name);
            let mut next = |ty: Scalar, pname: &str| -> Result<Num> {
                let Some(tok) = tokens.next() else {
                    return Err(format_error(
                        name,
                        line,
                        format!("{}: too few values (missing '{pname}')", what()),
                    ));
                };
                parse_ascii_num(tok, ty).ok_or_else(|| {
                    format_error(
                        name,
                        line,
                        format!(
                            "{}: cannot parse '{}' as {} (property '{pname}')",
                            what(),
                            String::from_utf8_lossy(tok),
                            ty.name()
                        ),
                    )
                })
            };
            for (k, p) in e.props.iter().enumerate() {
                match p.kind {
                    Kind::Scalar(s) => {
                        let v = next(s, &p.name)?;
                        if ei == layout.vertex {
                            if let Some(slot) = layout.slots[k] {
                                values[slot] = v.as_f64();
                            }
                            if layout.extra == Some(k) {
                                values[EXTRA_SLOT] = v.as_f64();
                            }
                        }
                    }
                    Kind::List(c, item) => {
                        let n = next(c, &p.name)?.as_int().unwrap_or(-1);
                        if n < 0 {
                            return Err(format_error(
                                name,
                                line,
                                format!("{}: negative list count {n}", what()),
                            ));
                        }
                        let keep = face_prop == Some(k);
                        if keep {
                            b.polygon.clear();
                        }
                        // Each item needs a token, so this loop is bounded by the line length.
                        for _ in 0..n {
                            let v = next(item, &p.name)?;
                            if keep {
                                push(&mut b.polygon, v.as_int().unwrap_or(-1), name)?;
                            }
                        }
                        if keep {
                            b.push_polygon(i, name, line)?;
                        }
                    }
                }
            }
            if tokens.next().is_some() {
                return Err(format_error(
                    name,
                    line,
                    format!("{}: more values than the header declares", what()),
                ));
            }
            if ei == layout.vertex {
                b.push_vertex(&values, layout);
            }
        }
    }
    Ok(b.finish(layout))
}

// ------------------------------------------------------------------------------------------
// Writer
// ------------------------------------------------------------------------------------------

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

#[cfg(test)]
mod tests {
    use super::super::test_util::{sample_mesh, TempDir};
    use super::*;

    const ENCODINGS: [PlyEncoding; 3] = [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ];

    fn to_bytes(mesh: &MeshData, extra: &[VertexProperty], enc: PlyEncoding) -> Vec<u8> {
        let mut buf = Vec::new();
        write_ply_to(&mut buf, mesh, extra, enc).unwrap();
        buf
    }

    fn parse(data: &[u8]) -> Result<MeshData> {
        parse_ply(data, "test.ply")
    }

    fn err_text(data: &[u8]) -> String {
        match parse(data) {
            Ok(m) => panic!("expected an error, got {m:?}"),
            Err(e) => {
                assert!(matches!(e, FoldMatchError::Format { .. }), "{e:?}");
                e.to_string()
            }
        }
    }

    fn full_mesh() -> MeshData {
        let mut m = sample_mesh();
        m.normals = Some(vec![
            [0.0, 0.0, 1.0],
            [0.6, 0.8, 0.0],
            [-1.0, 0.0, 0.0],
            [0.1, 0.2, 0.3],
            [f64::NAN, 0.0, 0.0],
        ]);
        m.colors = Some(vec![
            [0, 0, 0],
            [255, 255, 255],
            [1, 2, 3],
            [200, 100, 50],
            [9, 9, 9],
        ]);
        m
    }

    /// Equality that treats NaN as equal to NaN.
    fn same(a: &MeshData, b: &MeshData) -> bool {
        let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        bits(&a.vertices) == bits(&b.vertices)
            && a.faces == b.faces
            && a.normals.as_deref().map(bits) == b.normals.as_deref().map(bits)
            && a.colors == b.colors
    }

    #[test]
    fn round_trip_all_encodings() {
        for enc in ENCODINGS {
            for mesh in [sample_mesh(), full_mesh()] {
                let bytes = to_bytes(&mesh, &[], enc);
                let back = parse(&bytes).unwrap();
                assert!(same(&back, &mesh), "{enc:?}: {back:?}");
            }
        }
    }

    #[test]
    fn round_trip_point_cloud_with_normals_and_colors() {
        for enc in ENCODINGS {
            let mut pc = MeshData::point_cloud(vec![[1.0, 2.0, 3.0], [-4.5, 1e-9, 6.25]]);
            pc.normals = Some(vec![[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]);
            pc.colors = Some(vec![[10, 20, 30], [40, 50, 60]]);
            let bytes = to_bytes(&pc, &[], enc);
            assert!(!String::from_utf8_lossy(&bytes).contains("element face"));
            assert_eq!(parse(&bytes).unwrap(), pc, "{enc:?}");
        }
    }

    #[test]
    fn round_trip_through_files() {
        let dir = TempDir::new("ply-files");
        let mesh = full_mesh();
        for (i, enc) in ENCODINGS.into_iter().enumerate() {
            let p = dir.join(&format!("m{i}.ply"));
            write_ply_with_encoding(&p, &mesh, &[], enc).unwrap();
            assert!(same(&read_ply(&p).unwrap(), &mesh), "{enc:?}");
        }
        let p = dir.join("ascii.ply");
        write_ply(&p, &mesh, &[], true).unwrap();
        assert!(std::fs::read(&p)
            .unwrap()
            .starts_with(b"ply\nformat ascii 1.0\n"));
        write_ply(&p, &mesh, &[], false).unwrap();
        assert!(std::fs::read(&p)
            .unwrap()
            .starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    }

    #[test]
    fn extra_properties_are_written_and_skipped_on_read() {
        let mesh = full_mesh();
        let extra = [
            VertexProperty::new("wvf_x", vec![0.5; 5]),
            VertexProperty::new("wvf_magnitude", vec![1.0, 2.0, 3.0, 4.0, 5.0]),
        ];
        for enc in ENCODINGS {
            let bytes = to_bytes(&mesh, &extra, enc);
            let text = String::from_utf8_lossy(&bytes);
            assert!(text.contains("property double wvf_x\nproperty double wvf_magnitude\n"));
            assert!(same(&parse(&bytes).unwrap(), &mesh), "{enc:?}");
        }
        let ascii =
            String::from_utf8(to_bytes(&sample_mesh(), &extra, PlyEncoding::Ascii)).unwrap();
        let first = ascii
            .lines()
            .find(|l| l.starts_with("0.0 0.0 0.0"))
            .unwrap();
        assert_eq!(first, "0.0 0.0 0.0 0.5 1.0");
    }

    #[test]
    fn bad_extra_properties_are_rejected() {
        let mesh = sample_mesh();
        let cases = [
            (
                VertexProperty::new("wvf", vec![1.0; 4]),
                "4 values for 5 vertices",
            ),
            (
                VertexProperty::new("has space", vec![1.0; 5]),
                "printable ASCII",
            ),
            (VertexProperty::new("", vec![1.0; 5]), "printable ASCII"),
            (VertexProperty::new("red", vec![1.0; 5]), "clashes"),
        ];
        for (p, want) in cases {
            let mut buf = Vec::new();
            let e = write_ply_to(&mut buf, &mesh, &[p], PlyEncoding::Ascii).unwrap_err();
            assert!(e.to_string().contains(want), "{e}");
            assert!(buf.is_empty());
        }
        let dup = [
            VertexProperty::new("a", vec![0.0; 5]),
            VertexProperty::new("a", vec![0.0; 5]),
        ];
        assert!(write_ply_to(&mut Vec::new(), &mesh, &dup, PlyEncoding::Ascii).is_err());
    }

    #[test]
    fn a_requested_vertex_property_is_read_in_every_encoding() {
        let mesh = full_mesh();
        let confidence = vec![0.25, 1.0, 0.0, 0.5, 1e-300];
        let extra = [
            VertexProperty::new("wvf_x", vec![7.0; 5]),
            VertexProperty::new("confidence", confidence.clone()),
        ];
        for enc in ENCODINGS {
            let bytes = to_bytes(&mesh, &extra, enc);
            let (back, values) = parse_ply_property(&bytes, "scan.ply", "confidence").unwrap();
            assert!(same(&back, &mesh), "{enc:?}");
            assert_eq!(values, confidence, "{enc:?}");
            // A property the mesh already holds can be asked for too.
            let (_, red) = parse_ply_property(&bytes, "scan.ply", "red").unwrap();
            assert_eq!(red, [0.0, 255.0, 1.0, 200.0, 9.0], "{enc:?}");
            let (_, x) = parse_ply_property(&bytes, "scan.ply", "x").unwrap();
            let xs: Vec<f64> = mesh.vertices.iter().map(|v| v[0]).collect();
            assert_eq!(x, xs, "{enc:?}");
        }
    }

    /// What segmenters write: `uchar label` and `float confidence` on a point cloud, ASCII and
    /// binary, between the coordinates.
    #[test]
    fn uchar_labels_and_float_confidence_of_a_point_cloud() {
        let head = |format: &str| {
            format!(
                "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\n\
                 property float y\nproperty uchar label\nproperty float z\n\
                 property float confidence\nend_header\n"
            )
        };
        let ascii = head("ascii") + "0 0 1 0 0.5\n1 0 0 0 0.75\n0 1 255 0.5 1\n";
        let mut binary = head("binary_little_endian").into_bytes();
        for (x, y, label, z, c) in [
            (0f32, 0f32, 1u8, 0f32, 0.5f32),
            (1.0, 0.0, 0, 0.0, 0.75),
            (0.0, 1.0, 255, 0.5, 1.0),
        ] {
            binary.extend(x.to_le_bytes());
            binary.extend(y.to_le_bytes());
            binary.push(label);
            binary.extend(z.to_le_bytes());
            binary.extend(c.to_le_bytes());
        }
        for data in [ascii.as_bytes(), binary.as_slice()] {
            let (mesh, label) = parse_ply_property(data, "scan.ply", "label").unwrap();
            assert_eq!(label, [1.0, 0.0, 255.0]);
            assert_eq!(mesh.vertices[2], [0.0, 1.0, 0.5]);
            assert!(mesh.is_point_cloud());
            let (_, c) = parse_ply_property(data, "scan.ply", "confidence").unwrap();
            assert_eq!(c, [0.5, 0.75, 1.0]);
            // The plain reader skips both.
            assert_eq!(parse(data).unwrap(), mesh);
        }
    }

    #[test]
    fn a_missing_or_list_property_is_an_error_naming_file_and_property() {
        let mut h = String::from("ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\n");
        h += "property double y\nproperty double z\nproperty list uchar int labels\n";
        h += "element face 0\nproperty list uchar int vertex_indices\n";
        h += "end_header\n0 0 0 2 1 2\n1 0 0 0\n";
        let err = |prop: &str| match parse_ply_property(h.as_bytes(), "scan.ply", prop) {
            Ok(v) => panic!("{prop}: accepted {v:?}"),
            Err(e) => {
                assert!(matches!(e, FoldMatchError::Format { .. }), "{e:?}");
                e.to_string()
            }
        };
        assert_eq!(
            err("label"),
            "scan.ply:3: vertex element has no property 'label' (it has: x, y, z, labels)"
        );
        assert_eq!(
            err("labels"),
            "scan.ply:3: vertex property 'labels' is a list, expected one number per vertex"
        );
        // Face properties are not vertex properties.
        assert!(err("vertex_indices").contains("no property 'vertex_indices'"));
        // Without a property the file reads as before.
        assert_eq!(parse(h.as_bytes()).unwrap().vertices.len(), 2);
        // Through a file: the path names it.
        let dir = TempDir::new("ply-property");
        let p = dir.join("labelled.ply");
        std::fs::write(&p, &h).unwrap();
        let e = read_ply_property(&p, "label").unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}:3: ", p.display())), "{e}");
        assert!(read_ply_property(&dir.join("none.ply"), "label").is_err());
    }

    #[test]
    fn a_requested_property_of_every_scalar_type_in_binary_with_lists() {
        // The vertex record of the test below: int8 a, float32 x, list junk, int16 y, uint64 b.
        let mut h = String::from("ply\nformat binary_big_endian 1.0\nelement vertex 2\n");
        h += "property int8 a\nproperty float32 x\nproperty list uint8 int16 junk\n";
        h += "property int16 y\nproperty uint64 b\nproperty float64 z\nend_header\n";
        let mut d = h.into_bytes();
        for i in 0..2u8 {
            d.push(0xfe); // a = -2
            d.extend_from_slice(&f32::from(i).to_be_bytes());
            d.push(i);
            for k in 0..i {
                d.extend_from_slice(&i16::from(k).to_be_bytes());
            }
            d.extend_from_slice(&(-300i16).to_be_bytes());
            d.extend_from_slice(&u64::from(i).to_be_bytes());
            d.extend_from_slice(&1.5f64.to_be_bytes());
        }
        let get = |p: &str| parse_ply_property(&d, "t.ply", p).unwrap().1;
        assert_eq!(get("a"), [-2.0, -2.0]);
        assert_eq!(get("y"), [-300.0, -300.0]);
        assert_eq!(get("b"), [0.0, 1.0]);
        assert_eq!(get("z"), [1.5, 1.5]);
        let e = parse_ply_property(&d, "t.ply", "junk")
            .unwrap_err()
            .to_string();
        assert!(e.contains("'junk' is a list"), "{e}");
        // Truncated: the same errors as without a property.
        let e = parse_ply_property(&d[..d.len() - 1], "t.ply", "a").unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
    }

    #[test]
    fn all_scalar_types_lists_on_vertices_and_unknown_elements() {
        // Little-endian binary with every type, a list on the vertex element, an unknown
        // element with a list before the faces, and a quad plus a triangle.
        let mut h = String::from("ply\r\nformat binary_little_endian 1.0\r\ncomment hi\r\n");
        h += "obj_info made by hand\r\nelement vertex 4\r\n";
        h += "property int8 a\r\nproperty float32 x\r\nproperty list uint8 int16 junk\r\n";
        h += "property int16 y\r\nproperty uint64 b\r\nproperty float64 z\r\n";
        h += "property uint16 red\r\nproperty uint32 green\r\nproperty int32 blue\r\n";
        h += "element material 2\r\nproperty list ushort double coeffs\r\nproperty uchar id\r\n";
        h += "element face 2\r\nproperty uchar flags\r\nproperty list uint uint vertex_index\r\n";
        h += "element edge 3\r\nproperty int v1\r\nproperty int v2\r\n";
        h += "end_header\r\n";
        let mut d = h.into_bytes();
        for i in 0..4u8 {
            d.push(0xff); // a
            d.extend_from_slice(&(f32::from(i) + 0.5).to_le_bytes()); // x
            d.push(i); // junk: i items of int16
            for k in 0..i {
                d.extend_from_slice(&(i16::from(k)).to_le_bytes());
            }
            d.extend_from_slice(&(-(i16::from(i))).to_le_bytes()); // y
            d.extend_from_slice(&u64::MAX.to_le_bytes()); // b
            d.extend_from_slice(&(f64::from(i) * 0.25).to_le_bytes()); // z
            d.extend_from_slice(&300u16.to_le_bytes()); // red (clamped)
            d.extend_from_slice(&u32::from(i).to_le_bytes()); // green
            d.extend_from_slice(&(-5i32).to_le_bytes()); // blue (clamped)
        }
        for k in 0..2u16 {
            d.extend_from_slice(&(k + 1).to_le_bytes());
            for j in 0..=k {
                d.extend_from_slice(&f64::from(j).to_le_bytes());
            }
            d.push(7);
        }
        d.push(0);
        d.extend_from_slice(&4u32.to_le_bytes());
        for v in [0u32, 1, 2, 3] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.push(0);
        d.extend_from_slice(&3u32.to_le_bytes());
        for v in [3u32, 2, 1] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&[0u8; 24]); // edges
        let m = parse(&d).unwrap();
        // The same file with a 2-gon for the triangle is an error naming the face (issue 31:
        // PLY faces of 0 or 2 indices are errors, as OBJ's `f 1 2`).
        let mut two = d.clone();
        let at = two.len() - 24 - 16;
        two[at..at + 4].copy_from_slice(&2u32.to_le_bytes());
        two.drain(at + 12..at + 16);
        let err = parse(&two).unwrap_err().to_string();
        assert!(
            err.contains("face 1 has 2 vertices, at least 3 are needed"),
            "{err}"
        );
        assert_eq!(
            m.vertices,
            vec![
                [0.5, 0.0, 0.0],
                [1.5, -1.0, 0.25],
                [2.5, -2.0, 0.5],
                [3.5, -3.0, 0.75]
            ]
        );
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
        assert_eq!(
            m.colors.unwrap(),
            vec![[255, 0, 0], [255, 1, 0], [255, 2, 0], [255, 3, 0]]
        );
        assert!(m.normals.is_none());
    }

    #[test]
    fn ascii_variants() {
        let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty uchar red\n\
            property double x\nproperty float y\nproperty float z\nproperty float nx\n\
            property float ny\nproperty float nz\nproperty list uchar int extra\n\
            property uchar green\nproperty uchar blue\n\
            element face 2\nproperty list uchar int vertex_indices\nproperty float q\n\
            end_header\n\
            1 0 0 0 0 0 1 0 2 3\n\
            \n\
            2.0 1e0 NaN -inf 1 0 0 2 5 6 4 5\n\
            3 0 1 0 0 1 0 1 9 6 7\n\
            4 1 1 0 0.5 0.5 0 3 1 2 3 8 9\n\
            4 0 1 2 3 0.5\n\
            3 3 2 1 -1";
        let m = parse(text.as_bytes()).unwrap();
        assert_eq!(m.vertices[0], [0.0, 0.0, 0.0]);
        assert_eq!(m.vertices[1][0], 1.0);
        assert!(m.vertices[1][1].is_nan(), "NaN is read as-is");
        assert_eq!(m.vertices[1][2], f64::NEG_INFINITY);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
        assert_eq!(
            m.colors.unwrap(),
            vec![[1, 2, 3], [2, 4, 5], [3, 6, 7], [4, 8, 9]]
        );
        assert_eq!(m.normals.unwrap()[3], [0.5, 0.5, 0.0]);
    }

    #[test]
    fn float_colors_are_scaled() {
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
            property float y\nproperty float z\nproperty float red\nproperty float green\n\
            property float blue\nend_header\n0 0 0 1.0 0.5 0\n";
        assert_eq!(
            parse(text.as_bytes()).unwrap().colors.unwrap(),
            vec![[255, 128, 0]]
        );
    }

    #[test]
    fn empty_file() {
        assert!(err_text(b"").contains("test.ply:0: empty file"));
    }

    #[test]
    fn non_ply_binary_file() {
        let junk: Vec<u8> = (0..200u32).map(|i| (i * 37 % 251) as u8).collect();
        let e = err_text(&junk);
        assert!(
            e.contains("test.ply:1: not a PLY file (missing 'ply' magic)"),
            "{e}"
        );
        assert!(err_text(b"plyfoo\n").contains("missing 'ply' magic"));
        // An OBJ renamed .ply
        assert!(err_text(b"v 0 0 0\n").contains("missing 'ply' magic"));
    }

    #[test]
    fn huge_header_counts_are_rejected_before_allocating() {
        for enc in ["binary_little_endian", "binary_big_endian", "ascii"] {
            let mut d = format!(
                "ply\nformat {enc} 1.0\nelement vertex 1000000000\nproperty float x\n\
                 property float y\nproperty float z\nend_header\n"
            )
            .into_bytes();
            d.resize(1024, b'0');
            let e = err_text(&d);
            assert!(
                e.contains("test.ply:3: header announces 1000000000 vertices"),
                "{e}"
            );
            assert!(e.contains("but the file holds at most"), "{e}");
        }
        // Exactly at the limit for faces: the face count is checked after the vertices.
        let mut d = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n\
            property float x\nproperty float y\nproperty float z\n\
            element face 18446744073709551615\nproperty list uchar int vertex_indices\n\
            end_header\n"
            .to_vec();
        d.extend_from_slice(&[0u8; 12 + 5]);
        let e = err_text(&d);
        assert!(
            e.contains(
                ":7: header announces 18446744073709551615 faces but the file holds at most 5"
            ),
            "{e}"
        );
        // An unknown element with a huge count.
        let d = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
            property float y\nproperty float z\nelement junk 99999999999\nproperty double w\n\
            end_header\n";
        assert!(err_text(d).contains("header announces 99999999999 'junk' elements"));
        // A count that does not fit in usize.
        let d = b"ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nend_header\n";
        assert!(err_text(d).contains(":3: element 'vertex': invalid count"));
    }

    #[test]
    fn truncated_files() {
        let mesh = full_mesh();
        for enc in [
            PlyEncoding::BinaryLittleEndian,
            PlyEncoding::BinaryBigEndian,
        ] {
            let bytes = to_bytes(&mesh, &[], enc);
            let header_len = bytes
                .windows(11)
                .position(|w| w == b"end_header\n")
                .unwrap()
                + 11;
            for cut in [header_len + 1, header_len + 100, bytes.len() - 1] {
                let e = err_text(&bytes[..cut]);
                assert!(
                    e.contains("header announces") || e.contains("truncated file"),
                    "{enc:?} cut {cut}: {e}"
                );
            }
        }
        // A list that runs past the end (passes the size check, fails while reading).
        let mut d = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
            property uchar x\nproperty uchar y\nproperty uchar z\n\
            element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            .to_vec();
        d.extend_from_slice(&[0u8; 9]);
        d.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0]);
        let e = err_text(&d);
        assert!(
            e.contains("test.ply:0: truncated file: face record 0 of 1"),
            "{e}"
        );

        let bytes = to_bytes(&mesh, &[], PlyEncoding::Ascii);
        let text = String::from_utf8(bytes).unwrap();
        let cut: String = text
            .lines()
            .take(text.lines().count() - 2)
            .collect::<Vec<_>>()
            .join("\n");
        let e = err_text(cut.as_bytes());
        assert!(
            e.contains("truncated file: expected 4 faces, found 2"),
            "{e}"
        );
        // Header without end_header.
        let e = err_text(b"ply\nformat ascii 1.0\nelement vertex 1\n");
        assert!(
            e.contains(":4: header is not terminated by 'end_header'"),
            "{e}"
        );
    }

    #[test]
    fn face_index_out_of_range_names_the_face() {
        let bytes = to_bytes(&sample_mesh(), &[], PlyEncoding::Ascii);
        let text = String::from_utf8(bytes.clone())
            .unwrap()
            .replace("3 1 3 2", "3 1 5 2");
        let e = err_text(text.as_bytes());
        let last = text.lines().count();
        assert!(
            e.contains(&format!(
                "test.ply:{last}: face 3 refers to vertex 5, but there are only 5 vertices"
            )),
            "{e}"
        );
        let text = String::from_utf8(bytes)
            .unwrap()
            .replace("3 0 1 2", "3 0 -1 2");
        assert!(err_text(text.as_bytes()).contains("face 0 refers to vertex -1"));
        // Binary: overwrite the last index of the last face.
        let bytes_le = {
            let mut b = to_bytes(&sample_mesh(), &[], PlyEncoding::BinaryLittleEndian);
            let n = b.len();
            b[n - 4..].copy_from_slice(&7i32.to_le_bytes());
            b
        };
        let e = err_text(&bytes_le);
        assert!(e.contains("test.ply:0: face 3 refers to vertex 7"), "{e}");
    }

    #[test]
    fn malformed_ascii_lines_name_the_line() {
        let good = String::from_utf8(to_bytes(&sample_mesh(), &[], PlyEncoding::Ascii)).unwrap();
        let lines: Vec<&str> = good.lines().collect();
        let header_lines = lines.iter().position(|l| *l == "end_header").unwrap() + 1;
        let third_vertex_line = header_lines + 3;
        let mut bad = lines.clone();
        bad[third_vertex_line - 1] = "0.1 zero 3";
        let e = err_text(bad.join("\n").as_bytes());
        assert!(
            e.contains(&format!(
                "test.ply:{third_vertex_line}: vertex 2: cannot parse 'zero' as double (property 'y')"
            )),
            "{e}"
        );
        bad[third_vertex_line - 1] = "0.1 0.2";
        let e = err_text(bad.join("\n").as_bytes());
        assert!(
            e.contains(&format!(":{third_vertex_line}: vertex 2: too few values")),
            "{e}"
        );
        bad[third_vertex_line - 1] = "0.1 0.2 0.3 0.4";
        let e = err_text(bad.join("\n").as_bytes());
        assert!(
            e.contains(&format!(":{third_vertex_line}: vertex 2: more values")),
            "{e}"
        );
        let mut bad = lines.clone();
        let n = bad.len();
        bad[n - 1] = "3 1 2.5 3";
        let e = err_text(bad.join("\n").as_bytes());
        assert!(
            e.contains(&format!(":{n}: face 3: cannot parse '2.5' as int")),
            "{e}"
        );
        bad[n - 1] = "-3 1 2 3";
        assert!(err_text(bad.join("\n").as_bytes()).contains("negative list count -3"));
        bad[n - 1] = "300 1 2 3";
        assert!(err_text(bad.join("\n").as_bytes()).contains("too few values"));
    }

    #[test]
    fn header_errors() {
        let cases: &[(&str, &str)] = &[
            ("ply\nformat xml 1.0\nend_header\n", ":2: unknown format 'xml'"),
            ("ply\nformat ascii 1.0\nend_header\n", "no 'vertex' element"),
            ("ply\nelement vertex 1\nproperty float x\nend_header\n", "no 'format' line"),
            ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", ":3: 'property' before"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\nend_header\n", ":4: unknown property type 'half'"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n", "no 'y' property"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nfoo bar\nend_header\n", ":4: unexpected header line"),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
                 property float z\nelement face 0\nproperty int flags\nend_header\n",
                ":7: face element has no 'vertex_indices'",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
                 property float z\nelement face 0\nproperty list float int vertex_indices\nend_header\n",
                ":8: list 'vertex_indices': count type 'float' is not an integer type",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
                 property float z\nelement face 0\nproperty list uchar float vertex_indices\nend_header\n",
                "expected an integer type",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nelement vertex 0\nend_header\n",
                ":4: second 'vertex' element",
            ),
        ];
        for (text, want) in cases {
            let e = err_text(text.as_bytes());
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    /// Deterministic mutation fuzzing: flipped bytes, truncations and spliced digits must give
    /// `Ok` or `Err`, never a panic or a runaway allocation.
    #[test]
    fn mutated_files_never_panic() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut rand = move |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        let extra = [VertexProperty::new("q", vec![0.5; 5])];
        for enc in ENCODINGS {
            let good = to_bytes(&full_mesh(), &extra, enc);
            for _ in 0..2000 {
                let mut d = good.clone();
                match rand(4) {
                    0 => d.truncate(rand(good.len())),
                    1 => {
                        for _ in 0..1 + rand(4) {
                            let i = rand(d.len());
                            d[i] = rand(256) as u8;
                        }
                    }
                    2 => {
                        let i = rand(d.len());
                        d.splice(i..i, b"99999999999".iter().copied());
                    }
                    _ => {
                        let i = rand(d.len());
                        let alphabet = b"0123456789 \n-.e";
                        d[i] = alphabet[rand(alphabet.len())];
                    }
                }
                let _ = parse(&d);
                let _ = super::super::parse_obj(&d, "fuzz.obj");
            }
        }
    }

    #[test]
    fn empty_mesh_and_no_trailing_newline() {
        let m = parse(
            b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
              property float z\nend_header\n",
        )
        .unwrap();
        assert_eq!(m, MeshData::default());
        let m = parse(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nend_header\n1 2 3",
        )
        .unwrap();
        assert_eq!(m.vertices, vec![[1.0, 2.0, 3.0]]);
    }
}
