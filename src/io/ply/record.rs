//! Where a vertex record's values go ([`Layout`]), the decoded numbers ([`Num`]), and the
//! collection of vertices and fan-triangulated faces while the payload is decoded
//! ([`Builder`]); shared by the binary and the ASCII readers.

use super::header::{Header, Kind};
use super::{format_error, MeshData};
use crate::error::Result;
use crate::limits::{push, try_vec};

/// Where the vertex and face data live in the header.
pub(super) struct Layout {
    pub(super) vertex: usize,
    /// For each vertex property: the slot it fills (0..3 xyz, 3..6 normal, 6..9 color).
    pub(super) slots: Vec<Option<usize>>,
    has_normals: bool,
    has_colors: bool,
    /// Whether color properties are floats (0..1) rather than integers.
    float_colors: bool,
    /// The face element and its index-list property.
    pub(super) face: Option<(usize, usize)>,
    /// The vertex property asked for besides the mesh (read into slot [`EXTRA_SLOT`]).
    pub(super) extra: Option<usize>,
}

/// Where a vertex record's values go: 0..3 xyz, 3..6 normal, 6..9 color, 9 the extra property.
pub(super) const EXTRA_SLOT: usize = 9;

pub(super) const NORMAL_NAMES: [&str; 3] = ["nx", "ny", "nz"];
pub(super) const COLOR_NAMES: [[&str; 3]; 2] = [
    ["red", "green", "blue"],
    ["diffuse_red", "diffuse_green", "diffuse_blue"],
];

impl Layout {
    pub(super) fn new(header: &Header, name: &str, property: Option<&str>) -> Result<Self> {
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
pub(super) struct Builder {
    n_vertices: usize,
    pub(super) vertices: Vec<[f64; 3]>,
    pub(super) normals: Vec<[f64; 3]>,
    pub(super) colors: Vec<[u8; 3]>,
    pub(super) faces: Vec<[u32; 3]>,
    /// The extra property's values, when one was asked for.
    pub(super) extra: Vec<f64>,
    float_colors: bool,
    /// Scratch list of one face's indices.
    pub(super) polygon: Vec<i64>,
}

impl Builder {
    pub(super) fn new(
        header: &Header,
        layout: &Layout,
        payload_len: usize,
        name: &str,
    ) -> Result<Self> {
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
    pub(super) fn push_vertex(&mut self, values: &[f64; 10], layout: &Layout) {
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
    pub(super) fn push_polygon(&mut self, face: usize, name: &str, line: usize) -> Result<()> {
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

    pub(super) fn finish(self, layout: &Layout) -> (MeshData, Option<Vec<f64>>) {
        let mesh = MeshData {
            vertices: self.vertices,
            faces: self.faces,
            normals: layout.has_normals.then_some(self.normals),
            colors: layout.has_colors.then_some(self.colors),
        };
        (mesh, layout.extra.is_some().then_some(self.extra))
    }
}

/// A decoded number: integers stay exact (indices, counts), floats as they are.
#[derive(Clone, Copy, Debug)]
pub(super) enum Num {
    Int(i64),
    Float(f64),
}

impl Num {
    pub(super) fn as_f64(self) -> f64 {
        match self {
            Self::Int(i) => i as f64,
            Self::Float(f) => f,
        }
    }
    pub(super) fn as_int(self) -> Option<i64> {
        match self {
            Self::Int(i) => Some(i),
            Self::Float(f) if f.fract() == 0.0 && f.abs() < 9.0e18 => Some(f as i64),
            Self::Float(_) => None,
        }
    }
}
