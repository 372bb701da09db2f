//! The per-pixel background taken again without the named tracks, while it steadies them.

use super::size_class::{exclusion_reach, largest_radius, light_reach, SizeClass};
use super::stage::Pass;
use crate::scale::{self, ScaleBlob};
use crate::{Background, BackgroundModel, FrameView, SampleExposure, TrackPoint, TrackTable};
use std::collections::HashMap;

/// Most rounds of excluding named particles from the per-pixel median and measuring them
/// again.
pub(super) const EXCLUSION_ROUNDS: usize = 4;
/// Relative change of the largest radius at which those rounds stop.
pub(super) const SETTLED_SIZE: f64 = 0.05;

/// A named particle whose scale-space answer against a flat level is this many times its
/// answer against the per-pixel median hovers in that median.
const HOVER_RATIO: f64 = 1.5;

/// The starts of the named particles that hover in the per-pixel median: the strongest
/// scale-space answer holding the start ([`scale::holding`]) in the first sample's scan
/// against a flat level (`flat_scan`, see [`first_frame_scan`]) is more than [`HOVER_RATIO`]
/// times its answer in the scan against the median (`median_scan`), or the median shows
/// nothing there. A particle that moves shows
/// whole against both; one that stays put is half or wholly in the median and shows only its
/// leading and trailing edges against it.
pub(super) fn hovering_starts(
    median_scan: &[ScaleBlob],
    flat_scan: &[ScaleBlob],
    starts: &[[f64; 2]],
) -> Vec<[f64; 2]> {
    let (against_median, against_flat) = (
        scale::holding(median_scan, starts),
        scale::holding(flat_scan, starts),
    );
    starts
        .iter()
        .zip(against_median.iter().zip(&against_flat))
        .filter(|(_, (m, f))| match (m, f) {
            (_, None) => false,
            (None, Some(_)) => true,
            (Some(m), Some(f)) => f.peak > HOVER_RATIO * m.peak,
        })
        .map(|(s, _)| *s)
        .collect()
}

/// The per-pixel `background` taken again with every track of `pass` left out of each
/// sample (within the `classes`' [`exclusion_reach`] of its point there, each sample on the
/// background's exposure) and the pixels no sample shows clear filled from around them (an
/// unevenly lit surface's light read where their [`light_reach`] leaves the frame clear: see
/// [`Background::exclude_particles`]); `None` when it would not
/// matter: a background not per-pixel, a pass with concerns other than skirts, no tracked
/// point in a sample whose centroid (over the largest radius) the change would move by half its own
/// standard error, or (for a pass without concerns) masses it would not make steadier by
/// [`STEADIER`].
pub(super) fn background_without_tracks(
    background: &Background,
    samples: &[FrameView<'_>],
    gains: &SampleGains,
    pass: &Pass,
    classes: &[SizeClass],
    blind_search: Option<(f32, usize)>,
) -> Option<Background> {
    let radius = largest_radius(classes);
    // Concerns other than a skirt say the tracks themselves went astray (fresh 6509: a jump
    // of 44.5 px in two frames; taken out of the median, the track's wrong points let the
    // second pass through without a concern, 0.52 px off against 0.10).
    if background.model != BackgroundModel::PerPixel
        || pass.table.points.is_empty()
        || pass.concerns.iter().any(|c| !c.skirt)
    {
        return None;
    }
    let mut at: Vec<Vec<[f64; 2]>> = vec![Vec::new(); samples.len()];
    let mut points: Vec<(usize, &TrackPoint)> = Vec::new();
    for p in &pass.table.points {
        if let Some(j) = gains.sample(p.frame) {
            at[j].push([p.x, p.y]);
            points.push((j, p));
        }
    }
    // A sample a track holds no point in (its particle cut by the border and not written,
    // or before its first point and after its last) still holds the particle: it is left
    // out there too, where the track's points either side put it, or its nearest point.
    // Counted clear, three such samples made a median of their own particle (fresh style
    // 6237, a disc of 34.5 px near the border in frames 11, 13 and 14: 90 grey levels where
    // the background is 12, and the disc followed 12 px off its centre).
    for track in pass.table.by_particle().values() {
        let held: std::collections::HashSet<usize> = track.iter().map(|p| p.frame).collect();
        for (&frame, &(j, _)) in &gains.by_frame {
            if let Some(p) = position_at(track, frame).filter(|_| !held.contains(&frame)) {
                at[j].push(p);
            }
        }
    }
    let everywhere: Vec<[f64; 2]> = at.iter().flatten().copied().collect();
    let mut cleaner = background.clone();
    cleaner.exclude_particles(
        samples,
        &at,
        &everywhere,
        exclusion_reach(classes),
        light_reach(classes),
        SampleExposure::Matched,
    );
    // Structure as bright as the particles may have been a particle in the median.
    if let Some((contrast, blind_reach)) = blind_search {
        cleaner.find_blind(contrast, blind_reach);
    }
    // What the change does to each point's mass and centroid, read off the two backgrounds
    // without locating again: it matters when some centroid moves by half its standard
    // error and the masses come out steadier by a tenth at least ([`STEADIER`]).
    let mut predicted = pass.table.clone();
    let mut moves = false;
    for (point, (_, p)) in predicted
        .points
        .iter_mut()
        .filter(|q| gains.sample(q.frame).is_some())
        .zip(&points)
    {
        let (mass, moment) = signal_change(background, &cleaner, [p.x, p.y], radius);
        moves |= p.mass.is_finite() && p.mass > 0.0 && moment / p.mass > 0.5 * p.ep.max(1e-3);
        point.mass += mass;
    }
    // A pass whose skirts reach beyond the radius would be refused: the particles it tracks
    // may be what its median holds (sweep style 1033: a dot hovering for ten of its fifteen frames, its skirt 26 %
    // of its level against that median, the masses predicted steadier by only 8 %, measured
    // 0.23 -> 0.063 once located again, and then followed 0.026 px off). Whether the tracks
    // were right is then judged on the frames located again, which must raise no concern.
    let steadier = || mass_spread(&predicted, gains) < (1.0 - STEADIER) * mass_spread(&pass.table, gains);
    let matters = moves && (!pass.concerns.is_empty() || steadier());
    matters.then_some(cleaner)
}

/// Where a track (its points in frame order) puts its particle in `frame`: linearly between
/// its points either side, or at its nearest point before its first or after its last, px;
/// `None` for a track without points.
fn position_at(track: &[&TrackPoint], frame: usize) -> Option<[f64; 2]> {
    let after = track.partition_point(|p| p.frame < frame);
    match (after.checked_sub(1).map(|i| track[i]), track.get(after).copied()) {
        (Some(a), Some(b)) => {
            let f = (frame - a.frame) as f64 / (b.frame - a.frame) as f64;
            Some([a.x + f * (b.x - a.x), a.y + f * (b.y - a.y)])
        }
        (Some(p), None) | (None, Some(p)) => Some([p.x, p.y]),
        (None, None) => None,
    }
}

/// How much steadier the masses must come out of a background taken without the tracks for
/// every frame to be located again: on the real bouncing ball they came out 0.3 % steadier,
/// the points moved 0.05 px at most, and the second pass cost 42 % more time; where the
/// particle is in the median they come out 30 % to 99 % steadier (sweep styles 1003,
/// 1030, 1038).
const STEADIER: f64 = 0.1;

/// Each sample frame's place among the samples and its exposure gain (its
/// [`Background::frame_gain`] over the samples' [`Background::reference_gain`]), by frame
/// number.
pub(super) struct SampleGains {
    by_frame: HashMap<usize, (usize, f64)>,
}

impl SampleGains {
    /// The gains of `samples` against `background`; `sample_of[i]` is the sample that holds
    /// frame `numbers[i]`, if one does. Where the exposure saturates the background, every
    /// gain is 1: the particles' light against clipped pixels does not follow the gain.
    pub(super) fn measure(
        background: &Background,
        samples: &[FrameView<'_>],
        sample_of: &[Option<usize>],
        numbers: &[usize],
    ) -> Self {
        let saturates = background.exposure_saturates();
        let gain = |j: usize| {
            if saturates {
                1.0
            } else {
                background.frame_gain(samples[j]) / background.reference_gain
            }
        };
        let by_frame = numbers
            .iter()
            .zip(sample_of)
            .filter_map(|(&k, j)| j.map(|j| (k, (j, gain(j)))))
            .collect();
        Self { by_frame }
    }

    /// The exposure gain of frame `frame`, if a sample holds it.
    pub(super) fn gain(&self, frame: usize) -> Option<f64> {
        self.by_frame.get(&frame).map(|&(_, g)| g)
    }

    /// The sample that holds frame `frame`, if one does.
    fn sample(&self, frame: usize) -> Option<usize> {
        self.by_frame.get(&frame).map(|&(j, _)| j)
    }
}

/// The mean over `table`'s tracks of the relative spread (standard deviation over mean) of
/// their masses in the sample frames, each mass divided by its frame's exposure gain; 0
/// without any track holding two such points.
///
/// A particle's mass follows the exposure (the light it reflects or gives off is exposed
/// with the background's), so only over a steady exposure does a steady mass mean a clean
/// background. Fresh style 6248 (two dark Gaussian spots of 3.9 px hovering under an
/// exposure drifting by ±8 %): taken without the tracks, the background made the plain
/// masses less steady (0.046 -> 0.053) but the masses on the frames' exposure three times
/// steadier (0.047 -> 0.015), and the spots, partly in the median, were followed 0.68 / 0.61
/// px off their centres.
pub(super) fn mass_spread(table: &TrackTable, gains: &SampleGains) -> f64 {
    let spreads: Vec<f64> = table
        .by_particle()
        .values()
        .filter_map(|points| {
            let masses: Vec<f64> = points
                .iter()
                .filter_map(|p| gains.by_frame.get(&p.frame).map(|&(_, g)| p.mass / g))
                .filter(|m| m.is_finite())
                .collect();
            let n = masses.len() as f64;
            let mean = masses.iter().sum::<f64>() / n;
            let var = masses.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / n;
            (masses.len() >= 2 && mean.abs() > 0.0).then(|| var.sqrt() / mean.abs())
        })
        .collect();
    spreads.iter().sum::<f64>() / spreads.len().max(1) as f64
}

/// The change of a particle's signal from background `before` to `after`, over the disc of
/// `radius` px about `centre` (px) along the particles' colour direction: its sum (the change
/// of the particle's mass, grey levels · px²) and the length of its first moment about
/// `centre` (grey levels · px³; divided by the mass, how far the change moves the
/// centroid, px).
fn signal_change(before: &Background, after: &Background, centre: [f64; 2], radius: f64) -> (f64, f64) {
    let (w, h, c) = (before.width, before.height, before.channels);
    let (x0, x1) = (
        (centre[0] - radius).floor().max(0.0) as usize,
        ((centre[0] + radius).ceil().max(0.0) as usize).min(w.saturating_sub(1)),
    );
    let (y0, y1) = (
        (centre[1] - radius).floor().max(0.0) as usize,
        ((centre[1] + radius).ceil().max(0.0) as usize).min(h.saturating_sub(1)),
    );
    let (mut sum, mut moment) = (0.0, [0.0f64; 2]);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (dx, dy) = (x as f64 - centre[0], y as f64 - centre[1]);
            if dx * dx + dy * dy > radius * radius {
                continue;
            }
            let i = (y * w + x) * c;
            let change: f64 = (0..c)
                .map(|ch| f64::from(before.direction[ch] * (before.image[i + ch] - after.image[i + ch])))
                .sum();
            sum += change;
            moment[0] += change * dx;
            moment[1] += change * dy;
        }
    }
    (sum, moment[0].hypot(moment[1]))
}

#[cfg(test)]
mod tests {
    use super::{mass_spread, position_at, SampleGains};
    use crate::{TrackPoint, TrackTable};

    /// Masses that follow their frames' exposure gains exactly are steady; the same masses
    /// read plainly are not, and points in frames no sample holds are not counted.
    #[test]
    fn masses_are_compared_on_their_frames_exposure() {
        let gains = [1.0, 1.08, 0.93, 1.12, 0.9];
        let sampled = SampleGains {
            by_frame: (0..gains.len()).map(|k| (2 * k, (k, gains[k]))).collect(),
        };
        let plain = SampleGains {
            by_frame: (0..gains.len()).map(|k| (2 * k, (k, 1.0))).collect(),
        };
        let table = |mass: &dyn Fn(usize) -> f64| TrackTable {
            points: (0..2 * gains.len())
                .map(|frame| {
                    let mut p = TrackPoint::new(frame, "p0", 10.0, 10.0);
                    // Odd frames are not samples: a mass there would spoil any spread.
                    p.mass = if frame % 2 == 0 { mass(frame) } else { 1e6 };
                    p
                })
                .collect(),
        };
        let following = table(&|frame| 250.0 * gains[frame / 2]);
        assert!(mass_spread(&following, &sampled) < 1e-12);
        let mean = gains.iter().sum::<f64>() / gains.len() as f64;
        let sd = (gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / gains.len() as f64).sqrt();
        let plain_spread = mass_spread(&following, &plain);
        assert!(
            (plain_spread - sd / mean).abs() < 1e-12,
            "{plain_spread} against {}",
            sd / mean
        );
        let steady = table(&|_| 250.0);
        assert!(mass_spread(&steady, &sampled) > 0.05);
    }

    /// Between two points the position is interpolated by frame; before the first and after
    /// the last it is the nearest point.
    #[test]
    fn a_track_puts_its_particle_between_its_points_and_at_its_ends() {
        let points = [
            TrackPoint::new(2, "p0", 10.0, 20.0),
            TrackPoint::new(6, "p0", 30.0, 0.0),
        ];
        let track: Vec<&TrackPoint> = points.iter().collect();
        let near = |frame: usize, want: [f64; 2]| {
            let got = position_at(&track, frame).expect("a track with points");
            assert!(
                (got[0] - want[0]).abs() < 1e-12 && (got[1] - want[1]).abs() < 1e-12,
                "{frame}: {got:?}"
            );
        };
        near(3, [15.0, 15.0]);
        near(0, [10.0, 20.0]);
        near(9, [30.0, 0.0]);
        near(6, [30.0, 0.0]);
        assert_eq!(position_at(&[], 3), None);
    }
}
