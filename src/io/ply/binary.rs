//! The binary payload (little or big endian).

use super::header::{Element, Header, Kind, Scalar};
use super::record::{Builder, Layout, Num, EXTRA_SLOT};
use super::{format_error, MeshData};
use crate::error::Result;
use crate::limits::push;

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

pub(super) fn read_binary(
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
