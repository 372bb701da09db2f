//! The track table: the data physfit's stages exchange between tracking and identification.
//!
//! This crate owns [`TrackTable`] (rows of [`TrackPoint`], each with a [`PointFlag`]) and its
//! CSV contract (`tracks.csv`: `frame,particle,x,y,mass,size,ep,flag`), the readers of other
//! trackers' tables (trackpy, TrackMate, Tracker; [`read_track_table`]) and the robust
//! statistics ([`stats`]) the stages share, and the atomic file writer every stage uses
//! ([`write_atomic`]). It sees neither pixels nor the model: the tracker
//! (`physfit-track`) writes these tables, the identifier (`physfit-identify`) reads them, and
//! neither needs the other to do so.
//!
//! # Example
//! ```
//! use std::path::Path;
//! use physfit_tracks::{PointFlag, TrackTable};
//!
//! let text = "frame,particle,x,y\n0,a,1.5,2.0\n1,a,2.5,2.0\n";
//! let table = TrackTable::read_from(text.as_bytes(), Path::new("tracks.csv")).unwrap();
//! assert_eq!(table.particle_ids(), ["a"]);
//! assert_eq!((table.points[1].frame, table.points[1].x), (1, 2.5));
//! assert_eq!(table.points[1].flag, PointFlag::Detected);
//! assert!(table.points[1].mass.is_nan()); // a column the table lacks is unknown
//!
//! // A bad cell names the file, the line and the column.
//! let bad = "frame,particle,x,y\n0,a,oops,2.0\n";
//! let e = TrackTable::read_from(bad.as_bytes(), Path::new("t.csv")).unwrap_err();
//! assert!(e.to_string().starts_with("t.csv:2: column `x`"));
//! ```

mod error;
mod io;
pub mod stats;
mod tables;
mod track_table;

pub use error::TableError;
pub use io::write_atomic;
pub use tables::{
    detect_format, read_track_table, read_track_table_str, ForeignTable, TableFormat, TableOptions,
};
pub use track_table::{PointFlag, TrackPoint, TrackTable};
