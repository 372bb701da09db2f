//! The crate's error type.

use std::fmt;
use std::path::PathBuf;

/// Writing a recording failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum SynthError {
    /// A file or folder could not be written.
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A frame could not be encoded as PNG.
    Encode {
        /// The frame file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
}

impl fmt::Display for SynthError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SynthError::Io { path, source } => write!(f, "writing {}: {source}", path.display()),
            SynthError::Encode { path, source } => {
                write!(f, "encoding {} as PNG: {source}", path.display())
            }
        }
    }
}

impl std::error::Error for SynthError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SynthError::Io { source, .. } => Some(source),
            SynthError::Encode { source, .. } => Some(source),
        }
    }
}
