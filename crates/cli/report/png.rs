//! PNG output: encode in memory, then write atomically.

use std::path::Path;

use anyhow::Context;
use image::{ExtendedColorType, ImageEncoder, RgbImage};

/// Encodes `image` as an 8-bit RGB PNG and writes it to `path` atomically (temporary file + rename), so a reader
/// never sees half a picture. The error names the file.
pub fn write_png(path: &Path, image: &RgbImage) -> anyhow::Result<()> {
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            ExtendedColorType::Rgb8,
        )
        .with_context(|| format!("encoding {}", path.display()))?;
    physfit_model::write_atomic(path, &bytes).with_context(|| format!("writing {}", path.display()))
}
