//! The PLY header: its scalar and property types, elements, and the parse that checks the
//! announced counts against the payload before anything is allocated.

use super::{format_error, PlyEncoding};
use crate::error::Result;

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
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

    pub(super) fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::I64 | Self::U64 | Self::F64 => 8,
        }
    }

    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    pub(super) fn name(self) -> &'static str {
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
pub(super) enum Kind {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

#[derive(Clone, Debug)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) kind: Kind,
}

#[derive(Clone, Debug)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: usize,
    pub(super) props: Vec<Property>,
    /// Header line of the `element` statement (for error messages).
    pub(super) line: usize,
}

impl Element {
    /// What the count counts, for messages: "vertices", "faces", or "'edge' elements".
    pub(super) fn plural(&self) -> String {
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
    pub(super) fn fixed_size(&self) -> Option<usize> {
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
pub(super) struct Header {
    pub(super) encoding: PlyEncoding,
    pub(super) elements: Vec<Element>,
    /// Byte offset of the first payload byte.
    pub(super) payload_start: usize,
    /// Number of header lines (the payload's first line is `lines + 1`).
    pub(super) lines: usize,
}

pub(super) fn parse_header(data: &[u8], name: &str) -> Result<Header> {
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
pub(super) fn check_sizes(header: &Header, payload_len: usize, name: &str) -> Result<()> {
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
