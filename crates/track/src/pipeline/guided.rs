//! Named particles the detector missed, searched for where their motion puts them.
//!
//! The detector looks for particles anywhere in a frame, so its threshold (five noise sigmas
//! of its band-pass answer) guards every pixel at once, and a band-pass keeps only part of a
//! small particle's light: sweep style 1025 (shaded spheres of 2.42 px at noise 23, seven in
//! a frame of 58 x 58 px) stands about 21 grey levels high in the band-pass, the threshold
//! 21.4, and four of its seven named particles were bridged in half their frames or lost,
//! refused. A named track knows where its particle is to within a few pixels in the frames
//! it was missed in: between two located points, or just past its last one. There the
//! question is narrower, "is the particle here", and asked over a few dozen positions
//! instead of a frame's thousands.
//!
//! The statistic is the particle's signal summed over a disc of its radius (the matched
//! filter of a flat disc) at each whole-pixel centre within the track's largest step
//! (plus its radius) of the predicted position. Its noise is measured in the same frame,
//! as the robust spread of the same disc sum over a grid of positions clear of every
//! particle and detection: it holds the pixel noise however correlated, and whatever the
//! background model left of the light. The particle counts as found where the largest
//! sum stands above the grid's median by a normal quantile of [`FALSE_ALARMS`] shared
//! (Bonferroni) over every position searched in the recording, and holds between a quarter
//! and four times the track's usual mass. It is then located by the centroid as detections
//! are. A particle predicted within two radii of another particle's point or of a
//! detection is not searched (it overlaps them; a dense crossing of discs of 4 px had one
//! found between itself and a neighbour 4.1 px away, 2.7 px off and named after the
//! neighbour). Positions within two radii of another particle's located point or of any
//! detection are not searched (their light is theirs), nor those nearer another missed
//! particle's prediction than to the track's own, nor is a point the shared-blob fit placed
//! from the image (`crate::shared_blobs`; in fresh style 6353, noise 0.5, the search's
//! centroids beside a neighbour were 0.9-1.7 px off where the fit had 0.03-0.08). A
//! track's end is searched frame by frame for [`TAIL_FRAMES`] frames past its last located
//! point, its gate widening by its largest step each frame missed.
//!
//! Found points are flagged detected and listed as `Faint` ambiguity runs, and each
//! particle with any is named in a warning with their frames and heights: at low signal a
//! found point can lie farther off than the bridge it replaced (fresh style 10744, rings of
//! 1.76 px at noise 23: one point 1.9 px off, 3.3 times its error, where the bridge was
//! 0.35 px off).

use super::border::runs;
use super::stage::sort_in_structure_order;
use crate::locate::refine_centroids;
use crate::point_grid::PointGrid;
use crate::shared_blobs::SharedBlobs;
use crate::{Ambiguity, AmbiguityKind, FrameDetections, PointFlag, TrackError, TrackPoint, TrackTable};
use physfit_tracks::stats::{median, normal_upper_quantile, robust_spread};
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// The chance, over a whole recording, that noise alone is taken for a particle somewhere
/// in the search.
const FALSE_ALARMS: f64 = 0.01;
/// Frames past a track's last located point that are searched while the particle stays
/// unseen.
const TAIL_FRAMES: usize = 3;
/// Fewest background disc sums a frame's noise is measured from; with fewer (large
/// particles in a small frame) the frame is not searched.
const MIN_SAMPLES: usize = 30;
/// Most background disc sums measured in one frame (the grid is thinned beyond it).
const MAX_SAMPLES: usize = 2048;
/// Range of the found disc sum over the track's median located mass: a quarter to four
/// times (a faint particle's located points are its brighter frames).
const MASS_RANGE: (f64, f64) = (0.25, 4.0);

/// What the image showed of the particles before the search.
pub(super) struct Seen<'a> {
    /// Every frame's detections (frame `first` first).
    pub(super) located: &'a [FrameDetections],
    /// The particle and frame of each point placed from the image where particles shared a
    /// blob (`crate::shared_blobs`): located, though flagged interpolated.
    pub(super) placed: &'a BTreeSet<(String, usize)>,
}

/// One place to search: a named particle in a frame where it has no located point.
struct Slot {
    /// The particle's index in the structure's order.
    track: usize,
    /// Its predicted position, px.
    at: [f64; 2],
    /// Search radius about it, px.
    gate: f64,
}

/// Searches each named particle (`named`, in the structure's order) in the frames of
/// `first..=last` where its track has no located point (an interpolated point or none), near
/// where its motion puts it (see the module documentation), in the particle signal of
/// `image` (radius and window in px); not where `seen` says a point was placed from the
/// image where particles shared a blob. Found points replace the interpolated ones or are
/// added, flagged detected; the `Missing` and `Lost` runs of `ambiguities` lose their frames
/// to `Faint` runs. `noise_sigma` (grey levels per pixel) sets the found points' errors.
/// Returns a warning per particle with points found, naming their frames.
pub(super) fn search_missed(
    table: &mut TrackTable,
    ambiguities: &mut Vec<Ambiguity>,
    named: &[(String, [f64; 2])],
    seen: &Seen<'_>,
    (first, last): (usize, usize),
    image: &SharedBlobs,
    noise_sigma: f64,
) -> Result<Vec<String>, TrackError> {
    let r = image.radius.max(1.0);
    let size = (image.width, image.height);
    let mut tracks = points_by_track(table, named, last);
    let total: usize = tracks.iter().map(|t| t.searches).sum();
    if total == 0 {
        return Ok(Vec::new());
    }
    let disc = DiscRows::new(r);
    // The table's points are sorted by frame up to here; found points are added after them.
    let sorted = table.points.len();
    // Track, frame, point and its disc sum's height in noise sigmas.
    let mut found: Vec<(usize, usize, TrackPoint, f64)> = Vec::new();
    for k in first..=last {
        let slots: Vec<Slot> = tracks
            .iter()
            .enumerate()
            .filter_map(|(i, t)| slot(i, t, k, r, size))
            .filter(|s| !seen.placed.contains(&(tracks[s.track].name.clone(), k)))
            .collect();
        if slots.is_empty() {
            continue;
        }
        let signal = (image.signal_of)(k)?;
        let frame = Frame::new(&signal, image.width, image.height);
        // Everything located in this frame: the tracks' located points (those found here
        // are added as they are) and the detections.
        let in_frame = &table.points[..sorted];
        let from = in_frame.partition_point(|p| p.frame < k);
        let to = in_frame.partition_point(|p| p.frame <= k);
        let mut taken: Vec<[f64; 2]> = in_frame[from..to]
            .iter()
            .filter(|p| p.flag != PointFlag::Interpolated || seen.placed.contains(&(p.particle.clone(), k)))
            .map(|p| [p.x, p.y])
            .collect();
        if let Some(f) = seen.located.get(k - first) {
            taken.extend(f.detections.iter().map(|d| [d.x, d.y]));
        }
        let mut clear_of = taken.clone();
        clear_of.extend(slots.iter().map(|s| s.at));
        let Some(noise) = background_sums(&frame, &disc, &clear_of, 2.0 * r + 1.0) else {
            continue;
        };
        let before = found.len();
        for s in &slots {
            let t = &tracks[s.track];
            // A particle predicted within two radii of another's point (located or bridged)
            // or of a detection overlaps it: its light is in their blob, which the
            // shared-blob fit places, and the search would find the pair's parts.
            let d = |p: [f64; 2]| (p[0] - s.at[0]).hypot(p[1] - s.at[1]);
            let crowded = in_frame[from..to]
                .iter()
                .any(|p| p.particle != t.name && d([p.x, p.y]) < 2.0 * r)
                || seen
                    .located
                    .get(k - first)
                    .is_some_and(|f| f.detections.iter().any(|e| d([e.x, e.y]) < 2.0 * r));
            if crowded {
                continue;
            }
            let Some((centre, sum, positions)) = best_sum(&frame, &disc, s, &slots, &taken, 2.0 * r) else {
                continue;
            };
            let z = (sum - noise.median) / noise.spread;
            let share = (sum - noise.median) / t.mass;
            let threshold = normal_upper_quantile(FALSE_ALARMS / (total as f64 * positions as f64));
            if !(z > threshold && (MASS_RANGE.0..=MASS_RANGE.1).contains(&share)) {
                continue;
            }
            let Some(located) = locate(&signal, image, centre, &taken, noise_sigma) else {
                continue;
            };
            if d([located.x, located.y]) > s.gate + 1.0 {
                continue;
            }
            taken.push([located.x, located.y]);
            let point = TrackPoint {
                frame: k,
                particle: t.name.clone(),
                x: located.x,
                y: located.y,
                mass: located.mass,
                size: located.size,
                ep: located.fixed_point_error(),
                flag: PointFlag::Detected,
            };
            found.push((s.track, k, point, z));
        }
        // Found points predict the frames after them (a track's end).
        for (track, _, point, _) in &found[before..] {
            let index = match tracks[*track].by_frame.get(&k) {
                Some(e) => {
                    table.points[e.index] = point.clone();
                    e.index
                }
                None => {
                    table.points.push(point.clone());
                    table.points.len() - 1
                }
            };
            let entry = Entry {
                index,
                at: [point.x, point.y],
                located: true,
            };
            tracks[*track].by_frame.insert(k, entry);
        }
    }
    if found.is_empty() {
        return Ok(Vec::new());
    }
    sort_in_structure_order(&mut table.points, named);
    let keys: BTreeSet<(String, usize)> = found.iter().map(|f| (f.2.particle.clone(), f.1)).collect();
    forget_found(ambiguities, &keys);
    Ok(warnings(&found, &tracks))
}

/// One point of a named track.
#[derive(Clone, Copy)]
struct Entry {
    /// Its index in the table.
    index: usize,
    /// Its position, px.
    at: [f64; 2],
    /// Whether it was located from the image (not bridged).
    located: bool,
}

/// A named track's points by frame.
struct Points {
    name: String,
    by_frame: BTreeMap<usize, Entry>,
    /// Frames it is searched in at most: those from its first point (its named start) to its
    /// last located point with none located, and [`TAIL_FRAMES`] after that (up to the last
    /// frame); 0 for a track located throughout, whose other fields are left empty.
    searches: usize,
    /// The largest step between located points, per frame, px (NaN: not searched).
    step: f64,
    /// The median mass of its located points, grey levels · px².
    mass: f64,
}

impl Points {
    /// The located points before frame `k`, latest first.
    fn located_before(&self, k: usize) -> impl Iterator<Item = (usize, [f64; 2])> + '_ {
        self.by_frame
            .range(..k)
            .rev()
            .filter(|(_, e)| e.located)
            .map(|(&f, e)| (f, e.at))
    }

    /// The first located point after frame `k`.
    fn located_after(&self, k: usize) -> Option<(usize, [f64; 2])> {
        self.by_frame
            .range(k + 1..)
            .find(|(_, e)| e.located)
            .map(|(&f, e)| (f, e.at))
    }
}

/// Each named track's points, how often it is searched, its largest step and its usual
/// mass; a track located in every frame from its start to `last` is left empty.
fn points_by_track(table: &TrackTable, named: &[(String, [f64; 2])], last: usize) -> Vec<Points> {
    let index: HashMap<&str, usize> = named.iter().enumerate().map(|(i, n)| (n.0.as_str(), i)).collect();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); named.len()];
    for (i, p) in table.points.iter().enumerate() {
        if let Some(&t) = index.get(p.particle.as_str()) {
            members[t].push(i);
        }
    }
    let located = |i: &usize| table.points[*i].flag != PointFlag::Interpolated;
    named
        .iter()
        .zip(members)
        .map(|(n, mut members)| {
            let mut t = Points {
                name: n.0.clone(),
                by_frame: BTreeMap::new(),
                searches: 0,
                step: f64::NAN,
                mass: f64::NAN,
            };
            members.sort_by_key(|&i| table.points[i].frame);
            let start = members.first().map(|&i| table.points[i].frame);
            let end = members
                .iter()
                .rev()
                .find(|i| located(i))
                .map(|&i| table.points[i].frame);
            let (Some(start), Some(end)) = (start, end) else {
                return t;
            };
            let unlocated = (end + 1 - start) - members.iter().filter(|i| located(i)).count();
            t.searches = unlocated + last.saturating_sub(end).min(TAIL_FRAMES);
            if t.searches == 0 {
                return t;
            }
            for &i in &members {
                let p = &table.points[i];
                let entry = Entry {
                    index: i,
                    at: [p.x, p.y],
                    located: located(&i),
                };
                t.by_frame.insert(p.frame, entry);
            }
            let points: Vec<&TrackPoint> = members
                .iter()
                .filter(|i| located(i))
                .map(|&i| &table.points[i])
                .collect();
            t.step = points
                .windows(2)
                .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y) / (w[1].frame - w[0].frame) as f64)
                .fold(f64::NAN, f64::max);
            let mut masses: Vec<f64> = points
                .iter()
                .map(|p| p.mass)
                .filter(|m| m.is_finite() && *m > 0.0)
                .collect();
            t.mass = median(&mut masses);
            t
        })
        .collect()
}

/// Where track `i` is to be searched in frame `k` (particle radius `r`, px), if at all:
/// a frame with no located point, at its first point (the named start), between two
/// located points or the start and a located point (predicted on the line between them) or
/// at most [`TAIL_FRAMES`] past its last (predicted at the velocity of its last two), with
/// the prediction's disc inside the `width` x `height` frame.
fn slot(i: usize, t: &Points, k: usize, r: f64, (width, height): (usize, usize)) -> Option<Slot> {
    if !(t.step.is_finite() && t.mass.is_finite()) || t.by_frame.get(&k).is_some_and(|e| e.located) {
        return None;
    }
    let mut before = t.located_before(k);
    // Before its first located point, the track's first point (its named start) stands in.
    let start = t
        .by_frame
        .iter()
        .next()
        .map(|(&f, e)| (f, e.at))
        .filter(|s| s.0 <= k);
    let (kb, b) = before.next().or(start)?;
    let (at, gate) = match t.located_after(k) {
        _ if kb == k => (b, r + t.step),
        Some((ka, a)) => {
            let f = (k - kb) as f64 / (ka - kb) as f64;
            ([b[0] + f * (a[0] - b[0]), b[1] + f * (a[1] - b[1])], r + t.step)
        }
        None => {
            let missed = k - kb - 1;
            if missed >= TAIL_FRAMES {
                return None;
            }
            let (kp, p) = before.next()?;
            let v = [(b[0] - p[0]) / (kb - kp) as f64, (b[1] - p[1]) / (kb - kp) as f64];
            let n = (k - kb) as f64;
            (
                [b[0] + n * v[0], b[1] + n * v[1]],
                r + t.step * (1 + missed) as f64,
            )
        }
    };
    let inside = at[0] - r >= 0.0
        && at[1] - r >= 0.0
        && at[0] + r <= width as f64 - 1.0
        && at[1] + r <= height as f64 - 1.0;
    inside.then_some(Slot { track: i, at, gate })
}

/// A frame's particle signal with each row's running sum, for disc sums.
struct Frame {
    width: usize,
    height: usize,
    /// `(width + 1) * height` running sums: row `y`'s entry `x` sums its first `x` pixels.
    rows: Vec<f64>,
}

impl Frame {
    fn new(signal: &[f32], width: usize, height: usize) -> Frame {
        let mut rows = Vec::with_capacity((width + 1) * height);
        for row in signal.chunks_exact(width).take(height) {
            let mut acc = 0.0f64;
            rows.push(0.0);
            for &s in row {
                acc += f64::from(s);
                rows.push(acc);
            }
        }
        Frame { width, height, rows }
    }

    /// The signal summed over `disc` about the pixel `(x, y)`, if the disc lies inside.
    fn disc_sum(&self, disc: &DiscRows, x: i64, y: i64) -> Option<f64> {
        let reach = disc.half.len() as i64 / 2;
        let fits = x - disc.widest >= 0
            && y - reach >= 0
            && x + disc.widest < self.width as i64
            && y + reach < self.height as i64;
        if !fits {
            return None;
        }
        let stride = self.width + 1;
        let mut sum = 0.0;
        for (dy, &h) in disc.half.iter().enumerate() {
            let row = (y - reach + dy as i64) as usize * stride;
            sum += self.rows[row + (x + h + 1) as usize] - self.rows[row + (x - h) as usize];
        }
        Some(sum)
    }
}

/// A disc of pixels as the half-width of each of its rows.
struct DiscRows {
    /// Half-width of rows `-R..=R` (`R` the radius rounded down), px.
    half: Vec<i64>,
    /// The largest half-width, px.
    widest: i64,
}

impl DiscRows {
    /// The pixels whose centres lie within `r` px of a pixel centre.
    fn new(r: f64) -> DiscRows {
        let reach = r.floor() as i64;
        let half: Vec<i64> = (-reach..=reach)
            .map(|dy| (r * r - (dy * dy) as f64).max(0.0).sqrt().floor() as i64)
            .collect();
        let widest = half.iter().copied().max().unwrap_or(0);
        DiscRows { half, widest }
    }
}

/// The level and spread of the disc sum over the background.
struct BackgroundSums {
    median: f64,
    spread: f64,
}

/// The median and robust spread of `disc`'s sum over a grid of positions (spaced by the
/// disc's diameter, so that no two share a pixel) at least `clear` px from every point of
/// `clear_of`; none if fewer than [`MIN_SAMPLES`] such positions or no spread.
fn background_sums(
    frame: &Frame,
    disc: &DiscRows,
    clear_of: &[[f64; 2]],
    clear: f64,
) -> Option<BackgroundSums> {
    let cells = (frame.width * frame.height) as f64;
    let mut spacing = (2 * disc.widest + 1).max(2) as usize;
    while cells / (spacing * spacing) as f64 > MAX_SAMPLES as f64 {
        spacing += 1;
    }
    let grid = PointGrid::new(clear_of);
    let mut sums = Vec::new();
    for y in (spacing / 2..frame.height).step_by(spacing) {
        for x in (spacing / 2..frame.width).step_by(spacing) {
            let mut clear_here = true;
            grid.within(&[x as f64, y as f64], clear, |_, d2| {
                clear_here &= d2 >= clear * clear
            });
            if let Some(s) = frame.disc_sum(disc, x as i64, y as i64).filter(|_| clear_here) {
                sums.push(s);
            }
        }
    }
    if sums.len() < MIN_SAMPLES {
        return None;
    }
    let median = median(&mut sums.clone());
    let spread = robust_spread(&mut sums);
    (spread > 0.0).then_some(BackgroundSums { median, spread })
}

/// The whole-pixel centre of `slot`'s gate with the largest disc sum, that sum and how many
/// centres were compared: centres at least `clear` px from every point of `taken` and no
/// nearer another slot's prediction than `slot`'s.
fn best_sum(
    frame: &Frame,
    disc: &DiscRows,
    slot: &Slot,
    slots: &[Slot],
    taken: &[[f64; 2]],
    clear: f64,
) -> Option<([f64; 2], f64, usize)> {
    let g = slot.gate;
    let (x0, x1) = ((slot.at[0] - g).ceil() as i64, (slot.at[0] + g).floor() as i64);
    let (y0, y1) = ((slot.at[1] - g).ceil() as i64, (slot.at[1] + g).floor() as i64);
    let near: Vec<[f64; 2]> = taken
        .iter()
        .filter(|t| (t[0] - slot.at[0]).hypot(t[1] - slot.at[1]) < g + clear)
        .copied()
        .collect();
    let mut best: Option<([f64; 2], f64)> = None;
    let mut positions = 0;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let c = [x as f64, y as f64];
            let own = (c[0] - slot.at[0]).hypot(c[1] - slot.at[1]);
            if own > g
                || near.iter().any(|t| (t[0] - c[0]).hypot(t[1] - c[1]) < clear)
                || slots
                    .iter()
                    .any(|o| o.track != slot.track && (o.at[0] - c[0]).hypot(o.at[1] - c[1]) < own)
            {
                continue;
            }
            let Some(sum) = frame.disc_sum(disc, x, y) else {
                continue;
            };
            positions += 1;
            if best.map_or(true, |b| sum > b.1) {
                best = Some((c, sum));
            }
        }
    }
    best.map(|(c, s)| (c, s, positions))
}

/// The centroid from `centre` in `signal` (window `image.window` px), split from the light of
/// the located points `taken` that its window may share; none if it runs off or holds no
/// signal.
fn locate(
    signal: &[f32],
    image: &SharedBlobs,
    centre: [f64; 2],
    taken: &[[f64; 2]],
    noise_sigma: f64,
) -> Option<crate::locate::Detection> {
    let reach = 2.0 * image.window + 2.0;
    let mut seeds = vec![centre];
    seeds.extend(
        taken
            .iter()
            .filter(|t| (t[0] - centre[0]).hypot(t[1] - centre[1]) < reach),
    );
    let area = std::f64::consts::PI * image.radius * image.radius;
    let areas = vec![area; seeds.len()];
    let out = refine_centroids(
        signal,
        image.width,
        image.height,
        &seeds,
        &areas,
        image.window,
        noise_sigma,
    );
    // The estimates keep their seeds' order, less those dropped: the candidate's is the one
    // nearest its seed, if no other seed is nearer it.
    let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    out.into_iter()
        .filter(|e| {
            let at = [e.x, e.y];
            seeds[1..].iter().all(|s| d(at, *s) > d(at, centre))
        })
        .min_by(|a, b| d([a.x, a.y], centre).total_cmp(&d([b.x, b.y], centre)))
        .filter(|e| d([e.x, e.y], centre) <= image.window)
}

/// Removes the found `(particle, frame)` pairs from the `Missing` and `Lost` runs (a
/// particle with some of a run's frames found keeps runs of the rest, each its own) and adds
/// a `Faint` run for each run of a particle's found frames.
fn forget_found(ambiguities: &mut Vec<Ambiguity>, found: &BTreeSet<(String, usize)>) {
    let mut out = Vec::with_capacity(ambiguities.len());
    for a in ambiguities.drain(..) {
        let bridged = matches!(a.kind, AmbiguityKind::Missing | AmbiguityKind::Lost);
        let touched = |p: &String| (a.first_frame..=a.last_frame).any(|k| found.contains(&(p.clone(), k)));
        if !bridged || !a.particles.iter().any(touched) {
            out.push(a);
            continue;
        }
        let (changed, kept): (Vec<String>, Vec<String>) = a.particles.iter().cloned().partition(touched);
        if !kept.is_empty() {
            out.push(Ambiguity {
                particles: kept,
                ..a.clone()
            });
        }
        for p in changed {
            let rest: Vec<usize> = (a.first_frame..=a.last_frame)
                .filter(|&k| !found.contains(&(p.clone(), k)))
                .collect();
            for run in rest.chunk_by(|x, y| y == &(x + 1)) {
                out.push(Ambiguity {
                    kind: a.kind,
                    particles: vec![p.clone()],
                    first_frame: run[0],
                    last_frame: run[run.len() - 1],
                });
            }
        }
    }
    let mut by_particle: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (p, k) in found {
        by_particle.entry(p.as_str()).or_default().push(*k);
    }
    for (p, frames) in by_particle {
        for run in frames.chunk_by(|x, y| *y == x + 1) {
            out.push(Ambiguity {
                kind: AmbiguityKind::Faint,
                particles: vec![p.to_string()],
                first_frame: run[0],
                last_frame: run[run.len() - 1],
            });
        }
    }
    *ambiguities = out;
}

/// One warning per particle with points found: their frames and how far above the noise.
fn warnings(found: &[(usize, usize, TrackPoint, f64)], tracks: &[Points]) -> Vec<String> {
    let mut by_track: BTreeMap<usize, Vec<(usize, f64)>> = BTreeMap::new();
    for (t, k, _, z) in found {
        by_track.entry(*t).or_default().push((*k, *z));
    }
    by_track
        .into_iter()
        .map(|(t, hits)| {
            let frames: Vec<usize> = hits.iter().map(|h| h.0).collect();
            let lo = hits.iter().map(|h| h.1).fold(f64::INFINITY, f64::min);
            let hi = hits.iter().map(|h| h.1).fold(f64::NEG_INFINITY, f64::max);
            let height = if hi - lo < 0.05 {
                format!("{lo:.1}")
            } else {
                format!("{lo:.1}-{hi:.1}")
            };
            format!(
                "{}: missed by the detector in {}, found there near its predicted path ({height} noise \
                 sigmas of a disc's sum above the background): a faint particle, those points less certain",
                tracks[t].name,
                runs(&frames),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const SIZE: usize = 64;
    const RADIUS: f64 = 2.5;
    /// Disc amplitude and pixel noise, grey levels: a disc sum about 8 noise sigmas high.
    const AMPLITUDE: f64 = 40.0;
    const NOISE: f32 = 20.0;

    /// Where particle `a` is in frame `k`: 1.5 px right and 0.5 px down a frame.
    fn truth(k: usize) -> [f64; 2] {
        [20.0 + 1.5 * k as f64, 30.0 + 0.5 * k as f64]
    }

    /// A frame's signal: discs (antialiased by 8 x 8 samples) at `discs` plus noise.
    fn signal(discs: &[[f64; 2]], seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0f32, NOISE).expect("a normal law");
        let mut out = vec![0.0f32; SIZE * SIZE];
        for (i, v) in out.iter_mut().enumerate() {
            let (x, y) = ((i % SIZE) as f64, (i / SIZE) as f64);
            let mut cover = 0.0;
            for c in discs {
                for s in 0..64 {
                    let sx = x - 0.5 + ((s % 8) as f64 + 0.5) / 8.0;
                    let sy = y - 0.5 + ((s / 8) as f64 + 0.5) / 8.0;
                    cover += f64::from(u8::from((sx - c[0]).hypot(sy - c[1]) <= RADIUS)) / 64.0;
                }
            }
            *v = (AMPLITUDE * cover) as f32 + noise.sample(&mut rng);
        }
        out
    }

    fn point(k: usize, name: &str, at: [f64; 2], flag: PointFlag) -> TrackPoint {
        TrackPoint {
            mass: AMPLITUDE * std::f64::consts::PI * RADIUS * RADIUS,
            flag,
            ..TrackPoint::new(k, name, at[0], at[1])
        }
    }

    /// Particle `a` located in frames 0-2 and 5-6, bridged (on the line) in 3-4, without
    /// points in 7-9; `b` (if given) located where it stands in every frame.
    fn table(b: Option<[f64; 2]>) -> (TrackTable, Vec<Ambiguity>) {
        let mut points = Vec::new();
        for k in 0..10 {
            match k {
                0..=2 | 5..=6 => points.push(point(k, "a", truth(k), PointFlag::Detected)),
                3 | 4 => {
                    let (p, q) = (truth(2), truth(5));
                    let f = (k - 2) as f64 / 3.0;
                    let at = [p[0] + f * (q[0] - p[0]), p[1] + f * (q[1] - p[1])];
                    points.push(point(k, "a", at, PointFlag::Interpolated));
                }
                _ => {}
            }
            if let Some(b) = b {
                points.push(point(k, "b", b, PointFlag::Detected));
            }
        }
        let ambiguities = vec![
            Ambiguity {
                kind: AmbiguityKind::Missing,
                particles: vec!["a".into()],
                first_frame: 3,
                last_frame: 4,
            },
            Ambiguity {
                kind: AmbiguityKind::Lost,
                particles: vec!["a".into()],
                first_frame: 7,
                last_frame: 9,
            },
        ];
        (TrackTable { points }, ambiguities)
    }

    /// Runs the search on frames 0-9 whose discs `discs(k)` gives; returns the table, the
    /// ambiguities left and the warnings.
    fn search(
        b: Option<[f64; 2]>,
        discs: &(dyn Fn(usize) -> Vec<[f64; 2]> + Sync),
        seed: u64,
    ) -> (TrackTable, Vec<Ambiguity>, Vec<String>) {
        let (mut table, mut ambiguities) = table(b);
        let mut named = vec![("a".to_string(), truth(0))];
        if let Some(b) = b {
            named.push(("b".to_string(), b));
        }
        let signal_of =
            |k: usize| -> Result<Vec<f32>, TrackError> { Ok(signal(&discs(k), seed * 100 + k as u64)) };
        let image = SharedBlobs {
            signal_of: &signal_of,
            width: SIZE,
            height: SIZE,
            radius: RADIUS,
            window: RADIUS + 1.0,
        };
        let located: Vec<FrameDetections> = (0..10)
            .map(|k| FrameDetections {
                frame: k,
                detections: Vec::new(),
            })
            .collect();
        let warnings = search_missed(
            &mut table,
            &mut ambiguities,
            &named,
            &Seen {
                located: &located,
                placed: &BTreeSet::new(),
            },
            (0, 9),
            &image,
            f64::from(NOISE),
        )
        .expect("signals are in memory");
        (table, ambiguities, warnings)
    }

    #[test]
    fn a_faint_particle_is_found_between_its_points_and_past_its_last() {
        for seed in 0..5 {
            let (table, ambiguities, warnings) = search(None, &|k| vec![truth(k)], seed);
            let a: Vec<&TrackPoint> = table.points.iter().filter(|p| p.particle == "a").collect();
            assert_eq!(a.len(), 10, "seed {seed}: every frame holds a point");
            for p in &a {
                let t = truth(p.frame);
                assert_eq!(p.flag, PointFlag::Detected, "seed {seed}, frame {}", p.frame);
                let off = (p.x - t[0]).hypot(p.y - t[1]);
                assert!(off < 0.75, "seed {seed}, frame {}: {off} px off", p.frame);
            }
            assert!(table.points.windows(2).all(|w| w[0].frame <= w[1].frame));
            let faint: Vec<(AmbiguityKind, usize, usize)> = ambiguities
                .iter()
                .map(|a| (a.kind, a.first_frame, a.last_frame))
                .collect();
            assert_eq!(
                faint,
                vec![(AmbiguityKind::Faint, 3, 4), (AmbiguityKind::Faint, 7, 9)],
                "seed {seed}"
            );
            assert_eq!(warnings.len(), 1);
            assert!(
                warnings[0].starts_with("a: missed by the detector in frames 3-4, 7-9"),
                "{}",
                warnings[0]
            );
        }
    }

    #[test]
    fn noise_where_the_particle_is_gone_is_not_taken_for_it() {
        // The particle is in view only where it was located: the rest is noise.
        let seen = |k: usize| {
            if matches!(k, 0..=2 | 5..=6) {
                vec![truth(k)]
            } else {
                Vec::new()
            }
        };
        for seed in 0..20 {
            let (table, ambiguities, warnings) = search(None, &seen, seed);
            assert!(warnings.is_empty(), "seed {seed}: {warnings:?}");
            assert_eq!(ambiguities.len(), 2);
            let bridged = table
                .points
                .iter()
                .filter(|p| p.flag == PointFlag::Interpolated)
                .count();
            assert_eq!((table.points.len(), bridged), (7, 2), "seed {seed}");
        }
    }

    #[test]
    fn a_located_neighbour_in_the_gate_is_not_taken_for_the_particle() {
        // `b` stands 3.4 px from where `a` is predicted in frame 3, inside its gate; `a` is gone.
        let b = [truth(3)[0] + 3.0, truth(3)[1] - 1.6];
        let seen = move |k: usize| {
            let mut d = vec![b];
            if matches!(k, 0..=2 | 5..=6) {
                d.push(truth(k));
            }
            d
        };
        for seed in 0..10 {
            let (table, _, warnings) = search(Some(b), &seen, seed);
            assert!(warnings.is_empty(), "seed {seed}: {warnings:?}");
            assert_eq!(table.points.iter().filter(|p| p.particle == "a").count(), 7);
        }
    }

    #[test]
    fn found_frames_leave_the_bridged_runs() {
        let mut ambiguities = vec![
            Ambiguity {
                kind: AmbiguityKind::Missing,
                particles: vec!["a".into(), "b".into()],
                first_frame: 3,
                last_frame: 7,
            },
            Ambiguity {
                kind: AmbiguityKind::Merged,
                particles: vec!["a".into()],
                first_frame: 4,
                last_frame: 4,
            },
        ];
        let found: BTreeSet<(String, usize)> = [("a".to_string(), 5)].into_iter().collect();
        forget_found(&mut ambiguities, &found);
        let runs: Vec<(AmbiguityKind, Vec<String>, usize, usize)> = ambiguities
            .into_iter()
            .map(|a| (a.kind, a.particles, a.first_frame, a.last_frame))
            .collect();
        assert_eq!(
            runs,
            vec![
                (AmbiguityKind::Missing, vec!["b".to_string()], 3, 7),
                (AmbiguityKind::Missing, vec!["a".to_string()], 3, 4),
                (AmbiguityKind::Missing, vec!["a".to_string()], 6, 7),
                (AmbiguityKind::Merged, vec!["a".to_string()], 4, 4),
                (AmbiguityKind::Faint, vec!["a".to_string()], 5, 5),
            ]
        );
    }
}
