//! The ASCII payload: one record per line, blank lines tolerated.

use super::header::{Header, Kind, Scalar};
use super::record::{Builder, Layout, Num, EXTRA_SLOT};
use super::{format_error, MeshData};
use crate::error::Result;
use crate::limits::push;

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

pub(super) fn read_ascii(
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
