//! What linking returns: the trajectories and the runs of frames it found ambiguous.

use super::track::Track;
use crate::track_table::TrackTable;

/// What kind of ambiguity a run of frames held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AmbiguityKind {
    /// The particles shared one blob; their positions were split from it.
    Merged,
    /// The particle was not seen; its position was bridged from its motion.
    Missing,
    /// The particle was outside the image or lost; no position was written.
    Lost,
    /// The detector missed the particle; with a structure it was found near where its track
    /// put it, standing less far above the noise than a detection (its position less
    /// certain).
    Faint,
}

/// A run of frames where tracking was ambiguous for some particles.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Ambiguity {
    /// What happened.
    pub kind: AmbiguityKind,
    /// The tracks involved.
    pub particles: Vec<String>,
    /// First frame of the run.
    pub first_frame: usize,
    /// Last frame of the run (inclusive).
    pub last_frame: usize,
}

impl std::fmt::Display for Ambiguity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match self.kind {
            AmbiguityKind::Merged => "shared one blob (positions split from it)",
            AmbiguityKind::Missing => "not seen (bridged from its motion)",
            AmbiguityKind::Lost => "outside the image or lost (no positions written)",
            AmbiguityKind::Faint => "missed by the detector, found near its predicted path (less certain)",
        };
        let frames = if self.first_frame == self.last_frame {
            format!("frame {}", self.first_frame)
        } else {
            format!("frames {}-{}", self.first_frame, self.last_frame)
        };
        write!(f, "{frames}: {} {what}", self.particles.join(", "))
    }
}

/// The trajectories and what linking had to bridge.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkOutcome {
    /// One point per track per frame it was followed.
    pub table: TrackTable,
    /// Every ambiguity bridged, in frame order.
    pub ambiguities: Vec<Ambiguity>,
    /// Human-readable warnings (unmatched named particles, particles that left the image).
    pub warnings: Vec<String>,
}
/// Groups per-frame events into runs of consecutive frames with the same kind and tracks.
pub(super) fn collect_runs(
    events: &[(usize, AmbiguityKind, Vec<usize>)],
    tracks: &[Track],
) -> Vec<Ambiguity> {
    let mut sorted: Vec<(AmbiguityKind, Vec<usize>, usize)> = events
        .iter()
        .map(|(f, k, ids)| {
            let mut ids = ids.clone();
            ids.sort_unstable();
            (*k, ids, *f)
        })
        .collect();
    sorted.sort();
    let mut out: Vec<Ambiguity> = Vec::new();
    let mut last: Option<(AmbiguityKind, Vec<usize>, usize, usize)> = None;
    let names = |ids: &[usize]| ids.iter().map(|&i| tracks[i].name.clone()).collect::<Vec<_>>();
    for (k, ids, f) in sorted {
        match &mut last {
            Some((lk, lids, _, lf)) if *lk == k && *lids == ids && *lf + 1 == f => *lf = f,
            _ => {
                if let Some((lk, lids, ff, lf)) = last.take() {
                    out.push(Ambiguity {
                        kind: lk,
                        particles: names(&lids),
                        first_frame: ff,
                        last_frame: lf,
                    });
                }
                last = Some((k, ids, f, f));
            }
        }
    }
    if let Some((lk, lids, ff, lf)) = last {
        out.push(Ambiguity {
            kind: lk,
            particles: names(&lids),
            first_frame: ff,
            last_frame: lf,
        });
    }
    out.sort_by(|a, b| (a.first_frame, a.kind, &a.particles).cmp(&(b.first_frame, b.kind, &b.particles)));
    out
}
