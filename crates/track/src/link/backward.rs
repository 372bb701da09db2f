//! Named identities checked by linking the recording again backward in time.
//!
//! Forward, each frame's assignment is made from the tracks' past alone. Where two named
//! particles pass close while their motion changes (one turns or stops as the other comes
//! on: a bounce, a collision, a throw at a low frame rate), the predictions can hand each
//! the other's blob, and every frame after follows the wrong particle under each name while
//! the motion stays smooth enough for every later check. Linked backward from where the
//! forward tracks end, the same detections are joined from the other side of that frame,
//! where the motion before the turn is what the predictions extrapolate; where the two
//! directions put a name on different blobs, the recording does not say which particle is
//! which, and the tracks are named in a warning (`uncertain identities`) instead of written as though it did.
//! (Fast-motion style 6119: two shaded spheres of 1.6 px, 10 px apart as one turned back,
//! exchanged at frame 11; 6064: rings of 3.2 px stepping 7 px a frame as one stopped dead
//! beside another. Judging the exchange by how straight lines fitted before and after the
//! frame meet, as crossings are, exchanged six pairs of 1000 random walks the forward
//! linking had right: lines say little of a random walk.)

use super::link_detections::link_detections;
use super::options::{FrameDetections, LinkOptions};
use crate::track_table::{PointFlag, TrackTable};
use std::collections::{BTreeMap, HashMap};

/// Named particles that the forward and backward linkings put on different blobs in a run
/// of frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Disagreement {
    /// The particles, in name order.
    pub particles: Vec<String>,
    /// First frame of the run.
    pub first_frame: usize,
    /// Last frame of the run (inclusive).
    pub last_frame: usize,
    /// First and last frame linked.
    pub linked: (usize, usize),
}

/// The runs of frames in which the named tracks of `forward` (linked from `frames` with
/// `options`) and a linking of the same frames backward in time, its particles started
/// where `forward`'s last points put them, give a particle different located blobs (more
/// than half a radius apart; points placed from a prediction or split from a shared blob
/// are not compared). Empty without named particles.
pub fn backward_disagreements(
    frames: &[FrameDetections],
    options: &LinkOptions,
    forward: &TrackTable,
) -> Vec<Disagreement> {
    let (Some(named), Some(first), Some(last)) = (
        options.named_start.as_deref(),
        frames.first().map(|f| f.frame),
        frames.last().map(|f| f.frame),
    ) else {
        return Vec::new();
    };
    if frames.len() < 3 {
        return Vec::new();
    }
    // Each name's last point forward is its start backward.
    let ends = forward.by_particle();
    let starts: Vec<(String, [f64; 2])> = named
        .iter()
        .filter_map(|(name, _)| {
            let end = ends.get(name.as_str())?.last()?;
            Some((name.clone(), [end.x, end.y]))
        })
        .collect();
    if starts.len() < 2 {
        return Vec::new();
    }
    // Frame `k` backward is frame `first + last - k`, so the frames still increase.
    let mirror = |k: usize| first + last - k;
    let reversed: Vec<FrameDetections> = frames
        .iter()
        .rev()
        .map(|f| FrameDetections {
            frame: mirror(f.frame),
            detections: f.detections.clone(),
        })
        .collect();
    let backward = link_detections(
        &reversed,
        &LinkOptions {
            named_start: Some(starts),
            ..options.clone()
        },
    )
    .table;
    // Each name's located point in each frame, one row of `span` frames a name.
    let index: HashMap<&str, usize> = named
        .iter()
        .enumerate()
        .map(|(i, (n, _))| (n.as_str(), i))
        .collect();
    let span = last - first + 1;
    let located = |t: &TrackTable, frame_of: &dyn Fn(usize) -> usize| {
        let mut at: Vec<Option<[f64; 2]>> = vec![None; named.len() * span];
        for p in t.points.iter().filter(|p| p.flag == PointFlag::Detected) {
            let k = frame_of(p.frame);
            if let (Some(&i), true) = (index.get(p.particle.as_str()), (first..=last).contains(&k)) {
                at[i * span + k - first] = Some([p.x, p.y]);
            }
        }
        at
    };
    let (ahead, behind) = (located(forward, &|k| k), located(&backward, &mirror));
    let apart = 0.5 * options.radius;
    // Each name's runs of consecutive frames where the two put it on different blobs; names
    // with the same run are one disagreement (two named particles exchanged).
    let mut runs: BTreeMap<(usize, usize), Vec<String>> = BTreeMap::new();
    for (i, (name, _)) in named.iter().enumerate() {
        let mut run: Option<(usize, usize)> = None;
        for k in 0..=span {
            let differ = k < span
                && matches!(
                    (ahead[i * span + k], behind[i * span + k]),
                    (Some(p), Some(q)) if (p[0] - q[0]).hypot(p[1] - q[1]) > apart
                );
            match (differ, run) {
                (true, Some((s, _))) => run = Some((s, first + k)),
                (true, None) => run = Some((first + k, first + k)),
                (false, Some(r)) => {
                    runs.entry(r).or_default().push(name.clone());
                    run = None;
                }
                (false, None) => {}
            }
        }
    }
    runs.into_iter()
        .map(|((first_frame, last_frame), particles)| Disagreement {
            particles,
            first_frame,
            last_frame,
            linked: (first, last),
        })
        .collect()
}

impl std::fmt::Display for Disagreement {
    /// `p2 and p6: uncertain identities: their tracks before frame 11 and ...`
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = match self.particles.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => self.particles.join(""),
        };
        let frames = if self.first_frame == self.last_frame {
            format!("frame {}", self.first_frame)
        } else {
            format!("frames {}-{}", self.first_frame, self.last_frame)
        };
        // Backward tracks start where the forward ones end: an exchange shows as a run that
        // reaches one end of the recording, and the doubt is about either side of its other
        // end.
        let across = if self.first_frame == self.linked.0 && self.last_frame < self.linked.1 {
            Some(self.last_frame + 1)
        } else if self.first_frame > self.linked.0 && self.last_frame == self.linked.1 {
            Some(self.first_frame)
        } else {
            None
        };
        let (one, whose) = (
            self.particles.len() == 1,
            if self.particles.len() == 1 { "its" } else { "their" },
        );
        let doubt = match (across, one) {
            (Some(b), true) => {
                format!("its track before frame {b} and from it on may follow different particles")
            }
            (Some(b), false) => {
                format!("their tracks before frame {b} and from it on may each belong to another of them")
            }
            (None, true) => format!("its track may follow another particle in {frames}"),
            (None, false) => format!("their tracks may each follow another of them in {frames}"),
        };
        let what = if one { "identity" } else { "identities" };
        write!(
            f,
            "{names}: uncertain {what}: {doubt} (linked again backward in time from where {whose} \
             track{} end{}, the blobs of {frames} join other tracks; particles that pass close as one turns or \
             stops can be handed each other's blobs)",
            if one { "" } else { "s" },
            if one { "s" } else { "" },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::tests::frame;
    use crate::track_table::TrackPoint;

    /// Two particles 20 px apart moving side by side, 2 px a frame, over 10 frames.
    fn paths() -> Vec<[[f64; 2]; 2]> {
        (0..10)
            .map(|t| {
                let x = 20.0 + 2.0 * t as f64;
                [[x, 40.0], [x, 60.0 - 0.5 * t as f64]]
            })
            .collect()
    }

    fn frames() -> Vec<FrameDetections> {
        paths().iter().enumerate().map(|(k, at)| frame(k, at)).collect()
    }

    fn options() -> LinkOptions {
        LinkOptions {
            named_start: Some(vec![("a".into(), [20.0, 40.0]), ("b".into(), [20.0, 60.0])]),
            radius: 2.0,
            width: 100,
            height: 100,
            memory: 3,
        }
    }

    /// The tracks of `paths`, the particles' names exchanged from frame `swap` on.
    fn tracks(swap: usize) -> TrackTable {
        let mut points = Vec::new();
        for (frame, at) in paths().iter().enumerate() {
            for (k, name) in ["a", "b"].iter().enumerate() {
                let p = at[if frame >= swap { 1 - k } else { k }];
                points.push(TrackPoint {
                    frame,
                    particle: (*name).into(),
                    x: p[0],
                    y: p[1],
                    mass: 100.0,
                    size: 2.0,
                    ep: 0.05,
                    flag: PointFlag::Detected,
                });
            }
        }
        TrackTable { points }
    }

    /// Tracks right in every frame: linked backward, the particles keep their blobs.
    #[test]
    fn tracks_that_follow_their_particles_are_not_doubted() {
        assert_eq!(
            backward_disagreements(&frames(), &options(), &tracks(usize::MAX)),
            Vec::new()
        );
    }

    /// Tracks whose names were exchanged from frame 6 on: linked backward from where they
    /// end, each name follows the other particle before it, and the run of frames 0-5 is
    /// named, with the frame the doubt is about.
    #[test]
    fn exchanged_tracks_are_doubted_before_the_exchange() {
        let found = backward_disagreements(&frames(), &options(), &tracks(6));
        assert_eq!(
            found,
            vec![Disagreement {
                particles: vec!["a".into(), "b".into()],
                first_frame: 0,
                last_frame: 5,
                linked: (0, 9),
            }]
        );
        let said = found[0].to_string();
        assert!(
            said.starts_with("a and b: uncertain identities: their tracks before frame 6 and from it on"),
            "{said}"
        );
    }

    /// Without named particles there is nothing to compare.
    #[test]
    fn unnamed_tracks_are_not_checked() {
        let options = LinkOptions {
            named_start: None,
            ..options()
        };
        assert!(backward_disagreements(&frames(), &options, &tracks(6)).is_empty());
    }
}
