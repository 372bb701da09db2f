//! Frame files: listing a folder in natural name order and decoding one frame to a
//! floating-point pixel buffer. (A recording may also be a video or a TIFF stack: see
//! [`crate::FrameSource`].)
//!
//! Every frame is held as `f32` samples on the 8-bit scale (0 = black, 255 = white), one
//! channel for grey images and three for colour ones (alpha is dropped). 16-bit images
//! keep their precision as fractional levels. An 8-bit grey file's bytes are also taken as
//! they are, read as the same levels: by the locate pass ([`FrameView::Grey8`]) and for the
//! sample frames kept for the estimates ([`DecodedFrame::Grey8`]).

use std::cmp::Ordering;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use image::DynamicImage;

use crate::png_reader::{read_png, PngImage, PngScratch};
use crate::TrackError;

/// One decoded frame: `channels` interleaved `f32` samples per pixel, row-major, on the
/// 8-bit grey-level scale (0..255). The default is an empty frame (no pixels).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Samples per pixel: 1 (grey) or 3 (red, green, blue).
    pub channels: usize,
    /// `width * height * channels` samples, grey levels (0..255).
    pub data: Vec<f32>,
}

impl Frame {
    /// A frame filled with one colour (`level.len()` = channels), grey levels.
    pub fn filled(width: usize, height: usize, level: &[f32]) -> Frame {
        let channels = level.len().max(1);
        // One grey level is a plain fill (copied a pixel at a time, 7 M instructions for a
        // frame of 512 x 512).
        let data = if let [v] = level {
            vec![*v; width * height]
        } else {
            let mut data = Vec::with_capacity(width * height * channels);
            for _ in 0..width * height {
                data.extend_from_slice(level);
            }
            data
        };
        Frame {
            width,
            height,
            channels,
            data,
        }
    }

    /// This frame with `channels` channels: grey is replicated into red, green and blue;
    /// colour is averaged into grey.
    #[must_use]
    pub fn with_channels(self, channels: usize) -> Frame {
        if channels == self.channels {
            return self;
        }
        let data = if channels == 3 {
            self.data.iter().flat_map(|&v| [v, v, v]).collect()
        } else {
            self.data
                .chunks_exact(3)
                .map(|c| (c[0] + c[1] + c[2]) / 3.0)
                .collect()
        };
        Frame {
            channels,
            data,
            ..self
        }
    }
}

/// Returns the image files of `dir` (PNG, JPEG and single-page TIFF, by extension,
/// case-insensitive; hidden files skipped) in natural name order: digit runs compare by value, so `frame_2`
/// comes before `frame_10`.
pub fn list_frames(dir: &Path) -> Result<Vec<PathBuf>, TrackError> {
    let io_err = |source| TrackError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let path = entry.map_err(io_err)?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if !name.starts_with('.')
            && matches!(ext.as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff")
            && path.is_file()
        {
            files.push(path);
        }
    }
    files.sort_by(|a, b| compare_natural(&a.to_string_lossy(), &b.to_string_lossy()));
    Ok(files)
}

/// Compares two names in natural order: runs of digits by numeric value (then by length,
/// so `01` sorts after `1`), everything else character by character.
pub fn compare_natural(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let na = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let nb = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (da, db) = (&a[..na], &b[..nb]);
                let ta = trim_zeros(da);
                let tb = trim_zeros(db);
                let ord = ta
                    .len()
                    .cmp(&tb.len())
                    .then_with(|| ta.cmp(tb))
                    .then_with(|| na.cmp(&nb));
                if ord != Ordering::Equal {
                    return ord;
                }
                a = &a[na..];
                b = &b[nb..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let k = d.iter().take_while(|&&c| c == b'0').count();
    &d[k..]
}

/// The number in a frame file's name (its last run of digits), if any.
pub fn frame_number(path: &Path) -> Option<u64> {
    let stem = path.file_stem()?.to_string_lossy();
    let digits: String = stem
        .chars()
        .rev()
        .skip_while(|c| !c.is_ascii_digit())
        .take_while(char::is_ascii_digit)
        .collect();
    digits.chars().rev().collect::<String>().parse().ok()
}

/// Decodes one frame file (PNG or TIFF 8/16-bit grey, grey+alpha, RGB, RGBA; JPEG; a TIFF's
/// first page) to a [`Frame`].
/// Errors name the file: unreadable, empty, corrupt or truncated.
pub fn load_frame(path: &Path) -> Result<Frame, TrackError> {
    FrameDecoder::default().load(path)
}

/// Decodes frame files one after another into reused buffers (the file's bytes and its
/// decoded samples), so that a stream of frames allocates nothing after the first.
#[derive(Debug, Default)]
pub struct FrameDecoder {
    /// The last file's bytes.
    file: Vec<u8>,
    /// The last image's samples as decoded (the file's own channel layout and depth).
    samples: Vec<u8>,
    /// The 8-bit PNG reader's buffers.
    png: PngScratch,
}

impl FrameDecoder {
    /// Decodes the frame file `path` (see [`load_frame`]) into a new frame.
    pub fn load(&mut self, path: &Path) -> Result<Frame, TrackError> {
        let mut frame = Frame::default();
        self.load_into(path, &mut frame)?;
        Ok(frame)
    }

    /// Decodes the frame file `path` (see [`load_frame`]) to be kept: an 8-bit grey file's
    /// bytes as they are (a quarter of the memory of its [`Frame`]), any other layout as a
    /// [`Frame`].
    pub fn load_decoded(&mut self, path: &Path) -> Result<DecodedFrame, TrackError> {
        let mut frame = Frame::default();
        Ok(match self.decode(path, &mut frame)? {
            // The samples buffer goes with the frame; the next file is decoded into a new one.
            Some((width, height)) => DecodedFrame::Grey8 {
                samples: std::mem::take(&mut self.samples),
                width,
                height,
            },
            None => DecodedFrame::Frame(frame),
        })
    }

    /// Decodes the frame file `path` (see [`load_frame`]) into `frame`, reusing its buffer.
    pub fn load_into(&mut self, path: &Path, frame: &mut Frame) -> Result<(), TrackError> {
        if let Some(size) = self.decode(path, frame)? {
            grey8_to_frame(&self.samples, size, frame);
        }
        Ok(())
    }

    /// Decodes the frame file `path` (see [`load_frame`]): an 8-bit grey file's samples as
    /// they are (the commonest frames: their signal is formed from the bytes, without a
    /// frame-sized floating-point copy), every other file into `frame`, reusing its buffer.
    pub fn load_view<'a>(
        &'a mut self,
        path: &Path,
        frame: &'a mut Frame,
    ) -> Result<FrameView<'a>, TrackError> {
        Ok(match self.decode(path, frame)? {
            Some((width, height)) => FrameView::Grey8 {
                samples: &self.samples,
                width,
                height,
            },
            None => FrameView::Frame(frame),
        })
    }

    /// The buffer 8-bit grey samples are decoded into, for frames read from elsewhere than
    /// a file (a video's cache file).
    pub(crate) fn samples_mut(&mut self) -> &mut Vec<u8> {
        &mut self.samples
    }

    /// The 8-bit grey samples last decoded (see [`FrameDecoder::decode`]).
    pub(crate) fn samples(&self) -> &[u8] {
        &self.samples
    }

    /// Decodes the current page of `tiff` as [`FrameDecoder::decode`] decodes a file: 8-bit
    /// grey samples left in `self.samples` (their size returned), every other layout into
    /// `frame`. Errs with a message (without the file's name).
    pub(crate) fn decode_tiff<R: std::io::Read + std::io::Seek>(
        &mut self,
        tiff: &mut tiff::decoder::Decoder<R>,
        frame: &mut Frame,
    ) -> Result<Option<(usize, usize)>, String> {
        let (colour, size) = crate::stack::read_page(tiff, &mut self.samples)?;
        if colour == image::ColorType::L8 {
            return Ok(Some(size));
        }
        samples_to_frame(&self.samples, colour, size, frame)?;
        Ok(None)
    }

    /// Decodes `path`: 8-bit grey samples are left in `self.samples` (their size returned),
    /// every other layout is converted into `frame` (`None` returned).
    pub(crate) fn decode(
        &mut self,
        path: &Path,
        frame: &mut Frame,
    ) -> Result<Option<(usize, usize)>, TrackError> {
        use image::ImageDecoder;
        use std::io::Read;
        let io_err = |source| TrackError::Io {
            path: path.to_path_buf(),
            source,
        };
        self.file.clear();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut self.file))
            .map_err(io_err)?;
        let decode_err = |message: String| TrackError::Decode {
            path: path.to_path_buf(),
            message,
        };
        if self.file.is_empty() {
            return Err(decode_err("the file is empty".into()));
        }
        // Limits first: the header's claims are checked before any sample is allocated.
        let declared_png = crate::png_reader::declared_size(&self.file);
        if let Some((size, stored)) = declared_png {
            crate::limits::check_frame_size(path, size, stored, self.file.len() as u64)?;
        }
        // 8-bit PNG, the commonest frame file, through the tracker's own reader; every other
        // file through the general decoders.
        let png = read_png(&self.file, &mut self.samples, &mut self.png)
            .map_err(|e| decode_err(format!("corrupt or truncated image: {e}")))?;
        if let Some(PngImage {
            colour,
            width,
            height,
        }) = png
        {
            if colour == image::ColorType::L8 {
                return Ok(Some((width, height)));
            }
            samples_to_frame(&self.samples, colour, (width, height), frame).map_err(decode_err)?;
            return Ok(None);
        }
        if crate::stack::is_tiff(&self.file) {
            let mut file = std::mem::take(&mut self.file);
            let decoded = tiff::decoder::Decoder::new(Cursor::new(&file))
                .map_err(|e| format!("corrupt or truncated TIFF: {e}"))
                .and_then(|mut tiff| self.decode_tiff(&mut tiff, frame));
            // The file's buffer is kept for the next file.
            std::mem::swap(&mut self.file, &mut file);
            return decoded.map_err(decode_err);
        }
        let decoder = image::ImageReader::new(Cursor::new(&self.file))
            .with_guessed_format()
            .map_err(|e| decode_err(e.to_string()))?
            .into_decoder()
            .map_err(|e| decode_err(format!("corrupt or truncated image: {e}")))?;
        let (width, height) = decoder.dimensions();
        if declared_png.is_none() {
            let size = (u64::from(width), u64::from(height));
            crate::limits::check_frame_size(path, size, decoder.total_bytes(), self.file.len() as u64)?;
        }
        let colour = decoder.color_type();
        let bytes = usize::try_from(decoder.total_bytes())
            .map_err(|_| decode_err(format!("a {width}x{height} image is too large")))?;
        self.samples.resize(bytes, 0);
        decoder
            .read_image(&mut self.samples)
            .map_err(|e| decode_err(format!("corrupt or truncated image: {e}")))?;
        samples_to_frame(&self.samples, colour, (width as usize, height as usize), frame)
            .map_err(decode_err)?;
        Ok(None)
    }
}

/// A decoded frame kept for later ([`FrameDecoder::load_decoded`]): 8-bit grey as the file's
/// bytes, read as the same levels; any other layout as a [`Frame`].
#[derive(Clone, Debug, PartialEq)]
pub enum DecodedFrame {
    /// 8-bit grey.
    Grey8 {
        /// One byte per pixel, grey levels, rows back to back (`width * height`).
        samples: Vec<u8>,
        /// Width, px.
        width: usize,
        /// Height, px.
        height: usize,
    },
    /// Any other layout.
    Frame(Frame),
}

impl DecodedFrame {
    /// The frame's pixels, borrowed.
    pub fn view(&self) -> FrameView<'_> {
        match self {
            DecodedFrame::Grey8 {
                samples,
                width,
                height,
            } => FrameView::Grey8 {
                samples,
                width: *width,
                height: *height,
            },
            DecodedFrame::Frame(f) => FrameView::Frame(f),
        }
    }
}

/// A decoded frame as [`FrameDecoder::load_view`] hands it over.
#[derive(Clone, Copy, Debug)]
pub enum FrameView<'a> {
    /// 8-bit grey.
    Grey8 {
        /// One byte per pixel, grey levels, rows back to back (`width * height`).
        samples: &'a [u8],
        /// Width, px.
        width: usize,
        /// Height, px.
        height: usize,
    },
    /// Any other layout, as a [`Frame`].
    Frame(&'a Frame),
}

/// The largest value a frame holds, grey levels (8-bit white; deeper frames are scaled to it).
pub(crate) const CLIP_LEVEL: f32 = 255.0;
/// Values at least this bright are taken as clipped: half a level below [`CLIP_LEVEL`] (an
/// 8-bit frame's 255).
pub(crate) const CLIPPED: f32 = CLIP_LEVEL - 0.5;

impl FrameView<'_> {
    /// Returns true if and only if pixel `i` (row-major) holds the 8-bit clip level (255) in
    /// some channel: the light there saturated, and the value says only that it is at least
    /// that bright.
    pub fn clipped_at(&self, i: usize) -> bool {
        match self {
            FrameView::Grey8 { samples, .. } => samples[i] == u8::MAX,
            FrameView::Frame(f) => f.data[i * f.channels..(i + 1) * f.channels]
                .iter()
                .any(|&v| v >= CLIPPED),
        }
    }

    /// Returns true if and only if some pixel holds the clip level ([`FrameView::clipped_at`]).
    pub(crate) fn any_clipped(&self) -> bool {
        match self {
            FrameView::Grey8 { samples, .. } => samples.contains(&u8::MAX),
            FrameView::Frame(f) => f.data.iter().any(|&v| v >= CLIPPED),
        }
    }

    /// Width and height, px.
    pub fn size(&self) -> (usize, usize) {
        match self {
            FrameView::Grey8 { width, height, .. } => (*width, *height),
            FrameView::Frame(f) => (f.width, f.height),
        }
    }

    /// Samples per pixel: 1 (grey) or 3 (red, green, blue).
    pub fn channels(&self) -> usize {
        match self {
            FrameView::Grey8 { .. } => 1,
            FrameView::Frame(f) => f.channels,
        }
    }

    /// Number of samples, `width * height * channels`.
    pub fn len(&self) -> usize {
        match self {
            FrameView::Grey8 { samples, .. } => samples.len(),
            FrameView::Frame(f) => f.data.len(),
        }
    }

    /// Whether the frame has no pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample `i` of the channel-interleaved samples (pixel `i / channels`, channel
    /// `i % channels`), grey levels: what [`Frame::data`] holds there.
    #[inline]
    pub fn value(&self, i: usize) -> f32 {
        match self {
            FrameView::Grey8 { samples, .. } => f32::from(samples[i]),
            FrameView::Frame(f) => f.data[i],
        }
    }

    /// Pixel `p`'s channels, grey levels: the first [`FrameView::channels`] entries (the
    /// rest 0).
    #[inline]
    pub fn pixel(&self, p: usize) -> [f32; 3] {
        match self {
            FrameView::Grey8 { samples, .. } => [f32::from(samples[p]), 0.0, 0.0],
            FrameView::Frame(f) => {
                let mut out = [0.0; 3];
                let c = f.channels;
                out[..c].copy_from_slice(&f.data[p * c..(p + 1) * c]);
                out
            }
        }
    }

    /// The same pixels as a [`Frame`] (a copy for 8-bit grey samples).
    pub fn to_frame(&self) -> Frame {
        match self {
            FrameView::Grey8 {
                samples,
                width,
                height,
            } => {
                let mut frame = Frame::default();
                grey8_to_frame(samples, (*width, *height), &mut frame);
                frame
            }
            FrameView::Frame(f) => (*f).clone(),
        }
    }
}

impl<'a> From<&'a Frame> for FrameView<'a> {
    fn from(frame: &'a Frame) -> FrameView<'a> {
        FrameView::Frame(frame)
    }
}

/// Fills `frame` (`size` = width, height, px) with 8-bit grey `samples`.
pub(crate) fn grey8_to_frame(samples: &[u8], size: (usize, usize), frame: &mut Frame) {
    samples_to_frame(samples, image::ColorType::L8, size, frame).expect("8-bit grey is a known layout");
}

/// Converts a decoded image to a [`Frame`] (8-bit scale, alpha dropped).
pub fn frame_from_image(image: &DynamicImage) -> Frame {
    let mut frame = Frame::default();
    let size = (image.width() as usize, image.height() as usize);
    if samples_to_frame(image.as_bytes(), image.color(), size, &mut frame).is_err() {
        // A layout the decoders do not produce today: through image's own conversion.
        let rgb = image.to_rgb32f();
        frame = Frame {
            width: size.0,
            height: size.1,
            channels: 3,
            data: rgb.as_raw().iter().map(|&v| v * 255.0).collect(),
        };
    }
    frame
}

/// Fills `frame` (`size` = width, height, px) from decoded `samples` laid out as `colour`
/// (native-endian 16- and 32-bit samples, as image's decoders write them): grey stays one
/// channel, colour becomes three, alpha is dropped, and every depth is put on the 8-bit
/// scale. Errs with a message for a colour type it does not know.
pub(crate) fn samples_to_frame(
    samples: &[u8],
    colour: image::ColorType,
    size: (usize, usize),
    frame: &mut Frame,
) -> Result<(), String> {
    use image::ColorType as C;
    fn u16s(b: &[u8]) -> impl Iterator<Item = f32> + '_ {
        b.chunks_exact(2)
            .map(|p| f32::from(u16::from_ne_bytes([p[0], p[1]])) / 257.0)
    }
    fn f32s(b: &[u8]) -> impl Iterator<Item = f32> + '_ {
        b.chunks_exact(4)
            .map(|p| f32::from_ne_bytes([p[0], p[1], p[2], p[3]]) * 255.0)
    }
    /// The first `keep` of every `stride` samples.
    fn keep<T>(it: impl Iterator<Item = T>, stride: usize, keep: usize) -> impl Iterator<Item = T> {
        it.enumerate()
            .filter(move |(i, _)| i % stride < keep)
            .map(|(_, v)| v)
    }
    let data = &mut frame.data;
    data.clear();
    let channels = match colour {
        C::L8 => {
            data.extend(samples.iter().map(|&v| f32::from(v)));
            1
        }
        C::La8 => {
            data.extend(samples.chunks_exact(2).map(|p| f32::from(p[0])));
            1
        }
        C::Rgb8 => {
            data.extend(samples.iter().map(|&v| f32::from(v)));
            3
        }
        C::Rgba8 => {
            data.extend(
                samples
                    .chunks_exact(4)
                    .flat_map(|p| [p[0], p[1], p[2]].map(f32::from)),
            );
            3
        }
        C::L16 => {
            data.extend(u16s(samples));
            1
        }
        C::La16 => {
            data.extend(keep(u16s(samples), 2, 1));
            1
        }
        C::Rgb16 => {
            data.extend(u16s(samples));
            3
        }
        C::Rgba16 => {
            data.extend(keep(u16s(samples), 4, 3));
            3
        }
        C::Rgb32F => {
            data.extend(f32s(samples));
            3
        }
        C::Rgba32F => {
            data.extend(keep(f32s(samples), 4, 3));
            3
        }
        other => return Err(format!("unsupported colour type {other:?}")),
    };
    frame.width = size.0;
    frame.height = size.1;
    frame.channels = channels;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_puts_2_before_10() {
        let mut names = vec![
            "frame_10.png",
            "frame_2.png",
            "frame_1.png",
            "frame_02.png",
            "a.png",
        ];
        names.sort_by(|a, b| compare_natural(a, b));
        assert_eq!(
            names,
            [
                "a.png",
                "frame_1.png",
                "frame_2.png",
                "frame_02.png",
                "frame_10.png"
            ]
        );
    }

    #[test]
    fn frame_number_is_the_last_digit_run() {
        assert_eq!(frame_number(Path::new("/x/run3_frame_0012.png")), Some(12));
        assert_eq!(frame_number(Path::new("/x/last.png")), None);
    }

    #[test]
    fn sixteen_bit_and_rgba_are_scaled_to_8_bit_levels() {
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(2, 1, vec![0u16, 65535]).unwrap();
        let f = frame_from_image(&DynamicImage::ImageLuma16(img));
        assert_eq!(f.channels, 1);
        assert!((f.data[1] - 255.0).abs() < 1e-4);
        let img = image::RgbaImage::from_raw(1, 1, vec![10, 20, 30, 0]).unwrap();
        let f = frame_from_image(&DynamicImage::ImageRgba8(img));
        assert_eq!(f.data, vec![10.0, 20.0, 30.0]);
    }

    #[test]
    fn truncated_file_is_named() {
        let dir = std::env::temp_dir().join(format!("physfit-frames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("frame_3.png");
        let img = image::GrayImage::from_fn(64, 64, |x, y| image::Luma([((x * 7 + y * 13) % 251) as u8]));
        let mut bytes = Vec::new();
        DynamicImage::ImageLuma8(img)
            .write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png)
            .unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let e = load_frame(&path).unwrap_err().to_string();
        assert!(e.contains("frame_3.png"), "{e}");
        std::fs::write(&path, b"").unwrap();
        let e = load_frame(&path).unwrap_err().to_string();
        assert!(e.contains("frame_3.png") && e.contains("empty"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Files of every layout decode through one reused decoder to the 8-bit scale: 16-bit
    /// grey and RGBA PNG (the decoder's native-endian samples), grey+alpha, RGB, and a grey
    /// JPEG (lossy: within a few levels), each file after a larger one.
    #[test]
    fn every_layout_decodes_through_a_reused_decoder() {
        let dir = std::env::temp_dir().join(format!("physfit-layouts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (24u32, 16u32);
        let level = |x: u32, y: u32| (x * 9 + y * 5) % 256;
        let save = |name: &str, img: DynamicImage, format: image::ImageFormat| {
            let path = dir.join(name);
            img.save_with_format(&path, format).unwrap();
            path
        };
        /// A file, its channels, the tolerance (levels) and the expected level at (x, y, channel).
        type Case = (PathBuf, usize, f32, Box<dyn Fn(u32, u32, usize) -> f32>);
        let cases: Vec<Case> = vec![
            (
                save(
                    "a_rgba16.png",
                    DynamicImage::ImageRgba16(image::ImageBuffer::from_fn(w, h, |x, y| {
                        let v = (level(x, y) * 257) as u16;
                        image::Rgba([v, 65535 - v, 1000, 7])
                    })),
                    image::ImageFormat::Png,
                ),
                3,
                1e-3,
                Box::new(move |x, y, c| {
                    let v = (level(x, y) * 257) as f32;
                    [v, 65535.0 - v, 1000.0][c] / 257.0
                }),
            ),
            (
                save(
                    "b_grey16.png",
                    DynamicImage::ImageLuma16(image::ImageBuffer::from_fn(w, h, |x, y| {
                        image::Luma([(level(x, y) * 200) as u16])
                    })),
                    image::ImageFormat::Png,
                ),
                1,
                1e-3,
                Box::new(move |x, y, _| (level(x, y) * 200) as f32 / 257.0),
            ),
            (
                save(
                    "c_grey_alpha.png",
                    DynamicImage::ImageLumaA8(image::ImageBuffer::from_fn(w, h, |x, y| {
                        image::LumaA([level(x, y) as u8, 3])
                    })),
                    image::ImageFormat::Png,
                ),
                1,
                0.0,
                Box::new(move |x, y, _| level(x, y) as f32),
            ),
            (
                save(
                    "d_rgb.png",
                    DynamicImage::ImageRgb8(image::ImageBuffer::from_fn(w, h, |x, y| {
                        image::Rgb([level(x, y) as u8, 10, 250])
                    })),
                    image::ImageFormat::Png,
                ),
                3,
                0.0,
                Box::new(move |x, y, c| [level(x, y) as f32, 10.0, 250.0][c]),
            ),
            (
                save(
                    "e_grey.jpg",
                    DynamicImage::ImageLuma8(image::ImageBuffer::from_fn(w, h, |x, _| {
                        image::Luma([if x < w / 2 { 40 } else { 200 }])
                    })),
                    image::ImageFormat::Jpeg,
                ),
                1,
                12.0,
                Box::new(move |x, _, _| if x < w / 2 { 40.0 } else { 200.0 }),
            ),
        ];
        let (mut decoder, mut frame) = (FrameDecoder::default(), Frame::default());
        for (path, channels, tolerance, want) in &cases {
            decoder.load_into(path, &mut frame).unwrap();
            assert_eq!(
                (frame.width, frame.height, frame.channels),
                (w as usize, h as usize, *channels)
            );
            assert_eq!(frame.data.len(), (w * h) as usize * channels);
            // Away from the JPEG's one edge, where its blocks ring.
            for y in 0..h {
                for x in (0..w).filter(|x| x.abs_diff(w / 2) > 2) {
                    for c in 0..*channels {
                        let got = frame.data[(y * w + x) as usize * channels + c];
                        let expected = want(x, y, c);
                        assert!(
                            (got - expected).abs() <= *tolerance,
                            "{}: ({x}, {y}) channel {c}: {got} vs {expected}",
                            path.display()
                        );
                    }
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
