//! Panel titles and color bars: a 3×5 pixel bitmap font (drawn at twice its size) holding
//! the digits, upper-case letters and the few signs the labels use, and the vertical bar of a
//! color scale with its top, middle and bottom values.

use super::colormap::Scale;
use super::raster::Canvas;

/// Pixel size of one font dot.
const DOT: usize = 2;
/// Advance from one character to the next, in pixels.
pub(crate) const ADVANCE: usize = 4 * DOT;
/// Height of a line of text, in pixels.
pub(crate) const LINE: usize = 5 * DOT;

/// The 3×5 glyph of `c` (rows top to bottom, bit 2 the left column); `None` when the font has
/// no such character (drawn as a blank).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        '+' => [0, 2, 7, 2, 0],
        '|' => [2, 2, 2, 2, 2],
        '/' => [1, 1, 2, 4, 4],
        ':' => [0, 2, 0, 2, 0],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 7, 4, 7],
        'F' => [7, 4, 7, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        _ => return None,
    })
}

/// Writes `text` with its top-left corner at (`x`, `y`), clipped to the canvas.
pub(crate) fn text(canvas: &mut Canvas, x: usize, y: usize, text: &str, color: [u8; 3]) {
    for (n, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) == 0 {
                    continue;
                }
                for dy in 0..DOT {
                    for dx in 0..DOT {
                        let (px, py) = (x + n * ADVANCE + col * DOT + dx, y + r * DOT + dy);
                        if px < canvas.width && py < canvas.height {
                            canvas.rgb[py * canvas.width + px] = color;
                        }
                    }
                }
            }
        }
    }
}

/// A value as a short label: three decimals between 0.1 and 1000, else scientific notation
/// with two (`1.25E-3`).
pub(crate) fn number(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if (0.1..1000.0).contains(&a) {
        format!("{v:.3}")
    } else {
        format!("{v:.2e}").to_uppercase()
    }
}

/// Draws the color bar of `scale` over `[lo, hi]` in the column `x0..canvas.width`, rows
/// `y0..y0 + height`: a caption, the bar (high values on top) and three values beside it.
pub(crate) fn color_bar(
    canvas: &mut Canvas,
    (x0, y0, height): (usize, usize, usize),
    caption: &str,
    scale: Scale,
    (lo, hi): (f64, f64),
) {
    let ink = [40, 40, 40];
    text(canvas, x0 + 4, y0 + 8, caption, ink);
    let top = y0 + 8 + LINE + 10;
    let bottom = (y0 + height).saturating_sub(16);
    if bottom <= top + 2 {
        return;
    }
    let (bar_x, bar_w) = (x0 + 6, 12);
    for y in top..bottom {
        let t = 1.0 - (y - top) as f64 / (bottom - 1 - top) as f64;
        let color = scale.at(t);
        for x in bar_x..(bar_x + bar_w).min(canvas.width) {
            canvas.rgb[y * canvas.width + x] = color;
        }
    }
    let label_x = bar_x + bar_w + 4;
    let mid = 0.5 * (lo + hi);
    for (y, v) in [
        (top, hi),
        ((top + bottom) / 2 - LINE / 2, mid),
        (bottom - LINE, lo),
    ] {
        text(canvas, label_x, y, &number(v), ink);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_are_short_and_in_the_font() {
        for (v, s) in [
            (0.0, "0"),
            (0.25, "0.250"),
            (12.5, "12.500"),
            (0.00125, "1.25E-3"),
            (-3.0e5, "-3.00E5"),
        ] {
            assert_eq!(number(v), s);
            assert!(s.chars().all(|c| glyph(c).is_some()), "{s}");
        }
    }

    #[test]
    fn text_draws_ink_only_where_the_glyph_has_dots() {
        let mut c = Canvas::new(20, 12, [255; 3]);
        text(&mut c, 0, 0, "1", [0; 3]);
        let ink = c.rgb.iter().filter(|&&p| p == [0; 3]).count();
        // '1' has 1 + 2 + 1 + 1 + 3 = 8 dots of DOT × DOT pixels.
        assert_eq!(ink, 8 * DOT * DOT);
        // A character outside the font draws nothing.
        let mut blank = Canvas::new(20, 12, [255; 3]);
        text(&mut blank, 0, 0, "~", [0; 3]);
        assert!(blank.rgb.iter().all(|&p| p == [255; 3]));
    }
}
