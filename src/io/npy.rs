//! A reader of one-dimensional NumPy `.npy` arrays (what `np.save(path, w)` writes), for
//! per-point scan weights, and a writer of boolean masks ([`write_npy_mask`]: the scan points a
//! fit took for the garment).
//!
//! Accepts format versions 1.0, 2.0 and 3.0; a header dictionary with `'descr'`,
//! `'fortran_order'` and `'shape'`; the little-endian (or byte-order-free) types `<f8 <f4`,
//! `<i1..<i8` / `|i1`, `<u1..<u8` / `|u1` and `|b1` (bool: 0 or 1); the shapes `(N,)` and
//! `(N, 1)`. Everything else (big-endian data, other types, structured or object arrays,
//! Fortran order, other shapes, a payload of the wrong size) is refused with a
//! [`FoldMatchError::Format`](crate::FoldMatchError::Format) naming the file and what is wrong; the payload's size is checked
//! against the shape before anything is allocated, and no input makes the reader panic.

use super::{format_error, read_file};
use crate::error::Result;
use std::path::Path;

/// The magic string that starts every `.npy` file.
const MAGIC: &[u8] = b"\x93NUMPY";

/// Reads an `(N,)` or `(N, 1)` NumPy array of numbers or booleans as `f64` values.
///
/// # Errors
/// [`FoldMatchError::Io`](crate::FoldMatchError::Io) when the file cannot be read, [`FoldMatchError::Format`](crate::FoldMatchError::Format) (naming the
/// file and the reason) when it is not such an array.
pub fn read_npy(path: &Path) -> Result<Vec<f64>> {
    let data = read_file(path)?;
    parse_npy(&data, &path.display().to_string())
}

/// Parses `.npy` bytes as [`read_npy`] does; `name` is used in error messages.
///
/// # Errors
/// [`FoldMatchError::Format`](crate::FoldMatchError::Format) as for [`read_npy`].
pub fn parse_npy(data: &[u8], name: &str) -> Result<Vec<f64>> {
    let err = |reason: String| format_error(name, 0, reason);
    if !data.starts_with(MAGIC) {
        return Err(err(
            "not a NumPy .npy file (it does not start with the NUMPY magic string; save the \
             array with np.save)"
                .into(),
        ));
    }
    let (Some(&major), Some(&minor)) = (data.get(6), data.get(7)) else {
        return Err(err(
            "truncated file: no format version after the magic".into()
        ));
    };
    let (len_size, utf8) = match (major, minor) {
        (1, 0) => (2, false),
        (2, 0) => (4, false),
        (3, 0) => (4, true),
        _ => {
            return Err(err(format!(
                "unsupported .npy format version {major}.{minor} (expected 1.0, 2.0 or 3.0)"
            )))
        }
    };
    let header_start = 8 + len_size;
    let Some(len_bytes) = data.get(8..header_start) else {
        return Err(err("truncated file: no header length".into()));
    };
    let header_len = len_bytes
        .iter()
        .rev()
        .fold(0usize, |acc, &b| (acc << 8) | usize::from(b));
    let header_end = header_start
        .checked_add(header_len)
        .filter(|&end| end <= data.len())
        .ok_or_else(|| {
            err(format!(
                "truncated file: the header announces {header_len} bytes, the file holds {}",
                data.len().saturating_sub(header_start)
            ))
        })?;
    let raw = &data[header_start..header_end];
    let text: String = if utf8 {
        std::str::from_utf8(raw)
            .map_err(|_| err("the header is not valid UTF-8".into()))?
            .to_string()
    } else {
        // Versions 1.0 and 2.0 are latin-1: every byte is one character.
        raw.iter().map(|&b| char::from(b)).collect()
    };
    let header = parse_header(&text).map_err(|e| err(format!("header {text:?}: {e}")))?;
    let dtype = Dtype::parse(&header.descr).map_err(err)?;
    if header.fortran_order {
        return Err(err(
            "Fortran-ordered arrays are not supported (save np.ascontiguousarray(w))".into(),
        ));
    }
    let n = match header.shape[..] {
        [n] | [n, 1] => n,
        _ => {
            return Err(err(format!(
                "shape {} is not (N,) or (N, 1): give one weight per scan point",
                shape_text(&header.shape)
            )))
        }
    };
    let payload = &data[header_end..];
    let expected = n
        .checked_mul(dtype.size)
        .ok_or_else(|| err(format!("shape {} is too large", shape_text(&header.shape))))?;
    if payload.len() != expected {
        let what = if payload.len() < expected {
            "truncated file"
        } else {
            "trailing data"
        };
        return Err(err(format!(
            "{what}: shape {} of '{}' needs {expected} bytes of data, the file holds {}",
            shape_text(&header.shape),
            header.descr,
            payload.len()
        )));
    }
    Ok(payload
        .chunks_exact(dtype.size)
        .map(|b| dtype.decode(b))
        .collect())
}

/// The header dictionary's three keys.
#[derive(Debug)]
struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<usize>,
}

/// A value of the header dictionary (a Python literal).
#[derive(Debug)]
enum Literal {
    Str(String),
    Bool(bool),
    Tuple(Vec<usize>),
    /// Anything else (a list: a structured dtype), kept for the message.
    Other(String),
}

/// Parses `{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }` (with any spacing and
/// key order, single or double quotes, a trailing comma).
fn parse_header(text: &str) -> std::result::Result<Header, String> {
    let mut p = Parser {
        s: text.trim().as_bytes(),
        pos: 0,
    };
    p.expect(b'{')?;
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    loop {
        p.skip_ws();
        if p.eat(b'}') {
            break;
        }
        let key = p.string()?;
        p.skip_ws();
        p.expect(b':')?;
        p.skip_ws();
        let value = p.literal()?;
        match (key.as_str(), value) {
            ("descr", Literal::Str(s)) => descr = Some(s),
            ("descr", Literal::Other(s)) => {
                return Err(format!(
                    "structured dtype {s} is not supported: give a plain array of numbers"
                ))
            }
            ("fortran_order", Literal::Bool(b)) => fortran = Some(b),
            ("shape", Literal::Tuple(t)) => shape = Some(t),
            ("descr" | "fortran_order" | "shape", v) => {
                return Err(format!("unexpected value {v:?} for '{key}'"))
            }
            (other, _) => return Err(format!("unknown key '{other}'")),
        }
        p.skip_ws();
        if p.eat(b',') {
            continue;
        }
        p.skip_ws();
        p.expect(b'}')?;
        break;
    }
    p.skip_ws();
    if p.pos != p.s.len() {
        return Err("text after the closing brace".into());
    }
    Ok(Header {
        descr: descr.ok_or("no 'descr' key")?,
        fortran_order: fortran.ok_or("no 'fortran_order' key")?,
        shape: shape.ok_or("no 'shape' key")?,
    })
}

struct Parser<'a> {
    s: &'a [u8],
    pos: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<u8> {
        self.s.get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while self.peek().is_some_and(|b| b.is_ascii_whitespace()) {
            self.pos += 1;
        }
    }

    fn eat(&mut self, b: u8) -> bool {
        let hit = self.peek() == Some(b);
        if hit {
            self.pos += 1;
        }
        hit
    }

    fn expect(&mut self, b: u8) -> std::result::Result<(), String> {
        if self.eat(b) {
            Ok(())
        } else {
            Err(format!(
                "expected '{}' at character {}",
                char::from(b),
                self.pos
            ))
        }
    }

    /// A quoted string without escapes (dtype strings and keys need none).
    fn string(&mut self) -> std::result::Result<String, String> {
        let quote = match self.peek() {
            Some(q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("expected a quoted key at character {}", self.pos)),
        };
        self.pos += 1;
        let start = self.pos;
        while let Some(b) = self.peek() {
            if b == quote {
                let s = String::from_utf8_lossy(&self.s[start..self.pos]).into_owned();
                self.pos += 1;
                return Ok(s);
            }
            self.pos += 1;
        }
        Err("unterminated string".into())
    }

    fn literal(&mut self) -> std::result::Result<Literal, String> {
        match self.peek() {
            Some(b'\'' | b'"') => self.string().map(Literal::Str),
            Some(b'(') => {
                self.pos += 1;
                let mut dims = Vec::new();
                loop {
                    self.skip_ws();
                    if self.eat(b')') {
                        break;
                    }
                    let start = self.pos;
                    while self.peek().is_some_and(|b| b.is_ascii_digit()) {
                        self.pos += 1;
                    }
                    let digits = std::str::from_utf8(&self.s[start..self.pos]).unwrap_or("");
                    let dim: usize = digits
                        .parse()
                        .map_err(|_| format!("expected a dimension at character {start}"))?;
                    self.eat(b'L'); // Python 2 longs
                    dims.push(dim);
                    self.skip_ws();
                    if !self.eat(b',') {
                        self.skip_ws();
                        self.expect(b')')?;
                        break;
                    }
                }
                Ok(Literal::Tuple(dims))
            }
            Some(b'[') => {
                // A structured dtype: a list of fields. Take it whole (brackets nest) for the
                // message.
                let start = self.pos;
                let mut depth = 0usize;
                while let Some(b) = self.peek() {
                    self.pos += 1;
                    match b {
                        b'[' => depth += 1,
                        b']' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                Ok(Literal::Other(
                    String::from_utf8_lossy(&self.s[start..self.pos]).into_owned(),
                ))
            }
            _ => {
                for (word, value) in [("True", true), ("False", false)] {
                    if self.s[self.pos..].starts_with(word.as_bytes()) {
                        self.pos += word.len();
                        return Ok(Literal::Bool(value));
                    }
                }
                Err(format!("unexpected value at character {}", self.pos))
            }
        }
    }
}

fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The accepted element types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Float,
    Int,
    Uint,
    Bool,
}

#[derive(Clone, Copy, Debug)]
struct Dtype {
    kind: Kind,
    size: usize,
}

impl Dtype {
    fn parse(descr: &str) -> std::result::Result<Self, String> {
        let refuse = |why: &str| {
            format!(
                "dtype '{descr}' {why}; accepted: float64, float32, int8..int64, uint8..uint64, \
                 bool (little endian)"
            )
        };
        let bytes = descr.as_bytes();
        let (Some(&order), Some(&code)) = (bytes.first(), bytes.get(1)) else {
            return Err(refuse("is not understood"));
        };
        let size: usize = match descr.get(2..).and_then(|s| s.parse().ok()) {
            Some(n) => n,
            None => return Err(refuse("is not supported")),
        };
        let kind = match (code, size) {
            (b'f', 4 | 8) => Kind::Float,
            (b'i', 1 | 2 | 4 | 8) => Kind::Int,
            (b'u', 1 | 2 | 4 | 8) => Kind::Uint,
            (b'b', 1) => Kind::Bool,
            _ => return Err(refuse("is not supported")),
        };
        match order {
            b'<' => {}
            b'|' if size == 1 => {}
            b'>' if size > 1 => return Err(refuse("is big endian, which is not supported")),
            _ => return Err(refuse("has an unsupported byte order")),
        }
        Ok(Self { kind, size })
    }

    /// One element (`bytes.len() == self.size`, little endian).
    fn decode(self, bytes: &[u8]) -> f64 {
        let mut word = [0u8; 8];
        word[..self.size].copy_from_slice(bytes);
        match (self.kind, self.size) {
            (Kind::Float, 4) => f64::from(f32::from_le_bytes([word[0], word[1], word[2], word[3]])),
            (Kind::Float, _) => f64::from_le_bytes(word),
            (Kind::Bool, _) => f64::from(u8::from(word[0] != 0)),
            (Kind::Uint, _) => u64::from_le_bytes(word) as f64,
            (Kind::Int, _) => {
                // Sign-extend from `size` bytes.
                let shift = 64 - 8 * self.size as u32;
                ((i64::from_le_bytes(word) << shift) >> shift) as f64
            }
        }
    }
}

/// Writes `mask` as a one-dimensional NumPy bool array (`|b1`, shape `(N,)`, format 1.0),
/// atomically: what `np.load` reads as a boolean mask and [`read_npy`] reads back as 0/1.
///
/// # Errors
/// [`FoldMatchError::Io`](crate::FoldMatchError::Io) when the file cannot be written.
pub fn write_npy_mask(path: &Path, mask: &[bool]) -> Result<()> {
    let mut header = format!(
        "{{'descr': '|b1', 'fortran_order': False, 'shape': ({},), }}",
        mask.len()
    );
    // The magic, version and length take 10 bytes; the header ends in a newline and pads the
    // whole preamble to a multiple of 64 bytes.
    let used = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - used % 64) % 64));
    header.push('\n');
    super::write_atomically(path, |w| {
        use std::io::Write;
        w.write_all(MAGIC)?;
        w.write_all(&[1, 0])?;
        w.write_all(&(header.len() as u16).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        let bytes: Vec<u8> = mask.iter().map(|&b| u8::from(b)).collect();
        w.write_all(&bytes)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::FoldMatchError;

    /// An `.npy` file as `np.save` writes it: version `major`.0, header padded with spaces to
    /// a multiple of 64 bytes and ended by a newline.
    fn npy(major: u8, descr: &str, fortran: bool, shape: &str, payload: &[u8]) -> Vec<u8> {
        let fortran = if fortran { "True" } else { "False" };
        let mut dict =
            format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}");
        let len_size = if major == 1 { 2 } else { 4 };
        let used = MAGIC.len() + 2 + len_size + dict.len() + 1;
        dict.push_str(&" ".repeat((64 - used % 64) % 64));
        dict.push('\n');
        let mut out = MAGIC.to_vec();
        out.extend([major, 0]);
        if major == 1 {
            out.extend((dict.len() as u16).to_le_bytes());
        } else {
            out.extend((dict.len() as u32).to_le_bytes());
        }
        out.extend(dict.as_bytes());
        out.extend(payload);
        out
    }

    fn parse(data: &[u8]) -> Result<Vec<f64>> {
        parse_npy(data, "w.npy")
    }

    /// The error text; it must be a `Format` error naming the file.
    fn refused(data: &[u8]) -> String {
        match parse(data) {
            Ok(v) => panic!("accepted: {v:?}"),
            Err(e) => {
                assert!(matches!(e, FoldMatchError::Format { .. }), "{e:?}");
                let text = e.to_string();
                assert!(text.starts_with("w.npy:"), "{text}");
                text
            }
        }
    }

    #[test]
    fn every_accepted_dtype() {
        let values = [0.0f64, 1.0, 2.0, 5.0];
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("<f8", values.iter().flat_map(|v| v.to_le_bytes()).collect()),
            (
                "<f4",
                values
                    .iter()
                    .flat_map(|&v| (v as f32).to_le_bytes())
                    .collect(),
            ),
            (
                "|i1",
                values
                    .iter()
                    .flat_map(|&v| (v as i8).to_le_bytes())
                    .collect(),
            ),
            (
                "<i1",
                values
                    .iter()
                    .flat_map(|&v| (v as i8).to_le_bytes())
                    .collect(),
            ),
            (
                "<i2",
                values
                    .iter()
                    .flat_map(|&v| (v as i16).to_le_bytes())
                    .collect(),
            ),
            (
                "<i4",
                values
                    .iter()
                    .flat_map(|&v| (v as i32).to_le_bytes())
                    .collect(),
            ),
            (
                "<i8",
                values
                    .iter()
                    .flat_map(|&v| (v as i64).to_le_bytes())
                    .collect(),
            ),
            (
                "|u1",
                values
                    .iter()
                    .flat_map(|&v| (v as u8).to_le_bytes())
                    .collect(),
            ),
            (
                "<u2",
                values
                    .iter()
                    .flat_map(|&v| (v as u16).to_le_bytes())
                    .collect(),
            ),
            (
                "<u4",
                values
                    .iter()
                    .flat_map(|&v| (v as u32).to_le_bytes())
                    .collect(),
            ),
            (
                "<u8",
                values
                    .iter()
                    .flat_map(|&v| (v as u64).to_le_bytes())
                    .collect(),
            ),
        ];
        for (descr, payload) in &cases {
            for major in [1, 2, 3] {
                let got = parse(&npy(major, descr, false, "(4,)", payload)).unwrap();
                assert_eq!(got, values, "{descr} v{major}");
            }
        }
        let mask = parse(&npy(1, "|b1", false, "(4,)", &[0, 1, 1, 0])).unwrap();
        assert_eq!(mask, [0.0, 1.0, 1.0, 0.0]);
        // Signed types keep their sign (the fit then refuses it, naming the index).
        let neg = parse(&npy(1, "<i2", false, "(2,)", &[0xff, 0xff, 0x00, 0x80])).unwrap();
        assert_eq!(neg, [-1.0, -32768.0]);
        let neg = parse(&npy(1, "|i1", false, "(1,)", &[0x80])).unwrap();
        assert_eq!(neg, [-128.0]);
        let f = parse(&npy(1, "<f4", false, "(1,)", &0.1f32.to_le_bytes())).unwrap();
        assert_eq!(f, [f64::from(0.1f32)]);
        let empty = parse(&npy(1, "<f8", false, "(0,)", &[])).unwrap();
        assert!(empty.is_empty());
    }

    #[test]
    fn column_shape_and_header_variants() {
        let payload: Vec<u8> = [0.5f64, 2.0, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        assert_eq!(
            parse(&npy(1, "<f8", false, "(3, 1)", &payload)).unwrap(),
            [0.5, 2.0, 3.0]
        );
        assert_eq!(
            parse(&npy(1, "<f8", false, "(3,1)", &payload)).unwrap(),
            [0.5, 2.0, 3.0]
        );
        // Other key order, double quotes, no trailing comma, Python 2 long.
        let dict = "{\"shape\": (3L,), \"fortran_order\": False, \"descr\": \"<f8\"}\n";
        let mut data = MAGIC.to_vec();
        data.extend([1, 0]);
        data.extend((dict.len() as u16).to_le_bytes());
        data.extend(dict.as_bytes());
        data.extend(&payload);
        assert_eq!(parse(&data).unwrap(), [0.5, 2.0, 3.0]);
    }

    #[test]
    fn truncated_and_oversized_payloads_are_refused() {
        let payload: Vec<u8> = [1.0f64, 2.0, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let e = refused(&npy(1, "<f8", false, "(3,)", &payload[..20]));
        assert!(
            e.contains("truncated file") && e.contains("needs 24 bytes"),
            "{e}"
        );
        let e = refused(&npy(
            1,
            "<f8",
            false,
            "(3,)",
            &[payload.clone(), vec![0]].concat(),
        ));
        assert!(e.contains("trailing data"), "{e}");
        // A shape far beyond the file is refused before anything is allocated.
        let e = refused(&npy(1, "<f8", false, "(1000000000000,)", &payload));
        assert!(e.contains("truncated file"), "{e}");
        let e = refused(&npy(1, "<f8", false, "(18446744073709551615,)", &payload));
        assert!(e.contains("too large"), "{e}");
        let e = refused(&npy(
            1,
            "<f8",
            false,
            "(99999999999999999999999,)",
            &payload,
        ));
        assert!(e.contains("dimension"), "{e}");
        // The header itself cut short.
        let whole = npy(1, "<f8", false, "(3,)", &payload);
        for cut in [0, 3, 6, 7, 9, 30] {
            refused(&whole[..cut]);
        }
    }

    #[test]
    fn wrong_magic_and_versions_are_refused() {
        let e = refused(b"PK\x03\x04 a zip, as np.savez writes");
        assert!(e.contains("not a NumPy .npy file"), "{e}");
        let mut data = npy(1, "<f8", false, "(0,)", &[]);
        data[6] = 4;
        let e = refused(&data);
        assert!(e.contains("version 4.0"), "{e}");
    }

    #[test]
    fn fortran_order_and_other_shapes_are_refused() {
        let payload = [1u8; 6];
        let e = refused(&npy(1, "|u1", true, "(6,)", &payload));
        assert!(e.contains("Fortran"), "{e}");
        let e = refused(&npy(1, "|u1", false, "(2, 3)", &payload));
        assert!(e.contains("shape (2, 3) is not (N,) or (N, 1)"), "{e}");
        let e = refused(&npy(1, "|u1", false, "(6, 1, 1)", &payload));
        assert!(e.contains("shape (6, 1, 1)"), "{e}");
        let e = refused(&npy(1, "|u1", false, "()", &payload[..1]));
        assert!(e.contains("shape ()"), "{e}");
    }

    #[test]
    fn other_dtypes_are_refused() {
        let payload = [0u8; 16];
        let e = refused(&npy(1, ">f8", false, "(2,)", &payload));
        assert!(e.contains("'>f8' is big endian"), "{e}");
        let e = refused(&npy(1, ">i4", false, "(4,)", &payload));
        assert!(e.contains("big endian"), "{e}");
        for descr in [
            "<f2", "<c16", "|O", "<U3", "|S2", "<M8[ns]", "=f8", "|f8", "<f16", "x",
        ] {
            let e = refused(&npy(1, descr, false, "(1,)", &payload));
            assert!(e.contains(&format!("dtype '{descr}'")), "{e}");
        }
        // A structured array: 'descr' is a list of fields.
        let dict =
            "{'descr': [('a', '<f8'), ('b', '<i4')], 'fortran_order': False, 'shape': (1,), }\n";
        let mut data = MAGIC.to_vec();
        data.extend([1, 0]);
        data.extend((dict.len() as u16).to_le_bytes());
        data.extend(dict.as_bytes());
        data.extend([0u8; 12]);
        let e = refused(&data);
        assert!(e.contains("structured dtype"), "{e}");
    }

    #[test]
    fn malformed_headers_are_refused() {
        for dict in [
            "",
            "{",
            "{'descr': '<f8'}",
            "{'descr': '<f8', 'fortran_order': False}",
            "{'descr': '<f8', 'fortran_order': Maybe, 'shape': (1,)}",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1,), 'extra': 1}",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1,)} junk",
            "{'descr': '<f8, 'fortran_order': False, 'shape': (1,)}",
            "{'descr': 8, 'fortran_order': False, 'shape': (1,)}",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (-1,)}",
            "{'descr': '<f8', 'fortran_order': False, 'shape': [1]}",
        ] {
            let mut data = MAGIC.to_vec();
            data.extend([1, 0]);
            data.extend((dict.len() as u16).to_le_bytes());
            data.extend(dict.as_bytes());
            data.extend([0u8; 8]);
            let e = refused(&data);
            assert!(e.contains("header"), "{dict}: {e}");
        }
        // Version 3.0 headers are UTF-8.
        let mut data = npy(3, "<f8", false, "(0,)", &[]);
        data[12] = 0xff;
        let e = refused(&data);
        assert!(e.contains("UTF-8"), "{e}");
    }

    /// Every truncation and every single-byte change of valid files is answered without a
    /// panic.
    #[test]
    fn mutated_files_never_panic() {
        let payload: Vec<u8> = [1.0f64, 0.0, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        for file in [
            npy(1, "<f8", false, "(3,)", &payload),
            npy(2, "|b1", false, "(3, 1)", &[1, 0, 1]),
            npy(3, "<i2", false, "(2,)", &[1, 0, 2, 0]),
        ] {
            for cut in 0..file.len() {
                let _ = parse(&file[..cut]);
            }
            for i in 0..file.len() {
                for b in [0u8, b'(', b')', b'\'', b',', b'1', b'[', 0xff] {
                    let mut m = file.clone();
                    m[i] = b;
                    let _ = parse(&m);
                }
            }
        }
    }

    #[test]
    fn a_written_mask_reads_back_with_an_aligned_header() {
        let dir = std::env::temp_dir().join(format!("fm-npy-mask-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for n in [0usize, 1, 5, 117, 100_000] {
            let mask: Vec<bool> = (0..n).map(|j| j % 3 == 1).collect();
            let path = dir.join(format!("m{n}.npy"));
            write_npy_mask(&path, &mask).unwrap();
            let data = std::fs::read(&path).unwrap();
            let header = u16::from_le_bytes([data[8], data[9]]) as usize;
            assert_eq!((10 + header) % 64, 0, "n = {n}");
            assert_eq!(data.len(), 10 + header + n);
            let back: Vec<bool> = read_npy(&path).unwrap().iter().map(|&w| w == 1.0).collect();
            assert_eq!(back, mask);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn read_npy_names_missing_files() {
        let e = read_npy(Path::new("/nonexistent/w.npy")).unwrap_err();
        assert!(matches!(e, FoldMatchError::Io { .. }), "{e:?}");
        assert!(e.to_string().contains("/nonexistent/w.npy"));
    }
}
