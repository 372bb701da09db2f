//! TIFF files: multi-page stacks (one frame per page, as microscope software writes them)
//! and single pages among a folder's frames, read through the `tiff` crate.
//!
//! Pages may be 8- or 16-bit, grey or RGB (alpha is dropped), uncompressed, LZW or Deflate.
//! They decode to the same samples as a PNG of the same layout: 8-bit grey as its bytes,
//! everything else to a [`Frame`] on the 8-bit scale, 16-bit samples keeping their precision
//! as fractional levels.
//!
//! A stack is read page by page as the tracker asks for frames, through one decoder behind a
//! lock: the decoder remembers where each page it has passed starts, so a page asked for
//! again is found without walking the file's list of pages from the start.

use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use tiff::decoder::{Decoder, DecodingResult, Limits};

use crate::frames::{Frame, FrameDecoder};
use crate::TrackError;

/// File name extensions (lower case) read as TIFF.
pub const TIFF_EXTENSIONS: [&str; 2] = ["tif", "tiff"];

/// Returns true if and only if `bytes` starts like a TIFF file (either byte order, classic
/// or BigTIFF).
pub fn is_tiff(bytes: &[u8]) -> bool {
    matches!(bytes.get(..4), Some(b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+"))
}

/// A multi-page TIFF file, one frame per page.
#[derive(Debug)]
pub struct TiffStack {
    /// The file.
    pub path: PathBuf,
    /// Pages in the file.
    pub page_count: usize,
    decoder: Mutex<Decoder<BufReader<File>>>,
}

impl TiffStack {
    /// Opens `path` and counts its pages. Errors name the file.
    pub fn open(path: &Path) -> Result<TiffStack, TrackError> {
        let file = File::open(path).map_err(|source| TrackError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let decode_err = |e: tiff::TiffError| TrackError::Decode {
            path: path.to_path_buf(),
            message: format!("corrupt or truncated TIFF: {e}"),
        };
        let mut decoder = Decoder::new(BufReader::new(file))
            .map_err(decode_err)?
            .with_limits(Limits::unlimited());
        let mut page_count = 1;
        while decoder.more_images() {
            decoder.next_image().map_err(decode_err)?;
            page_count += 1;
        }
        Ok(TiffStack {
            path: path.to_path_buf(),
            page_count,
            decoder: Mutex::new(decoder),
        })
    }

    /// Decodes page `k` (from 0) with `decoder`'s buffers: see
    /// [`FrameDecoder::decode_tiff`]. Errors name the file and page.
    pub(crate) fn decode(
        &self,
        k: usize,
        decoder: &mut FrameDecoder,
        frame: &mut Frame,
    ) -> Result<Option<(usize, usize)>, TrackError> {
        let decode_err = |message: String| TrackError::Decode {
            path: self.path.clone(),
            message: format!("page {k}: {message}"),
        };
        // A page that failed to decode leaves the decoder usable: the next call seeks anew.
        let mut tiff = self
            .decoder
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        tiff.seek_to_image(k)
            .map_err(|e| decode_err(format!("corrupt or truncated TIFF: {e}")))?;
        decoder.decode_tiff(&mut tiff, frame).map_err(decode_err)
    }
}

/// Reads the current page of `tiff` into `samples` in the layout image's decoders write
/// (native-endian 16-bit samples); returns that layout and the page's width and height, px.
pub(crate) fn read_page<R: Read + Seek>(
    tiff: &mut Decoder<R>,
    samples: &mut Vec<u8>,
) -> Result<(image::ColorType, (usize, usize)), String> {
    use image::ColorType as C;
    use tiff::ColorType as T;
    let corrupt = |e: tiff::TiffError| format!("corrupt or truncated TIFF: {e}");
    let (width, height) = tiff.dimensions().map_err(corrupt)?;
    let colour = match tiff.colortype().map_err(corrupt)? {
        T::Gray(8) => C::L8,
        T::Gray(16) => C::L16,
        T::GrayA(8) => C::La8,
        T::GrayA(16) => C::La16,
        T::RGB(8) => C::Rgb8,
        T::RGB(16) => C::Rgb16,
        T::RGBA(8) => C::Rgba8,
        T::RGBA(16) => C::Rgba16,
        other => {
            return Err(format!(
                "unsupported TIFF layout {other:?} (8- or 16-bit grey or RGB)"
            ))
        }
    };
    let max = crate::limits::frame_limits().max_megapixels;
    let megapixels = f64::from(width) * f64::from(height) / 1e6;
    if megapixels > max {
        return Err(format!(
            "a page declares {width}x{height} px = {megapixels:.0} megapixels, above the \
             `frame-megapixels` limit of {max} megapixels (raise it with --limit frame-megapixels=N)"
        ));
    }
    let size = (width as usize, height as usize);
    let expected = size.0 * size.1 * usize::from(colour.bytes_per_pixel());
    samples.clear();
    match tiff.read_image().map_err(corrupt)? {
        DecodingResult::U8(v) => samples.extend_from_slice(&v),
        DecodingResult::U16(v) => samples.extend(v.iter().flat_map(|s| s.to_ne_bytes())),
        _ => return Err("unsupported TIFF sample format (8- or 16-bit unsigned)".into()),
    }
    if samples.len() != expected {
        // Planar pages: the decoder reads the first plane alone.
        return Err(format!(
            "unsupported TIFF page: {} bytes for {}x{} px {colour:?} (planar pages are not read)",
            samples.len(),
            size.0,
            size.1
        ));
    }
    Ok((colour, size))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FrameSource;
    use tiff::encoder::{colortype, TiffEncoder};

    /// A stack of each layout reads back page by page, in any order, to the samples written.
    #[test]
    fn stacks_of_every_layout_read_back() {
        let dir = std::env::temp_dir().join(format!("physfit-tiff-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h, pages) = (7u32, 5u32, 4usize);
        let level = |p: usize, i: usize| ((p * 31 + i * 7) % 256) as u8;
        let n = (w * h) as usize;

        let grey8 = dir.join("grey8.tif");
        let mut e = TiffEncoder::new(File::create(&grey8).unwrap()).unwrap();
        for p in 0..pages {
            let data: Vec<u8> = (0..n).map(|i| level(p, i)).collect();
            e.write_image::<colortype::Gray8>(w, h, &data).unwrap();
        }
        drop(e);
        let grey16 = dir.join("grey16.tiff");
        let mut e = TiffEncoder::new(File::create(&grey16).unwrap()).unwrap();
        for p in 0..pages {
            let data: Vec<u16> = (0..n).map(|i| u16::from(level(p, i)) * 256 + 100).collect();
            e.write_image::<colortype::Gray16>(w, h, &data).unwrap();
        }
        drop(e);
        let rgb = dir.join("rgb.TIF");
        let mut e = TiffEncoder::new(File::create(&rgb).unwrap()).unwrap();
        for p in 0..pages {
            let data: Vec<u8> = (0..n).flat_map(|i| [level(p, i), 9, 250]).collect();
            e.write_image::<colortype::RGB8>(w, h, &data).unwrap();
        }
        drop(e);

        for (path, channels) in [(&grey8, 1), (&grey16, 1), (&rgb, 3)] {
            let source = FrameSource::open(path, None).unwrap();
            assert_eq!(source.len(), pages, "{}", path.display());
            for p in [2, 0, 3, 1] {
                let f = source.load_frame(p).unwrap();
                assert_eq!(
                    (f.width, f.height, f.channels),
                    (w as usize, h as usize, channels)
                );
                for i in 0..n {
                    // 16-bit samples keep their precision as fractional levels.
                    let want = if path == &grey16 {
                        (f32::from(level(p, i)) * 256.0 + 100.0) / 257.0
                    } else {
                        f32::from(level(p, i))
                    };
                    let got = f.data[i * channels];
                    assert!(
                        (got - want).abs() < 1e-3,
                        "{}: page {p} pixel {i}: {got} vs {want}",
                        path.display()
                    );
                }
                if channels == 3 {
                    assert_eq!(&f.data[1..3], &[9.0, 250.0]);
                }
            }
        }
        // A single page in a folder is a frame like a PNG.
        let folder = dir.join("folder");
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::copy(&grey16, folder.join("frame_2.tif")).unwrap();
        std::fs::copy(&grey16, folder.join("frame_10.tif")).unwrap();
        let source = FrameSource::open(&folder, None).unwrap();
        assert_eq!(source.len(), 2);
        let f = source.load_frame(1).unwrap();
        assert_eq!(f.channels, 1);
        assert!((f.data[0] - (100.0 / 257.0)).abs() < 1e-4, "{}", f.data[0]);

        let truncated = dir.join("cut.tif");
        let bytes = std::fs::read(&grey8).unwrap();
        std::fs::write(&truncated, &bytes[..bytes.len() / 3]).unwrap();
        let e = FrameSource::open(&truncated, None)
            .and_then(|s| (0..s.len()).try_for_each(|k| s.load_frame(k).map(drop)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cut.tif"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
