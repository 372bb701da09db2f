//! Video files (`.mp4`, `.mov`, `.avi`, `.mkv`) decoded through the `ffmpeg` program.
//!
//! A key design decision made here is to decode a video once, sequentially, into 8-bit
//! frames kept for the whole tracking stage, rather than to seek in the file for every frame
//! the tracker asks for. The tracker reads frames out of order (a spread of sample frames for
//! the background first, then the window in parallel), and seeking in a compressed stream
//! decodes from the previous key frame each time: with H.264's key frames every 250 frames
//! that is up to 250 decodes per frame asked for. One sequential pass is the cheapest way
//! through the file, and the decoder it needs is the one users of OpenCV and imageio already
//! rely on: `ffprobe` for the stream's size, frame rate and frame count, `ffmpeg` for the
//! pixels, piped raw (`-f rawvideo`) to this process, with no temporary image files.
//!
//! Frames are kept as bytes, one per sample, on the tracker's 8-bit scale: grey (one byte per
//! pixel) while every frame decoded so far has neutral colour (each pixel's red, green and
//! blue within [`NEUTRAL_LEVELS`] of each other, as a grey recording comes out of a YUV
//! codec), red, green and blue otherwise. A video whose stream is grey (`gray`, `ya8`, ...)
//! is decoded as grey directly.
//!
//! Up to [`VIDEO_MEMORY_BYTES`] of frames are kept in memory; beyond that they go to a
//! cache file in the system's temporary folder, read back by offset for each frame asked
//! for and removed when the [`VideoFrames`] is dropped. (A 1920x1080 grey video holds about
//! 500 frames in memory; the cache file costs one read from the page cache per frame.)
//!
//! The programs are found on the `PATH`. When `ffprobe` cannot be started, the error says
//! what to install; a file the decoder cannot read, or that ends before the frame count its
//! container gives, is an error naming the file.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::TrackError;

/// Most bytes of decoded frames kept in memory (1 GiB); a longer video goes to a cache file.
pub const VIDEO_MEMORY_BYTES: usize = 1 << 30;

/// Largest difference between a pixel's red, green and blue, grey levels, for which the
/// pixel still counts as grey (a grey picture through YUV 4:2:0 and back comes out equal
/// within a level or two).
pub const NEUTRAL_LEVELS: u8 = 2;

/// File name extensions (lower case) read as video.
pub const VIDEO_EXTENSIONS: [&str; 4] = ["mp4", "mov", "avi", "mkv"];

/// Returns true if and only if `path`'s extension names a video container
/// ([`VIDEO_EXTENSIONS`], case-insensitive).
pub fn is_video_path(path: &Path) -> bool {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .is_some_and(|e| VIDEO_EXTENSIONS.contains(&e.as_str()))
}

/// What the container says about a video's first video stream, as ffmpeg decodes it (a
/// stream stored with a quarter-turn rotation, as phones film upright, is turned upright).
#[derive(Clone, Debug, PartialEq)]
pub struct VideoInfo {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// Frame rate, frames/s (the stream's average rate, else its base rate); `None` when the
    /// container gives none.
    pub fps: Option<f64>,
    /// Frames in the stream, when the container says (MP4 and AVI do, Matroska does not).
    pub frame_count: Option<usize>,
    /// True if and only if the stream's pixels are grey (`gray`, `gray16le`, `ya8`, ...).
    pub grey: bool,
}

/// The error for a program that could not be started.
fn missing_program(path: &Path, program: &str, source: std::io::Error) -> TrackError {
    if source.kind() == std::io::ErrorKind::NotFound {
        TrackError::MissingProgram {
            path: path.to_path_buf(),
            program: program.to_string(),
        }
    } else {
        TrackError::Io {
            path: PathBuf::from(program),
            source,
        }
    }
}

/// Reads `path`'s first video stream's size, frame rate and frame count with `ffprobe`.
pub fn probe_video(path: &Path) -> Result<VideoInfo, TrackError> {
    let video_err = |message: String| TrackError::Video {
        path: path.to_path_buf(),
        message,
    };
    if !path.is_file() {
        return Err(TrackError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    let output = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .arg("stream=width,height,avg_frame_rate,r_frame_rate,nb_frames,pix_fmt:stream_side_data=rotation:stream_tags=rotate")
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| missing_program(path, "ffprobe", e))?;
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !output.status.success() {
        return Err(video_err(format!(
            "corrupt, truncated or not a video: {}",
            last_lines(&stderr)
        )));
    }
    let text = String::from_utf8_lossy(&output.stdout);
    let field = |key: &str| {
        text.lines()
            .filter_map(|l| l.split_once('='))
            .find(|(k, _)| k.trim() == key)
            .map(|(_, v)| v.trim().to_string())
    };
    let size = |key: &str| {
        field(key)
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&v| v > 0)
    };
    let (Some(width), Some(height)) = (size("width"), size("height")) else {
        return Err(video_err(format!(
            "no video stream found{}",
            if stderr.trim().is_empty() {
                String::new()
            } else {
                format!(": {}", last_lines(&stderr))
            }
        )));
    };
    let rate = |key: &str| field(key).and_then(|v| parse_rate(&v));
    let pix_fmt = field("pix_fmt").unwrap_or_default();
    // A phone held upright stores its frames on their side with a rotation to display them
    // by; ffmpeg turns the frames upright as it decodes, so the frames it pipes are the
    // other way round from the stored size.
    let rotation = field("rotation")
        .or_else(|| field("TAG:rotate"))
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(0.0);
    let quarter_turn = (rotation.round() as i64).rem_euclid(180) == 90;
    let (width, height) = if quarter_turn {
        (height, width)
    } else {
        (width, height)
    };
    Ok(VideoInfo {
        width,
        height,
        fps: rate("avg_frame_rate").or_else(|| rate("r_frame_rate")),
        frame_count: field("nb_frames").and_then(|v| v.parse().ok()).filter(|&n| n > 0),
        grey: pix_fmt.starts_with("gray") || pix_fmt.starts_with("ya"),
    })
}

/// A frame rate as ffprobe writes it (`30000/1001`, `25/1`, `25`), frames/s; `None` for
/// `0/0` and anything not positive and finite.
fn parse_rate(s: &str) -> Option<f64> {
    let rate = match s.split_once('/') {
        Some((n, d)) => n.trim().parse::<f64>().ok()? / d.trim().parse::<f64>().ok()?,
        None => s.trim().parse().ok()?,
    };
    (rate.is_finite() && rate > 0.0).then_some(rate)
}

/// The last few lines of a program's error output, on one line.
fn last_lines(stderr: &str) -> String {
    let lines: Vec<&str> = stderr.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    let tail = &lines[lines.len().saturating_sub(3)..];
    if tail.is_empty() {
        "the decoder gave no reason".to_string()
    } else {
        tail.join("; ")
    }
}

/// The decoded frames of a video: frames `first..first + count` of its stream, each
/// `width * height * channels` bytes, grey levels. See the module doc.
#[derive(Debug)]
pub struct VideoFrames {
    /// The video file.
    pub path: PathBuf,
    /// What the container says.
    pub info: VideoInfo,
    /// Index of the first frame kept (frames before it were decoded and dropped).
    pub first: usize,
    /// Frames kept.
    pub count: usize,
    /// Samples per pixel: 1 (grey) or 3 (red, green, blue).
    pub channels: usize,
    store: Store,
}

impl VideoFrames {
    /// Decodes frames `window.0..=window.1` of `path` (all when `None`), keeping up to
    /// [`VIDEO_MEMORY_BYTES`] in memory. Decoding stops after the window's last frame; a window
    /// past the end keeps the frames there are (see [`VideoFrames::len`]).
    pub fn open(path: &Path, window: Option<(usize, usize)>) -> Result<VideoFrames, TrackError> {
        VideoFrames::open_with_memory(path, window, VIDEO_MEMORY_BYTES)
    }

    /// [`VideoFrames::open`] keeping at most `memory_bytes` of frames in memory (bytes).
    pub fn open_with_memory(
        path: &Path,
        window: Option<(usize, usize)>,
        memory_bytes: usize,
    ) -> Result<VideoFrames, TrackError> {
        let info = probe_video(path)?;
        let video_err = |message: String| TrackError::Video {
            path: path.to_path_buf(),
            message,
        };
        let (first, last) = window.unwrap_or((0, usize::MAX));
        let mut command = Command::new("ffmpeg");
        command.args(["-nostdin", "-v", "error", "-i"]).arg(path).args([
            "-map",
            "0:v:0",
            "-vsync",
            "passthrough",
        ]);
        if last != usize::MAX {
            command.args(["-frames:v", &(last + 1).to_string()]);
        }
        let pixels = if info.grey { "gray" } else { "rgb24" };
        command
            .args(["-f", "rawvideo", "-pix_fmt", pixels, "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        // A video's frames are decoded by ffmpeg, not here: only their size is limited.
        crate::limits::check_frame_size(path, (info.width as u64, info.height as u64), 0, 1)?;
        let mut child = command.spawn().map_err(|e| missing_program(path, "ffmpeg", e))?;
        let mut stderr = child.stderr.take().expect("stderr is piped");
        // Read apart from stdout, so that a decoder with much to say cannot block on a full pipe.
        let errors = std::thread::spawn(move || {
            let mut text = String::new();
            let _ = stderr.read_to_string(&mut text);
            text
        });
        let mut stdout = child.stdout.take().expect("stdout is piped");
        let plane = info.width * info.height;
        let in_channels = if info.grey { 1 } else { 3 };
        let mut raw = vec![0u8; plane * in_channels];
        let mut grey = vec![0u8; plane];
        let mut store = Store::new(memory_bytes, path);
        let mut channels = 1;
        let mut decoded = 0usize;
        let mut partial = false;
        loop {
            match read_full(&mut stdout, &mut raw) {
                Ok(0) => break,
                Ok(n) if n < raw.len() => {
                    partial = true;
                    break;
                }
                Ok(_) => {}
                Err(e) => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err(video_err(format!("reading the decoder's output: {e}")));
                }
            }
            decoded += 1;
            if decoded - 1 < first {
                continue;
            }
            let frame: &[u8] = if in_channels == 3 && channels == 1 {
                if neutral_to_grey(&raw, &mut grey) {
                    &grey
                } else {
                    // The first colour frame: every frame is kept in colour from here on.
                    store.grey_to_rgb()?;
                    channels = 3;
                    &raw
                }
            } else {
                &raw
            };
            store.push(frame)?;
        }
        drop(stdout);
        let status = child
            .wait()
            .map_err(|e| video_err(format!("waiting for ffmpeg: {e}")))?;
        let stderr = errors.join().unwrap_or_default();
        if !status.success() {
            return Err(video_err(format!(
                "corrupt or truncated video: ffmpeg failed after {decoded} frames: {}",
                last_lines(&stderr)
            )));
        }
        if partial {
            return Err(video_err(format!(
                "corrupt or truncated video: the decoder's output ends within frame {decoded}"
            )));
        }
        let expected = info.frame_count.map(|n| n.min(last.saturating_add(1)));
        if expected.is_some_and(|n| decoded < n) {
            return Err(video_err(format!(
                "corrupt or truncated video: the container lists {} frames but only {decoded} could be decoded{}",
                info.frame_count.unwrap_or_default(),
                if stderr.trim().is_empty() {
                    String::new()
                } else {
                    format!(" ({})", last_lines(&stderr))
                }
            )));
        }
        if decoded == 0 {
            return Err(video_err(format!(
                "no frame could be decoded{}",
                if stderr.trim().is_empty() {
                    String::new()
                } else {
                    format!(": {}", last_lines(&stderr))
                }
            )));
        }
        Ok(VideoFrames {
            path: path.to_path_buf(),
            info,
            first: first.min(decoded),
            count: decoded.saturating_sub(first),
            channels,
            store,
        })
    }

    /// Frames known: those up to the last one decoded (the whole stream, or up to the
    /// window's last frame when that is in the stream).
    pub fn len(&self) -> usize {
        self.first + self.count
    }

    /// Returns true if and only if no frame was decoded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Returns true if and only if the frames are held in a cache file, not in memory.
    pub fn is_cached_on_disk(&self) -> bool {
        matches!(self.store, Store::File { .. })
    }

    /// Bytes of one frame.
    pub fn frame_bytes(&self) -> usize {
        self.info.width * self.info.height * self.channels
    }

    /// Frame `k`'s bytes (`k` counted from the start of the stream): borrowed from memory, or
    /// read from the cache file into `buf`. Errs for a frame not kept.
    pub fn frame<'a>(&'a self, k: usize, buf: &'a mut Vec<u8>) -> Result<&'a [u8], TrackError> {
        if k < self.first || k >= self.len() {
            return Err(TrackError::Video {
                path: self.path.clone(),
                message: format!(
                    "frame {k} was not decoded (frames {}..{} are kept)",
                    self.first,
                    self.len().saturating_sub(1)
                ),
            });
        }
        let n = self.frame_bytes();
        let offset = (k - self.first) * n;
        match &self.store {
            Store::Memory { bytes, .. } => Ok(&bytes[offset..offset + n]),
            Store::File { file, path, .. } => {
                buf.resize(n, 0);
                read_exact_at(file, buf, offset as u64).map_err(|source| TrackError::Io {
                    path: path.clone(),
                    source,
                })?;
                Ok(buf)
            }
        }
    }
}

/// Reads into `buf` until it is full or the reader ends; returns the bytes read.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Writes the mean of each pixel's red, green and blue (`rgb`) into `grey` and returns true
/// if and only if every pixel is neutral (channels within [`NEUTRAL_LEVELS`]).
fn neutral_to_grey(rgb: &[u8], grey: &mut [u8]) -> bool {
    for (g, p) in grey.iter_mut().zip(rgb.chunks_exact(3)) {
        let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        if hi - lo > NEUTRAL_LEVELS {
            return false;
        }
        *g = ((u16::from(p[0]) + u16::from(p[1]) + u16::from(p[2]) + 1) / 3) as u8;
    }
    true
}

/// Where decoded frames are kept: memory up to a limit, then a cache file.
#[derive(Debug)]
enum Store {
    Memory {
        bytes: Vec<u8>,
        /// Most bytes kept in memory.
        limit: usize,
        /// The video, to name the cache file after.
        video: PathBuf,
    },
    File {
        file: File,
        path: PathBuf,
        /// Bytes written.
        len: u64,
    },
}

impl Store {
    fn new(limit: usize, video: &Path) -> Store {
        Store::Memory {
            bytes: Vec::new(),
            limit,
            video: video.to_path_buf(),
        }
    }

    /// Appends one frame's bytes.
    fn push(&mut self, frame: &[u8]) -> Result<(), TrackError> {
        if let Store::Memory { bytes, limit, video } = self {
            if bytes.len() + frame.len() <= *limit {
                bytes.extend_from_slice(frame);
                return Ok(());
            }
            let spilled = Store::file_with(video, bytes)?;
            *self = spilled;
        }
        let Store::File { file, path, len } = self else {
            unreachable!("memory spilled to a file above")
        };
        file.write_all(frame).map_err(|source| TrackError::Io {
            path: path.clone(),
            source,
        })?;
        *len += frame.len() as u64;
        Ok(())
    }

    /// A new cache file in the temporary folder holding `bytes`.
    fn file_with(video: &Path, bytes: &[u8]) -> Result<Store, TrackError> {
        static SERIAL: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let stem = video
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let serial = SERIAL.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = std::env::temp_dir().join(format!(
            "physfit-video-{}-{serial}-{stem}.raw",
            std::process::id()
        ));
        let io_err = |source| TrackError::Io {
            path: path.clone(),
            source,
        };
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(io_err)?;
        let store = Store::File {
            // Removed on drop from here on, whatever fails next.
            file: file.try_clone().map_err(io_err)?,
            path: path.clone(),
            len: bytes.len() as u64,
        };
        file.write_all(bytes).map_err(io_err)?;
        Ok(store)
    }

    /// Replaces every kept grey frame (one byte per pixel) with its red, green and blue.
    fn grey_to_rgb(&mut self) -> Result<(), TrackError> {
        match self {
            Store::Memory { bytes, limit, video } => {
                let rgb: Vec<u8> = bytes.iter().flat_map(|&v| [v, v, v]).collect();
                // Three times the bytes may no longer fit the memory limit.
                *self = if rgb.len() <= *limit {
                    Store::Memory {
                        bytes: rgb,
                        limit: *limit,
                        video: std::mem::take(video),
                    }
                } else {
                    Store::file_with(video, &rgb)?
                };
                Ok(())
            }
            Store::File { file, path, len } => {
                let io_err = |source| TrackError::Io {
                    path: path.clone(),
                    source,
                };
                let mut grey = vec![0u8; *len as usize];
                read_exact_at(file, &mut grey, 0).map_err(io_err)?;
                let rgb: Vec<u8> = grey.iter().flat_map(|&v| [v, v, v]).collect();
                write_all_at(file, &rgb, 0).map_err(io_err)?;
                *len = rgb.len() as u64;
                use std::io::Seek;
                file.seek(std::io::SeekFrom::Start(*len)).map_err(io_err)?;
                Ok(())
            }
        }
    }
}

impl Drop for Store {
    fn drop(&mut self) {
        if let Store::File { path, .. } = self {
            // A cache file left behind is only disk space; nothing to report it to.
            let _ = std::fs::remove_file(path);
        }
    }
}

#[cfg(unix)]
fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(unix)]
fn write_all_at(file: &File, buf: &[u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::write_all_at(file, buf, offset)
}

#[cfg(windows)]
fn read_exact_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    while !buf.is_empty() {
        let n = std::os::windows::fs::FileExt::seek_read(file, buf, offset)?;
        if n == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        buf = &mut buf[n..];
        offset += n as u64;
    }
    Ok(())
}

#[cfg(windows)]
fn write_all_at(file: &File, mut buf: &[u8], mut offset: u64) -> std::io::Result<()> {
    while !buf.is_empty() {
        let n = std::os::windows::fs::FileExt::seek_write(file, buf, offset)?;
        buf = &buf[n..];
        offset += n as u64;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_parse_as_ffprobe_writes_them() {
        assert_eq!(parse_rate("30/1"), Some(30.0));
        assert!((parse_rate("30000/1001").unwrap() - 29.97).abs() < 1e-3);
        assert_eq!(parse_rate("0/0"), None);
        assert_eq!(parse_rate("25"), Some(25.0));
    }

    #[test]
    fn neutral_pixels_become_grey_and_colour_is_refused() {
        let mut grey = [0u8; 2];
        assert!(neutral_to_grey(&[10, 11, 12, 200, 200, 200], &mut grey));
        assert_eq!(grey, [11, 200]);
        assert!(!neutral_to_grey(&[10, 11, 12, 200, 0, 200], &mut grey));
    }

    /// A colour video, stored on its side as a phone films upright, decoded through a small
    /// memory limit: turned upright, kept in colour, spilled to a cache file, read back equal
    /// to the frames kept in memory, the cache file removed on drop.
    #[test]
    fn a_rotated_colour_video_spills_to_a_cache_file() {
        let dir = std::env::temp_dir().join(format!("physfit-video-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ffmpeg = |args: &[&str]| {
            let status = Command::new("ffmpeg")
                .args(["-nostdin", "-v", "error", "-y"])
                .args(args)
                .current_dir(&dir)
                .status()
                .expect("this test needs the ffmpeg program on the PATH");
            assert!(status.success(), "ffmpeg {args:?}");
        };
        ffmpeg(&[
            "-f",
            "lavfi",
            "-i",
            "testsrc=size=48x32:rate=25",
            "-frames:v",
            "12",
            "-c:v",
            "mjpeg",
            "side.mp4",
        ]);
        // The rotation is written as ffmpeg 5 does (a `rotate` tag), else as ffmpeg 6 and
        // later do (a display matrix).
        ffmpeg(&[
            "-i",
            "side.mp4",
            "-c",
            "copy",
            "-metadata:s:v",
            "rotate=90",
            "upright.mp4",
        ]);
        let video = dir.join("upright.mp4");
        if probe_video(&video).unwrap().width == 48 {
            ffmpeg(&[
                "-display_rotation",
                "90",
                "-i",
                "side.mp4",
                "-c",
                "copy",
                "upright.mp4",
            ]);
        }
        let info = probe_video(&video).unwrap();
        assert_eq!((info.width, info.height), (32, 48), "turned upright");
        assert_eq!(info.fps, Some(25.0));
        let whole = VideoFrames::open(&video, None).unwrap();
        assert_eq!((whole.len(), whole.channels), (12, 3));
        assert!(!whole.is_cached_on_disk());
        // Four frames' worth of memory: frames 2..=9 are kept, the last four in the file.
        let frame_bytes = whole.frame_bytes();
        let cached = VideoFrames::open_with_memory(&video, Some((2, 9)), 4 * frame_bytes).unwrap();
        assert!(cached.is_cached_on_disk());
        assert_eq!((cached.first, cached.count, cached.len()), (2, 8, 10));
        let cache_file = match &cached.store {
            Store::File { path, .. } => path.clone(),
            Store::Memory { .. } => unreachable!(),
        };
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for k in 2..=9 {
            assert_eq!(
                whole.frame(k, &mut a).unwrap(),
                cached.frame(k, &mut b).unwrap(),
                "frame {k}"
            );
        }
        assert!(cached.frame(1, &mut b).is_err() && cached.frame(10, &mut b).is_err());
        drop(cached);
        assert!(!cache_file.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_store_spills_to_a_file_keeps_every_byte_and_removes_it() {
        let video = Path::new("clip.mp4");
        let mut store = Store::new(5, video);
        store.push(&[1, 2, 3]).unwrap();
        store.push(&[4, 5, 6]).unwrap();
        let Store::File { path, file, len } = &store else {
            panic!("should have spilled");
        };
        let path = path.clone();
        assert_eq!(*len, 6);
        let mut back = [0u8; 6];
        read_exact_at(file, &mut back, 0).unwrap();
        assert_eq!(back, [1, 2, 3, 4, 5, 6]);
        store.grey_to_rgb().unwrap();
        store.push(&[7, 7, 7]).unwrap();
        // Grey frames that fit in memory but not once in colour go to a file.
        let mut small = Store::new(5, video);
        small.push(&[1, 2]).unwrap();
        small.grey_to_rgb().unwrap();
        let Store::File {
            file: small_file,
            len: 6,
            ..
        } = &small
        else {
            panic!("colour should have spilled");
        };
        let mut back = [0u8; 6];
        read_exact_at(small_file, &mut back, 0).unwrap();
        assert_eq!(back, [1, 1, 1, 2, 2, 2]);
        let Store::File { file, len, .. } = &store else {
            panic!("still a file");
        };
        assert_eq!(*len, 21);
        let mut back = [0u8; 21];
        read_exact_at(file, &mut back, 0).unwrap();
        assert_eq!(&back[..6], &[1, 1, 1, 2, 2, 2]);
        assert_eq!(&back[18..], &[7, 7, 7]);
        drop(store);
        assert!(!path.exists());
    }
}
