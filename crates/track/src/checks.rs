//! Self-checks of finished tracks: evidence in the tracks and the frames that a particle was
//! not followed.
//!
//! * **Skirt.** A particle's signal lies within its radius (and its blur): the ring from one to
//!   two radii (plus a pixel each) around a followed particle holds little of it. Where the
//!   radius in use is too small for the particles, the detector finds parts of each, and the
//!   ring around each part holds the rest of the particle. For each track, the median over the
//!   sample frames of the ring's mean signal over the disc's (each ring pixel counted for the
//!   nearest point only, so touching neighbours do not count) is its *skirt*. Measured:
//!   0.00-0.03 on discs, small Gaussian spots and the real recordings followed; 0.5-0.9 where
//!   discs of radius 9 px were tracked at 3.7 px. A Gaussian spot's own skirt is large (0.29
//!   at its half-maximum radius, 0.38 at 0.87 of it, 0.40-0.49 at 0.68 of it, where the
//!   radius of gyration puts a large one) but even all round it; a flat disc tracked below
//!   half its radius has a skirt of 1, and a track on the edge of a disc or the rim of a
//!   ring has the rest of the particle to one side. So a skirt above [`MAX_SKIRT`], or
//!   above [`LOPSIDED_SKIRT`] and lopsided by more than [`MAX_LOPSIDED`] or elongated by more
//!   than [`MAX_ELONGATED`], says the particle is larger than the radius. A track on a ring's
//!   rim at a radius well below the ring's has the rim running through it, as much on either
//!   side: even all round in direction, but along one line. The same test holds for a ring
//!   that is below the background by as much (a particle left in a per-pixel background
//!   shows as a dark ring round its track), and for one whose parts above and below the
//!   background cancel in the mean (its mean magnitude beyond the noise's counts).
//! * **Off the rim.** A ring's located points (its centroids) should keep one offset from its
//!   rim's centre ([`crate::rim`]), the centroid's lean with the light, give or take their
//!   errors; points that scatter about it far more have followed something else in some
//!   frames (see [`MAX_RIM_SCATTER_SIGMAS`]).
//! * **Unseen.** A named particle detected in fewer than half its frames is not followed.
//! * **Jumped.** A particle's image moves continuously, so between two detected points the
//!   track moves, per frame, about as fast as it moves before and after: a move
//!   over `g` frames longer than `g` times [`JUMP_FACTOR`] times the faster of those two
//!   steps, plus the particle's diameter, leaves the particle for another image
//!   ([`jumped`]).
//! * **Lost inside the image.** A track with frames missing between two of its points (the
//!   particle lost, bridged no farther, and found again) whose points either side lie too far
//!   inside the image for the particle to have left it and come back in those frames, at
//!   twice the largest step the track shows between detected points, and no other track
//!   within `2 R + 2` of them (a neighbour it crossed or merged with may have hidden it): the
//!   particle was there alone and was not followed. Likewise a track whose particle is lost
//!   for good, its last detected point farther inside the image than it can travel to the
//!   border in the frames left.
//! * **One image, two tracks.** Each size class is linked on its own, so a track of one
//!   class can take the image another class's track follows. Two tracks of different
//!   classes whose detected points in a frame lie within a quarter of the smaller radius (at
//!   least half a pixel) of each other follow one image there: where that holds in at least
//!   half of the frames in which both were detected (and two or more), one of the particles
//!   was not followed ([`Concern::SharedImage`], see [`shared_images`]); in fewer frames the
//!   two overlapped in view, or one track took the other's image for a while, and a warning
//!   names them and the frames.

use std::collections::BTreeMap;

use crate::appearance::ln_mass_noise_spread;
use crate::frames::FrameView;
use crate::link::FrameDetections;
use crate::locate::locate_window;
use crate::point_grid::PointGrid;
#[cfg(doc)]
use crate::rim::rim_centre;
use crate::rim::Rim;
use crate::track_table::{PointFlag, TrackPoint, TrackTable};
use std::cell::OnceCell;

/// Largest skirt (see the module doc) of a particle whose radius is the one in use.
pub(crate) const MAX_SKIRT: f64 = 0.6;

/// Skirt above which a lopsided one (see [`MAX_LOPSIDED`]) says the track follows a part of
/// a particle: a centred particle's ring holds its own skirt evenly around it.
pub(crate) const LOPSIDED_SKIRT: f64 = 0.2;

/// Largest lopsidedness of a followed particle's skirt: the magnitude of the ring's signal
/// summed as vectors pointing away from the point, over the sum of its magnitudes (0 for a
/// ring holding the same signal all round, 1 for all of it in one direction). A track on the
/// rim of a ring-shaped particle has the rest of the rim curving away to one side (0.2 for
/// a ring of radii 13.5-19 px followed at 5 px), one on the edge of a large disc has the
/// disc to one side (0.5-0.9); a centred particle's is zero but for the noise (about
/// `sigma / (mean ring signal sqrt(2 n))` over `n` ring pixels: 0.015 for a Gaussian spot
/// of radius 10 px and contrast 100 under noise 20).
pub(crate) const MAX_LOPSIDED: f64 = 0.12;

/// Largest elongation of a followed particle's skirt: the magnitude of the ring's signal
/// summed as unit vectors at twice each pixel's direction from the point, over the sum of
/// its magnitudes (0 for a ring holding the same signal all round, 1 for all of it on one
/// line through the point). A band `2 R` wide through the point (`R` the radius in use), the
/// rim of a ring much larger than `R`, covers `a = asin(R / (1.5 R + 1))` rad either side of
/// its line at the skirt's mid-radius `1.5 R + 1` (0.63 at `R` = 5 px): an elongation of
/// `sin 2a / 2a = 0.75` (measured, median over frames: 0.34-0.66 on the rims of rings of
/// 9-20 px tracked at 3.1-8.0 px); a centred particle's is zero but for the noise, as for
/// [`MAX_LOPSIDED`] (followed rings of 4-20 px: 0.01-0.11). The limit lies a third of the way
/// from the one to the other. Like the lopsidedness it counts only with a skirt above
/// [`LOPSIDED_SKIRT`]: small, noisy particles of the sweep that are followed read up to 0.29
/// with a skirt under 0.04.
pub(crate) const MAX_ELONGATED: f64 = 0.25;

/// Largest scatter of a ring's located points about its rim's centre: each sample frame's
/// offset from the typical one (the median on each axis), as a chi-square of 2 degrees of
/// freedom against the rim's and the point's own standard errors; the median over the `n`
/// frames, over that chi-square's own median `2 ln 2`, may exceed 1 by this many of its
/// standard deviations (asymptotically `1 / (ln 2 sqrt(n))` for the median of `n`
/// exponentials, 0.51 over 8 frames; see [`Concern::OffRim`]). A steady offset is allowed: a
/// centroid leans with the light, and the rim's centre does not. Measured on the ring
/// neighbours and the sweep's rings (`ring_neighbours_table`, 180 tracks): 0.9 median, up
/// to 5.1 over 8 frames (limit 7.1) and 6.1 over 4 (limit 9.7) on followed rings, whose
/// errors leave out the centroid's own bias from frame to frame; offsets of half a pixel in
/// every direction against errors of 0.05 px read about 50 (the unit test).
pub(crate) const MAX_RIM_SCATTER_SIGMAS: f64 = 12.0;

/// A particle's skirt in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Skirt {
    /// The ring's mean signal over the disc's.
    pub(crate) level: f64,
    /// How much of the ring's signal lies to one side (see [`MAX_LOPSIDED`]), in [0, 1].
    pub(crate) lopsided: f64,
    /// How much of the ring's signal lies along one line through the point (see
    /// [`MAX_ELONGATED`]), in [0, 1].
    pub(crate) elongated: f64,
    /// The ring's mean absolute signal beyond what its noise alone gives (`sigma sqrt(2 /
    /// pi)`), over the disc's mean signal: as large as `level` where the ring's signal has
    /// one sign, larger where parts above and below the background cancel in `level`.
    pub(crate) magnitude: f64,
    /// The mean signal within half the radius over the disc's: well under 1 where the
    /// particle is hollow about the point (a ring), about 1 or more for a disc or a spot.
    pub(crate) inner: f64,
    /// The rim of a hollow particle about the point ([`rim_centre`]), where measured.
    pub(crate) rim: Option<Rim>,
    /// The point's own standard error on one axis (its `ep`), px.
    pub(crate) point_error: f64,
}

/// Why a track does not follow one particle.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Concern {
    /// The particle's signal reaches well beyond the radius in use.
    Larger {
        /// Its skirt (see the module doc): the ring's mean signal over the disc's.
        skirt: f64,
        /// How much of the ring's signal lies to one side (median over `frames`).
        lopsided: f64,
        /// How much of the ring's signal lies along one line through it (median over
        /// `frames`).
        elongated: f64,
        /// The ring's mean magnitude beyond the noise over the disc's level (median over
        /// `frames`).
        magnitude: f64,
        /// The radius in use, px.
        radius: f64,
        /// Sample frames it was measured in.
        frames: Vec<usize>,
    },
    /// The particle was lost, and found again, where it cannot have left the image.
    LostInside {
        /// First and last frame without a position.
        frames: (usize, usize),
        /// How far inside the image its points either side of the gap lie, px (beyond the
        /// radius).
        inside: [f64; 2],
        /// The largest step between its detected points, px per frame.
        step: f64,
    },
    /// The particle is hollow about its points (a ring), and its located points scatter
    /// about its rim's centre far more than their errors allow.
    OffRim {
        /// The median frame's chi-square of its offset from the typical one, over that
        /// chi-square's median under pure noise (see [`MAX_RIM_SCATTER_SIGMAS`]).
        scatter: f64,
        /// The rim's centre's distance from the point, px (median over `frames`).
        offset: f64,
        /// The standard error of the offset on one axis (the rim's and the point's), px
        /// (median over `frames`).
        error: f64,
        /// The rim's radius, px (median over `frames`).
        rim_radius: f64,
        /// Sample frames it was measured in.
        frames: Vec<usize>,
    },
    /// The particle was lost for good where it cannot have left the image.
    Vanished {
        /// First and last frame without a detection (the last of the window).
        frames: (usize, usize),
        /// How far inside the image its last detected point lies, px (beyond the radius).
        inside: f64,
        /// The largest step between its detected points, px per frame.
        step: f64,
    },
    /// The change of the track's step from frame to frame itself changes by more than the
    /// particle's diameter, as a rule: it hops between parts of a larger particle, or between
    /// objects.
    Erratic {
        /// Median over the track of the magnitude of its third differences, px.
        jerk: f64,
        /// The radius in use, px.
        radius: f64,
        /// Runs of four consecutive detected frames measured.
        count: usize,
        /// Steps of those runs that landed on another blob of the frame before or left one
        /// of the frame after (see [`FrameBlobs`]), and steps looked at; `None` where the
        /// frames' blobs were not given.
        hops: Option<(usize, usize)>,
    },
    /// The track moves between two of its detected points far faster than before and after:
    /// it left its particle for another image.
    Jumped {
        /// The frames of the two points.
        frames: (usize, usize),
        /// The step between them per frame, px.
        step: f64,
        /// The faster of the nearest steps between consecutive detected frames before and
        /// after (one at least), px per frame.
        around: f64,
        /// The radius in use, px.
        radius: f64,
    },
    /// The track's detected points lie on another size class's track's points (one image
    /// followed twice) in most frames both were detected in.
    SharedImage {
        /// The other track's particle.
        other: String,
        /// Frames where the two points lie within `apart` of each other.
        frames: Vec<usize>,
        /// Frames where both were detected.
        both: usize,
        /// The largest distance between the two points in `frames`, px.
        apart: f64,
    },
    /// The particle was detected in fewer than half of its frames.
    MostlyUnseen {
        /// Frames where it was detected.
        detected: usize,
        /// Frames of its track.
        frames: usize,
    },
}

/// A track's concern.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TrackConcern {
    /// The track's particle.
    pub(crate) particle: String,
    /// What is wrong.
    pub(crate) concern: Concern,
}

impl std::fmt::Display for TrackConcern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = &self.particle;
        match &self.concern {
            Concern::Larger {
                skirt,
                lopsided,
                elongated,
                magnitude,
                radius,
                frames,
            } => write!(
                f,
                "{p}: its signal reaches well beyond the radius {radius:.2} px in use (the ring from {:.1} to {:.1} px \
                 around it holds {:.0} % of its centre's level, {:.0} % in magnitude beyond the noise, {:.0} % of it to one side and {:.0} % along one line, \
                 median over frames {}; under {:.0} %, or under {:.0} % when lopsided or elongated, where the track \
                 follows one particle of this size): the particle is larger than that and was found as parts, or the \
                 track follows other objects",
                skirt_ring(*radius)[0],
                skirt_ring(*radius)[1],
                100.0 * skirt,
                100.0 * magnitude,
                100.0 * lopsided,
                100.0 * elongated,
                list(frames),
                100.0 * MAX_SKIRT,
                100.0 * LOPSIDED_SKIRT
            ),
            Concern::LostInside { frames, inside, step } => write!(
                f,
                "{p}: lost in frames {}-{} and found again, though its positions before and after lie {:.1} and {:.1} px \
                 inside the image, farther than it moves in those frames (at most {:.1} px a frame, twice its largest \
                 step): it was in view and not followed (no positions written there)",
                frames.0,
                frames.1,
                inside[0],
                inside[1],
                2.0 * step
            ),
            Concern::OffRim {
                scatter,
                offset,
                error,
                rim_radius,
                frames,
            } => write!(
                f,
                "{p}: it is a ring (hollow about its points, rim radius {rim_radius:.1} px) whose located points lie \
                 {offset:.2} px from its rim's centre and scatter about it {scatter:.1} times as much as their errors \
                 ({error:.2} px) allow (frames {}): the points do not follow the ring",
                list(frames)
            ),
            Concern::Vanished { frames, inside, step } => write!(
                f,
                "{p}: lost from frame {} to the last, {}, though its last position lies {inside:.1} px inside the \
                 image, farther than it moves in those frames (at most {:.1} px a frame, twice its largest step): it \
                 was in view and not followed",
                frames.0,
                frames.1,
                2.0 * step
            ),
            Concern::Erratic {
                jerk,
                radius,
                count,
                hops,
            } => {
                write!(
                    f,
                    "{p}: its positions jump about: how much the change of its step from one frame to the next \
                     itself changes (its third difference) has a median of {jerk:.1} px over {count} runs of frames, \
                     more than its diameter and 2 px ({:.1} px at the radius {radius:.2} px in use), where forces \
                     change smoothly",
                    2.0 * (radius + 1.0)
                )?;
                if let Some((hops, of)) = hops {
                    write!(
                        f,
                        ", and {hops} of its {of} steps there land on another blob of the frame before or leave \
                         one of the frame after"
                    )?;
                }
                write!(f, ": the track hops between parts of a larger particle or between objects")
            }
            Concern::Jumped {
                frames,
                step,
                around,
                radius,
            } => {
                // Over a gap, the whole move and its rate; between consecutive frames, the step.
                let gap = frames.1 - frames.0;
                let (moves, over) = if gap == 1 {
                    (format!("{step:.1} px a frame"), String::new())
                } else {
                    (
                        format!("{:.1} px", step * gap as f64),
                        format!(" ({step:.1} px a frame over {gap} frames)"),
                    )
                };
                let those = if gap == 1 { "" } else { " over those frames" };
                write!(
                    f,
                    "{p}: it moves {moves} from frame {} to frame {}{over}, against {around:.1} px a frame between \
                     the consecutive frames nearest it; more than {JUMP_FACTOR} times that{those} plus its diameter \
                     ({:.1} px at the radius {radius:.2} px in use) is no motion of one particle: the track left its \
                     particle for another image",
                    frames.0,
                    frames.1,
                    2.0 * radius
                )
            }
            Concern::SharedImage {
                other,
                frames,
                both,
                apart,
            } => write!(
                f,
                "{p}: its points lie on {other}'s (within {apart:.2} px) in {} of the {both} frames both were \
                 detected in (frames {}): the two tracks follow one image, and one of the particles was not \
                 followed",
                frames.len(),
                list(frames)
            ),
            Concern::MostlyUnseen { detected, frames } => write!(
                f,
                "{p}: detected in only {detected} of its {frames} frames (the rest bridged from its motion)"
            ),
        }
    }
}

/// Frames named in a report: the first this many.
const NAMED_FRAMES: usize = 6;

/// The frames, the first [`NAMED_FRAMES`] of them named.
fn list(frames: &[usize]) -> String {
    let named: Vec<String> = frames.iter().take(NAMED_FRAMES).map(|k| k.to_string()).collect();
    if frames.len() > NAMED_FRAMES {
        format!("{} and {} more", named.join(", "), frames.len() - NAMED_FRAMES)
    } else {
        named.join(", ")
    }
}

/// The concerns of every track of `table` for particles of radius `radius` (px), with the
/// skirts of their points measured in some frames (`skirts[particle]`: frame and skirt each,
/// from [`skirts`]), and the skirts of the points as located (`located`, before rings were
/// moved to their rims' centres), whose rims say whether the located points agreed with them
/// ([`Concern::OffRim`]); one concern a track, the first of: mostly unseen, larger than the
/// radius ([`skirt_concern`]), off its rim, erratic ([`erratic`], judged with the frames'
/// blobs `blobs`, where given: see [`FrameBlobs`]).
pub(crate) fn check_tracks(
    table: &TrackTable,
    radius: f64,
    skirts: &BTreeMap<String, Vec<(usize, Skirt)>>,
    located: &BTreeMap<String, Vec<(usize, Skirt)>>,
    blobs: &[FrameDetections],
) -> Vec<TrackConcern> {
    let positions = FrameBlobs::positions(blobs);
    let blobs = FrameBlobs::new(blobs, &positions);
    let mut out = Vec::new();
    for (particle, points) in table.by_particle() {
        let detected = points.iter().filter(|p| p.flag == PointFlag::Detected).count();
        if 2 * detected < points.len() {
            out.push(TrackConcern {
                particle: particle.to_string(),
                concern: Concern::MostlyUnseen {
                    detected,
                    frames: points.len(),
                },
            });
            continue;
        }
        if let Some(concern) = skirt_concern(skirts.get(particle), radius)
            .or_else(|| located.get(particle).and_then(|m| off_rim(m)))
            .or_else(|| erratic(&points, radius, &blobs))
            .or_else(|| jumped(&points, radius, &blobs))
        {
            out.push(TrackConcern {
                particle: particle.to_string(),
                concern,
            });
        }
    }
    out
}

/// [`Concern::Larger`] where a track's skirts (`measured`: frame and skirt each, for a
/// particle of radius `radius` px) say its particle reaches well beyond the radius in use.
fn skirt_concern(measured: Option<&Vec<(usize, Skirt)>>, radius: f64) -> Option<Concern> {
    let measured = measured.filter(|m| !m.is_empty())?;
    let mut values: Vec<f64> = measured.iter().map(|m| m.1.level).collect();
    let skirt = physfit_tracks::stats::median_upper(&mut values);
    let mut sides: Vec<f64> = measured.iter().map(|m| m.1.lopsided).collect();
    let lopsided = physfit_tracks::stats::median_upper(&mut sides);
    let mut lines: Vec<f64> = measured.iter().map(|m| m.1.elongated).collect();
    let elongated = physfit_tracks::stats::median_upper(&mut lines);
    let mut magnitudes: Vec<f64> = measured.iter().map(|m| m.1.magnitude).collect();
    let magnitude = physfit_tracks::stats::median_upper(&mut magnitudes);
    // A ring below the background is as telling as one above it, and parts above and
    // below it that cancel in the mean as telling as either (see the module doc).
    let uneven = lopsided > MAX_LOPSIDED || elongated > MAX_ELONGATED;
    (skirt.abs() > MAX_SKIRT || (skirt.abs().max(magnitude) > LOPSIDED_SKIRT && uneven)).then(|| {
        Concern::Larger {
            skirt,
            lopsided,
            elongated,
            magnitude,
            radius,
            frames: measured.iter().map(|m| m.0).collect(),
        }
    })
}

/// Least runs of four consecutive detected frames for [`erratic`] to judge a track.
const ERRATIC_RUNS: usize = 3;

/// [`Concern::Erratic`] where the median magnitude of the third differences of `points`
/// (one track, frame order) over consecutive detected frames exceeds the diameter of a
/// particle of radius `radius` (px) plus 2 px. A particle's image moves with it, and the
/// forces on it change smoothly: its step changes by its acceleration times the frame
/// interval squared, which may be large (the shared ball toss at its frame rate: 16.5-19.1 px
/// a frame, for a ball of 5 px), but that change itself changes little (1.0-2.1 px there);
/// a bounce or a kick changes it in a frame or two, which the median passes over, and random
/// walks of 0.5-3 px a frame change it by about 4 px. A track hopping between the arcs of a
/// ring of 25 px under noise 28 changed it by tens of px a frame at a radius of 6.4 px, and had
/// been written without a word.
///
/// A track hops between objects or parts only onto others that are there: with the frames'
/// blobs given (`blobs`, see [`FrameBlobs::hop_site`]), at least a third of the steps of
/// those runs (two at least) must land within half their length of another blob of the
/// frame before, or leave the point within half their length of another blob of the frame
/// after; or the track must neither keep its image's mass ([`keeps_its_mass`]: one object)
/// nor move away as a random walk does ([`spreads_as_a_walk`]): a track taking blobs that
/// come and go about one place, such as clutter in a real video. A
/// small particle in Brownian motion changes its step's change by as much (random walks of
/// 0.5-3 px a frame: medians of 5-9 px, above the 5-6 px of discs of 1.5-2 px), but steps
/// from its own blob to where no other was, and wanders off.
fn erratic(points: &[&TrackPoint], radius: f64, blobs: &FrameBlobs) -> Option<Concern> {
    let detected = |p: &TrackPoint| p.flag == PointFlag::Detected;
    // The runs: where four consecutive detected frames start.
    let runs: Vec<usize> = (0..points.len().saturating_sub(3))
        .filter(|&i| {
            let w = &points[i..i + 4];
            w.iter().all(|p| detected(p)) && w.windows(2).all(|q| q[1].frame == q[0].frame + 1)
        })
        .collect();
    let thirds: Vec<[f64; 2]> = runs
        .iter()
        .map(|&i| {
            let w = &points[i..i + 4];
            let third = |c: fn(&TrackPoint) -> f64| c(w[3]) - 3.0 * c(w[2]) + 3.0 * c(w[1]) - c(w[0]);
            [third(|p| p.x), third(|p| p.y)]
        })
        .collect();
    if thirds.len() < ERRATIC_RUNS {
        return None;
    }
    let count = thirds.len();
    let mut jerks: Vec<f64> = thirds.iter().map(|d| d[0].hypot(d[1])).collect();
    let jerk = physfit_tracks::stats::median(&mut jerks);
    // Along one line they are a motion's, not hops: a ball bouncing on a floor every few
    // frames changes its step's change at each bounce, always along the floor's normal.
    // The axial concentration: the magnitudes summed as vectors at twice each direction,
    // over the sum of magnitudes (1 on one line, about `1 / sqrt(n)` for random directions).
    let (mut c, mut s, mut total) = (0.0, 0.0, 0.0);
    for d in &thirds {
        let m = d[0].hypot(d[1]);
        if m > 0.0 {
            let (cos, sin) = (d[0] / m, d[1] / m);
            c += m * (cos * cos - sin * sin);
            s += m * 2.0 * cos * sin;
            total += m;
        }
    }
    let on_a_line = total > 0.0 && c.hypot(s) / total > MAX_ERRATIC_ALIGNMENT;
    if jerk <= 2.0 * (radius + 1.0) || on_a_line {
        return None;
    }
    // The steps of the runs measured, and how many of them hopped onto another blob: the
    // point they land on lies nearer another blob of the frame before than half the step,
    // or the point they leave nearer another blob of the frame after.
    let mut in_runs = vec![false; points.len()];
    for &i in &runs {
        in_runs[i..i + 3].fill(true);
    }
    let mut steps = (0..points.len())
        .filter(|&i| in_runs[i])
        .map(|i| (points[i], points[i + 1]));
    let hops = steps.try_fold((0, 0), |(hops, of), (a, b)| {
        let (a, b) = ((a.frame, [a.x, a.y]), (b.frame, [b.x, b.y]));
        Some((hops + usize::from(blobs.step_hops(a, b)?), of + 1))
    });
    match hops {
        Some((hops, of))
            if (hops < 2 || 3 * hops < of)
                && (keeps_its_mass(points, radius) || spreads_as_a_walk(points)) =>
        {
            None
        }
        _ => Some(Concern::Erratic {
            jerk,
            radius,
            count,
            hops,
        }),
    }
}

/// Largest median change of a track's log mass from one detected frame to the next for
/// [`keeps_its_mass`], beyond what the pixel noise makes it change by: a fifth (about 22 %
/// either way). One object's image keeps its mass but for noise, blur and light that change
/// it slowly: 0.016-0.047 on the real bob, ball toss and bouncing ball, 0.01-0.02 on bright
/// beads jittering in traps, 0.08-0.20 on beads of 2 px standing 2.7 noise levels high (of
/// which the noise makes a spread of 0.17); a track taking clutter that comes and goes
/// takes images of other masses (the ball toss's tracks on the hand, the stick and the
/// body, unnamed: 0.29 median, 0.24-0.73 on those whose positions jumped about, the noise
/// 0.03-0.1 of it).
const STEADY_MASS_CHANGE: f64 = 0.2;

/// Least frame-to-frame mass changes for [`keeps_its_mass`] to judge a track.
const STEADY_MASS_CHANGES: usize = 3;

/// Whether the track `points` (frame order; particles of radius `radius` px) keeps its
/// image's mass: the median of `|ln(m₂ / m₁)|` over consecutive detected frames is at most
/// [`STEADY_MASS_CHANGE`] plus the spread the pixel noise makes it change by at the track's
/// median position error ([`ln_mass_noise_spread`], over the centroid window,
/// [`locate_window`]), from [`STEADY_MASS_CHANGES`] changes at least of positive masses (`false`
/// with fewer). Such a track follows one object, even where it does not move away as a
/// random walk does (a bead jittering in a trap, a particle in a cage of neighbours:
/// isolated beads of 2 px jittering by 1-2 px a frame about fixed places had their tracks,
/// right to 0.02 px, called hops, and refused under a structure).
fn keeps_its_mass(points: &[&TrackPoint], radius: f64) -> bool {
    let steady = |p: &TrackPoint| p.flag == PointFlag::Detected && p.mass > 0.0 && p.mass.is_finite();
    let pairs = points
        .windows(2)
        .filter(|w| steady(w[0]) && steady(w[1]) && w[1].frame == w[0].frame + 1);
    let mut changes: Vec<f64> = pairs
        .clone()
        .map(|w| (w[1].mass / w[0].mass).ln().abs())
        .collect();
    if changes.len() < STEADY_MASS_CHANGES {
        return false;
    }
    let mut eps: Vec<f64> = pairs.map(|w| w[1].ep).filter(|e| e.is_finite()).collect();
    let noise = if eps.is_empty() {
        0.0
    } else {
        ln_mass_noise_spread(physfit_tracks::stats::median(&mut eps), locate_window(radius))
    };
    physfit_tracks::stats::median(&mut changes) <= STEADY_MASS_CHANGE + noise
}

/// Frames over which [`spreads_as_a_walk`] compares a track's displacement with its step.
const WALK_LAG: usize = 4;

/// Whether the track `points` (frame order) moves away as a random walk does: its mean
/// squared displacement over [`WALK_LAG`] frames at least twice its mean squared step
/// (a random walk's is `WALK_LAG` times it, a track visiting places at random about one
/// centre about once: of 4 000 simulated tracks of 20 steps each, about 4 % of walks and 1-4
/// % of such tracks fell the wrong side of 2; of 12 steps, about 9 % and 3-8 %), from
/// detected points, three such displacements at least (`false` with fewer).
fn spreads_as_a_walk(points: &[&TrackPoint]) -> bool {
    let detected: BTreeMap<usize, [f64; 2]> = points
        .iter()
        .filter(|p| p.flag == PointFlag::Detected)
        .map(|p| (p.frame, [p.x, p.y]))
        .collect();
    let msd = |lag: usize| {
        let (mut sum, mut n) = (0.0, 0usize);
        for (k, a) in &detected {
            if let Some(b) = detected.get(&(k + lag)) {
                sum += (b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2);
                n += 1;
            }
        }
        (sum, n)
    };
    let ((one, n1), (far, n4)) = (msd(1), msd(WALK_LAG));
    n4 >= 3 && n1 > 0 && far / n4 as f64 >= 2.0 * one / n1 as f64
}

/// The blobs of a recording's frames, for asking whether a track's point had another blob
/// near it; each frame's positions and neighbour grid are built when first asked for.
pub(crate) struct FrameBlobs<'a> {
    frames: &'a [FrameDetections],
    points: &'a [OnceCell<Vec<[f64; 2]>>],
    grids: Vec<OnceCell<PointGrid<'a>>>,
}

impl<'a> FrameBlobs<'a> {
    /// Room for the positions of the blobs of `frames`, filled as frames are asked for.
    pub(crate) fn positions(frames: &[FrameDetections]) -> Vec<OnceCell<Vec<[f64; 2]>>> {
        frames.iter().map(|_| OnceCell::new()).collect()
    }

    /// The blobs of `frames` (consecutive frames, any first), their positions kept in
    /// `points` (from [`FrameBlobs::positions`] of the same frames).
    pub(crate) fn new(
        frames: &'a [FrameDetections],
        points: &'a [OnceCell<Vec<[f64; 2]>>],
    ) -> FrameBlobs<'a> {
        FrameBlobs {
            frames,
            points,
            grids: frames.iter().map(|_| OnceCell::new()).collect(),
        }
    }

    /// Whether the step between the points `a` and `b` (frame, position px) hops: it lands on
    /// another blob of `a`'s frame or leaves one of `b`'s ([`FrameBlobs::hop_site`] both
    /// ways). `None` where a frame is not held.
    fn step_hops(&self, a: (usize, [f64; 2]), b: (usize, [f64; 2])) -> Option<bool> {
        Some(self.hop_site(a, b.1)? || self.hop_site(b, a.1)?)
    }

    /// Whether a step from the point `from` (frame, position px) to `to` (px) lands on
    /// another blob of `from`'s frame: one other than the blob nearest `from` (its own)
    /// lies within half the step of `to`. `None` where the frame is not held.
    fn hop_site(&self, from: (usize, [f64; 2]), to: [f64; 2]) -> Option<bool> {
        let (frame, at) = from;
        let first = self.frames.first()?.frame;
        let k = frame.checked_sub(first)?;
        let fd = self.frames.get(k).filter(|f| f.frame == frame)?;
        if fd.detections.len() < 2 {
            return Some(false);
        }
        let points = self.points[k].get_or_init(|| fd.detections.iter().map(|d| [d.x, d.y]).collect());
        let grid = self.grids[k].get_or_init(|| PointGrid::new(points));
        let own = grid.nearest_two(&at)[0].map(|n| n.0);
        let half = 0.5 * (to[0] - at[0]).hypot(to[1] - at[1]);
        let landing = grid
            .nearest_two(&to)
            .into_iter()
            .flatten()
            .find(|n| Some(n.0) != own);
        Some(landing.is_some_and(|n| n.1 < half * half))
    }
}

/// How many times the faster of the neighbouring steps a track's step per frame may exceed
/// (beyond the particle's diameter) before [`jumped`] calls it a jump.
const JUMP_FACTOR: f64 = 3.0;

/// [`Concern::Jumped`] at the largest step per frame between two detected points of
/// `points` (one track, frame order; frames missing between them allowed) that exceeds
/// [`JUMP_FACTOR`] times the faster of the nearest steps between consecutive detected frames
/// before it and after it (at a track's end, the two nearest on its one side where the step
/// lands on no other blob of `blobs` and leaves none; one at least measured), plus the
/// diameter of a particle of radius `radius` (px) spread over the frames between the two
/// points. A continuous motion's step over a frame lies between the steps either side of
/// it, give or take its acceleration: a bounce reverses the step but keeps its size, a kick
/// from rest is followed by steps as large as the kick's, and a frame lost from the
/// recording doubles one step. The diameter covers a slow particle's noise and the
/// detector's changes of mind about its extent. Sweep style 1038 (shaded spheres of 9.6 and
/// 24 px under a saturating exposure drift): the small sphere's track, lost at frame 11, took
/// the large one's highlight at frame 12, 125 px away, moving 1.5 and 2.6 px a frame before
/// and after.
fn jumped(points: &[&TrackPoint], radius: f64, blobs: &FrameBlobs) -> Option<Concern> {
    let detected: Vec<&TrackPoint> = points
        .iter()
        .copied()
        .filter(|p| p.flag == PointFlag::Detected)
        .collect();
    // The step per frame from detected point `i` to `i + 1`, and whether they are consecutive frames.
    let step = |i: usize| {
        let (a, b) = (detected[i], detected[i + 1]);
        let frames = (b.frame - a.frame) as f64;
        ((b.x - a.x).hypot(b.y - a.y) / frames, b.frame == a.frame + 1)
    };
    let steps: Vec<(f64, bool)> = (0..detected.len().saturating_sub(1)).map(step).collect();
    // Each step beyond its bound, with the faster of its consecutive neighbours. Over a gap
    // of `g` frames the particle may cover `g` such steps, and the diameter once: the
    // detector's slop does not grow with the gap (fresh style 6165: a spot lost for 11
    // frames was found again on another image 122 px away, 10 px a frame against 1.2
    // before, under the bound of 17 px a frame that the diameter alone gave).
    let jumps = steps.iter().enumerate().filter_map(|(i, &(s, _))| {
        // The nearest steps between consecutive frames on either side: two points found
        // after a gap on two other images make a step with no consecutive neighbour (fresh
        // 6165: 39 px in a frame between them, after the spot had moved 0.2-1.8 px a frame).
        // Two of them: the nearest on each side. At a track's end, where one side has none,
        // the two nearest on the other side, unless the step lands on another blob or leaves
        // one (a hop there is judged against its one neighbour: fresh 8312's last step, 65.6
        // px onto another particle after steps of 0.8 and 23 px between two images). Against
        // one alone, a random walk's step is three times its neighbour's one time in ten (the
        // squared ratio of two Rayleigh steps is F(2, 2)); against the larger of two, one in
        // sixty. Beads jittering in traps were refused at their tracks' first or last step
        // (trap 7664: 15.4 px a frame against the 2.1 px of its one neighbour, where the
        // bead's steps spread 5 px per axis).
        let before = two_consecutive(steps[..i].iter().rev());
        let after = two_consecutive(steps[i + 1..].iter());
        let gap = (detected[i + 1].frame - detected[i].frame) as f64;
        let beyond = |around: f64| s > JUMP_FACTOR * around + 2.0 * radius / gap;
        let around = match (before[0], after[0]) {
            (Some(b), Some(a)) => b.max(a),
            (None, None) => return None,
            // At an end: the blobs are looked at only where the one neighbour calls it a jump.
            (Some(near), None) | (None, Some(near)) => {
                let second = before[1].or(after[1]);
                let (a, b) = (detected[i], detected[i + 1]);
                let lone = || blobs.step_hops((a.frame, [a.x, a.y]), (b.frame, [b.x, b.y])) == Some(false);
                match second {
                    Some(second) if beyond(near) && lone() => near.max(second),
                    _ => near,
                }
            }
        };
        beyond(around).then_some((i, s, around))
    });
    jumps
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, step, around)| Concern::Jumped {
            frames: (detected[i].frame, detected[i + 1].frame),
            step,
            around,
            radius,
        })
}

/// The first two steps per frame of `side` (each with whether it joins consecutive frames)
/// that join consecutive frames, nearest first.
fn two_consecutive<'s>(side: impl Iterator<Item = &'s (f64, bool)>) -> [Option<f64>; 2] {
    let mut found = side.filter(|q| q.1).map(|q| q.0);
    [found.next(), found.next()]
}

/// Largest axial concentration of an erratic track's third differences (see [`erratic`]):
/// half way between random directions' (0.2-0.3 over 10-20 runs) and one line's 1.
const MAX_ERRATIC_ALIGNMENT: f64 = 0.6;

/// The least standard error of each axis of a point's offset from its rim's centre, px,
/// whatever the noise: the pixel sampling's own error, which no noise estimate holds. The
/// noise-free rings the sweep tables follow are 0.0007-0.10 px RMS per axis off their
/// centres, 0.011 the median and about 0.02 the upper quartile (19 styles, session 30).
/// Without it, errors under 0.005 px under no noise refused rings whose offsets scattered
/// 7.2-12.6 times as much as those allow (fresh 6045 and 6551, ring neighbour 4006), followed
/// since within their tolerance.
const RIM_OFFSET_FLOOR: f64 = 0.02;

/// [`Concern::OffRim`] where the particle is hollow about its points in most measured
/// frames (3 at least) and their offsets from its rim's centre scatter beyond
/// [`MAX_RIM_SCATTER_SIGMAS`] (each offset's error at least [`RIM_OFFSET_FLOOR`]).
fn off_rim(measured: &[(usize, Skirt)]) -> Option<Concern> {
    let rims: Vec<(usize, Rim, f64)> = measured
        .iter()
        .filter_map(|m| m.1.rim.map(|r| (m.0, r, m.1.point_error)))
        .collect();
    if rims.len() < 3 || 2 * rims.len() < measured.len() {
        return None;
    }
    // Each frame's offset from the typical one (the median on each axis) against what the
    // rim's and the point's own errors allow: a chi-square of 2 degrees of freedom each,
    // whose median is 2 ln 2 where the offsets only scatter as their errors say. The median
    // over the frames, not the mean: a neighbour's light can pull the centroid in a frame
    // or two, and the rim's centre puts that right (`pipeline::rims`); a track that follows
    // something else in most of them is off in most.
    let typical = [0, 1].map(|a| {
        let mut v: Vec<f64> = rims.iter().map(|r| r.1.offset[a]).collect();
        physfit_tracks::stats::median(&mut v)
    });
    let mut chi2: Vec<f64> = rims
        .iter()
        .map(|r| {
            let v = r.1.error.powi(2) + r.2.powi(2) + RIM_OFFSET_FLOOR.powi(2);
            ((r.1.offset[0] - typical[0]).powi(2) + (r.1.offset[1] - typical[1]).powi(2)) / v
        })
        .collect();
    let scatter = physfit_tracks::stats::median(&mut chi2) / (2.0 * std::f64::consts::LN_2);
    let mut offsets: Vec<f64> = rims.iter().map(|r| r.1.offset[0].hypot(r.1.offset[1])).collect();
    let offset = physfit_tracks::stats::median_upper(&mut offsets);
    let mut errors: Vec<f64> = rims.iter().map(|r| r.1.error.hypot(r.2)).collect();
    let error = physfit_tracks::stats::median_upper(&mut errors);
    let mut radii: Vec<f64> = rims.iter().map(|r| r.1.radius).collect();
    let rim_radius = physfit_tracks::stats::median_upper(&mut radii);
    let spread = 1.0 / (std::f64::consts::LN_2 * (rims.len() as f64).sqrt());
    (scatter > 1.0 + MAX_RIM_SCATTER_SIGMAS * spread).then(|| Concern::OffRim {
        scatter,
        offset,
        error,
        rim_radius,
        frames: rims.iter().map(|r| r.0).collect(),
    })
}

/// The tracks of `table` (particles of radius `radius` px in frames of `size` px) that were
/// lost inside the image: each run of frames missing between two of a track's points
/// where the distances of those points from the image border, less the radius, add up to
/// more than the particle can travel in the run's frames and one more at twice the largest
/// step between consecutive detected points of the track (a particle that leaves the image
/// and comes back travels to the border and back), and no other track's point lies within
/// `2 radius + 2` px of either point in its frame (the crossing distance: two particles that
/// met may hide each other). Tracks of fewer than two such steps are left alone.
pub(crate) fn lost_inside(
    table: &TrackTable,
    radius: f64,
    size: (usize, usize),
    last_frame: usize,
) -> Vec<TrackConcern> {
    let (w, h) = (size.0 as f64, size.1 as f64);
    let mut by_frame: BTreeMap<usize, Vec<&crate::track_table::TrackPoint>> = BTreeMap::new();
    for p in &table.points {
        by_frame.entry(p.frame).or_default().push(p);
    }
    let crowded = |p: &crate::track_table::TrackPoint| {
        by_frame.get(&p.frame).is_some_and(|others| {
            others
                .iter()
                .any(|o| o.particle != p.particle && (o.x - p.x).hypot(o.y - p.y) < 2.0 * radius + 2.0)
        })
    };
    let inside = |p: &crate::track_table::TrackPoint| {
        (p.x.min(w - 1.0 - p.x).min(p.y).min(h - 1.0 - p.y) - radius).max(0.0)
    };
    let mut out = Vec::new();
    for (particle, points) in table.by_particle() {
        let steps: Vec<f64> = points
            .windows(2)
            .filter(|p| {
                p[1].frame == p[0].frame + 1
                    && p[0].flag == PointFlag::Detected
                    && p[1].flag == PointFlag::Detected
            })
            .map(|p| (p[1].x - p[0].x).hypot(p[1].y - p[0].y))
            .collect();
        if steps.len() < 2 {
            continue;
        }
        let step = steps.iter().copied().fold(0.0, f64::max);
        // Lost for good: its last detected point lies farther inside the image than it can
        // travel to the border in the frames after it.
        if let Some(end) = points.iter().rev().find(|p| p.flag == PointFlag::Detected) {
            let gap = last_frame.saturating_sub(end.frame);
            let a = inside(end);
            if gap >= 2 && a > 2.0 * step * gap as f64 && !crowded(end) {
                out.push(TrackConcern {
                    particle: particle.to_string(),
                    concern: Concern::Vanished {
                        frames: (end.frame + 1, last_frame),
                        inside: a,
                        step,
                    },
                });
                continue;
            }
        }
        for p in points.windows(2) {
            let gap = p[1].frame - p[0].frame;
            if gap < 2 {
                continue;
            }
            let (a, b) = (inside(p[0]), inside(p[1]));
            if a + b > 2.0 * step * gap as f64 && !crowded(p[0]) && !crowded(p[1]) {
                out.push(TrackConcern {
                    particle: particle.to_string(),
                    concern: Concern::LostInside {
                        frames: (p[0].frame + 1, p[1].frame - 1),
                        inside: [a, b],
                        step,
                    },
                });
                break;
            }
        }
    }
    out
}

/// Tracks of different size classes that follow one image (see the module doc): `classes`
/// holds each class's radius (px) and the particles of its tracks in `table`. Returns the
/// concerns ([`Concern::SharedImage`], on the pair's first particle in `table`'s order) and
/// the warnings of pairs that share an image in fewer frames.
pub(crate) fn shared_images(
    table: &TrackTable,
    classes: &[(f64, Vec<String>)],
) -> (Vec<TrackConcern>, Vec<String>) {
    let class_of: std::collections::HashMap<&str, usize> = classes
        .iter()
        .enumerate()
        .flat_map(|(c, (_, names))| names.iter().map(move |n| (n.as_str(), c)))
        .collect();
    // Each frame's detected points with their classes, and each track's detected frames.
    let mut by_frame: BTreeMap<usize, Vec<(&TrackPoint, usize)>> = BTreeMap::new();
    let mut detected: BTreeMap<&str, std::collections::BTreeSet<usize>> = BTreeMap::new();
    for p in table.points.iter().filter(|p| p.flag == PointFlag::Detected) {
        if let Some(&c) = class_of.get(p.particle.as_str()) {
            by_frame.entry(p.frame).or_default().push((p, c));
            detected.entry(p.particle.as_str()).or_default().insert(p.frame);
        }
    }
    // Each pair's frames on one image, and the largest distance there, by the pair's names in
    // first-seen order.
    let mut order: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for p in &table.points {
        let next = order.len();
        order.entry(p.particle.as_str()).or_insert(next);
    }
    let mut shared: BTreeMap<(&str, &str), (Vec<usize>, f64)> = BTreeMap::new();
    let near = |a: f64, b: f64| (0.25 * a.min(b)).max(0.5);
    let reach = classes.iter().map(|c| near(c.0, c.0)).fold(0.0, f64::max);
    for (&frame, points) in &by_frame {
        let positions: Vec<[f64; 2]> = points.iter().map(|(p, _)| [p.x, p.y]).collect();
        let grid = crate::point_grid::PointGrid::new(&positions);
        for (i, &(p, c)) in points.iter().enumerate() {
            grid.within(&positions[i], reach, |j, d2| {
                let (q, e) = points[j];
                let d = d2.sqrt();
                if e == c
                    || d > near(classes[c].0, classes[e].0)
                    || order.get(q.particle.as_str()) <= order.get(p.particle.as_str())
                {
                    return;
                }
                let entry = shared
                    .entry((p.particle.as_str(), q.particle.as_str()))
                    .or_insert((Vec::new(), 0.0));
                entry.0.push(frame);
                entry.1 = f64::max(entry.1, d);
            });
        }
    }
    let (mut concerns, mut warnings) = (Vec::new(), Vec::new());
    for ((a, b), (mut frames, apart)) in shared {
        frames.sort_unstable();
        frames.dedup();
        let both = detected[a].intersection(&detected[b]).count();
        if frames.len() >= 2 && 2 * frames.len() >= both {
            concerns.push(TrackConcern {
                particle: a.to_string(),
                concern: Concern::SharedImage {
                    other: b.to_string(),
                    frames,
                    both,
                    apart,
                },
            });
        } else {
            warnings.push(format!(
                "{a}: its points lie on {b}'s (within {apart:.2} px) in frames {}: the two tracks follow one image \
                 there (the particles overlap in view, or one track lost its own and took the other's), and \
                 their points there are the joint image's, not each particle's",
                list(&frames)
            ));
        }
    }
    (concerns, warnings)
}

/// The inner and outer radius of the ring round a point of a particle of radius `radius`
/// (px) whose signal is its skirt: `radius + 1` and `2 radius + 1`, px.
fn skirt_ring(radius: f64) -> [f64; 2] {
    [radius + 1.0, 2.0 * radius + 1.0]
}

/// The fraction of the pixels between `radius + 1` and `2 radius + 1` px from `p` (px) that
/// `frame` holds at the clip level ([`FrameView::clipped_at`]); 0 where the ring lies outside
/// the frame.
pub(crate) fn clipped_ring(frame: &FrameView<'_>, p: [f64; 2], radius: f64) -> f64 {
    let (width, height) = frame.size();
    let [inner, outer] = skirt_ring(radius);
    let (inner2, outer2) = (inner * inner, outer * outer);
    let x0 = (p[0] - outer).floor().max(0.0) as usize;
    let y0 = (p[1] - outer).floor().max(0.0) as usize;
    let x1 = ((p[0] + outer).ceil().max(0.0) as usize).min(width.saturating_sub(1));
    let y1 = ((p[1] + outer).ceil().max(0.0) as usize).min(height.saturating_sub(1));
    let (mut clipped, mut all) = (0usize, 0usize);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let d2 = (x as f64 - p[0]).powi(2) + (y as f64 - p[1]).powi(2);
            if d2 >= inner2 && d2 <= outer2 {
                all += 1;
                clipped += usize::from(frame.clipped_at(y * width + x));
            }
        }
    }
    if all == 0 {
        0.0
    } else {
        clipped as f64 / all as f64
    }
}

/// Of the ring round a point, the fraction at the clip level above which its particle's edge
/// is taken as cut off by saturated light ([`saturated_edges`]).
pub(crate) const CLIPPED_RING: f64 = 0.05;

/// Warnings for the tracks whose particles have saturated light round them in some frames
/// (`clipping`: by particle, frame and [`clipped_ring`] each): at least [`CLIPPED_RING`] of
/// the ring from `radius + 1` to `2 radius + 1` px at the clip level. There the particle's
/// edge is cut off where the light is brightest, so its centroid leans away from the light,
/// by an amount the frames no longer hold (sweep style 4023 drawn as Gaussian spots, a blurred dark spot on a light
/// background saturating with the exposure: 0.48 / 0.38 px RMS, tolerance 0.09 / 0.06).
pub(crate) fn saturated_edges(clipping: &BTreeMap<String, Vec<(usize, f64)>>, radius: f64) -> Vec<String> {
    let mut out = Vec::new();
    for (particle, measured) in clipping {
        let cut: Vec<(usize, f64)> = measured.iter().copied().filter(|c| c.1 >= CLIPPED_RING).collect();
        if cut.is_empty() {
            continue;
        }
        let most = cut.iter().map(|c| c.1).fold(0.0, f64::max);
        let frames: Vec<usize> = cut.iter().map(|c| c.0).collect();
        out.push(format!(
            "{particle}: the light round it is saturated in frames {} (up to {:.0} % of the ring from {:.1} to {:.1} \
             px round it at the clip level): its edge is cut off there where the light is brightest, and its \
             positions may lean away from the light",
            list(&frames),
            100.0 * most,
            skirt_ring(radius)[0],
            skirt_ring(radius)[1]
        ));
    }
    out
}

/// The skirt of each of `points` (px) in one frame's `signal` (`width * height`, grey levels):
/// the mean signal over the pixels between `radius + 1` and `2 radius + 1` px from the point
/// that are nearer to it than to any other point, over the mean signal within `radius` of it,
/// how lopsided and how elongated the ring's signal is, and its mean magnitude beyond the
/// pixel noise `noise_sigma` (grey levels); `None` where either region is empty or the disc
/// holds no signal.
pub(crate) fn skirts(
    signal: &[f32],
    width: usize,
    height: usize,
    points: &[[f64; 2]],
    radius: f64,
    noise_sigma: f64,
) -> Vec<Option<Skirt>> {
    let [inner, outer] = skirt_ring(radius);
    let (inner2, outer2, radius2) = (inner * inner, outer * outer, radius * radius);
    // The points sorted by x, so each finds its neighbours within two outer radii by a range.
    let mut by_x: Vec<usize> = (0..points.len()).collect();
    by_x.sort_by(|&a, &b| points[a][0].total_cmp(&points[b][0]));
    let xs: Vec<f64> = by_x.iter().map(|&i| points[i][0]).collect();
    let mut others: Vec<[f64; 2]> = Vec::new();
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            others.clear();
            let lo = xs.partition_point(|&x| x < p[0] - 2.0 * outer);
            let hi = xs.partition_point(|&x| x <= p[0] + 2.0 * outer);
            others.extend(
                by_x[lo..hi]
                    .iter()
                    .filter(|&&j| j != i && (points[j][1] - p[1]).abs() < 2.0 * outer)
                    .map(|&j| points[j]),
            );
            let (x0, x1) = (
                (p[0] - outer).floor().max(0.0),
                (p[0] + outer).ceil().min(width as f64 - 1.0),
            );
            let (y0, y1) = (
                (p[1] - outer).floor().max(0.0),
                (p[1] + outer).ceil().min(height as f64 - 1.0),
            );
            if !(x0 <= x1 && y0 <= y1) {
                return None;
            }
            let (mut core, mut nc, mut ring, mut nr) = (0.0, 0usize, 0.0, 0usize);
            let (mut inner, mut ni) = (0.0, 0usize);
            let (mut side, mut axis, mut magnitude) = ([0.0f64; 2], [0.0f64; 2], 0.0f64);
            for y in y0 as usize..=y1 as usize {
                let dy = y as f64 - p[1];
                for x in x0 as usize..=x1 as usize {
                    let dx = x as f64 - p[0];
                    let d2 = dx * dx + dy * dy;
                    if d2 <= radius2 {
                        let v = f64::from(signal[y * width + x]);
                        core += v;
                        nc += 1;
                        if 4.0 * d2 <= radius2 {
                            inner += v;
                            ni += 1;
                        }
                    } else if d2 > inner2
                        && d2 <= outer2
                        && others
                            .iter()
                            .all(|q| (x as f64 - q[0]).powi(2) + (y as f64 - q[1]).powi(2) > d2)
                    {
                        let v = f64::from(signal[y * width + x]);
                        ring += v;
                        nr += 1;
                        let d = d2.sqrt();
                        side[0] += v * dx / d;
                        side[1] += v * dy / d;
                        // cos 2θ and sin 2θ of the pixel's direction from the point.
                        axis[0] += v * (dx * dx - dy * dy) / d2;
                        axis[1] += v * 2.0 * dx * dy / d2;
                        magnitude += v.abs();
                    }
                }
            }
            if nc == 0 || nr == 0 || core <= 0.0 {
                return None;
            }
            Some(Skirt {
                level: (ring / nr as f64) / (core / nc as f64),
                lopsided: if magnitude > 0.0 {
                    side[0].hypot(side[1]) / magnitude
                } else {
                    0.0
                },
                elongated: if magnitude > 0.0 {
                    axis[0].hypot(axis[1]) / magnitude
                } else {
                    0.0
                },
                magnitude: (magnitude / nr as f64 - noise_sigma * std::f64::consts::FRAC_2_PI.sqrt())
                    .max(0.0)
                    / (core / nc as f64),
                inner: if ni > 0 {
                    (inner / ni as f64) / (core / nc as f64)
                } else {
                    1.0
                },
                rim: None,
                point_error: 0.0,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame of flat discs of `radius` (px), contrast 100, at `centres`.
    fn discs(width: usize, height: usize, centres: &[[f64; 2]], radius: f64) -> Vec<f32> {
        let mut img = vec![0f32; width * height];
        for (i, v) in img.iter_mut().enumerate() {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            if centres.iter().any(|c| (x - c[0]).hypot(y - c[1]) <= radius) {
                *v = 100.0;
            }
        }
        img
    }

    #[test]
    fn the_skirt_is_small_at_the_right_radius_and_large_on_parts_of_a_larger_disc() {
        let centres = [[30.0, 30.0], [50.0, 30.0]];
        let img = discs(80, 60, &centres, 9.0);
        // At the discs' own radius, touching neighbours at 20 px do not count.
        for s in skirts(&img, 80, 60, &centres, 9.0, 0.0) {
            assert!(s.unwrap().level < 0.01, "{s:?}");
        }
        // Parts of the discs at 3.7 px: the rest of each disc lies in the ring.
        let parts = [[26.0, 30.0], [50.0, 33.0]];
        for s in skirts(&img, 80, 60, &parts, 3.7, 0.0) {
            assert!(s.unwrap().level > 0.3, "{s:?}");
        }
    }

    #[test]
    fn a_gaussian_spot_has_an_even_skirt_and_a_rings_rim_a_lopsided_one() {
        // A Gaussian spot of half-maximum radius 20 px, followed at 17.4 px (0.87 of it):
        // a large skirt, all round; it must pass. A ring (radii 13.5-19 px) followed on its
        // rim at 5 px: a skirt as large, to one side; it must be caught.
        let (w, h) = (160usize, 160usize);
        let spot: Vec<f32> = (0..w * h)
            .map(|i| {
                let r = ((i % w) as f64 - 80.0).hypot((i / w) as f64 - 80.0);
                (100.0 * 0.5f64.powf((r / 20.0).powi(2))) as f32
            })
            .collect();
        let s = skirts(&spot, w, h, &[[80.0, 80.0]], 17.4, 0.0)[0].unwrap();
        assert!(s.level > LOPSIDED_SKIRT && s.level < MAX_SKIRT, "{s:?}");
        assert!(s.lopsided < 0.05, "{s:?}");
        let ring: Vec<f32> = (0..w * h)
            .map(|i| {
                let r = ((i % w) as f64 - 80.0).hypot((i / w) as f64 - 80.0);
                if (13.5..=19.0).contains(&r) {
                    100.0
                } else {
                    0.0
                }
            })
            .collect();
        let s = skirts(&ring, w, h, &[[96.0, 80.0]], 5.0, 0.0)[0].unwrap();
        assert!(s.level > LOPSIDED_SKIRT && s.lopsided > MAX_LOPSIDED, "{s:?}");
        let t = TrackTable {
            points: (0..4).map(|k| TrackPoint::new(k, "r", 96.0, 80.0)).collect(),
        };
        let measured = BTreeMap::from([("r".to_string(), vec![(0, s)])]);
        assert_eq!(check_tracks(&t, 5.0, &measured, &measured, &[]).len(), 1);
    }

    /// A ring of radii 14-20 px followed on its rim at 3.1 px: the rim runs through the point,
    /// about as much on either side (not lopsided enough to be caught), but along one line:
    /// caught by its elongation. A ring below the background round a point (a particle left
    /// in the background) is caught as one above it is, and one half above and half below it
    /// by its magnitude; a centred disc is not.
    #[test]
    fn a_track_on_a_large_rings_rim_and_one_in_a_dark_ring_are_reported() {
        let (w, h) = (120usize, 120usize);
        let ring: Vec<f32> = (0..w * h)
            .map(|i| {
                let r = ((i % w) as f64 - 60.0).hypot((i / w) as f64 - 60.0);
                if (14.0..=20.0).contains(&r) {
                    100.0
                } else {
                    0.0
                }
            })
            .collect();
        let s = skirts(&ring, w, h, &[[77.0, 60.0]], 3.1, 0.0)[0].unwrap();
        assert!(s.level > LOPSIDED_SKIRT && s.level < MAX_SKIRT, "{s:?}");
        assert!(s.lopsided < MAX_LOPSIDED && s.elongated > MAX_ELONGATED, "{s:?}");
        let t = TrackTable {
            points: (0..4).map(|k| TrackPoint::new(k, "r", 77.0, 60.0)).collect(),
        };
        let measured = BTreeMap::from([("r".to_string(), vec![(0, s)])]);
        assert_eq!(check_tracks(&t, 3.1, &measured, &measured, &[]).len(), 1);
        // A disc of 6 px, with the ring from 9 to 14 px 80 grey levels below the background on one side.
        let dark: Vec<f32> = (0..w * h)
            .map(|i| {
                let (dx, dy) = ((i % w) as f64 - 60.0, (i / w) as f64 - 60.0);
                let r = dx.hypot(dy);
                if r <= 6.0 {
                    100.0
                } else if (9.0..=14.0).contains(&r) && dx > 0.0 {
                    -80.0
                } else {
                    0.0
                }
            })
            .collect();
        let s = skirts(&dark, w, h, &[[60.0, 60.0]], 6.0, 0.0)[0].unwrap();
        assert!(s.level < -LOPSIDED_SKIRT && s.lopsided > MAX_LOPSIDED, "{s:?}");
        let measured = BTreeMap::from([("r".to_string(), vec![(0, s)])]);
        assert_eq!(check_tracks(&t, 6.0, &measured, &measured, &[]).len(), 1);
        // The same ring 60 grey levels above the background on one side and below it on the
        // other: its mean cancels, its magnitude does not.
        let split: Vec<f32> = dark
            .iter()
            .enumerate()
            .map(|(i, &v)| match v {
                v if v < 0.0 => -60.0,
                v if v > 50.0 => v,
                _ => {
                    let (dx, dy) = ((i % w) as f64 - 60.0, (i / w) as f64 - 60.0);
                    if (9.0..=14.0).contains(&dx.hypot(dy)) {
                        60.0
                    } else {
                        0.0
                    }
                }
            })
            .collect();
        let s = skirts(&split, w, h, &[[60.0, 60.0]], 6.0, 0.0)[0].unwrap();
        assert!(
            s.level.abs() < 0.05 && s.magnitude > 0.4 && s.lopsided > MAX_LOPSIDED,
            "{s:?}"
        );
        let measured = BTreeMap::from([("r".to_string(), vec![(0, s)])]);
        assert_eq!(check_tracks(&t, 6.0, &measured, &measured, &[]).len(), 1);
        let disc: Vec<f32> = dark.iter().map(|v| v.max(0.0)).collect();
        let s = skirts(&disc, w, h, &[[60.0, 60.0]], 6.0, 0.0)[0].unwrap();
        assert!(s.level.abs() < 0.01 && s.elongated < 0.01, "{s:?}");
        let measured = BTreeMap::from([("r".to_string(), vec![(0, s)])]);
        assert!(check_tracks(&t, 6.0, &measured, &measured, &[]).is_empty());
    }

    #[test]
    fn a_larger_particle_and_one_detected_in_under_half_its_frames_are_reported() {
        let mut t = TrackTable {
            points: (0..20).map(|k| TrackPoint::new(k, "a", k as f64, 0.0)).collect(),
        };
        let even = |level: f64| Skirt {
            level,
            lopsided: 0.0,
            elongated: 0.0,
            magnitude: level,
            inner: 1.0,
            rim: None,
            point_error: 0.0,
        };
        let mut skirts = BTreeMap::new();
        skirts.insert(
            "a".to_string(),
            vec![(0, even(0.1)), (5, even(0.9)), (10, even(0.7))],
        );
        let c = check_tracks(&t, 4.0, &skirts, &skirts, &[]);
        assert_eq!(c.len(), 1);
        assert!(matches!(c[0].concern, Concern::Larger { skirt, .. } if (skirt - 0.7).abs() < 1e-12));
        assert!(
            c[0].to_string().starts_with("a: its signal reaches well beyond"),
            "{}",
            c[0]
        );
        skirts.insert(
            "a".to_string(),
            vec![(0, even(0.1)), (5, even(0.9)), (10, even(0.05))],
        );
        assert!(check_tracks(&t, 4.0, &skirts, &skirts, &[]).is_empty());
        for p in t.points.iter_mut().skip(9) {
            p.flag = PointFlag::Interpolated;
        }
        assert_eq!(
            check_tracks(&t, 4.0, &skirts, &skirts, &[]),
            vec![TrackConcern {
                particle: "a".into(),
                concern: Concern::MostlyUnseen {
                    detected: 9,
                    frames: 20
                }
            }]
        );
        t.points[9].flag = PointFlag::Detected;
        assert!(check_tracks(&t, 4.0, &skirts, &skirts, &[]).is_empty());
    }

    /// Whether `c` is one [`Concern::OffRim`] and nothing else.
    fn only_off_rim(c: &[TrackConcern]) -> bool {
        matches!(
            c,
            [TrackConcern {
                concern: Concern::OffRim { .. },
                ..
            }]
        )
    }

    /// A ring whose located points scatter about its rim's centre far more than the rim's and
    /// the points' own errors allow (offsets of 0.5 px in every direction, errors 0.05 px) is
    /// reported; one whose points keep a steady offset within their errors (a centroid
    /// leaning with the light) is not, nor one hollow in under half its frames.
    #[test]
    fn a_ring_whose_points_scatter_about_its_rim_is_reported() {
        let t = TrackTable {
            points: (0..8).map(|k| TrackPoint::new(k, "r", 50.0, 50.0)).collect(),
        };
        let with_rim = |k: usize, offset: [f64; 2]| {
            (
                k,
                Skirt {
                    level: 0.0,
                    lopsided: 0.0,
                    elongated: 0.0,
                    magnitude: 0.0,
                    inner: 0.1,
                    rim: Some(Rim {
                        offset,
                        error: 0.03,
                        radius: 9.0,
                    }),
                    point_error: 0.04,
                },
            )
        };
        let scattered: Vec<(usize, Skirt)> = (0..8)
            .map(|k| {
                let a = k as f64 * 2.4;
                with_rim(k, [0.5 * a.cos(), 0.5 * a.sin()])
            })
            .collect();
        let measured = BTreeMap::from([("r".to_string(), scattered.clone())]);
        let c = check_tracks(&t, 9.0, &measured, &measured, &[]);
        assert!(only_off_rim(&c), "{c:?}");
        assert!(c[0].to_string().starts_with("r: it is a ring"), "{}", c[0]);
        let steady: Vec<(usize, Skirt)> = (0..8)
            .map(|k| with_rim(k, [0.3 + 0.04 * (k % 2) as f64, -0.2]))
            .collect();
        let measured = BTreeMap::from([("r".to_string(), steady)]);
        assert!(check_tracks(&t, 9.0, &measured, &measured, &[]).is_empty());
        let mut mostly_solid = scattered.clone();
        for s in mostly_solid.iter_mut().skip(3) {
            s.1.rim = None;
        }
        let measured = BTreeMap::from([("r".to_string(), mostly_solid)]);
        assert!(check_tracks(&t, 9.0, &measured, &measured, &[]).is_empty());
        // One frame of eight whose centroid a neighbour's light pulled 4.7 px off (the
        // rim's centre puts it right; ring neighbour 3001 at 14 px: a chi-square of 246 over
        // its degrees of freedom with the mean, refused) is not reported; pulls that way in
        // five of them, each a different way, are.
        let pulled = |n: usize| -> Vec<(usize, Skirt)> {
            (0..8)
                .map(|k| {
                    let a = k as f64 * 2.4;
                    let offset = if k < n {
                        [4.7 * a.cos(), 4.7 * a.sin()]
                    } else {
                        [0.3 + 0.04 * (k % 2) as f64, -0.2]
                    };
                    with_rim(k, offset)
                })
                .collect()
        };
        let measured = BTreeMap::from([("r".to_string(), pulled(1))]);
        assert!(check_tracks(&t, 9.0, &measured, &measured, &[]).is_empty());
        let measured = BTreeMap::from([("r".to_string(), pulled(5))]);
        let c = check_tracks(&t, 9.0, &measured, &measured, &[]);
        assert!(only_off_rim(&c), "{c:?}");
    }

    /// A point 10 px from the right edge of a light frame whose right part (x >= 25) is at
    /// 255: the ring from 5 to 9 px round it is partly clipped (the part right of it), and
    /// the track is named in a warning with that frame; a track whose rings hold no clipped
    /// pixel (and a point in a frame of 8-bit 254s) is not.
    #[test]
    fn particles_in_saturated_light_are_named() {
        let (w, h) = (40usize, 30usize);
        let samples: Vec<u8> = (0..w * h).map(|i| if i % w >= 25 { 255 } else { 200 }).collect();
        let frame = FrameView::Grey8 {
            samples: &samples,
            width: w,
            height: h,
        };
        let cut = clipped_ring(&frame, [20.0, 15.0], 4.0);
        assert!(cut > 0.2 && cut < 0.5, "{cut}");
        assert!(clipped_ring(&frame, [8.0, 15.0], 4.0).abs() < 1e-12);
        let lit: Vec<u8> = vec![254; w * h];
        let unclipped = FrameView::Grey8 {
            samples: &lit,
            width: w,
            height: h,
        };
        assert!(clipped_ring(&unclipped, [20.0, 15.0], 4.0).abs() < 1e-12);
        let mut clipping = BTreeMap::new();
        clipping.insert("a".to_string(), vec![(0, 0.0), (3, cut), (6, 0.01)]);
        clipping.insert("b".to_string(), vec![(0, 0.0), (3, 0.0)]);
        let warnings = saturated_edges(&clipping, 4.0);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].starts_with("a: the light round it is saturated in frames 3 (up to"),
            "{warnings:?}"
        );
    }

    /// A track of a class of radius 14 px on the points of one of radius 6 px (0.1 px off) in
    /// 5 of the 6 frames both were detected in follows that image: a concern on the first
    /// track. On it in one frame only (an overlap in view): a warning. The same points in one
    /// class, or 2 px apart: neither.
    #[test]
    fn two_classes_tracks_on_one_image_are_named() {
        let table = |on: &[usize], apart: f64, b_class: usize| {
            let mut points = Vec::new();
            for k in 0..6 {
                points.push(TrackPoint::new(k, "a", 20.0 + k as f64, 30.0));
                let x = if on.contains(&k) {
                    20.0 + k as f64 + apart
                } else {
                    80.0
                };
                points.push(TrackPoint::new(k, "b", x, 30.0));
            }
            let classes = if b_class == 0 {
                vec![(6.0, vec!["a".to_string(), "b".to_string()])]
            } else {
                vec![(6.0, vec!["a".to_string()]), (14.0, vec!["b".to_string()])]
            };
            shared_images(&TrackTable { points }, &classes)
        };
        let (concerns, warnings) = table(&[1, 2, 3, 4, 5], 0.1, 1);
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(concerns.len(), 1, "{concerns:?}");
        assert!(
            matches!(&concerns[0].concern, Concern::SharedImage { other, frames, both: 6, .. }
                if other == "b" && frames == &[1, 2, 3, 4, 5]),
            "{concerns:?}"
        );
        let text = concerns[0].to_string();
        assert!(
            text.starts_with("a: its points lie on b's (within 0.10 px) in 5 of the 6 frames"),
            "{text}"
        );
        let (concerns, warnings) = table(&[3], 0.1, 1);
        assert!(concerns.is_empty(), "{concerns:?}");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].starts_with("a: its points lie on b's") && warnings[0].contains("frames 3"),
            "{warnings:?}"
        );
        assert_eq!(table(&[1, 2, 3, 4, 5], 0.1, 0), (Vec::new(), Vec::new()));
        assert_eq!(table(&[1, 2, 3, 4, 5], 2.0, 1), (Vec::new(), Vec::new()));
    }

    /// A track walking 1 px a frame across the middle of a 100 px frame with frames 5-7
    /// missing is lost inside the image; the same track near the border (it may have left
    /// and come back), one with no gap, and one with its gap bridged are not.
    #[test]
    fn a_particle_lost_in_the_middle_of_the_image_is_reported() {
        let track = |y: f64, missing: &[usize], bridged: bool| TrackTable {
            points: (0..12)
                .filter(|k| bridged || !missing.contains(k))
                .map(|k| {
                    let mut p = TrackPoint::new(k, "a", 40.0 + k as f64, y);
                    if missing.contains(&k) {
                        p.flag = PointFlag::Interpolated;
                    }
                    p
                })
                .collect(),
        };
        let lost = lost_inside(&track(50.0, &[5, 6, 7], false), 4.0, (100, 100), 11);
        assert_eq!(lost.len(), 1, "{lost:?}");
        assert!(
            matches!(lost[0].concern, Concern::LostInside { frames: (5, 7), .. }),
            "{lost:?}"
        );
        assert!(lost[0].to_string().contains("lost in frames 5-7"), "{}", lost[0]);
        assert!(lost_inside(&track(6.0, &[5, 6, 7], false), 4.0, (100, 100), 11).is_empty());
        assert!(lost_inside(&track(50.0, &[], false), 4.0, (100, 100), 11).is_empty());
        assert!(lost_inside(&track(50.0, &[5, 6, 7], true), 4.0, (100, 100), 11).is_empty());
        // Beside a neighbour (within 2 R + 2 before the gap) it may have been hidden by it.
        let mut beside = track(50.0, &[5, 6, 7], false);
        beside.points.push(TrackPoint::new(4, "b", 44.0, 56.0));
        assert!(lost_inside(&beside, 4.0, (100, 100), 11).is_empty());
        // Lost for good after frame 6 in the middle of the image, the window running to frame
        // 11: it vanished in view; near the border it may have left.
        let mut ends = track(50.0, &[], false);
        ends.points.retain(|p| p.frame <= 6);
        let lost = lost_inside(&ends, 4.0, (100, 100), 11);
        assert!(
            matches!(
                lost[..],
                [TrackConcern {
                    concern: Concern::Vanished { frames: (7, 11), .. },
                    ..
                }]
            ),
            "{lost:?}"
        );
        assert!(
            lost[0].to_string().contains("lost from frame 7 to the last, 11"),
            "{}",
            lost[0]
        );
        let mut leaves = track(6.0, &[], false);
        leaves.points.retain(|p| p.frame <= 6);
        assert!(lost_inside(&leaves, 4.0, (100, 100), 11).is_empty());
    }

    /// A track moving 1.5 px a frame that, lost for a frame, goes on 125 px away has left its
    /// particle, and says where, and so have one lost for 11 frames and found 124 px away at
    /// 1.2 px a frame, and one found after a gap on two images 39 px apart in consecutive
    /// frames; one lost for 8 frames and found on its motion, a thrown ball's bounce, a kick from rest, a frame lost from
    /// the recording and a random walk of 0.5-3 px a frame at a radius of 1.5 px have not.
    #[test]
    fn a_track_taking_another_image_far_off_jumped_and_motions_did_not() {
        let track = |at: &dyn Fn(usize) -> Option<[f64; 2]>| -> Vec<TrackPoint> {
            (0..16)
                .filter_map(|k| at(k).map(|p| TrackPoint::new(k, "p0".to_string(), p[0], p[1])))
                .collect()
        };
        let judged = |points: &[TrackPoint], radius: f64| {
            jumped(
                &points.iter().collect::<Vec<_>>(),
                radius,
                &FrameBlobs::new(&[], &[]),
            )
        };
        let taken = track(&|k| match k {
            0..=10 => Some([210.0 + 1.5 * k as f64, 100.0]),
            11 => None,
            _ => Some([108.0 + 0.5 * k as f64, 71.0 - 2.0 * k as f64]),
        });
        let concern = judged(&taken, 9.3);
        let Some(Concern::Jumped {
            frames, step, around, ..
        }) = concern.clone()
        else {
            panic!("{concern:?}");
        };
        assert_eq!(frames, (10, 12));
        assert!(
            (step - 61.5).abs() < 0.01 && (around - 2.06).abs() < 0.01,
            "{step} {around}"
        );
        let said = |concern: Option<Concern>| {
            TrackConcern {
                particle: "p0".into(),
                concern: concern.expect("a concern"),
            }
            .to_string()
        };
        let message = said(concern);
        assert!(message.contains("from frame 10 to frame 12"), "{message}");
        // The same, lost for two frames more: still a jump (its step per frame is 31 px).
        let later = track(&|k| match k {
            0..=10 => Some([210.0 + 1.5 * k as f64, 100.0]),
            11..=13 => None,
            _ => Some([108.0 + 0.5 * k as f64, 71.0 - 2.0 * k as f64]),
        });
        assert!(matches!(
            judged(&later, 9.3),
            Some(Concern::Jumped { frames: (10, 14), .. })
        ));
        // Moving 1.2 px a frame, lost for 11 frames and found again on another image 124 px
        // away: 10.3 px a frame, under the 17.4 px a frame the diameter alone allowed, but
        // over 12 frames the diameter counts once: a jump.
        let far = track(&|k| match k {
            0..=3 => Some([50.0 - 1.2 * k as f64, 72.0]),
            4..=14 => None,
            _ => Some([162.0, 117.0]),
        });
        let concern = judged(&far, 6.9);
        assert!(
            matches!(concern, Some(Concern::Jumped { frames: (3, 15), .. })),
            "{concern:?}"
        );
        let message = said(concern);
        assert!(message.contains("over 12 frames"), "{message}");
        // Moving 3 px a frame, lost for 8 frames and found where its motion puts it: none.
        let hidden = track(&|k| (!(6..=13).contains(&k)).then_some([3.0 * k as f64, 40.0]));
        assert_eq!(judged(&hidden, 2.0), None);
        // Moving 0.2-1.8 px a frame, lost for 11 frames, then found on two other images 39 px
        // apart in consecutive frames: that step has no consecutive neighbour, and the
        // nearest before it is 1.2 px a frame: a jump.
        let two_others = track(&|k| match k {
            0..=4 => Some([52.0 - 1.2 * k as f64, 72.0]),
            5..=13 => None,
            14 => Some([162.5, 117.4]),
            15 => Some([162.9, 78.6]),
            _ => None,
        });
        assert!(
            matches!(
                judged(&two_others, 6.9),
                Some(Concern::Jumped { frames: (14, 15), .. })
            ),
            "{:?}",
            judged(&two_others, 6.9)
        );
        // A ball of 5 px falling 17 px a frame at 30 frames/s, bouncing back at 15.
        let bounce = track(&|k| {
            let t = k as f64;
            Some([
                100.0,
                if k <= 8 {
                    17.0 * t
                } else {
                    136.0 - 15.0 * (t - 8.0)
                },
            ])
        });
        assert_eq!(judged(&bounce, 5.0), None);
        // At rest, then kicked to 20 px a frame.
        let kicked = track(&|k| Some([100.0 + 20.0 * k.saturating_sub(7) as f64, 50.0]));
        assert_eq!(judged(&kicked, 3.0), None);
        // 6 px a frame, frame 9 missing from the recording (a step of 12 px).
        let dropped = track(&|k| Some([6.0 * (k + usize::from(k >= 9)) as f64, 50.0]));
        assert_eq!(judged(&dropped, 2.0), None);
        // A random walk of 0.5-3 px a frame (turning by the golden angle) at a radius of 1.5 px.
        let walk = track(&|k| {
            let (mut x, mut y) = (50.0, 50.0);
            for j in 0..k {
                let (len, a) = (if j % 4 == 3 { 3.0 } else { 0.5 }, 2.4 * j as f64);
                x += len * a.cos();
                y += len * a.sin();
            }
            Some([x, y])
        });
        assert_eq!(judged(&walk, 1.5), None);
        // A bead jittering in a trap (radius 4 px), its first step 15.4 px, the next 2.1 and
        // the one after 6.0, alone in its frames: the first step is judged against the larger
        // of the two, as an interior step is against the larger of its two neighbours. With
        // another blob where it lands, or no frames to tell, against the one after it alone:
        // a jump. The same step between steps of 2.1 px is a jump, alone or not.
        use crate::link::tests::frame;
        // Steps of the given lengths, turning back and forth.
        let steps = |lengths: &[f64]| {
            track(&|k| {
                let x =
                    (lengths.iter().take(k).enumerate())
                        .fold(50.0, |x, (j, l)| if j % 2 == 0 { x + l } else { x - l });
                (k <= lengths.len()).then_some([x, 80.0])
            })
        };
        let with_blobs = |points: &[TrackPoint], other: Option<[f64; 2]>| {
            let frames: Vec<FrameDetections> = points
                .iter()
                .map(|p| {
                    frame(
                        p.frame,
                        &[[p.x, p.y]].into_iter().chain(other).collect::<Vec<_>>(),
                    )
                })
                .collect();
            let positions = FrameBlobs::positions(&frames);
            let blobs = FrameBlobs::new(&frames, &positions);
            jumped(&points.iter().collect::<Vec<_>>(), 4.0, &blobs)
        };
        let bead = steps(&[15.4, 2.1, 6.0, 4.0]);
        assert_eq!(with_blobs(&bead, None), None);
        assert!(matches!(
            with_blobs(&bead, Some([65.4, 81.0])),
            Some(Concern::Jumped { frames: (0, 1), .. })
        ));
        assert!(matches!(
            judged(&bead, 4.0),
            Some(Concern::Jumped { frames: (0, 1), .. })
        ));
        let between = steps(&[2.1, 2.1, 15.4, 2.1, 2.1]);
        assert!(matches!(
            with_blobs(&between, None),
            Some(Concern::Jumped { frames: (2, 3), .. })
        ));
    }

    /// A ball of 5 px thrown up and falling back at 30 frames/s (its step changing by 18 px a
    /// frame, a bounce in frame 6) is one particle, and so is one bouncing every 3 frames; a
    /// track hopping 20 px about a centre in turning directions is not, and says by how much.
    #[test]
    fn a_thrown_ball_is_smooth_and_a_track_hopping_about_is_erratic() {
        let track = |name: &str, at: &dyn Fn(usize) -> [f64; 2]| -> Vec<TrackPoint> {
            (0..12)
                .map(|k| {
                    let p = at(k);
                    TrackPoint::new(k, name.to_string(), p[0], p[1])
                })
                .collect()
        };
        let thrown = track("ball", &|k| {
            let t = k as f64;
            let y = 300.0 - 90.0 * t + 9.0 * t * t;
            [
                100.0 + 12.0 * t,
                if k < 6 {
                    y
                } else {
                    2.0 * (300.0 - 90.0 * 6.0 + 9.0 * 36.0) - y
                },
            ]
        });
        let points: Vec<&TrackPoint> = thrown.iter().collect();
        assert_eq!(erratic(&points, 5.0, &FrameBlobs::new(&[], &[])), None);
        // A ball of 5 px on a vibrating floor, bouncing 6 px high every 3 frames (at 9 px a
        // frame): the change of its step jumps by 18 px at every bounce, always vertically.
        let bouncing = track("bouncer", &|k| {
            let t = (k % 3) as f64;
            [100.0 + 0.5 * k as f64, 200.0 - (9.0 * t - 3.0 * t * t)]
        });
        let points: Vec<&TrackPoint> = bouncing.iter().collect();
        assert_eq!(erratic(&points, 5.0, &FrameBlobs::new(&[], &[])), None);
        // Hops 20 px from a centre, each turned by the golden angle from the last.
        let hopping = track("hopper", &|k| {
            let a = 2.4 * k as f64;
            [100.0 + 20.0 * a.cos() + k as f64, 100.0 + 20.0 * a.sin()]
        });
        let points: Vec<&TrackPoint> = hopping.iter().collect();
        let Some(Concern::Erratic { jerk, count, .. }) = erratic(&points, 5.0, &FrameBlobs::new(&[], &[]))
        else {
            panic!("a track hopping 20 px about a centre is erratic");
        };
        assert!(
            jerk > 12.0 && count == 9,
            "median third difference {jerk:.1} px over {count}"
        );
    }

    /// A random walk of 3 px steps (a small particle in Brownian motion, its step's change
    /// changing by more than its diameter and 2 px) is no hopping where no other blob is
    /// near, but a track taking blobs that come and go about one place is; a track taking three blobs 12 px apart in turn (A B C A A C B B ...) hops,
    /// and says how many of its steps did.
    #[test]
    fn a_walk_alone_is_not_erratic_and_a_track_taking_blobs_in_turn_is() {
        use crate::link::tests::frame;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let walk: Vec<[f64; 2]> = (0..24)
            .scan([100.0, 100.0], |p, _| {
                let a: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
                *p = [p[0] + 3.0 * a.cos(), p[1] + 3.0 * a.sin()];
                Some(*p)
            })
            .collect();
        let far = |k: usize| [160.0 + k as f64, 40.0];
        let frames: Vec<FrameDetections> = walk
            .iter()
            .enumerate()
            .map(|(k, p)| frame(k, &[*p, far(k)]))
            .collect();
        let points: Vec<TrackPoint> = walk
            .iter()
            .enumerate()
            .map(|(k, p)| TrackPoint::new(k, "w", p[0], p[1]))
            .collect();
        let refs: Vec<&TrackPoint> = points.iter().collect();
        let positions = FrameBlobs::positions(&frames);
        let blobs = FrameBlobs::new(&frames, &positions);
        assert_eq!(erratic(&refs, 1.5, &blobs), None);
        // Judged without the blobs, the walk is taken for hops.
        assert!(erratic(&refs, 1.5, &FrameBlobs::new(&[], &[])).is_some());
        // Blobs that come and go at random within 20 px of one place (clutter), each the only
        // blob near when the track takes it: no blob to hop from, but no walk either.
        let visits: Vec<[f64; 2]> = (0..24)
            .map(|_| {
                [
                    100.0 + rng.gen_range(-20.0..20.0),
                    100.0 + rng.gen_range(-20.0..20.0),
                ]
            })
            .collect();
        let frames: Vec<FrameDetections> = visits
            .iter()
            .enumerate()
            .map(|(k, p)| frame(k, &[*p, far(k)]))
            .collect();
        let points: Vec<TrackPoint> = (visits.iter().enumerate())
            .map(|(k, p)| TrackPoint::new(k, "c", p[0], p[1]))
            .collect();
        let refs: Vec<&TrackPoint> = points.iter().collect();
        let positions = FrameBlobs::positions(&frames);
        let blobs = FrameBlobs::new(&frames, &positions);
        assert!(matches!(
            erratic(&refs, 1.5, &blobs),
            Some(Concern::Erratic {
                hops: Some((0, _)),
                ..
            })
        ));
        let site = |k: usize, t: usize| {
            let a = 2.1 * t as f64;
            [110.0 + 0.5 * k as f64 + 7.0 * a.cos(), 100.0 + 7.0 * a.sin()]
        };
        let turns = [0, 1, 2, 0, 0, 2, 1, 1, 0, 2, 1, 0, 0, 1, 2, 2];
        let frames: Vec<FrameDetections> = (0..16)
            .map(|k| frame(k, &[site(k, 0), site(k, 1), site(k, 2), far(k)]))
            .collect();
        let points: Vec<TrackPoint> = turns
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let p = site(k, t);
                TrackPoint::new(k, "h", p[0], p[1])
            })
            .collect();
        let refs: Vec<&TrackPoint> = points.iter().collect();
        let positions = FrameBlobs::positions(&frames);
        let blobs = FrameBlobs::new(&frames, &positions);
        let Some(Concern::Erratic { hops, .. }) = erratic(&refs, 1.5, &blobs) else {
            panic!("a track taking three blobs in turn is erratic");
        };
        // 11 of the 15 steps change blob, each landing on one that was there the frame before.
        assert_eq!(hops, Some((11, 15)));
    }

    /// A bead jittering about one place (iid offsets of 2 px per axis, radius 1.5 px) neither
    /// hops onto other blobs nor walks away: its image keeping its mass (2 % changes), it is
    /// one object; the same places taken by images of masses changing 2.5 times over are
    /// clutter, and the track is erratic.
    #[test]
    fn a_bead_jittering_in_a_trap_keeps_its_mass_and_clutter_does_not() {
        use crate::link::tests::frame;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut gauss = || {
            let (u, v): (f64, f64) = (1.0 - rng.gen::<f64>(), rng.gen());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let places: Vec<[f64; 2]> = (0..24)
            .map(|_| [100.0 + 2.0 * gauss(), 100.0 + 2.0 * gauss()])
            .collect();
        let frames: Vec<FrameDetections> = places
            .iter()
            .enumerate()
            .map(|(k, p)| frame(k, &[*p, [160.0 + k as f64, 40.0]]))
            .collect();
        let positions = FrameBlobs::positions(&frames);
        let blobs = FrameBlobs::new(&frames, &positions);
        let track = |mass: &dyn Fn(usize) -> f64| -> Vec<TrackPoint> {
            (places.iter().enumerate())
                .map(|(k, p)| TrackPoint {
                    mass: mass(k),
                    ep: 0.05,
                    ..TrackPoint::new(k, "b", p[0], p[1])
                })
                .collect()
        };
        let bead = track(&|k| 1000.0 * (1.0 + 0.02 * ((k % 3) as f64 - 1.0)));
        let refs: Vec<&TrackPoint> = bead.iter().collect();
        assert!(keeps_its_mass(&refs, 1.5));
        assert_eq!(erratic(&refs, 1.5, &blobs), None);
        let clutter = track(&|k| if k % 2 == 0 { 1000.0 } else { 400.0 });
        let refs: Vec<&TrackPoint> = clutter.iter().collect();
        assert!(!keeps_its_mass(&refs, 1.5));
        assert!(erratic(&refs, 1.5, &blobs).is_some());
    }
}
