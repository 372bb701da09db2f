//! Renaming another tracker's tracks after a structure's particles by first-frame position.

use crate::{match_to_starts, TrackTable};

/// Renames `table`'s tracks after the structure's particles when no track name is a particle
/// id: each track's position, px, in frame `first_frame` (the first analysed frame, where the
/// structure's positions are; its first point when it has none there or `first_frame` is
/// `None`) is matched to the particles' positions `starts` (id, px) by [`match_to_starts`],
/// the optimal assignment that names tracks in `track --structure`, with no distance limit.
/// Tracks left unmatched are dropped. Returns what was done, a sentence each (empty when the
/// names already were particle ids).
pub fn name_tracks_by_position(
    table: &mut TrackTable,
    starts: &[(String, [f64; 2])],
    first_frame: Option<usize>,
) -> Vec<String> {
    let by = table.by_particle();
    if starts.iter().any(|(id, _)| by.contains_key(id.as_str())) {
        return Vec::new();
    }
    // Tracks in order of first appearance, each at the first analysed frame or its first point.
    let names = table.particle_ids();
    let firsts: Vec<[f64; 2]> = names
        .iter()
        .map(|n| {
            let points = &by[n.as_str()];
            let p = first_frame
                .and_then(|f| points.iter().find(|p| p.frame == f))
                .unwrap_or(&points[0]);
            [p.x, p.y]
        })
        .collect();
    drop(by);
    let all: Vec<[f64; 2]> = firsts
        .iter()
        .chain(starts.iter().map(|s| &s.1))
        .copied()
        .collect();
    let (lo, hi) = all
        .iter()
        .fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        });
    // Wider than any distance between the points: every pairing is allowed.
    let gate = 2.0 * ((hi[0] - lo[0]).hypot(hi[1] - lo[1]) + 1.0);
    let start_xy: Vec<[f64; 2]> = starts.iter().map(|s| s.1).collect();
    let assign = match_to_starts(&start_xy, &firsts, gate);
    let mut rename: std::collections::HashMap<&str, &str> = std::collections::HashMap::new();
    let mut notes = Vec::new();
    for ((id, at), a) in starts.iter().zip(&assign) {
        if let Some(j) = *a {
            rename.insert(names[j].as_str(), id.as_str());
            let d = (firsts[j][0] - at[0]).hypot(firsts[j][1] - at[1]);
            notes.push(format!(
                "track {} -> {id} ({d:.1} px from its structure position)",
                names[j]
            ));
        }
    }
    let dropped: Vec<&str> = names
        .iter()
        .map(String::as_str)
        .filter(|n| !rename.contains_key(n))
        .collect();
    let mut out = vec![format!(
        "track names are not the structure's particle ids: matched by first position: {}",
        notes.join(", ")
    )];
    if !dropped.is_empty() {
        out.push(format!(
            "{} track(s) matched to no structure particle and left out: {}",
            dropped.len(),
            dropped.join(", ")
        ));
    }
    let points = std::mem::take(&mut table.points);
    table.points = points
        .into_iter()
        .filter_map(|mut p| {
            let id = rename.get(p.particle.as_str())?;
            p.particle = (*id).to_string();
            Some(p)
        })
        .collect();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackPoint;

    #[test]
    fn tracks_take_the_nearest_particles_names() {
        let mut t = TrackTable {
            points: vec![
                TrackPoint::new(0, "7", 100.0, 10.0),
                TrackPoint::new(0, "3", 10.0, 10.0),
                TrackPoint::new(0, "9", 500.0, 500.0),
                TrackPoint::new(1, "7", 101.0, 10.0),
            ],
        };
        let starts = vec![("a".to_string(), [11.0, 9.0]), ("b".to_string(), [99.0, 11.0])];
        let notes = name_tracks_by_position(&mut t, &starts, None);
        assert_eq!(t.particle_ids(), ["b", "a"]);
        assert_eq!(t.points.len(), 3);
        assert!(notes[1].contains("9"), "{notes:?}");
        // Names already ids: nothing changes.
        assert!(name_tracks_by_position(&mut t, &starts, None).is_empty());
        assert_eq!(t.particle_ids(), ["b", "a"]);
        assert_eq!(t.points.len(), 3);
    }

    #[test]
    fn the_first_analysed_frame_decides() {
        // Two tracks that swap places by frame 5: the structure's positions are frame 5's.
        let mut t = TrackTable {
            points: vec![
                TrackPoint::new(0, "1", 0.0, 0.0),
                TrackPoint::new(0, "2", 100.0, 0.0),
                TrackPoint::new(5, "1", 100.0, 0.0),
                TrackPoint::new(5, "2", 0.0, 0.0),
            ],
        };
        let starts = vec![("a".to_string(), [0.0, 0.0]), ("b".to_string(), [100.0, 0.0])];
        name_tracks_by_position(&mut t, &starts, Some(5));
        assert_eq!(t.particle_ids(), ["b", "a"]);
    }
}
