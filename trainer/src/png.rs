//! Images written to disk: a PNG encoded in memory and put in place atomically (through
//! `snerf_files`), so that an interrupted evaluation or turntable never leaves a truncated
//! image. Below everything that writes images (evaluation, camera paths, commands), and it
//! depends on no other module of the crate.

use std::path::Path;

use anyhow::Result;

/// Write `img` as a PNG at `path`, replacing any file there only once the new one is whole.
pub fn write_png_atomic(path: &Path, img: &image::RgbImage) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)?;
    snerf_files::write_atomic(path, &bytes)
}
