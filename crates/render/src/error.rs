//! Errors from writing rendered frames.

use std::path::PathBuf;

/// An error rendering a recording to files; each names the file or folder at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// The frames folder could not be created.
    #[error("cannot create frames folder {path}: {source}")]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A frame could not be encoded as PNG.
    #[error("cannot encode frame {path}: {source}")]
    Encode {
        /// The frame file that was being written.
        path: PathBuf,
        /// The cause.
        #[source]
        source: image::ImageError,
    },
    /// A frame file could not be written.
    #[error("cannot write frame {path}: {source}")]
    Write {
        /// The frame file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
}
