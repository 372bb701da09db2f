//! Errors of reading and writing track tables.

use std::path::PathBuf;

/// An error reading or writing a track table (physfit's own or another tracker's).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TableError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A track CSV is malformed; `line` is 1-based (the header is line 1).
    #[error("{path}:{line}: {message}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// A cell of a track table is bad (not a number, not finite, not a frame index...);
    /// `line` is 1-based.
    #[error("{path}:{line}: column `{column}`: {message}")]
    Cell {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// The column's header.
        column: String,
        /// What is wrong.
        message: String,
    },
    /// A reading option is invalid (a scale that is not a positive number). The message
    /// keeps the words it had when the tracker owned the table readers.
    #[error("invalid tracking option: {0}")]
    Option(String),
}
