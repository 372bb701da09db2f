//! Track table text through every reader (the format detected, then each format named) and,
//! for a table read, the structure matching by first position: no panic, and a table read
//! holds finite positions only and frame indices up to `u32::MAX` (the readers' bound).

use std::path::Path;

use physfit_track::name_tracks_by_position;
use physfit_tracks::{read_track_table_str, TableFormat, TableOptions};

/// Panics when `data` breaks the property above.
pub fn check(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let named = [
        TableFormat::Physfit,
        TableFormat::Trackpy,
        TableFormat::TrackMate,
        TableFormat::Tracker,
    ]
    .map(|f| TableOptions {
        format: Some(f),
        metres_per_px: Some(1e-3),
        ..TableOptions::default()
    });
    for options in std::iter::once(TableOptions::default()).chain(named) {
        let Ok(read) = read_track_table_str(text, Path::new("fuzz.csv"), &options) else {
            continue;
        };
        let mut table = read.table;
        assert!(table.points.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
        // Frame indices fit the limits' arithmetic, and the frame count is past every one.
        let end = table.frame_end();
        assert!(table
            .points
            .iter()
            .all(|p| p.frame <= u32::MAX as usize && p.frame < end));
        let starts = [
            ("a".to_string(), [10.0, 10.0]),
            ("b".to_string(), [100.0, 50.0]),
            ("c".to_string(), [0.0, 0.0]),
        ];
        for first_frame in [None, Some(0), Some(3)] {
            let mut copy = table.clone();
            let _ = name_tracks_by_position(&mut copy, &starts, first_frame);
        }
        let _ = name_tracks_by_position(&mut table, &starts[..1], None);
    }
}
