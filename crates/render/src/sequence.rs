//! Rendering a whole recording to a folder of PNG frames, in parallel.

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::DynamicImage;
use physfit_model::{write_atomic, Recording, RenderSettings};
use rayon::prelude::*;

use crate::{render_frame_mut, RenderError, RenderScratch};

/// Digits in a frame file name: `000000.png`, `000001.png`, ...
pub const FRAME_NAME_DIGITS: usize = 6;

/// The file name of frame `k` (0-based): `k` zero-padded to [`FRAME_NAME_DIGITS`] digits, `.png`.
pub fn frame_file_name(k: usize) -> String {
    format!("{k:0width$}.png", width = FRAME_NAME_DIGITS)
}

/// Encodes a frame as PNG bytes (fast compression: noisy frames barely compress anyway).
pub fn encode_png(image: &DynamicImage) -> Result<Vec<u8>, image::ImageError> {
    let mut bytes = Vec::new();
    let encoder = PngEncoder::new_with_quality(
        Cursor::new(&mut bytes),
        CompressionType::Fast,
        FilterType::Adaptive,
    );
    image.write_with_encoder(encoder)?;
    Ok(bytes)
}

/// Renders every frame of `recording` with [`crate::render_frame`] (frame `k` uses noise
/// stream `k`) and writes them to `frames_dir/000000.png`, `000001.png`, ... (created if
/// missing), each atomically. Frames are drawn in parallel on the rayon pool; `progress(done)`
/// is called after each frame is written with the number written so far.
///
/// The first failure stops the work and names the file (frames already written stay).
pub fn render_sequence(
    recording: &Recording,
    settings: &RenderSettings,
    frames_dir: &Path,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(), RenderError> {
    std::fs::create_dir_all(frames_dir).map_err(|source| RenderError::CreateDir {
        path: frames_dir.to_path_buf(),
        source,
    })?;
    let done = AtomicUsize::new(0);
    (0..recording.frame_count()).into_par_iter().try_for_each_init(
        || (RenderScratch::new(), DynamicImage::new_luma8(0, 0)),
        |(scratch, image), k| {
            render_frame_mut(recording.frame(k), settings, k, scratch, image);
            let path: PathBuf = frames_dir.join(frame_file_name(k));
            let bytes = encode_png(image).map_err(|source| RenderError::Encode {
                path: path.clone(),
                source,
            })?;
            write_atomic(&path, &bytes).map_err(|source| RenderError::Write { path, source })?;
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            Ok(())
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render_frame;
    use physfit_model::{Colour, Vec2};
    use std::sync::Mutex;

    fn recording(frames: usize) -> Recording {
        let positions: Vec<Vec2> = (0..frames)
            .flat_map(|k| {
                [
                    Vec2::new(10.0 + k as f64, 12.0),
                    Vec2::new(40.0, 30.0 - 0.5 * k as f64),
                ]
            })
            .collect();
        Recording {
            particle_count: 2,
            velocities: vec![Vec2::zeros(); positions.len()],
            positions,
        }
    }

    #[test]
    fn frame_names_have_six_digits() {
        assert_eq!(frame_file_name(0), "000000.png");
        assert_eq!(frame_file_name(123), "000123.png");
    }

    #[test]
    fn writes_every_frame_and_they_decode_back() {
        let dir = tempfile::tempdir().expect("temp dir");
        let frames_dir = dir.path().join("frames");
        let rec = recording(7);
        let settings = RenderSettings {
            width: 60,
            height: 44,
            noise: 2.0,
            foreground: Colour::Rgb([250, 200, 10]),
            ..RenderSettings::default()
        };
        let seen = Mutex::new(Vec::new());
        render_sequence(&rec, &settings, &frames_dir, &|done| {
            seen.lock().expect("lock").push(done)
        })
        .expect("render");
        let mut names: Vec<String> = std::fs::read_dir(&frames_dir)
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let expected: Vec<String> = (0..7).map(frame_file_name).collect();
        assert_eq!(names, expected, "exactly the frame files, no temporaries");
        for k in 0..7 {
            let decoded = image::open(frames_dir.join(frame_file_name(k))).expect("decode");
            assert_eq!((decoded.width(), decoded.height()), (60, 44));
            assert_eq!(
                decoded.as_bytes(),
                render_frame(rec.frame(k), &settings, k).as_bytes(),
                "frame {k}"
            );
        }
        let mut seen = seen.into_inner().expect("lock");
        seen.sort();
        assert_eq!(seen, (1..=7).collect::<Vec<_>>());
    }

    #[test]
    fn error_names_the_folder() {
        let dir = tempfile::tempdir().expect("temp dir");
        let file = dir.path().join("not-a-folder");
        std::fs::write(&file, b"x").expect("write");
        let err = render_sequence(&recording(2), &RenderSettings::default(), &file, &|_| {})
            .expect_err("a file is no folder");
        assert!(err.to_string().contains("not-a-folder"), "{err}");
    }
}
