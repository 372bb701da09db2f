//! Points of particles cut by the image border (their centre within the radius in use of
//! the image's edge). The centroid of the part in view leans
//! inward, by more the further the particle is out (a disc of radius 6 px: 0.21 px with its
//! centre 5.1 px from the edge, 2.8 px at 0.3 px from it), and a bridge extrapolated from
//! such points runs off (7.6 px beyond the edge, in the same recording). Neither is written:
//! a position left out is a frame the fit does without; a position off by pixels with an
//! error of hundredths misleads it.

use std::collections::{BTreeMap, BTreeSet};

use crate::{edge_distance, Ambiguity, AmbiguityKind, TrackTable};

/// Removes from `table` every point whose centre lies within `radius` (px, the radius in
/// use, which holds the particle's blurred edge) of the edge of a `size` (width, height px)
/// image, or beyond it (pixel centres at integers: the image spans `-0.5` to
/// `width - 0.5`). Returns one warning per particle that lost points, naming its runs of
/// frames, and the `(particle, frame)` of every point dropped.
pub(super) fn drop_cut_by_border(
    table: &mut TrackTable,
    radius: f64,
    size: (usize, usize),
) -> (Vec<String>, BTreeSet<(String, usize)>) {
    let reach = radius;
    let inside = |x: f64, y: f64| edge_distance(x, y, size) >= reach;
    let mut cut: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    table.points.retain(|p| {
        let keep = inside(p.x, p.y) || !(p.x.is_finite() && p.y.is_finite());
        if !keep {
            cut.entry(p.particle.clone()).or_default().push(p.frame);
        }
        keep
    });
    let dropped = cut
        .iter()
        .flat_map(|(p, frames)| frames.iter().map(move |&k| (p.clone(), k)))
        .collect();
    let warnings = cut
        .into_iter()
        .map(|(particle, mut frames)| {
            frames.sort_unstable();
            format!(
                "{particle}: partly outside the image in {} (its centre within the radius in use, {reach:.1} px, of the border); the centroid of the part in view leans inward, so no positions were written there",
                runs(&frames)
            )
        })
        .collect();
    (warnings, dropped)
}

/// Takes out of the `Missing` and `Faint` runs of `ambiguities` the particles whose points there were all
/// `dropped` (a bridge no longer written is no longer bridged), and the runs left empty.
pub(super) fn forget_dropped_bridges(ambiguities: &mut Vec<Ambiguity>, dropped: &BTreeSet<(String, usize)>) {
    if dropped.is_empty() {
        return;
    }
    for a in ambiguities
        .iter_mut()
        .filter(|a| matches!(a.kind, AmbiguityKind::Missing | AmbiguityKind::Faint))
    {
        let (first, last) = (a.first_frame, a.last_frame);
        a.particles
            .retain(|p| !(first..=last).all(|k| dropped.contains(&(p.clone(), k))));
    }
    ambiguities.retain(|a| !a.particles.is_empty());
}

/// `frame 3` or `frames 3-5, 9` for sorted `frames`.
pub(super) fn runs(frames: &[usize]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            frames[i].to_string()
        } else {
            format!("{}-{}", frames[i], frames[j])
        });
        i = j + 1;
    }
    let word = if frames.len() == 1 { "frame" } else { "frames" };
    format!("{word} {}", parts.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackPoint;

    /// A particle of radius 6 px walking down a 100 x 100 image out through the bottom edge
    /// (rows 0-99, the edge at 99.5): its points beyond row 93.5 are cut and dropped, with
    /// a warning naming the frames; one that stays inside loses nothing.
    #[test]
    fn points_of_a_particle_cut_by_the_border_are_dropped_and_named() {
        let mut table = TrackTable {
            points: (0..12)
                .flat_map(|k| {
                    [
                        TrackPoint::new(k, "out", 50.0, 80.0 + 2.0 * k as f64),
                        TrackPoint::new(k, "in", 20.0 + k as f64, 50.0),
                    ]
                })
                .collect(),
        };
        let (warnings, dropped) = drop_cut_by_border(&mut table, 6.0, (100, 100));
        assert_eq!(dropped.len(), 5);
        // A bridge of frames 9-10 wholly dropped is forgotten; one reaching frame 6 stays.
        let run = |first: usize, last: usize| Ambiguity {
            kind: AmbiguityKind::Missing,
            particles: vec!["out".to_string()],
            first_frame: first,
            last_frame: last,
        };
        let mut ambiguities = vec![run(9, 10), run(6, 8)];
        forget_dropped_bridges(&mut ambiguities, &dropped);
        assert_eq!(ambiguities, vec![run(6, 8)]);
        // Row 80 + 2k is cut beyond 93.5: k >= 7 (row 94).
        let kept: Vec<usize> = table
            .points
            .iter()
            .filter(|p| p.particle == "out")
            .map(|p| p.frame)
            .collect();
        assert_eq!(kept, (0..7).collect::<Vec<_>>());
        assert_eq!(table.points.iter().filter(|p| p.particle == "in").count(), 12);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].starts_with("out: partly outside the image in frames 7-11"),
            "{}",
            warnings[0]
        );
        assert!(
            warnings[0].contains("within the radius in use, 6.0 px, of the border"),
            "{}",
            warnings[0]
        );
        assert_eq!(runs(&[3]), "frame 3");
        assert_eq!(runs(&[3, 4, 5, 9]), "frames 3-5, 9");
    }
}
