//! The particle scale, found in scale space before any size is assumed.
//!
//! The detector's band-pass (a box mean of a disc's area minus one twice as wide, see
//! [`crate::detect`]) is a difference of two means, so a particle of contrast `A` and radius
//! `R` answers it with `A f(r / R)` at detector radius `r`, whatever `R`: a curve with one
//! maximum near `r = R` at the particle's centre. Far below its own scale a flat particle
//! answers only along its rim (a straight edge gives `A / 2` at every scale), and above it
//! the particle's contrast is averaged away. So the blobs found at each radius of a ladder
//! from 1.5 px up to a sixth of the frame, strongest first, with any weaker blob of another
//! radius inside a stronger one's disc dropped, leave each particle once, at about its own
//! scale: the start of the radius estimate, which then converges from anywhere between
//! 0.7 and 2 radii (measured on discs of radius 9 px).
//!
//! Without this, an estimate started at a fixed small radius found a large disc as the
//! fragments of its rim and converged on them: discs of radius 6 px and more were lost.

/// A blob found at one radius of the ladder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ScaleBlob {
    /// Column of the band-pass peak, px.
    pub x: f64,
    /// Row of the band-pass peak, px.
    pub y: f64,
    /// Band-pass response at the peak, grey levels (comparable across radii: both boxes are
    /// means).
    pub peak: f64,
    /// Detector radius it was found at, px.
    pub radius: f64,
    /// `peak` over the band-pass noise at that radius (see [`crate::band_noise`]).
    pub snr: f64,
}

/// Detector radius tried when the frame is too small for any other, px (a 3 x 3 box).
const SMALLEST: f64 = 1.5;
/// Up to this radius (px) the ladder holds every box half-width, from the 3 x 3 box up.
const SMALL_BOXES_UP_TO: f64 = 8.0;
/// Ratio of consecutive radii above [`SMALL_BOXES_UP_TO`].
const LADDER_RATIO: f64 = 1.2;
/// Largest detector radius tried, as a fraction of the frame's shorter side: the wide box
/// (four times the radius across) then spans two thirds of it.
const LARGEST_OF_SIDE: f64 = 1.0 / 6.0;

/// Largest ratio of a particle's radius (at half its peak signal) to the detector radius of
/// its strongest answer. Computed for the band-pass's continuous form: the answer peaks at
/// 0.94 of a flat disc's radius, 0.80 of a shaded sphere's, 1.08 of a ring's outer radius
/// and 1.10 of a Gaussian spot's half-maximum radius; 1 / 0.8 covers them all.
const OWN_RADIUS_OF_PEAK: f64 = 1.25;

/// The detector radii the scan tries for a `width` x `height` frame, px: one for each box
/// half-width the detector can use (see [`crate::box_half_width`]: the radius whose box has
/// the disc's area) up to [`SMALL_BOXES_UP_TO`], then a geometric ladder of ratio
/// [`LADDER_RATIO`], up to [`LARGEST_OF_SIDE`] of the shorter side.
pub(crate) fn ladder(width: usize, height: usize) -> Vec<f64> {
    let largest = (width.min(height) as f64 * LARGEST_OF_SIDE).max(SMALLEST);
    let of_half_width = |h: usize| (2 * h + 1) as f64 / std::f64::consts::PI.sqrt();
    let mut radii: Vec<f64> = (1..)
        .map(of_half_width)
        .take_while(|&r| r <= SMALL_BOXES_UP_TO.min(largest))
        .collect();
    let mut r = radii.last().copied().unwrap_or(SMALLEST);
    while r * LADDER_RATIO <= largest {
        r *= LADDER_RATIO;
        radii.push(r);
    }
    if radii.is_empty() {
        radii.push(SMALLEST);
    }
    radii
}

/// The blobs that are each particle's strongest answer. Strongest first, a blob is kept
/// unless its disc overlaps a kept (stronger) blob's particle: far below its scale a
/// particle answers with fragments of its rim, at the edge of its own disc, and far above
/// it neighbouring particles answer together, halfway between them. A particle's own radius
/// is taken as up to [`OWN_RADIUS_OF_PEAK`] times the radius of its strongest answer.
/// Touching particles may be taken for one; the scale of the one kept is still theirs.
///
/// The kept blobs are bucketed on a grid as they are kept, and each blob is tested only
/// against those in the cells within its farthest reach: the same test as against every
/// kept blob (a scan of all of them was 82 M of a 3.09 G tracking run at N = 1000, 40
/// frames, callgrind).
pub(crate) fn strongest(mut blobs: Vec<ScaleBlob>) -> Vec<ScaleBlob> {
    blobs.sort_by(|a, b| b.peak.total_cmp(&a.peak));
    let inside = |k: &ScaleBlob, b: &ScaleBlob| {
        let reach = b.radius + OWN_RADIUS_OF_PEAK * k.radius;
        (k.x - b.x).powi(2) + (k.y - b.y).powi(2) < reach * reach
    };
    let mut kept: Vec<ScaleBlob> = Vec::new();
    let Some(mut grid) = KeptGrid::over(&blobs) else {
        // Some coordinate or radius not finite: every kept blob is asked.
        for b in blobs {
            if !kept.iter().any(|k| inside(k, &b)) {
                kept.push(b);
            }
        }
        return kept;
    };
    for b in blobs {
        if !grid.near(&b).any(|i| inside(&kept[i], &b)) {
            grid.insert(kept.len(), &b);
            kept.push(b);
        }
    }
    kept
}

/// The blobs [`strongest`] has kept (indices), bucketed by cell.
struct KeptGrid {
    /// Lower corner of the blobs' bounding box, px.
    lo: [f64; 2],
    /// Cell side, px.
    cell: f64,
    /// Cells along x and y.
    dims: [usize; 2],
    /// The kept blobs of each cell (row-major cells).
    cells: Vec<Vec<usize>>,
    /// Largest radius of a kept blob, px.
    largest: f64,
}

impl KeptGrid {
    /// An empty grid over the bounding box of `blobs`, cells about one mean spacing wide (at
    /// least 1/256 of the larger extent); `None` when some blob's position or radius is not
    /// finite, or a radius is negative.
    fn over(blobs: &[ScaleBlob]) -> Option<KeptGrid> {
        if blobs
            .iter()
            .any(|b| !(b.x.is_finite() && b.y.is_finite() && b.radius.is_finite() && b.radius >= 0.0))
        {
            return None;
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for b in blobs {
            lo = [lo[0].min(b.x), lo[1].min(b.y)];
            hi = [hi[0].max(b.x), hi[1].max(b.y)];
        }
        if blobs.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let extent = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
        let cell = (extent[0] * extent[1] / blobs.len().max(1) as f64)
            .sqrt()
            .max(extent[0].max(extent[1]) / 256.0);
        let dims = [0, 1].map(|k| (extent[k] / cell) as usize + 1);
        Some(KeptGrid {
            lo,
            cell,
            dims,
            cells: vec![Vec::new(); dims[0] * dims[1]],
            largest: 0.0,
        })
    }

    /// The cell index along axis `k` of coordinate `v` (clamped to the grid).
    fn index(&self, v: f64, k: usize) -> usize {
        let c = ((v - self.lo[k]) / self.cell).floor();
        if c <= 0.0 {
            0
        } else {
            (c as usize).min(self.dims[k] - 1)
        }
    }

    fn insert(&mut self, i: usize, b: &ScaleBlob) {
        let c = self.index(b.y, 1) * self.dims[0] + self.index(b.x, 0);
        self.cells[c].push(i);
        self.largest = self.largest.max(b.radius);
    }

    /// The kept blobs that may hold `b`: those in the cells within its reach of the largest
    /// kept blob (with a relative margin of 1e-6 for the rounding of the squared distance).
    fn near(&self, b: &ScaleBlob) -> impl Iterator<Item = usize> + '_ {
        let reach = (b.radius + OWN_RADIUS_OF_PEAK * self.largest) * (1.0 + 1e-6);
        let (x0, x1) = (self.index(b.x - reach, 0), self.index(b.x + reach, 0));
        let (y0, y1) = (self.index(b.y - reach, 1), self.index(b.y + reach, 1));
        (y0..=y1).flat_map(move |gy| {
            (x0..=x1).flat_map(move |gx| self.cells[gy * self.dims[0] + gx].iter().copied())
        })
    }
}

/// The particle at each named particle's start (px): the strongest of `blobs` (from every
/// radius of the ladder) whose own disc holds the start, or `None`. A thin ring answers most
/// strongly with fragments of its rim at a small scale, and [`strongest`] keeps those; but
/// none of them holds the ring's centre, where a structure names it, while the whole ring's
/// answer at its own scale does. A disc's own answer is its strongest anyway. Each radius's
/// blobs are searched sorted by column (thousands of named particles, a dozen radii).
pub(crate) fn holding(blobs: &[ScaleBlob], starts: &[[f64; 2]]) -> Vec<Option<ScaleBlob>> {
    let mut best: Vec<Option<ScaleBlob>> = vec![None; starts.len()];
    let mut radii: Vec<f64> = blobs.iter().map(|b| b.radius).collect();
    radii.sort_by(f64::total_cmp);
    radii.dedup();
    for r in radii {
        // The radii are copies of the ladder's values, so equality picks one level exactly.
        let mut level: Vec<&ScaleBlob> = blobs.iter().filter(|b| b.radius.total_cmp(&r).is_eq()).collect();
        // Sorted by column, each start searches the columns within `r` of its own. (kiddo
        // 4.2's immutable k-d tree, used before, panicked while it was built ("mid > len") on
        // one scan of `pendulum-scale`, whose grid lines put many maxima on equal columns.)
        level.sort_by(|a, b| a.x.total_cmp(&b.x));
        for (s, best) in starts.iter().zip(best.iter_mut()) {
            let from = level.partition_point(|b| b.x < s[0] - r);
            for b in level[from..].iter().take_while(|b| b.x <= s[0] + r) {
                if (b.x - s[0]).powi(2) + (b.y - s[1]).powi(2) <= r * r
                    && best.map_or(true, |k| b.peak > k.peak)
                {
                    *best = Some(**b);
                }
            }
        }
    }
    best
}

/// Returns true if and only if the blobs of the next radii, `level`, lie beyond the scale of
/// every particle of the blobs found so far, `below`: they are found at more than twice the
/// radius of the strongest blob below and none answers half as strongly. Above its own scale
/// a particle's answer falls as the square of the ratio of the scales (a quarter at twice its
/// scale), so the particles below have all peaked; a particle of a larger scale that answers
/// less than half as strongly as the strongest one weighs less than a quarter as much in
/// [`typical_radius`].
pub(crate) fn beyond_every_scale(below: &[ScaleBlob], level: &[ScaleBlob]) -> bool {
    let Some(strongest) = below.iter().max_by(|a, b| a.peak.total_cmp(&b.peak)) else {
        return false;
    };
    let smallest = level.iter().map(|b| b.radius).fold(f64::INFINITY, f64::min);
    let peak = level.iter().map(|b| b.peak).fold(0.0, f64::max);
    smallest > 2.0 * strongest.radius && peak < 0.5 * strongest.peak
}

/// The median radius of `kept` blobs, each weighing its squared signal-to-noise ratio (the
/// information it carries): the few noise peaks and specks that pass the detector's
/// threshold at small radii, at five noise deviations, weigh little beside particles that
/// stand tens of deviations out of the noise, however many more of them there are (13 noise
/// peaks beside 5 discs of radius 16 px at pixel noise 20 on black). `None` when empty.
pub(crate) fn typical_radius(kept: &[ScaleBlob]) -> Option<f64> {
    let mut by_radius: Vec<(f64, f64)> = kept.iter().map(|b| (b.radius, b.snr * b.snr)).collect();
    by_radius.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = by_radius.iter().map(|b| b.1).sum();
    let mut below = 0.0;
    for (radius, weight) in by_radius {
        below += weight;
        if below >= 0.5 * total {
            return Some(radius);
        }
    }
    None
}

/// Ratio of consecutive particle scales (sorted) above which named particles are told apart
/// as two sizes: the ladder's step is 1.2, and one size's particles answer at most a step or
/// two apart (a blurred edge, a neighbour close by), while recordings that mix sizes hold
/// ratios of 2 and more.
const SIZE_GAP: f64 = 1.6;

/// The named particles grouped by size: `radii[i]` is the scale of particle `i` (`None` when
/// nothing answered near it). Sorted by scale, a new group starts wherever a scale exceeds
/// the one before by more than [`SIZE_GAP`]; particles of no scale join the group of most
/// members.
/// Groups in increasing scale, each in increasing particle order; one group (possibly
/// empty) when every scale is within the gap of its neighbour.
pub(crate) fn size_groups(radii: &[Option<f64>]) -> Vec<Vec<usize>> {
    let mut order: Vec<(usize, f64)> = radii
        .iter()
        .enumerate()
        .filter_map(|(i, r)| r.map(|r| (i, r)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut groups: Vec<Vec<usize>> = vec![Vec::new()];
    for (k, &(i, r)) in order.iter().enumerate() {
        if k > 0 && r > SIZE_GAP * order[k - 1].1 {
            groups.push(Vec::new());
        }
        groups.last_mut().expect("one group at least").push(i);
    }
    let unknown: Vec<usize> = (0..radii.len()).filter(|&i| radii[i].is_none()).collect();
    if let Some(largest) = groups.iter_mut().max_by_key(|g| g.len()) {
        largest.extend(unknown);
    }
    for g in &mut groups {
        g.sort_unstable();
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{box_half_width, find_blobs, DetectParameters};

    /// A frame of flat discs of `radius` (px) and contrast 100 on 0, anti-aliased by
    /// 4 x 4 supersampling, at `centres`.
    fn discs(width: usize, height: usize, centres: &[[f64; 2]], radius: f64) -> Vec<f32> {
        let mut img = vec![0f32; width * height];
        for y in 0..height {
            for x in 0..width {
                let mut cover = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let px = x as f64 + (sx as f64 + 0.5) / 4.0 - 0.5;
                        let py = y as f64 + (sy as f64 + 0.5) / 4.0 - 0.5;
                        if centres
                            .iter()
                            .any(|c| (px - c[0]).powi(2) + (py - c[1]).powi(2) <= radius * radius)
                        {
                            cover += 1.0 / 16.0;
                        }
                    }
                }
                img[y * width + x] = (100.0 * cover) as f32;
            }
        }
        img
    }

    /// Every answer of `img` over the ladder (no suppression).
    fn answers(img: &[f32], width: usize, height: usize) -> Vec<ScaleBlob> {
        let mut all = Vec::new();
        for r in ladder(width, height) {
            let params = DetectParameters {
                radius: r,
                noise_sigma: 0.5,
                expected: None,
            };
            for b in find_blobs(img, width, height, &params).blobs {
                all.push(ScaleBlob {
                    x: b.x as f64,
                    y: b.y as f64,
                    peak: b.peak as f64,
                    radius: r,
                    snr: b.peak as f64 / crate::band_noise(r, 0.5),
                });
            }
        }
        all
    }

    fn scan(img: &[f32], width: usize, height: usize) -> Vec<ScaleBlob> {
        strongest(answers(img, width, height))
    }

    #[test]
    fn ladder_has_each_small_box_once_then_grows_geometrically() {
        let radii = ladder(512, 512);
        let boxes: Vec<usize> = radii.iter().map(|&r| box_half_width(r)).collect();
        for w in boxes.windows(2) {
            assert!(w[1] > w[0], "box half-widths not increasing: {boxes:?}");
        }
        assert_eq!(boxes[0], 1);
        assert!(radii.last().copied().unwrap() <= 512.0 / 6.0);
        assert!(radii.last().copied().unwrap() > 512.0 / 6.0 / 1.2);
        assert!(radii
            .windows(2)
            .all(|w| w[1] / w[0] <= 1.2 + 1e-9 || w[1] - w[0] < 1.2));
    }

    #[test]
    fn each_disc_is_kept_once_near_its_own_radius() {
        // Radii from 2 to 40 px, two discs each, well apart; fails when rim fragments at small
        // radii survive (several blobs a disc) or the kept radius is far from the disc's.
        for &radius in &[2.0, 3.5, 6.0, 9.0, 14.0, 25.0, 40.0] {
            let size = ((radius * 10.0) as usize).max(80);
            let c = [
                [size as f64 * 0.3 + 0.3, size as f64 * 0.5 - 0.2],
                [size as f64 * 0.7 - 0.4, size as f64 * 0.5 + 0.1],
            ];
            let img = discs(size, size, &c, radius);
            let kept = scan(&img, size, size);
            assert_eq!(kept.len(), 2, "radius {radius}: kept {kept:?}");
            for k in &kept {
                let ratio = k.radius / radius;
                assert!(
                    (0.7..=1.6).contains(&ratio),
                    "radius {radius}: kept at {}",
                    k.radius
                );
                let near = c
                    .iter()
                    .map(|c| (c[0] - k.x).hypot(c[1] - k.y))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    near < 0.25 * radius + 1.5,
                    "radius {radius}: blob {k:?} off centre"
                );
            }
        }
    }

    #[test]
    fn a_weaker_blob_inside_a_stronger_ones_disc_is_dropped_either_way() {
        let big = ScaleBlob {
            x: 10.0,
            y: 10.0,
            peak: 50.0,
            radius: 8.0,
            snr: 100.0,
        };
        let rim = ScaleBlob {
            x: 16.0,
            y: 10.0,
            peak: 40.0,
            radius: 2.0,
            snr: 40.0,
        };
        let apart = ScaleBlob {
            x: 30.0,
            y: 10.0,
            peak: 45.0,
            radius: 8.0,
            snr: 90.0,
        };
        assert_eq!(strongest(vec![rim, big, apart]), vec![big, apart]);
        // The rim stronger than the whole: the whole overlaps it.
        let strong_rim = ScaleBlob { peak: 60.0, ..rim };
        assert_eq!(strongest(vec![big, strong_rim]), vec![strong_rim]);
    }

    /// The grid keeps the blobs a test against every kept blob keeps, in the same order:
    /// random sets from fixed seeds, clustered and spread, radii from the ladder.
    #[test]
    fn strongest_keeps_what_a_scan_of_every_kept_blob_keeps() {
        let every = |mut blobs: Vec<ScaleBlob>| {
            blobs.sort_by(|a, b| b.peak.total_cmp(&a.peak));
            let mut kept: Vec<ScaleBlob> = Vec::new();
            for b in blobs {
                let inside = kept.iter().any(|k| {
                    let reach = b.radius + OWN_RADIUS_OF_PEAK * k.radius;
                    (k.x - b.x).powi(2) + (k.y - b.y).powi(2) < reach * reach
                });
                if !inside {
                    kept.push(b);
                }
            }
            kept
        };
        let radii = ladder(512, 512);
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for (n, side) in [
            (0, 512.0),
            (1, 512.0),
            (30, 40.0),
            (500, 512.0),
            (3000, 512.0),
            (2000, 60.0),
        ] {
            let blobs: Vec<ScaleBlob> = (0..n)
                .map(|_| ScaleBlob {
                    x: side * next(),
                    y: side * next(),
                    peak: 100.0 * next(),
                    radius: radii[(next() * radii.len() as f64) as usize % radii.len()],
                    snr: 1.0,
                })
                .collect();
            assert_eq!(strongest(blobs.clone()), every(blobs), "{n} blobs over {side} px");
        }
    }

    #[test]
    fn the_climb_stops_beyond_every_particles_scale_only() {
        let blob = |radius: f64, peak: f64| ScaleBlob {
            x: 0.0,
            y: 0.0,
            peak,
            radius,
            snr: peak,
        };
        let below = [blob(2.0, 50.0), blob(4.0, 100.0)];
        assert!(!beyond_every_scale(&[], &[blob(2.0, 1.0)]));
        // Weak answers at more than twice the strongest's radius: stop.
        assert!(beyond_every_scale(&below, &[blob(9.0, 30.0), blob(10.8, 20.0)]));
        // Still near its scale, or a larger particle answering strongly: go on.
        assert!(!beyond_every_scale(&below, &[blob(7.0, 30.0)]));
        assert!(!beyond_every_scale(&below, &[blob(9.0, 60.0)]));
    }

    #[test]
    fn a_rings_centre_is_held_by_the_whole_ring_not_its_rim() {
        // A ring of radii 7-10 px (contrast 100): the strongest answers overall are rim
        // fragments; the answer holding the centre is the whole ring's, at about its radius.
        let (w, h) = (80usize, 80usize);
        let img: Vec<f32> = (0..w * h)
            .map(|i| {
                let r = ((i % w) as f64 - 40.0).hypot((i / w) as f64 - 40.0);
                if (7.0..=10.0).contains(&r) {
                    100.0
                } else {
                    0.0
                }
            })
            .collect();
        let all = answers(&img, w, h);
        let held = holding(&all, &[[40.0, 40.0], [5.0, 75.0]]);
        let ring = held[0].expect("an answer holds the centre");
        assert!((7.0..=13.0).contains(&ring.radius), "{ring:?}");
        assert!((ring.x - 40.0).hypot(ring.y - 40.0) <= 1.5, "{ring:?}");
        assert!(held[1].is_none());
    }

    #[test]
    fn named_particles_split_into_sizes_only_at_a_wide_gap() {
        // One size (scales a ladder step or two apart): one group.
        assert_eq!(
            size_groups(&[Some(4.0), Some(4.8), Some(5.7)]),
            vec![vec![0, 1, 2]]
        );
        // Two sizes 2.5 times apart, interleaved; a particle of no scale joins the group of most members.
        assert_eq!(
            size_groups(&[Some(10.0), Some(4.0), None, Some(11.5), Some(4.4), Some(3.9)]),
            vec![vec![1, 2, 4, 5], vec![0, 3]]
        );
        assert_eq!(size_groups(&[None, None]), vec![vec![0, 1]]);
        assert_eq!(size_groups(&[]), vec![Vec::<usize>::new()]);
    }

    #[test]
    fn typical_radius_weighs_each_blob_by_its_squared_signal_to_noise() {
        let blob = |radius: f64, snr: f64| ScaleBlob {
            x: 0.0,
            y: 0.0,
            peak: snr,
            radius,
            snr,
        };
        // 13 noise peaks at the threshold beside 5 strong particles: the particles' radius.
        let mut kept: Vec<ScaleBlob> = (0..13).map(|_| blob(1.7, 5.5)).collect();
        kept.extend((0..5).map(|_| blob(15.2, 200.0)));
        assert_eq!(typical_radius(&kept), Some(15.2));
        // Equal weights: the plain (lower) median.
        let even = [blob(2.0, 10.0), blob(3.0, 10.0), blob(4.0, 10.0), blob(5.0, 10.0)];
        assert_eq!(typical_radius(&even), Some(3.0));
        assert_eq!(typical_radius(&[]), None);
    }
}
