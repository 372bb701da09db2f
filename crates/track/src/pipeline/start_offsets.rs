//! Named tracks checked against the structure's start positions.
//!
//! A structure names each particle at its position in the first frame tracked. A named
//! track whose point in that frame lies farther from the position than the particle's
//! radius has not started on the named particle: the blob taken holds none of the named
//! point (a textured ball of 3 px at noise 11 under vignetting, fresh style 8350, was not
//! found, and its track took the bright middle of the frame 16.6 px away, radius read 13 px,
//! without a word). A start position given by hand to within a pixel or two of the centre is
//! well inside the radius of any particle the tracker can follow (1.5 px and up).

use std::collections::HashMap;

use crate::track_table::{PointFlag, TrackPoint, TrackTable};

/// Nearest a detected start may lie from its named position before it is reported, px,
/// whatever the radius: a start clicked by hand on a particle of radius 1.5 px is about a
/// pixel off.
const MIN_START_OFFSET: f64 = 2.0;

/// Warnings for the named tracks of `table` (particles of radius `radius` px) whose point in
/// frame `first` was detected farther than the radius (and [`MIN_START_OFFSET`]) from the
/// particle's start position in `starts` (name, position in px).
pub(super) fn start_offsets(
    table: &TrackTable,
    starts: &[(String, [f64; 2])],
    first: usize,
    radius: f64,
) -> Vec<String> {
    let limit = radius.max(MIN_START_OFFSET);
    // The first frame's located points by particle, read in one pass (a search per start
    // reads the table once per named particle).
    let located: HashMap<&str, &TrackPoint> = (table.points.iter())
        .filter(|p| p.frame == first && p.flag != PointFlag::Interpolated)
        .map(|p| (p.particle.as_str(), p))
        .collect();
    let mut out = Vec::new();
    for (name, start) in starts {
        let Some(p) = located.get(name.as_str()) else {
            continue;
        };
        let off = (p.x - start[0]).hypot(p.y - start[1]);
        if off > limit {
            out.push(format!(
                "{name}: its track starts in frame {first} at ({:.1}, {:.1}), {off:.1} px from its start position ({:.1}, {:.1}) in the structure, farther than its radius {radius:.2} px: the track may follow another image; check the start position, or give the radius with --radius",
                p.x, p.y, start[0], start[1]
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(frame: usize, particle: &str, x: f64, y: f64, flag: PointFlag) -> TrackPoint {
        TrackPoint {
            flag,
            ..TrackPoint::new(frame, particle, x, y)
        }
    }

    #[test]
    fn a_track_starting_beyond_the_radius_from_its_named_position_is_reported() {
        let table = TrackTable {
            points: vec![
                point(3, "a", 20.0, 36.8, PointFlag::Detected),
                point(3, "b", 50.5, 50.0, PointFlag::Detected),
                point(4, "a", 20.4, 20.2, PointFlag::Detected),
            ],
        };
        let starts = vec![("a".to_string(), [20.4, 20.2]), ("b".to_string(), [50.0, 50.0])];
        let w = start_offsets(&table, &starts, 3, 4.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("a:") && w[0].contains("16.6 px") && w[0].contains("frame 3"),
            "{w:?}"
        );
        // Within a radius of 20 px the same start is the particle's.
        assert!(start_offsets(&table, &starts, 3, 20.0).is_empty());
    }

    #[test]
    fn small_particles_may_start_two_pixels_off_and_bridged_starts_are_not_judged() {
        let table = TrackTable {
            points: vec![
                point(0, "a", 11.9, 10.0, PointFlag::Detected),
                point(0, "b", 40.0, 10.0, PointFlag::Interpolated),
            ],
        };
        let starts = vec![("a".to_string(), [10.0, 10.0]), ("b".to_string(), [30.0, 10.0])];
        assert!(start_offsets(&table, &starts, 0, 1.5).is_empty());
        let far = TrackTable {
            points: vec![point(0, "a", 12.1, 10.0, PointFlag::Detected)],
        };
        assert_eq!(start_offsets(&far, &starts, 0, 1.5).len(), 1);
    }
}
