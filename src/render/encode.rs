//! PNG output (the `png` crate): 8-bit RGB, written atomically like every other output.

use super::Image;
use crate::error::{FoldMatchError, Result};
use crate::io::write_atomically;
use std::io::Write;
use std::path::Path;

/// The PNG encoding of `image`, with `text` as `tEXt` chunks (keyword, value).
pub fn encode_png(image: &Image, text: &[(&str, String)]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    write_png_to(&mut out, image, text).map_err(|e| FoldMatchError::Numerical(e.to_string()))?;
    Ok(out)
}

/// Writes `image` as a PNG file at `path`, atomically (a temporary file renamed into place),
/// with `text` as `tEXt` chunks.
pub fn write_png(path: &Path, image: &Image, text: &[(&str, String)]) -> Result<()> {
    write_atomically(path, |w| {
        write_png_to(w, image, text).map_err(|e| std::io::Error::other(e.to_string()))
    })
}

fn write_png_to<W: Write>(
    w: W,
    image: &Image,
    text: &[(&str, String)],
) -> std::result::Result<(), png::EncodingError> {
    let mut encoder = png::Encoder::new(w, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    for (keyword, value) in text {
        encoder.add_text_chunk((*keyword).to_string(), value.clone())?;
    }
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&image.pixels)?;
    writer.finish()
}
