//! [`FrameSource`]: the frames of a recording, whatever holds them (a folder of image files,
//! a video, a TIFF stack), each loaded by its index; and [`FrameWindow`], the frames to
//! track, given as frame numbers or as times.
//!
//! A key design decision made here is that the tracker sees one kind of recording: frame `k`
//! of a source, loaded on demand into the same [`FrameView`] a frame file gives, in any
//! order and from several threads at once. The pipeline is then one code path for every
//! input. A folder's files are decoded from disk as they are asked for, as before (nothing
//! is kept or copied that was not); a video is decoded once, up front (see
//! [`crate::VideoFrames`] for why); a stack's pages are decoded as asked for.

use std::path::{Path, PathBuf};

use crate::frames::{list_frames, samples_to_frame, DecodedFrame, Frame, FrameDecoder, FrameView};
use crate::stack::{TiffStack, TIFF_EXTENSIONS};
use crate::video::{is_video_path, VideoFrames, VIDEO_EXTENSIONS};
use crate::TrackError;

/// The frames of a recording, by index from 0.
#[derive(Debug)]
pub enum FrameSource {
    /// Image files, one frame each (a folder's, in natural name order).
    Files {
        /// The folder (or the single file) they were found in.
        dir: PathBuf,
        /// The files, in frame order.
        files: Vec<PathBuf>,
    },
    /// A video's decoded frames.
    Video(VideoFrames),
    /// A multi-page TIFF file, one frame per page.
    Stack(Box<TiffStack>),
}

impl FrameSource {
    /// Opens the recording at `path`: a folder of frame files ([`list_frames`]), a video
    /// ([`crate::VIDEO_EXTENSIONS`]; only the frames up to `window`'s last are decoded, and
    /// only those of `window` kept), a TIFF stack (`.tif`, `.tiff`), or one PNG or JPEG file.
    /// Errors name the path: missing, of no known kind, holding no frames, or unreadable.
    pub fn open(path: &Path, window: Option<(usize, usize)>) -> Result<FrameSource, TrackError> {
        if path.is_dir() {
            let files = list_frames(path)?;
            if files.is_empty() {
                return Err(TrackError::NoFrames {
                    dir: path.to_path_buf(),
                });
            }
            return Ok(FrameSource::Files {
                dir: path.to_path_buf(),
                files,
            });
        }
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if is_video_path(path) {
            return Ok(FrameSource::Video(VideoFrames::open(path, window)?));
        }
        if !path.exists() {
            return Err(TrackError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or folder"),
            });
        }
        if TIFF_EXTENSIONS.contains(&ext.as_str()) {
            return Ok(FrameSource::Stack(Box::new(TiffStack::open(path)?)));
        }
        if matches!(ext.as_str(), "png" | "jpg" | "jpeg") {
            return Ok(FrameSource::Files {
                dir: path.to_path_buf(),
                files: vec![path.to_path_buf()],
            });
        }
        Err(TrackError::Option(format!(
            "{}: not a folder of frames, a video (.{}) or a TIFF stack (.tif, .tiff)",
            path.display(),
            VIDEO_EXTENSIONS.join(", .")
        )))
    }

    /// The folder, video or stack the frames come from.
    pub fn path(&self) -> &Path {
        match self {
            FrameSource::Files { dir, .. } => dir,
            FrameSource::Video(v) => &v.path,
            FrameSource::Stack(s) => &s.path,
        }
    }

    /// Frames in the recording (for a video opened with a window: up to the window's last).
    pub fn len(&self) -> usize {
        match self {
            FrameSource::Files { files, .. } => files.len(),
            FrameSource::Video(v) => v.len(),
            FrameSource::Stack(s) => s.page_count,
        }
    }

    /// Returns true if and only if the recording holds no frame.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The recording's own frame rate, frames/s: a video container's; `None` for files and
    /// stacks.
    pub fn fps(&self) -> Option<f64> {
        match self {
            FrameSource::Video(v) => v.info.fps,
            _ => None,
        }
    }

    /// What names frame `k` in messages: its file, or the video or stack and the frame's
    /// number (`clip.mp4 frame 12`).
    pub fn frame_name(&self, k: usize) -> PathBuf {
        match self {
            FrameSource::Files { files, .. } => files.get(k).cloned().unwrap_or_default(),
            FrameSource::Video(v) => PathBuf::from(format!("{} frame {k}", v.path.display())),
            FrameSource::Stack(s) => PathBuf::from(format!("{} page {k}", s.path.display())),
        }
    }

    /// Decodes frame `k` to a new [`Frame`].
    pub fn load_frame(&self, k: usize) -> Result<Frame, TrackError> {
        let (mut decoder, mut frame) = (FrameDecoder::default(), Frame::default());
        let view = self.load_view(k, &mut decoder, &mut frame)?;
        Ok(match view {
            FrameView::Frame(_) => frame,
            grey => grey.to_frame(),
        })
    }

    /// Frame `k` as [`FrameDecoder::load_view`] gives a file's: 8-bit grey as bytes (the
    /// decoder's, or a video's own), every other layout decoded into `frame`.
    pub fn load_view<'a>(
        &'a self,
        k: usize,
        decoder: &'a mut FrameDecoder,
        frame: &'a mut Frame,
    ) -> Result<FrameView<'a>, TrackError> {
        self.check_index(k)?;
        match self {
            FrameSource::Files { files, .. } => decoder.load_view(&files[k], frame),
            FrameSource::Video(v) => {
                let size = (v.info.width, v.info.height);
                let bytes = v.frame(k, decoder.samples_mut())?;
                if v.channels == 1 {
                    return Ok(FrameView::Grey8 {
                        samples: bytes,
                        width: size.0,
                        height: size.1,
                    });
                }
                samples_to_frame(bytes, image::ColorType::Rgb8, size, frame)
                    .expect("8-bit RGB is a known layout");
                Ok(FrameView::Frame(frame))
            }
            FrameSource::Stack(s) => Ok(match s.decode(k, decoder, frame)? {
                Some((width, height)) => FrameView::Grey8 {
                    samples: decoder.samples(),
                    width,
                    height,
                },
                None => FrameView::Frame(frame),
            }),
        }
    }

    /// Frame `k` to be kept, as [`FrameDecoder::load_decoded`] keeps a file's.
    pub fn load_decoded(&self, k: usize, decoder: &mut FrameDecoder) -> Result<DecodedFrame, TrackError> {
        self.check_index(k)?;
        if let FrameSource::Files { files, .. } = self {
            return decoder.load_decoded(&files[k]);
        }
        let mut frame = Frame::default();
        Ok(match self.load_view(k, decoder, &mut frame)? {
            FrameView::Grey8 {
                samples,
                width,
                height,
            } => DecodedFrame::Grey8 {
                samples: samples.to_vec(),
                width,
                height,
            },
            FrameView::Frame(_) => DecodedFrame::Frame(frame),
        })
    }

    fn check_index(&self, k: usize) -> Result<(), TrackError> {
        if k < self.len() {
            return Ok(());
        }
        Err(TrackError::Window {
            start: k,
            end: k,
            count: self.len(),
        })
    }
}

/// The frames to track: first and last frame numbers (inclusive), or first and last times,
/// s (frame `k` is at time `k / fps`). Written `A..B` and `2.5s..4s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrameWindow {
    /// First and last frame, inclusive.
    Frames(usize, usize),
    /// First and last time, s, inclusive: the frames whose times lie between them.
    Seconds(f64, f64),
}

impl FrameWindow {
    /// The first and last frame (inclusive) of this window at `fps` frames/s (needed for
    /// times only). Errs when times are given without a frame rate, or select no frame.
    pub fn frames(&self, fps: Option<f64>) -> Result<(usize, usize), TrackError> {
        match *self {
            FrameWindow::Frames(a, b) => Ok((a, b)),
            FrameWindow::Seconds(a, b) => {
                let Some(fps) = fps.filter(|f| f.is_finite() && *f > 0.0) else {
                    return Err(TrackError::Option(format!(
                        "window {a}s..{b}s is in seconds but the recording has no frame rate: give --fps"
                    )));
                };
                // The frames whose times lie in [a, b], to within a millionth of a frame (so
                // that 2.5 s at 30 frames/s is frame 75 despite rounding).
                let first = (a * fps - 1e-6).ceil().max(0.0) as usize;
                let last = (b * fps + 1e-6).floor();
                if last < first as f64 {
                    return Err(TrackError::Option(format!(
                        "window {a}s..{b}s holds no frame at {fps} frames/s"
                    )));
                }
                Ok((first, last as usize))
            }
        }
    }
}

impl std::str::FromStr for FrameWindow {
    type Err = String;

    /// Parses `A..B` (frame numbers) or `As..Bs` (seconds, decimals allowed).
    fn from_str(s: &str) -> Result<FrameWindow, String> {
        let (a, b) = s.split_once("..").ok_or_else(|| {
            format!(
                "window `{s}` is not of the form A..B (first and last frame, inclusive) or 2.5s..4s (times)"
            )
        })?;
        let (a, b) = (a.trim(), b.trim());
        let seconds = |t: &str| -> Option<f64> {
            t.strip_suffix('s')
                .and_then(|v| v.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite() && *v >= 0.0)
        };
        if a.ends_with('s') || b.ends_with('s') {
            let ta = seconds(a)
                .ok_or_else(|| format!("window `{s}`: `{a}` is not a time in seconds (like 2.5s)"))?;
            let tb = seconds(b)
                .ok_or_else(|| format!("window `{s}`: `{b}` is not a time in seconds (like 4s)"))?;
            if tb < ta {
                return Err(format!(
                    "window `{s}`: last time {tb} s is before first time {ta} s"
                ));
            }
            return Ok(FrameWindow::Seconds(ta, tb));
        }
        let a: usize = a
            .parse()
            .map_err(|_| format!("window `{s}`: `{a}` is not a frame number"))?;
        let b: usize = b
            .parse()
            .map_err(|_| format!("window `{s}`: `{b}` is not a frame number"))?;
        if b < a {
            return Err(format!("window `{s}`: last frame {b} is before first frame {a}"));
        }
        Ok(FrameWindow::Frames(a, b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_parse_as_frames_or_seconds() {
        assert_eq!("2..12".parse(), Ok(FrameWindow::Frames(2, 12)));
        assert_eq!("2.5s..4s".parse(), Ok(FrameWindow::Seconds(2.5, 4.0)));
        assert!("12..2".parse::<FrameWindow>().unwrap_err().contains("before"));
        assert!("a..2".parse::<FrameWindow>().unwrap_err().contains("`a`"));
        assert!("3".parse::<FrameWindow>().unwrap_err().contains("A..B"));
        assert!("2s..1s".parse::<FrameWindow>().unwrap_err().contains("before"));
        assert!("2s..x".parse::<FrameWindow>().unwrap_err().contains("`x`"));
    }

    #[test]
    fn times_become_the_frames_between_them() {
        let w = FrameWindow::Seconds(2.5, 4.0);
        assert_eq!(w.frames(Some(30.0)).unwrap(), (75, 120));
        assert_eq!(
            FrameWindow::Seconds(0.01, 0.05).frames(Some(30.0)).unwrap(),
            (1, 1)
        );
        assert!(FrameWindow::Seconds(0.01, 0.02).frames(Some(30.0)).is_err());
        assert!(w.frames(None).unwrap_err().to_string().contains("--fps"));
        assert_eq!(FrameWindow::Frames(3, 9).frames(None).unwrap(), (3, 9));
    }

    #[test]
    fn unknown_paths_are_named() {
        let e = FrameSource::open(Path::new("/nonexistent/clip.tif"), None).unwrap_err();
        assert!(e.to_string().contains("clip.tif"), "{e}");
        let e = FrameSource::open(Path::new("Cargo.toml"), None).unwrap_err();
        assert!(
            e.to_string().contains("Cargo.toml") && e.to_string().contains("video"),
            "{e}"
        );
    }
}
