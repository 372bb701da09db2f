//! Reading the commonest frame files, non-interlaced 8-bit PNG (grey, grey + alpha, RGB,
//! RGBA), without the general decoder's row-at-a-time unfiltering (see [`unfilter`]).
//!
//! The file's chunks are walked and their checksums verified, the image data inflated in one
//! call (fdeflate, the PNG crate's own inflater) and unfiltered sixteen rows at a time. Every
//! other PNG (palette, 16-bit, interlaced, an unknown critical chunk) is left to the general
//! decoder.
//!
//! Why not the `png` crate (0.18, the decoder `image` 0.25 uses, which reads every other
//! file): it unfilters a row at a time, and the Average and Paeth filters that encoders
//! choose for most rows of a noisy frame make each byte wait on the one before it. Here
//! unfiltering takes 1.0 M instructions a 512 x 512 frame instead of 1.8 M, and tracking the
//! 200-frame N = 10 bench folder on one thread went from 316 to 275 ms (best of 7), 671 to
//! 796 frames/s in `physfit bench track` (2026-11-24; docs/benchmarks.md). zune-png 0.4 was
//! slower than `png` (1.68-2.01 ms a frame against 0.67-0.72). The inflater is a crate,
//! fdeflate, the fastest of five measured (0.35 ms a frame against libdeflate 0.54, zlib-rs
//! 0.63, zune-inflate 0.63, miniz_oxide 0.80). The fuzz target `png_reader` checks this
//! reader against `png` sample for sample (docs/fuzzing.md).

mod unfilter;

use image::ColorType;

/// The eight bytes every PNG file starts with.
const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Largest decoded image this reader takes on, bytes; a larger one is left to the general
/// decoder, whose limits then apply.
const MAX_BYTES: usize = 1 << 30;

/// The size a PNG file's header declares, read before anything is decoded: (width, height) in
/// px and the bytes of its image data once inflated (the filtered rows as stored, which the
/// compressed stream has to hold). `None` when `file` does not start with a PNG signature and
/// an image header.
pub(crate) fn declared_size(file: &[u8]) -> Option<((u64, u64), u64)> {
    if !file.starts_with(&SIGNATURE) || file.get(12..16)? != b"IHDR" {
        return None;
    }
    let word = |i: usize| -> Option<u64> {
        let b = file.get(i..i + 4)?;
        Some(u64::from(u32::from_be_bytes([b[0], b[1], b[2], b[3]])))
    };
    let (width, height) = (word(16)?, word(20)?);
    let (depth, colour_type) = (u64::from(*file.get(24)?), *file.get(25)?);
    let channels = match colour_type {
        2 => 3,
        4 => 2,
        6 => 4,
        _ => 1,
    };
    // One filter byte per row, then the row's samples rounded up to whole bytes.
    let row = 1 + (width * channels * depth).div_ceil(8);
    Some(((width, height), row.saturating_mul(height)))
}

/// Reusable buffers of [`read_png`]: the image data as stored and as inflated, and the
/// unfiltering's.
#[derive(Debug, Default)]
pub(crate) struct PngScratch {
    compressed: Vec<u8>,
    filtered: Vec<u8>,
    unfilter: unfilter::Scratch,
}

/// An image [`read_png`] decoded: its samples' layout and size (px).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PngImage {
    pub colour: ColorType,
    pub width: usize,
    pub height: usize,
}

/// Decodes `file` into `samples` (8-bit samples, the file's channels interleaved, rows back to
/// back) if it is a PNG this reader handles: `Ok(None)` when it is not (not a PNG, or one
/// for the general decoder), an error message when it is corrupt or truncated.
pub(crate) fn read_png(
    file: &[u8],
    samples: &mut Vec<u8>,
    scratch: &mut PngScratch,
) -> Result<Option<PngImage>, String> {
    if !file.starts_with(&SIGNATURE) {
        return Ok(None);
    }
    let mut header: Option<Header> = None;
    scratch.compressed.clear();
    // The image data of the first IDAT chunk; when more follow, all of it is gathered in
    // `scratch.compressed`.
    let mut first_data: Option<&[u8]> = None;
    let mut gathered = false;
    let mut at = SIGNATURE.len();
    let mut ended = false;
    while at < file.len() {
        let chunk = Chunk::at(file, at)?;
        at = chunk.end;
        match &chunk.kind {
            b"IHDR" => match Header::parse(chunk.data)? {
                Some(h) => header = Some(h),
                None => return Ok(None),
            },
            b"IDAT" if header.is_none() => return Err("image data before the header".into()),
            b"IDAT" => match first_data {
                None => first_data = Some(chunk.data),
                Some(first) => {
                    if !gathered {
                        scratch.compressed.extend_from_slice(first);
                        gathered = true;
                    }
                    scratch.compressed.extend_from_slice(chunk.data);
                }
            },
            b"IEND" => {
                ended = true;
                break;
            }
            b"PLTE" => {}
            // An unknown critical chunk (upper-case first letter): the general decoder decides.
            kind if kind[0].is_ascii_uppercase() => return Ok(None),
            _ => {}
        }
    }
    let header = header.ok_or("no image header (IHDR chunk)")?;
    let row = header.width * header.bpp;
    let Some(bytes) = row.checked_mul(header.height).filter(|&b| b <= MAX_BYTES) else {
        return Ok(None);
    };
    let filtered_len = bytes + header.height;
    sized(&mut scratch.filtered, filtered_len);
    let mut inflater = fdeflate::Decompressor::new();
    // Every byte of the compressed stream is covered by its chunk's CRC, already checked.
    inflater.ignore_adler32();
    let ends_early = if ended { "" } else { " (the file ends early)" };
    // Most files hold their image data in one chunk, inflated where it lies.
    let compressed = if gathered {
        &scratch.compressed
    } else {
        first_data.unwrap_or_default()
    };
    let written = match inflater.read(compressed, &mut scratch.filtered, 0, true) {
        Ok((_, written)) => written,
        Err(fdeflate::DecompressionError::InsufficientInput) => {
            return Err(format!(
                "truncated image data: the compressed stream stops short{ends_early}"
            ))
        }
        Err(e) => return Err(format!("corrupt image data: {e:?}")),
    };
    if written < filtered_len {
        return Err(format!(
            "truncated image data: {written} of {filtered_len} bytes{ends_early}"
        ));
    }
    sized(samples, bytes);
    unfilter::unfilter(&scratch.filtered, row, header.bpp, samples, &mut scratch.unfilter)
        .map_err(|bad| format!("unknown filter type {} in row {}", bad.kind, bad.row))?;
    Ok(Some(PngImage {
        colour: header.colour,
        width: header.width,
        height: header.height,
    }))
}

/// An image [`fuzz_read_png`] decoded: layout, size (width, height) in px, 8-bit samples.
#[doc(hidden)]
pub type FuzzPng = (ColorType, (usize, usize), Vec<u8>);

/// Fuzzing hook, not an API (the `png_reader` target of `fuzz/`, see `docs/fuzzing.md`): `file`
/// through the frame limits ([`crate::frame_limits`]) and [`read_png`] as a frame file is
/// decoded, with fresh buffers. `Ok(None)` for a file left to the general decoder, else the
/// colour layout, the size (width, height) in px and the 8-bit samples; an error message for a
/// file refused.
#[doc(hidden)]
pub fn fuzz_read_png(file: &[u8]) -> Result<Option<FuzzPng>, String> {
    if let Some((size, stored)) = declared_size(file) {
        let path = std::path::Path::new("fuzz input");
        crate::limits::check_frame_size(path, size, stored, file.len() as u64).map_err(|e| e.to_string())?;
    }
    let mut samples = Vec::new();
    let image = read_png(file, &mut samples, &mut PngScratch::default())?;
    Ok(image.map(|i| (i.colour, (i.width, i.height), samples)))
}

/// Gives `buffer` the length `len`, without clearing it when it has that length already (the
/// next frame's buffers, every byte of which is written before it is read).
fn sized(buffer: &mut Vec<u8>, len: usize) {
    if buffer.len() != len {
        buffer.clear();
        buffer.resize(len, 0);
    }
}

/// One chunk of a PNG file: its type, its data and where the next chunk starts.
struct Chunk<'a> {
    kind: [u8; 4],
    data: &'a [u8],
    end: usize,
}

impl<'a> Chunk<'a> {
    /// The chunk starting at byte `at` of `file`, its CRC checked.
    fn at(file: &'a [u8], at: usize) -> Result<Chunk<'a>, String> {
        let word = |i: usize| -> Option<u32> {
            let b = file.get(i..i + 4)?;
            Some(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
        };
        let truncated = || format!("truncated: the chunk at byte {at} runs past the end of the file");
        let len = word(at).ok_or_else(truncated)? as usize;
        let kind: [u8; 4] = file
            .get(at + 4..at + 8)
            .ok_or_else(truncated)?
            .try_into()
            .expect("four bytes");
        let end = at + 12 + len;
        let crc = word(at + 8 + len).ok_or_else(truncated)?;
        let name = String::from_utf8_lossy(&kind).into_owned();
        if !kind.iter().all(u8::is_ascii_alphabetic) {
            return Err(format!("not a chunk type at byte {at}: {name:?}"));
        }
        if crc32fast::hash(&file[at + 4..at + 8 + len]) != crc {
            return Err(format!("the {name} chunk at byte {at} fails its checksum (CRC)"));
        }
        Ok(Chunk {
            kind,
            data: &file[at + 8..at + 8 + len],
            end,
        })
    }
}

/// What the header says of an image this reader decodes.
struct Header {
    width: usize,
    height: usize,
    colour: ColorType,
    /// Bytes per pixel.
    bpp: usize,
}

impl Header {
    /// The image header chunk's `data`: `None` for an image left to the general decoder.
    fn parse(data: &[u8]) -> Result<Option<Header>, String> {
        if data.len() != 13 {
            return Err(format!("an image header of {} bytes instead of 13", data.len()));
        }
        let width = u32::from_be_bytes([data[0], data[1], data[2], data[3]]) as usize;
        let height = u32::from_be_bytes([data[4], data[5], data[6], data[7]]) as usize;
        let (depth, colour_type, compression, filter, interlace) =
            (data[8], data[9], data[10], data[11], data[12]);
        if width == 0 || height == 0 {
            return Err(format!("an image of {width}x{height} pixels"));
        }
        let (colour, bpp) = match colour_type {
            0 => (ColorType::L8, 1),
            4 => (ColorType::La8, 2),
            2 => (ColorType::Rgb8, 3),
            6 => (ColorType::Rgba8, 4),
            _ => return Ok(None),
        };
        if depth != 8 || compression != 0 || filter != 0 || interlace != 0 {
            return Ok(None);
        }
        Ok(Some(Header {
            width,
            height,
            colour,
            bpp,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::{DynamicImage, ImageEncoder};
    use rand::{Rng, SeedableRng};

    /// `img` as a PNG file, each row filtered with `filter`.
    fn encode(img: &DynamicImage, filter: FilterType) -> Vec<u8> {
        let mut bytes = Vec::new();
        PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, filter)
            .write_image(img.as_bytes(), img.width(), img.height(), img.color().into())
            .unwrap();
        bytes
    }

    /// A noisy image with a smooth gradient, of every 8-bit layout.
    fn noisy(colour: ColorType, w: u32, h: u32, seed: u64) -> DynamicImage {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let channels = u32::from(colour.channel_count());
        let data: Vec<u8> = (0..w * h * channels)
            .map(|i| {
                let x = (i / channels) % w;
                (30 + x * 100 / w + rng.gen_range(0..20)) as u8
            })
            .collect();
        match colour {
            ColorType::L8 => DynamicImage::ImageLuma8(image::GrayImage::from_raw(w, h, data).unwrap()),
            ColorType::La8 => DynamicImage::ImageLumaA8(image::GrayAlphaImage::from_raw(w, h, data).unwrap()),
            ColorType::Rgb8 => DynamicImage::ImageRgb8(image::RgbImage::from_raw(w, h, data).unwrap()),
            _ => DynamicImage::ImageRgba8(image::RgbaImage::from_raw(w, h, data).unwrap()),
        }
    }

    /// Every 8-bit layout, every filter choice and sizes on both sides of the wavefront's
    /// group decode to the general decoder's samples.
    #[test]
    fn decodes_as_the_general_decoder() {
        let mut scratch = PngScratch::default();
        let mut samples = Vec::new();
        let layouts = [ColorType::L8, ColorType::La8, ColorType::Rgb8, ColorType::Rgba8];
        let filters = [
            FilterType::NoFilter,
            FilterType::Sub,
            FilterType::Up,
            FilterType::Avg,
            FilterType::Paeth,
            FilterType::Adaptive,
        ];
        for (k, &colour) in layouts.iter().enumerate() {
            for &filter in &filters {
                for (w, h) in [(1, 1), (7, 3), (33, 17), (64, 48)] {
                    let img = noisy(colour, w, h, k as u64 * 100 + u64::from(w));
                    let file = encode(&img, filter);
                    let got = read_png(&file, &mut samples, &mut scratch).unwrap().unwrap();
                    assert_eq!(
                        got,
                        PngImage {
                            colour,
                            width: w as usize,
                            height: h as usize
                        }
                    );
                    let want = image::load_from_memory(&file).unwrap();
                    assert!(samples == want.as_bytes(), "{colour:?} {filter:?} {w}x{h}");
                }
            }
        }
    }

    /// `file` with its one image data chunk cut into chunks of at most `size` bytes (and an
    /// empty one second, which the format allows).
    fn split_image_data(file: &[u8], size: usize) -> Vec<u8> {
        let at = file.windows(4).position(|w| w == b"IDAT").unwrap() - 4;
        let len = u32::from_be_bytes(file[at..at + 4].try_into().unwrap()) as usize;
        let data = &file[at + 8..at + 8 + len];
        let mut out = file[..at].to_vec();
        let mut parts: Vec<&[u8]> = data.chunks(size).collect();
        parts.insert(1, &data[..0]);
        for part in parts {
            out.extend_from_slice(&(part.len() as u32).to_be_bytes());
            let mut body = b"IDAT".to_vec();
            body.extend_from_slice(part);
            out.extend_from_slice(&body);
            out.extend_from_slice(&crc32fast::hash(&body).to_be_bytes());
        }
        out.extend_from_slice(&file[at + 12 + len..]);
        out
    }

    #[test]
    fn image_data_split_over_chunks_decodes_the_same() {
        let mut scratch = PngScratch::default();
        let (mut whole, mut split) = (Vec::new(), Vec::new());
        let file = encode(&noisy(ColorType::Rgb8, 50, 40, 3), FilterType::Adaptive);
        read_png(&file, &mut whole, &mut scratch).unwrap().unwrap();
        for size in [1, 7, 1000] {
            read_png(&split_image_data(&file, size), &mut split, &mut scratch)
                .unwrap()
                .unwrap();
            assert!(split == whole, "chunks of {size} bytes");
        }
        // A file of one chunk after one of several: the gathered data is not reused.
        read_png(&file, &mut split, &mut scratch).unwrap().unwrap();
        assert!(split == whole);
    }

    #[test]
    fn other_pngs_and_other_files_are_left_to_the_general_decoder() {
        let mut scratch = PngScratch::default();
        let mut samples = Vec::new();
        let deep = DynamicImage::ImageLuma16(image::ImageBuffer::from_raw(4, 4, vec![1000u16; 16]).unwrap());
        let file = encode(&deep, FilterType::Sub);
        assert_eq!(read_png(&file, &mut samples, &mut scratch), Ok(None));
        assert_eq!(read_png(b"GIF89a....", &mut samples, &mut scratch), Ok(None));
    }

    #[test]
    fn corrupt_and_truncated_files_are_refused_with_the_reason() {
        let mut scratch = PngScratch::default();
        let mut samples = Vec::new();
        let file = encode(&noisy(ColorType::L8, 40, 30, 1), FilterType::Avg);
        // Cut inside the image data.
        let e = read_png(&file[..file.len() / 2], &mut samples, &mut scratch).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
        // One flipped bit in the image data.
        let mut flipped = file.clone();
        let idat = flipped.windows(4).position(|w| w == b"IDAT").unwrap();
        flipped[idat + 20] ^= 0x10;
        let e = read_png(&flipped, &mut samples, &mut scratch).unwrap_err();
        assert!(e.contains("IDAT") && e.contains("checksum"), "{e}");
        // Whole chunks missing: the image data stops short of the image.
        let e = read_png(&file[..idat - 4], &mut samples, &mut scratch).unwrap_err();
        assert!(
            e.contains("truncated image data") && e.contains("ends early"),
            "{e}"
        );
    }

    #[test]
    fn an_unknown_filter_type_is_refused() {
        // A 2x2 grey image whose second row claims filter type 9.
        let raw = [0u8, 1, 2, 9, 3, 4];
        let compressed = fdeflate::compress_to_vec(&raw);
        let mut file = SIGNATURE.to_vec();
        let mut chunk = |kind: &[u8; 4], data: &[u8]| {
            file.extend_from_slice(&(data.len() as u32).to_be_bytes());
            let mut body = kind.to_vec();
            body.extend_from_slice(data);
            file.extend_from_slice(&body);
            file.extend_from_slice(&crc32fast::hash(&body).to_be_bytes());
        };
        chunk(b"IHDR", &[0, 0, 0, 2, 0, 0, 0, 2, 8, 0, 0, 0, 0]);
        chunk(b"IDAT", &compressed);
        chunk(b"IEND", &[]);
        let e = read_png(&file, &mut Vec::new(), &mut PngScratch::default()).unwrap_err();
        assert_eq!(e, "unknown filter type 9 in row 1");
    }
}
