//! The tracker's own PNG reader against the `png` crate: for every file the reader takes on,
//! the same size, layout and pixels, or both refuse. Files it leaves to the general decoder
//! (`Ok(None)`: palette, 16-bit, interlaced...) are not compared. Three differences are by
//! design: a chunk failing its checksum, or whose type is not four ASCII letters, is refused
//! here, whatever the png crate makes of it; and a file that ends after complete image data
//! without its IEND chunk (a copy cut at its last 12 bytes) is read here, every pixel being in
//! it, where the png crate refuses it: its pixels are compared with the png crate's of the
//! file made whole.

use physfit_track::fuzz_read_png;

/// The `png` crate's decoding of `file` with no transformation: layout, size and samples, or
/// its error; with the error of reading the chunks after the image data to IEND (`finish`),
/// if any.
fn reference(file: &[u8]) -> Result<(png::OutputInfo, Vec<u8>, Option<String>), String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(file));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let bytes = reader.output_buffer_size().ok_or("too large")?;
    // Deflate holds at most 1032 bytes per byte: a larger image cannot be in the file, and
    // is not allocated (the tracker refuses it by its decompression-ratio limit).
    if bytes > 1032 * file.len() {
        return Err(format!(
            "{bytes} bytes of samples cannot be in {} bytes",
            file.len()
        ));
    }
    let mut samples = vec![0; bytes];
    let info = reader.next_frame(&mut samples).map_err(|e| e.to_string())?;
    samples.truncate(info.buffer_size());
    let end = reader.finish().err().map(|e| e.to_string());
    Ok((info, samples, end))
}

/// Panics when `file` breaks the property above.
pub fn check(file: &[u8]) {
    let ours = match fuzz_read_png(file) {
        Ok(None) => return,
        Ok(Some(image)) => Ok(image),
        Err(e) => Err(e),
    };
    // A file cut just before its IEND chunk is compared with the same file made whole.
    const IEND: [u8; 12] = [0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];
    let theirs = match reference(file) {
        Err(_) if ours.is_ok() && !file.ends_with(&IEND) => reference(&[file, &IEND[..]].concat())
            .map(|(info, samples, _)| (info, samples, Some("no IEND".to_string()))),
        other => other,
    };
    match (ours, theirs) {
        (Ok((colour, size, samples)), Ok((info, png_samples, _))) => {
            assert_eq!(info.bit_depth, png::BitDepth::Eight, "{colour:?}");
            let want = match info.color_type {
                png::ColorType::Grayscale => image::ColorType::L8,
                png::ColorType::GrayscaleAlpha => image::ColorType::La8,
                png::ColorType::Rgb => image::ColorType::Rgb8,
                png::ColorType::Rgba => image::ColorType::Rgba8,
                png::ColorType::Indexed => panic!("an indexed image taken on as {colour:?}"),
            };
            assert_eq!(colour, want);
            assert_eq!((size.0 as u32, size.1 as u32), (info.width, info.height));
            assert!(samples == png_samples, "different pixels");
        }
        (Err(_), Err(_)) | (Err(_), Ok((_, _, Some(_)))) => {}
        // Stricter than the png crate on chunk framing, by design: every chunk's CRC is
        // verified (the png crate skips an ancillary chunk with a bad CRC and stops checking
        // the image data once the image is complete), and a chunk type must be four ASCII
        // letters, as the PNG specification (5.4) requires (the png crate skips any other).
        (Err(e), Ok(_)) if e.contains("checksum (CRC)") || e.starts_with("not a chunk type") => {}
        (Ok((colour, size, _)), Err(e)) => panic!("read as {colour:?} {size:?}, the png crate refuses: {e}"),
        (Err(e), Ok((info, _, None))) => panic!(
            "refused ({e}), the png crate reads {:?} {}x{}",
            info.color_type, info.width, info.height
        ),
    }
}
