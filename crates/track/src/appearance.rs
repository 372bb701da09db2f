//! Appearance: how much a particle's image (its integrated signal and its size) changes
//! from one frame to the next, measured from the data, so that linking can tell a ball from
//! the hand that threw it or from its own reflection in the floor.
//!
//! Two features are compared: the natural logarithm of the mass (so that a change of
//! exposure, blur or partial occlusion, which scales the mass, counts the same on a faint
//! and a bright particle) and the radius of gyration, px. Their frame-to-frame spreads are
//! measured, never chosen:
//!
//! * for a track with a history, from its own located points (robust spread, 1.4826 times
//!   the median absolute change between successive located points);
//! * before that, pooled over the recording from unambiguous links: pairs of detections in
//!   successive frames that are each other's nearest neighbour and much closer to each
//!   other than to anything else in either frame.
//!
//! Neither spread is taken below what the pixel noise alone makes the features wander by:
//! for a centroid window of radius `W` holding a particle located to `ep` px, the mass's
//! relative error is about `2 ep / W` (both follow from the same weighted pixel sums), so
//! its change between two frames has spread `2 √2 ep / W`; the size's is about `√2 ep`.
//!
//! A change every particle of a frame shares (the exposure, or light that saturates and trims
//! every size) is the camera's, not a particle's: it is measured from the unambiguous links
//! and taken out of every appearance before they are compared ([`AppearanceLevels`]).

use crate::point_grid::PointGrid;
use physfit_tracks::stats::{robust_spread_upper, MAD_TO_SIGMA};

use crate::link::FrameDetections;
use crate::locate::Detection;

/// The spread of the change of a particle's log mass between two frames that the pixel noise
/// alone makes (see the module doc): `2 √2 ep / W` for a particle located to `ep` px in a
/// centroid window of radius `window` px (taken as 1 px at least).
pub(crate) fn ln_mass_noise_spread(ep: f64, window: f64) -> f64 {
    2.0 * std::f64::consts::SQRT_2 * ep / window.max(1.0)
}

/// Changes between successive located points needed before a track's own spread is used
/// (the median absolute deviation of fewer is too often near zero by chance).
pub const OWN_SPREAD_MIN_CHANGES: usize = 8;
/// Located points of a track's recent history its appearance is measured from.
pub const HISTORY: usize = 24;
/// Unambiguous links after which the pooled spread stops looking at more frames (the
/// relative error of a robust spread from this many is about 3 %).
const POOLED_LINKS: usize = 2000;
/// An unambiguous link is at most this fraction of the distance to the next nearest
/// detection (in either frame).
const UNAMBIGUOUS_RATIO: f64 = 0.25;

/// The appearance of one particle image: natural log of the mass, and the size, px.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Appearance {
    /// Natural logarithm of the integrated signal (grey levels · px²).
    pub ln_mass: f64,
    /// Largest natural log mass the particle may have: `ln_mass`, or `ln_mass + ln 2` when
    /// the centroid window was cut by the image border (the blob lost light to the border,
    /// but less than half of it while its centroid is inside the image).
    pub ln_mass_upper: f64,
    /// Radius of gyration, px; NaN when the centroid window was cut by the image border
    /// (the size is then biased).
    pub size: f64,
    /// Estimated position error of the detection, px (sets the noise floor of the spreads).
    pub ep: f64,
}

impl Appearance {
    /// The median of each feature over the latest [`HISTORY`] of located points (each with its
    /// frame index; unknown sizes left out), as one uncut appearance. Taken for every track in
    /// every frame, it allocates nothing.
    pub fn median_of(points: &[(usize, Appearance)]) -> Appearance {
        let recent = &points[points.len().saturating_sub(HISTORY)..];
        let feature = |f: fn(&Appearance) -> f64| {
            let mut v = SortedWindow::default();
            recent.iter().for_each(|(_, a)| v.update(f(a), true));
            sorted_median(v.values())
        };
        let ln_mass = feature(|a| a.ln_mass);
        Appearance {
            ln_mass,
            ln_mass_upper: ln_mass,
            size: feature(|a| a.size),
            ep: feature(|a| a.ep),
        }
    }

    /// The appearance of a detection holding `share` particles (its mass divided among
    /// them); `None` when the mass is not positive and finite.
    pub fn of(d: &Detection, share: usize) -> Option<Appearance> {
        let m = d.mass / share.max(1) as f64;
        (m > 0.0 && m.is_finite()).then(|| Appearance {
            ln_mass: m.ln(),
            ln_mass_upper: if d.clipped {
                m.ln() + std::f64::consts::LN_2
            } else {
                m.ln()
            },
            size: if d.clipped { f64::NAN } else { d.size },
            ep: if d.ep.is_finite() { d.ep } else { 0.0 },
        })
    }
}

/// Frame-to-frame spreads (one standard deviation) of the two appearance features.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AppearanceSpread {
    /// Spread of the change of log mass between successive frames (dimensionless).
    pub ln_mass: f64,
    /// Spread of the change of size between successive frames, px.
    pub size: f64,
}

impl AppearanceSpread {
    /// Pooled over a recording from unambiguous links (see the module doc); `None` when
    /// fewer than [`OWN_SPREAD_MIN_CHANGES`] such links exist, and the size's spread unknown
    /// (NaN) when fewer of them have both sizes. Frames are visited spread over
    /// the recording until 2 000 links are found (`POOLED_LINKS`).
    pub fn pooled(frames: &[FrameDetections], levels: &AppearanceLevels) -> Option<AppearanceSpread> {
        let mut dm: Vec<f64> = Vec::new();
        let mut ds: Vec<f64> = Vec::new();
        // Pairs of successive frames visited spread over the recording (every `stride`-th
        // first, then the ones between), until enough links are found.
        let pairs = frames.len().saturating_sub(1);
        let stride = (pairs / 32).max(1);
        let order = (0..stride).flat_map(|offset| (offset..pairs).step_by(stride));
        for k in order {
            if dm.len() >= POOLED_LINKS {
                break;
            }
            let w = &frames[k..k + 2];
            for (x, y) in unambiguous_links(&w[0], &w[1], usize::MAX) {
                let (x, y) = (levels.apply(x, w[0].frame), levels.apply(y, w[1].frame));
                dm.push(y.ln_mass - x.ln_mass);
                // A size is unknown (NaN) where the border cut the window; left out, as the
                // track's own spread leaves it out, else it sorts above every change.
                let d_size = y.size - x.size;
                if d_size.is_finite() {
                    ds.push(d_size);
                }
            }
        }
        (dm.len() >= OWN_SPREAD_MIN_CHANGES).then(|| AppearanceSpread {
            ln_mass: tail_spread(&mut dm),
            size: if ds.len() >= OWN_SPREAD_MIN_CHANGES {
                tail_spread(&mut ds)
            } else {
                f64::NAN
            },
        })
    }
}

/// The appearances of the unambiguous links from frame `a` to the next, `b` (see the module
/// doc): pairs that are each other's nearest neighbour, at most [`UNAMBIGUOUS_RATIO`] of the
/// distance to the next nearest detection in either frame; of `a`'s first `most` detections.
/// None when the frames are not successive.
fn unambiguous_links(a: &FrameDetections, b: &FrameDetections, most: usize) -> Vec<(Appearance, Appearance)> {
    let (fa, fb) = (&a.detections, &b.detections);
    if fa.is_empty() || fb.is_empty() || b.frame != a.frame + 1 {
        return Vec::new();
    }
    let pa: Vec<[f64; 2]> = fa.iter().map(|d| [d.x, d.y]).collect();
    let pb: Vec<[f64; 2]> = fb.iter().map(|d| [d.x, d.y]).collect();
    let ta = PointGrid::new(&pa);
    let tb = PointGrid::new(&pb);
    let far = |n: Option<(usize, f64)>| n.map_or(f64::INFINITY, |(_, d)| d.sqrt());
    let mut out = Vec::new();
    for (i, p) in pa.iter().enumerate().take(most) {
        let [first, second] = tb.nearest_two(p);
        let Some((j, d)) = first else { continue };
        let d1 = d.sqrt();
        let next_b = far(second);
        // Back from j: i must be its nearest in frame a, the next far away.
        let back = ta.nearest_two(&pb[j]);
        let next_a = far(back[1]);
        if back[0].map(|(k, _)| k) != Some(i) || d1 > UNAMBIGUOUS_RATIO * next_b.min(next_a) {
            continue;
        }
        if let (Some(x), Some(y)) = (Appearance::of(&fa[i], 1), Appearance::of(&fb[j], 1)) {
            out.push((x, y));
        }
    }
    out
}

/// The change the links of a pair of frames share (`changes`, one per link: the change and
/// its weight): their weighted median where there are at least [`LEVEL_LINKS_MIN`] and it
/// lies beyond [`LEVEL_SIGMAS`] of its own standard error, else 0: steps of noise would add
/// up, frame after frame, into a drift of their own. The error is taken from the changes'
/// weighted standard deviation (`1.2533 sd / √n`, `n` the weights' effective count), not a
/// robust spread: links that disagree make it larger, never zero (a robust spread is 0 where
/// more than half of the changes are equal, and would take any median for common). Each
/// link weighs the inverse of its change's noise variance (see [`link_weight`]): specks that
/// flicker with the light at a frame's border, located to a fifth of a pixel, weigh nothing
/// beside particles located to a thousandth (fresh style 6298: three specks' links changing
/// by 14-28 % hid the 3.2 % exposure step six spots shared within 0.1 %).
fn common_change(mut changes: Vec<(f64, f64)>) -> f64 {
    changes.retain(|(c, w)| c.is_finite() && w.is_finite() && *w > 0.0);
    if changes.len() < LEVEL_LINKS_MIN {
        return 0.0;
    }
    changes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = changes.iter().map(|c| c.1).sum();
    let squares: f64 = changes.iter().map(|c| c.1 * c.1).sum();
    let n = total * total / squares;
    let mean = changes.iter().map(|(c, w)| c * w).sum::<f64>() / total;
    let variance = changes.iter().map(|(c, w)| w * (c - mean).powi(2)).sum::<f64>() / total;
    let sd = (variance * n / (n - 1.0).max(f64::MIN_POSITIVE)).sqrt();
    // The weighted median: where the weight below reaches half (between two changes where it
    // is exactly half, as the plain median of an even count).
    let mut below = 0.0;
    let mut mid = changes[changes.len() - 1].0;
    for (i, (c, w)) in changes.iter().enumerate() {
        below += w;
        if (below - 0.5 * total).abs() <= 1e-12 * total && i + 1 < changes.len() {
            mid = 0.5 * (c + changes[i + 1].0);
            break;
        }
        if below > 0.5 * total {
            mid = *c;
            break;
        }
    }
    let error = 1.2533 * sd / n.sqrt();
    if mid.abs() > LEVEL_SIGMAS * error {
        mid
    } else {
        0.0
    }
}

/// A link's weight in its frame's common change: the inverse of its noise variance, the
/// two ends' `ep` squared (a mass's relative error and a size's error both scale as `ep`),
/// floored at a thousandth of a pixel.
fn link_weight(a: &Appearance, b: &Appearance) -> f64 {
    let floor = 1e-3f64;
    1.0 / (a.ep.max(floor).powi(2) + b.ep.max(floor).powi(2))
}

/// Standard errors beyond which a frame pair's median change of appearance is taken as
/// common to the frame (a change of exposure), not noise.
const LEVEL_SIGMAS: f64 = 3.0;

/// Unambiguous links per pair of successive frames that measure the frame's common change
/// of appearance ([`AppearanceLevels`]); with fewer, none is measured.
const LEVEL_LINKS_MIN: usize = 3;
/// Detections of a frame whose links measure its common change of appearance (the first
/// ones; a median of this many is as good as of all).
const LEVEL_LINKS_MOST: usize = 64;

/// Each frame's appearance level: the change of log mass and of size that every particle of
/// the frame shares, summed from the first frame (a change of exposure scales every mass
/// alike, and where the light saturates it trims every size alike). Measured as the median
/// change over the unambiguous links between successive frames, where there are at least
/// three of them (0 otherwise: a particle alone keeps its own changes). The
/// appearances linking compares are taken relative to their frame's level, so a particle's
/// own change is judged against its own spread, not the camera's.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AppearanceLevels {
    /// The first frame's index.
    first: usize,
    /// Each frame's level of log mass (dimensionless), from `first` on.
    ln_mass: Vec<f64>,
    /// Each frame's level of size, px, from `first` on.
    size: Vec<f64>,
}

impl AppearanceLevels {
    /// The levels of `frames` (contiguous, in order).
    pub fn measure(frames: &[FrameDetections]) -> AppearanceLevels {
        let mut levels = AppearanceLevels {
            first: frames.first().map_or(0, |f| f.frame),
            ln_mass: vec![0.0; frames.len()],
            size: vec![0.0; frames.len()],
        };
        for k in 1..frames.len() {
            let links = unambiguous_links(&frames[k - 1], &frames[k], LEVEL_LINKS_MOST);
            let m: Vec<(f64, f64)> = links
                .iter()
                .map(|(x, y)| (y.ln_mass - x.ln_mass, link_weight(x, y)))
                .collect();
            let s: Vec<(f64, f64)> = links
                .iter()
                .map(|(x, y)| (y.size - x.size, link_weight(x, y)))
                .collect();
            let (dm, ds) = (common_change(m), common_change(s));
            levels.ln_mass[k] = levels.ln_mass[k - 1] + dm;
            levels.size[k] = levels.size[k - 1] + ds;
        }
        levels
    }

    /// Appearance `a` of frame `frame` relative to the frame's level (unchanged outside the
    /// frames measured).
    pub fn apply(&self, a: Appearance, frame: usize) -> Appearance {
        let Some(k) = frame.checked_sub(self.first).filter(|&k| k < self.ln_mass.len()) else {
            return a;
        };
        Appearance {
            ln_mass: a.ln_mass - self.ln_mass[k],
            ln_mass_upper: a.ln_mass_upper - self.ln_mass[k],
            size: a.size - self.size[k],
            ep: a.ep,
        }
    }
}

/// What a track's particle looks like now, and how much that may change per frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackAppearance {
    /// Its recent appearance: the median of each feature over its latest three located
    /// points (one odd frame, such as light shared with a neighbour, does not set it).
    pub last: Appearance,
    /// Its usual appearance: the median of each feature over its recent history (up to 24
    /// located points). A real particle's image can change abruptly for a few frames (blur
    /// at a bounce's speed, contact) and come back; coming back to the usual is no change.
    pub usual: Appearance,
    /// Frame-to-frame spread: the track's own once it has enough history, else pooled.
    pub spread: AppearanceSpread,
    /// Frames between the latest located point and the frame being linked (1 for the next).
    pub frames_ahead: usize,
}

impl TrackAppearance {
    /// From a track's located appearances (oldest first, each with its frame index), for
    /// linking frame `frame`, with centroid window radius `window` px; `None` when there is
    /// no located point or no spread. (See [`AppearanceHistory::appearance`], which this
    /// is, for a history kept point by point.)
    pub fn from_history(
        history: &[(usize, Appearance)],
        frame: usize,
        pooled: Option<AppearanceSpread>,
        window: f64,
    ) -> Option<TrackAppearance> {
        let mut kept = AppearanceHistory::default();
        for &(k, a) in &history[history.len().saturating_sub(HISTORY)..] {
            kept.push(k, a);
        }
        kept.appearance(frame, pooled, window)
    }

    /// Standardised differences (log mass, size) of a candidate from the track's latest
    /// appearance, the spread grown as the square root of the frames since it was located
    /// (a random walk of the features). `compare_size` is false for a blob holding several
    /// particles (its size is the group's, not one particle's); the size difference is 0
    /// when either size or the size's spread is unknown (NaN). The log-mass difference is the distance from the
    /// track's to the candidate's range `[ln_mass, ln_mass_upper]` (0 inside it; a blob cut
    /// by the border is thus compared one-sidedly), signed as the candidate is lighter or
    /// heavier.
    pub fn z(&self, a: &Appearance, compare_size: bool) -> (f64, f64) {
        let grow = (self.frames_ahead as f64).sqrt();
        let own = self.last.ln_mass;
        let dm = if own < a.ln_mass {
            a.ln_mass - own
        } else if own > a.ln_mass_upper {
            a.ln_mass_upper - own
        } else {
            0.0
        };
        let zm = dm / (self.spread.ln_mass * grow).max(1e-3);
        // An unknown spread leaves the sizes uncompared: `max` would take NaN for its floor,
        // and a size changed by 0.013 px stood 13 standard deviations off (fresh style 6168,
        // one dark disc of 27 px whose pooled size spread was unknown: its track took a
        // speck of vignetting 166 px away in frame 1 and was refused).
        let zs = if compare_size && self.spread.size.is_finite() {
            (a.size - self.last.size) / (self.spread.size * grow).max(1e-3)
        } else {
            0.0
        };
        let zs = if zs.is_finite() { zs } else { 0.0 };
        (zm, zs)
    }

    /// The squared standardised distance of a candidate `a` (one particle's image, sizes
    /// compared) from the track's latest appearance: the sum of the squares of [`Self::z`],
    /// a chi-square of two degrees of freedom where the candidate is the particle.
    pub fn distance2(&self, a: &Appearance) -> f64 {
        let (zm, zs) = self.z(a, true);
        zm * zm + zs * zs
    }
}

/// A track's located appearances (each with its frame index, oldest first), with the
/// features of its recent history kept sorted, so that the medians and spreads linking asks
/// of a track cost a few dozen comparisons instead of a selection over each feature. The
/// sorted windows are brought up to date when an appearance is asked for: most tracks of a
/// crowd are never asked (only lone ones are), and their points cost nothing more.
#[derive(Clone, Debug, Default)]
pub struct AppearanceHistory {
    points: Vec<(usize, Appearance)>,
    windows: std::cell::RefCell<Windows>,
}

/// The sorted features of an [`AppearanceHistory`]'s latest points, counted up to `synced`.
#[derive(Clone, Debug, Default)]
struct Windows {
    /// The first point counted since the windows were last emptied.
    first: usize,
    /// Points counted: the windows hold the latest [`HISTORY`] of the first `synced` points
    /// (from `first` on).
    synced: usize,
    /// Log masses, finite sizes and finite position errors of those points.
    ln_mass: SortedWindow,
    size: SortedWindow,
    ep: SortedWindow,
    /// The changes between successive points among them: log-mass changes and finite size
    /// changes, each per square root of the frames between the two points.
    d_ln_mass: SortedWindow,
    d_size: SortedWindow,
}

impl Windows {
    /// Counts `points` up to the last.
    fn catch_up(&mut self, points: &[(usize, Appearance)]) {
        if points.len() - self.synced > HISTORY {
            // Further behind than the window reaches: start again from its first point.
            *self = Windows {
                first: points.len() - HISTORY,
                synced: points.len() - HISTORY,
                ..Windows::default()
            };
        }
        for n in self.synced..points.len() {
            // The window moves from points n - HISTORY ..= n - 1 to n - HISTORY + 1 ..= n:
            // point n and the change into it come in; point n - HISTORY and the change out
            // of it leave (first, so that no window ever holds more than HISTORY values).
            if n >= self.first + HISTORY {
                let k = n - HISTORY;
                self.count_point(points[k].1, false);
                self.count_change(points[k], points[k + 1], false);
            }
            self.count_point(points[n].1, true);
            if n > self.first {
                self.count_change(points[n - 1], points[n], true);
            }
        }
        self.synced = points.len();
    }

    /// Adds (`add`) or removes the features of point `p`.
    fn count_point(&mut self, p: Appearance, add: bool) {
        self.ln_mass.update(p.ln_mass, add);
        self.size.update(p.size, add);
        self.ep.update(p.ep, add);
    }

    /// Adds (`add`) or removes the change from point `from` to the next, `to`.
    fn count_change(&mut self, (f0, a0): (usize, Appearance), (f1, a1): (usize, Appearance), add: bool) {
        // A change over several frames counts as that many frames' worth of change.
        let root = ((f1 - f0).max(1) as f64).sqrt();
        self.d_ln_mass.update((a1.ln_mass - a0.ln_mass) / root, add);
        self.d_size.update((a1.size - a0.size) / root, add);
    }
}

impl AppearanceHistory {
    /// Every located appearance, oldest first.
    pub fn points(&self) -> &[(usize, Appearance)] {
        &self.points
    }

    /// Adds the appearance `a` located in frame `frame` (after every earlier one).
    pub fn push(&mut self, frame: usize, a: Appearance) {
        self.points.push((frame, a));
    }

    /// The track's appearance for linking frame `frame`, with centroid window radius
    /// `window` px; `None` when there is no located point or no spread.
    ///
    /// The latest appearance is the median of each feature over the latest three points,
    /// the usual one over the latest [`HISTORY`]. The spreads are the track's own (robust
    /// spread of its changes over the latest [`HISTORY`] points) once it has
    /// [`OWN_SPREAD_MIN_CHANGES`] of them, else `pooled`; neither is taken below what the
    /// pixel noise makes the features wander by (see the module doc).
    pub fn appearance(
        &self,
        frame: usize,
        pooled: Option<AppearanceSpread>,
        window: f64,
    ) -> Option<TrackAppearance> {
        let &(last_frame, _) = self.points.last()?;
        let last = Appearance::median_of(&self.points[self.points.len().saturating_sub(3)..]);
        let mut windows = self.windows.borrow_mut();
        windows.catch_up(&self.points);
        let own = |changes: &[f64], pooled: Option<f64>| {
            if changes.len() >= OWN_SPREAD_MIN_CHANGES {
                sorted_robust_spread(changes)
            } else {
                pooled.unwrap_or(f64::NAN)
            }
        };
        let own = AppearanceSpread {
            ln_mass: own(windows.d_ln_mass.values(), pooled.map(|p| p.ln_mass)),
            size: own(windows.d_size.values(), pooled.map(|p| p.size)),
        };
        if !own.ln_mass.is_finite() {
            return None;
        }
        let ln_mass = sorted_median(windows.ln_mass.values());
        let usual = Appearance {
            ln_mass,
            ln_mass_upper: ln_mass,
            size: sorted_median(windows.size.values()),
            ep: sorted_median(windows.ep.values()),
        };
        let ep = usual.ep;
        let spread = AppearanceSpread {
            ln_mass: own.ln_mass.max(ln_mass_noise_spread(ep, window)),
            // Unknown (NaN) stays unknown: sizes are then not compared.
            size: if own.size.is_finite() {
                own.size.max(std::f64::consts::SQRT_2 * ep)
            } else {
                f64::NAN
            },
        };
        Some(TrackAppearance {
            last,
            usual,
            spread,
            frames_ahead: frame.saturating_sub(last_frame).max(1),
        })
    }
}

/// Up to [`HISTORY`] finite values, sorted (by `f64::total_cmp`), held in place.
#[derive(Clone, Debug)]
struct SortedWindow {
    values: [f64; HISTORY],
    len: usize,
}

impl Default for SortedWindow {
    fn default() -> Self {
        SortedWindow {
            values: [0.0; HISTORY],
            len: 0,
        }
    }
}

impl SortedWindow {
    fn values(&self) -> &[f64] {
        &self.values[..self.len]
    }

    /// Inserts (`add`) or removes one copy of `x` (one that was inserted); a non-finite `x`
    /// is not kept. Shifting the few values past it in a plain loop, not by a call to move
    /// memory.
    fn update(&mut self, x: f64, add: bool) {
        if !x.is_finite() {
            return;
        }
        if add {
            assert!(self.len < HISTORY, "a window holds at most HISTORY values");
            let mut i = self.len;
            while i > 0 && self.values[i - 1].total_cmp(&x).is_gt() {
                self.values[i] = self.values[i - 1];
                i -= 1;
            }
            self.values[i] = x;
            self.len += 1;
        } else {
            let at = self.values().partition_point(|v| v.total_cmp(&x).is_lt());
            debug_assert!(self.values().get(at).is_some_and(|v| v.to_bits() == x.to_bits()));
            for i in at..self.len - 1 {
                self.values[i] = self.values[i + 1];
            }
            self.len -= 1;
        }
    }
}

/// The median of sorted `values` as [`median_upper`] takes it (the upper one of an even count);
/// NaN when empty.
fn sorted_median(values: &[f64]) -> f64 {
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

/// [`robust_spread_upper`] of sorted, non-empty `values`: the absolute deviations from the median
/// grow outwards from it on both sides, so the median deviation is found by merging the two
/// runs up to the middle rank.
fn sorted_robust_spread(values: &[f64]) -> f64 {
    let mid = values.len() / 2;
    let m = values[mid];
    let deviation = |i: usize| (values[i] - m).abs();
    // Rank 0 is the median's own deviation, 0; the next on each side follow.
    let (mut below, mut above) = (mid, mid + 1);
    let mut d = 0.0;
    for _ in 0..mid {
        let lower = below.checked_sub(1).map_or(f64::INFINITY, deviation);
        let upper = if above < values.len() {
            deviation(above)
        } else {
            f64::INFINITY
        };
        if lower <= upper {
            d = lower;
            below -= 1;
        } else {
            d = upper;
            above += 1;
        }
    }
    MAD_TO_SIGMA * d
}

/// The spread of `v` (reordered) that also covers its tail: the larger of
/// [`robust_spread_upper`] and the 99th percentile of the absolute deviations from the median over
/// 2.576 (the two agree for normal values). Compressed video changes a particle's mass by
/// 1-3 % between its first frames and by 0.25 % (the robust spread) in most others: an H.264
/// recording of `concealed-gravity` had its 99th percentile at 0.44, and a gate of five robust
/// spreads refused two particles their own blobs in frames 1-2, which then swapped names.
fn tail_spread(v: &mut [f64]) -> f64 {
    let spread = robust_spread_upper(v);
    if v.is_empty() {
        return spread;
    }
    v.sort_by(f64::total_cmp);
    let q99 = v[((v.len() - 1) as f64 * 0.99).round() as usize];
    spread.max(q99 / 2.576)
}

#[cfg(test)]
mod tests {
    use super::*;
    use physfit_tracks::stats::median_upper;
    use rand::{Rng, SeedableRng};

    /// Where the size's spread is unknown (no history of the track's own, none pooled), a
    /// candidate is judged on its mass alone: a size 0.013 px or 5 px off stands 0 standard
    /// deviations off, where a known spread of 0.1 px puts 0.5 px at 5.
    #[test]
    fn an_unknown_size_spread_leaves_sizes_uncompared() {
        let look = |size_spread: f64| TrackAppearance {
            last: Appearance {
                ln_mass: 12.0,
                ln_mass_upper: 12.0,
                size: 19.473,
                ep: 0.1,
            },
            usual: Appearance {
                ln_mass: 12.0,
                ln_mass_upper: 12.0,
                size: 19.473,
                ep: 0.1,
            },
            spread: AppearanceSpread {
                ln_mass: 0.27,
                size: size_spread,
            },
            frames_ahead: 1,
        };
        let candidate = |size: f64| Appearance {
            ln_mass: 12.006,
            ln_mass_upper: 12.006,
            size,
            ep: 0.1,
        };
        for size in [19.486, 24.5] {
            let (zm, zs) = look(f64::NAN).z(&candidate(size), true);
            assert!(zs.abs() < 1e-12, "size {size}: {zs}");
            assert!((zm - 0.006 / 0.27).abs() < 1e-9, "{zm}");
        }
        let (_, zs) = look(0.1).z(&candidate(19.973), true);
        assert!((zs - 5.0).abs() < 1e-9, "{zs}");
    }

    #[test]
    fn robust_spread_ignores_an_outlier_and_the_sorted_window_matches_a_vector() {
        // |x - 3| = 2, 1, 0, 1, 97: median 1.
        let mut v = [1.0, 2.0, 3.0, 4.0, 100.0];
        assert!((robust_spread_upper(&mut v) - 1.4826).abs() < 1e-12);
        let history: Vec<f64> = (0..HISTORY).map(|k| ((k * 7919) % 31) as f64 * 0.1).collect();
        let mut window = SortedWindow::default();
        history.iter().for_each(|&x| window.update(x, true));
        window.update(f64::NAN, true);
        assert_eq!(window.values().len(), HISTORY, "non-finite values are not kept");
        let mut first = history.clone();
        assert_eq!(
            sorted_median(window.values()).to_bits(),
            median_upper(&mut first).to_bits()
        );
        let mut first = history.clone();
        assert_eq!(
            sorted_robust_spread(window.values()).to_bits(),
            robust_spread_upper(&mut first).to_bits()
        );
    }

    fn det(x: f64, y: f64, mass: f64, size: f64) -> Detection {
        Detection {
            x,
            y,
            mass,
            size,
            ep: 0.01,
            follow: 0.0,
            area: 50.0,
            clipped: false,
        }
    }

    #[test]
    fn own_spread_flags_a_reflection_and_keeps_the_ball() {
        // A ball whose log mass wanders by a few hundredths a frame (spread of the changes
        // 0.059) and size by twice that.
        let wobble = [0.0, 0.04, -0.03, 0.05, -0.02, 0.01, -0.05, 0.03, 0.0, -0.04];
        let history: Vec<(usize, Appearance)> = wobble
            .iter()
            .enumerate()
            .map(|(k, w)| {
                (
                    k,
                    Appearance {
                        ln_mass: 35000f64.ln() + w,
                        ln_mass_upper: 35000f64.ln() + w,
                        size: 6.5 + w * 2.0,
                        ep: 0.01,
                    },
                )
            })
            .collect();
        let t = TrackAppearance::from_history(&history, 10, None, 10.0).expect("appearance");
        let ball = Appearance::of(&det(0.0, 0.0, 32000.0, 6.6), 1).expect("ball");
        let reflection = Appearance::of(&det(0.0, 0.0, 11000.0, 8.9), 1).expect("reflection");
        let (bm, bs) = t.z(&ball, true);
        let (rm, rs) = t.z(&reflection, true);
        assert!(bm.abs() < 2.0 && bs.abs() < 2.0, "ball z {bm} {bs}");
        assert!(rm.abs() > 8.0 && rs.abs() > 8.0, "reflection z {rm} {rs}");
    }

    /// The appearance as its definition reads, by sorting: the reference the kept history
    /// must match to the bit.
    fn appearance_by_sorting(
        history: &[(usize, Appearance)],
        frame: usize,
        pooled: Option<AppearanceSpread>,
        window: f64,
    ) -> Option<TrackAppearance> {
        let sorted_median = |mut v: Vec<f64>| {
            v.retain(|x| x.is_finite());
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
        };
        let spread = |v: Vec<f64>| {
            let m = sorted_median(v.clone());
            1.4826 * sorted_median(v.iter().map(|x| (x - m).abs()).collect())
        };
        let medians = |points: &[(usize, Appearance)]| {
            let f = |g: fn(&Appearance) -> f64| sorted_median(points.iter().map(|(_, a)| g(a)).collect());
            Appearance {
                ln_mass: f(|a| a.ln_mass),
                ln_mass_upper: f(|a| a.ln_mass),
                size: f(|a| a.size),
                ep: f(|a| a.ep),
            }
        };
        let &(last_frame, _) = history.last()?;
        let recent = &history[history.len().saturating_sub(HISTORY)..];
        let changes = |g: fn(&Appearance) -> f64| -> Vec<f64> {
            recent
                .windows(2)
                .map(|w| (g(&w[1].1) - g(&w[0].1)) / ((w[1].0 - w[0].0) as f64).sqrt())
                .filter(|x| x.is_finite())
                .collect()
        };
        let own = |c: Vec<f64>, pooled: Option<f64>| {
            if c.len() >= OWN_SPREAD_MIN_CHANGES {
                spread(c)
            } else {
                pooled.unwrap_or(f64::NAN)
            }
        };
        let own_m = own(changes(|a| a.ln_mass), pooled.map(|p| p.ln_mass));
        let own_s = own(changes(|a| a.size), pooled.map(|p| p.size));
        if !own_m.is_finite() {
            return None;
        }
        let usual = medians(recent);
        Some(TrackAppearance {
            last: medians(&history[history.len().saturating_sub(3)..]),
            usual,
            spread: AppearanceSpread {
                ln_mass: own_m.max(ln_mass_noise_spread(usual.ep, window)),
                size: if own_s.is_finite() {
                    own_s.max(std::f64::consts::SQRT_2 * usual.ep)
                } else {
                    f64::NAN
                },
            },
            frames_ahead: frame - last_frame,
        })
    }

    /// Kept point by point (and rebuilt from a slice), the history gives the appearance its
    /// definition gives, to the bit, asked after 1 to 31 new points (within and beyond the
    /// window's reach): features repeating exactly, unknown sizes, gaps of several frames,
    /// with and without a pooled spread.
    #[test]
    fn kept_history_matches_the_definition_however_often_asked() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for pooled in [
            None,
            Some(AppearanceSpread {
                ln_mass: 0.05,
                size: 0.1,
            }),
        ] {
            let mut kept = AppearanceHistory::default();
            let (mut frame, mut next_ask, mut asked) = (0, 0, 0);
            for n in 0..400 {
                frame += rng.gen_range(1..=3);
                // Values on a coarse grid, so that equal ones come and go.
                let ln_mass = 10.0 + f64::from(rng.gen_range(0..12)) * 0.01;
                let size = if rng.gen_bool(0.1) {
                    f64::NAN
                } else {
                    3.0 + f64::from(rng.gen_range(0..8)) * 0.05
                };
                let a = Appearance {
                    ln_mass,
                    ln_mass_upper: ln_mass,
                    size,
                    ep: 0.01 + f64::from(rng.gen_range(0..5)) * 0.002,
                };
                kept.push(frame, a);
                // Asked after gaps within and beyond the window's reach.
                if n != next_ask {
                    continue;
                }
                next_ask += [1, 2, 5, 24, 25, 31, 3][asked % 7];
                asked += 1;
                let at = frame + 1 + n % 2;
                let want = format!("{:?}", appearance_by_sorting(kept.points(), at, pooled, 5.0));
                assert_eq!(
                    format!("{:?}", kept.appearance(at, pooled, 5.0)),
                    want,
                    "{n} points"
                );
                let rebuilt = TrackAppearance::from_history(kept.points(), at, pooled, 5.0);
                assert_eq!(format!("{rebuilt:?}"), want, "{n} points, from a slice");
            }
        }
    }

    #[test]
    fn pooled_spread_comes_from_unambiguous_links() {
        // Two far-apart particles whose masses alternate by ±10 %: the log-mass change
        // between frames is ±0.2 (spread 0.2 × 1.4826 × median |dev| = 0.2965).
        let frames: Vec<FrameDetections> = (0..8)
            .map(|k| FrameDetections {
                frame: k,
                detections: vec![
                    det(
                        10.0 + k as f64,
                        10.0,
                        if k % 2 == 0 { 1100.0 } else { 900.0 },
                        3.0,
                    ),
                    det(200.0, 200.0 - k as f64, 1000.0, 3.0),
                ],
            })
            .collect();
        let s = AppearanceSpread::pooled(&frames, &AppearanceLevels::default()).expect("spread");
        // Changes: ±0.2007 for the first, 0 for the second: median 0 at best, so the
        // spread is that of the mixture about its median.
        assert!(s.ln_mass > 0.0 && s.ln_mass < 0.31, "{s:?}");
        assert!(s.size.abs() < 1e-12, "{s:?}");
        // No pairs: no pooled spread.
        assert!(AppearanceSpread::pooled(&frames[..1], &AppearanceLevels::default()).is_none());
    }
    /// Three particles far apart whose windows the border cuts (no size) and two whose
    /// sizes alternate by ±0.1 px: the pooled size spread is theirs (the changes ±0.2 px),
    /// the unknown sizes left out (among the changes they sorted above every one and made
    /// the spread unknown); with every size unknown it is unknown.
    #[test]
    fn pooled_size_spread_leaves_out_unknown_sizes() {
        let frames = |known: bool| -> Vec<FrameDetections> {
            (0..8)
                .map(|k| FrameDetections {
                    frame: k,
                    detections: (0..5)
                        .map(|i| {
                            let mut d = det(20.0 + 60.0 * i as f64, 20.0 + k as f64, 1000.0, 3.0);
                            if i < 3 || !known {
                                d.clipped = true;
                            } else {
                                d.size += if k % 2 == 0 { 0.1 } else { -0.1 };
                            }
                            d
                        })
                        .collect(),
                })
                .collect()
        };
        let s = AppearanceSpread::pooled(&frames(true), &AppearanceLevels::default()).expect("spread");
        assert!(
            s.size.is_finite() && (s.size - 0.2 * MAD_TO_SIGMA).abs() < 0.2,
            "{s:?}"
        );
        let s = AppearanceSpread::pooled(&frames(false), &AppearanceLevels::default()).expect("spread");
        assert!(s.size.is_nan() && s.ln_mass.is_finite(), "{s:?}");
    }

    /// Five particles far apart whose masses all drop by a tenth from frame 3 on (an
    /// exposure change), each with its own wobble of ±1 %: the frames from 3 on sit at a
    /// level of ln 0.9, and a particle's appearance relative to it is back where it was.
    /// Wobble alone moves no level (its median steps are within their error), and two
    /// particles are too few to tell a common change from their own.
    #[test]
    fn a_change_every_particle_shares_is_the_frame_level() {
        let frames = |count: usize, drop: f64| -> Vec<FrameDetections> {
            (0..8)
                .map(|k| FrameDetections {
                    frame: 10 + k,
                    detections: (0..count)
                        .map(|i| {
                            let wobble = if (i + k) % 2 == 0 { 1.01 } else { 0.99 };
                            let scale = if k >= 3 { drop } else { 1.0 };
                            det(40.0 * i as f64 + k as f64, 50.0, 1000.0 * wobble * scale, 3.0)
                        })
                        .collect(),
                })
                .collect()
        };
        let levels = AppearanceLevels::measure(&frames(5, 0.9));
        for k in 0..8 {
            let expected = if k >= 3 { 0.9f64.ln() } else { 0.0 };
            assert!(
                (levels.ln_mass[k] - expected).abs() < 0.021,
                "frame {k}: {levels:?}"
            );
        }
        let d = det(0.0, 50.0, 900.0, 3.0);
        let a = levels.apply(Appearance::of(&d, 1).expect("appearance"), 15);
        assert!((a.ln_mass - 1000f64.ln()).abs() < 0.021, "{a:?}");
        // Outside the frames measured, unchanged.
        assert_eq!(
            levels.apply(Appearance::of(&d, 1).unwrap(), 40),
            Appearance::of(&d, 1).unwrap()
        );
        let still = AppearanceLevels::measure(&frames(5, 1.0));
        assert!(still.ln_mass.iter().all(|&l| l == 0.0), "{still:?}");
        let two = AppearanceLevels::measure(&frames(2, 0.9));
        assert!(two.ln_mass.iter().all(|&l| l == 0.0), "{two:?}");
    }
}
