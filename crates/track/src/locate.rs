//! Sub-pixel localisation: an intensity-weighted centroid iterated on a circular window
//! re-centred on the estimate.
//!
//! Pixel-locking (estimates drawn towards pixel centres) comes from windows whose edge
//! jumps by whole pixels as the estimate moves. Here each pixel's window weight is the
//! linear approximation of the fraction of it inside the circle of radius `W` about the
//! current estimate, `clamp(W + 1/2 − d, 0, 1)`, which varies continuously with the
//! estimate; the centroid of a symmetric blob in a window centred on its true centre is
//! that centre, so the fixed point of the iteration is unbiased (Crocker & Grier 1996,
//! J. Colloid Interface Sci. 179:298, with the iteration of trackpy's `refine_com`).
//!
//! Touching particles share pixels. Each pixel is shared between neighbouring estimates
//! by a soft Voronoi split: its weight for a particle ramps from 1 to 0 over one pixel
//! across the perpendicular bisector with each neighbour. All estimates of a frame are
//! refined together (Jacobi iterations), so the split follows the estimates.
//!
//! Position error: for independent pixel noise σ the centroid of one window has the standard
//! error `σ sqrt(Σ w² (x − x̂)²) / Σ w s` on one axis (the linear error propagation of the
//! weighted mean). The estimate is the fixed point `c = f(c)` of the window's centroid
//! `f`, so an error `δf` of the centroid moves it by `δf / (1 − j)`, where
//! `j = ∂f/∂c` is how far the centroid follows its window: the signal on the window's edge
//! ramp, `Σ_ramp s r / (2 Σ w s)` (each axis's derivative, averaged). A window short of
//! its particle (a Gaussian spot's skirt, a large ball's soft edge) holds a nearly flat
//! part of it and follows itself: profile neighbour 4001's Gaussian spot of 26.6 px,
//! windowed at 21.7 px, reads `j` = 0.75 and scattered 0.54 px about its centre where the
//! window's error said 0.107. The fixed point's error is the window's over `1 − j` (`j` in `[0, MAX_FOLLOW]`),
//! averaged over both axes: the `ep` of the track table ([`Detection::fixed_point_error`]).
//! A detection's own `ep` stays the window's error, the unit in which the checks judge how
//! far a second estimate of the same image (the local plane taken out) moves it: both share
//! that image's noise, so their difference does not scatter as either fixed point does
//! (judged in the fixed point's error, fresh style 6646's ball, moved 1.1-2.5 px by its
//! plane, was no longer named in a warning).

/// One located particle image in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    /// Column coordinate, px (pixel centres at integers, x right).
    pub x: f64,
    /// Row coordinate, px (y down).
    pub y: f64,
    /// Integrated signal above background in the window, grey levels · px².
    pub mass: f64,
    /// Radius of gyration of the signal in the window, px.
    pub size: f64,
    /// Standard error of one window's centroid on `x` and `y` from the pixel noise, px: what
    /// noise moves one centroid by, the unit in which moves between estimates of the same
    /// image are judged.
    pub ep: f64,
    /// How far the window's centroid follows the window, `j` in `[0, 0.95]` (see the module
    /// documentation): the fixed point's error is `ep / (1 − j)`
    /// ([`Detection::fixed_point_error`]).
    pub follow: f64,
    /// Area of the detection's blob component per particle in it, px².
    pub area: f64,
    /// Returns true if and only if the window was cut by the image border.
    pub clipped: bool,
}

impl Detection {
    /// Standard error of the fixed point on `x` and `y`, px: the window's over `1 − j`
    /// (see the module documentation); what the track table's `ep` says.
    pub fn fixed_point_error(&self) -> f64 {
        self.ep / (1.0 - self.follow)
    }
}

/// Maximum number of centroid iterations.
const MAX_ITERATIONS: usize = 30;
/// Iteration stops when no estimate's remaining distance to its fixed point (judged from
/// its last step and the contraction of its steps) exceeds this, px, or
/// [`TOLERANCE_OF_ERROR`] of its own standard error, whichever is larger.
const TOLERANCE: f64 = 1e-4;
/// The part of an estimate's standard error left to the iteration: stopping that close adds
/// at most 0.1 % to the error's variance. Touching particles, whose shared light couples
/// their estimates, converge slowly; this keeps them from iterating far below their noise.
const TOLERANCE_OF_ERROR: f64 = 0.03;
/// Lanes of the per-row accumulations (a multiple of every SIMD width in use).
const LANES: usize = 4;
/// Largest `j` (how far a window's centroid follows the window, see the module
/// documentation) that `ep` is amplified for: a window that follows itself more closely
/// holds no position, and its error, twenty times its window's, says so.
const MAX_FOLLOW: f64 = 0.95;
/// Sums of [`window_stats`]: Σ w s, Σ w s dx, Σ w s dy, Σ w s r², Σ w² r², Σ_ramp f s r.
const SUMS: usize = 6;

/// Centroid window radius for particles of radius `radius` (at half the peak signal), px:
/// the disc, its anti-aliased edge (half a pixel) and the half-pixel ramp of the window
/// weight, so the window holds all of an isolated disc's signal and as little background
/// noise as possible. Every background pixel in the window adds noise to the centroid in
/// proportion to its distance from the centre, so the centroid's error grows as the square
/// of the window radius: at `radius + 1` it is about 0.0022 px per grey level of pixel noise
/// for the discs (radius 4, amplitude 200), against 0.0031 at `1.25 radius + 1`.
/// Blur widens the measured radius, and with it the window. The linker compares appearances
/// over it too.
pub(crate) fn locate_window(radius: f64) -> f64 {
    radius + 1.0
}

/// Refines seed positions (px) to sub-pixel centroids on `signal` (`width * height`,
/// row-major, particles positive) with window radius `window` px. Seeds whose window
/// holds no positive signal, or whose estimate runs off by more than the window, are
/// dropped. `areas[i]` is copied into the detection of seed `i`; `noise_sigma` (grey
/// levels) sets `ep`.
pub fn refine_centroids(
    signal: &[f32],
    width: usize,
    height: usize,
    seeds: &[[f64; 2]],
    areas: &[f64],
    window: f64,
    noise_sigma: f64,
) -> Vec<Detection> {
    let mut scratch = LocateScratch::default();
    refine_centroids_with_scratch(
        signal,
        width,
        height,
        seeds,
        areas,
        window,
        noise_sigma,
        &mut scratch,
    )
}

/// Reusable buffers of [`refine_centroids_with_scratch`].
#[derive(Default, Debug)]
pub struct LocateScratch {
    /// Neighbours of each seed, concatenated; `offsets[i]..offsets[i + 1]` are seed `i`'s.
    neighbours: Vec<u32>,
    offsets: Vec<usize>,
    splits: Vec<([f64; 2], f64)>,
    rows: RowBuffers,
}

/// Per-row buffers of [`window_stats`], padded to whole lanes.
#[derive(Default, Debug)]
struct RowBuffers {
    dx: Vec<f32>,
    s: Vec<f32>,
    /// The splits that cut the current row, as [`Row::splits`] holds them.
    splits: Vec<[f32; 2]>,
    /// The window's splits in single precision, as the rows use them.
    window_splits: Vec<WindowSplit>,
}

/// One split of a window (a bisector with a neighbour) as each row of the window uses it.
#[derive(Clone, Copy, Debug)]
struct WindowSplit {
    /// The bisector's unit normal towards the neighbour.
    n: [f32; 2],
    /// The bisector's distance from the centre along the normal plus half a pixel (where
    /// the split's ramp reaches 0), px.
    offset: f32,
    /// The largest `dx n0` over the window's columns (the row's pixel nearest the
    /// neighbour, along x), px.
    reach_x: f32,
}

/// [`refine_centroids`] with reusable buffers.
///
/// All estimates move together (Gauss-Seidel sweeps), so the soft Voronoi split follows
/// them, but each sweep measures only the estimates that can still change: those not yet
/// converged, and their neighbours (seeds whose windows may share pixels). An estimate has
/// converged when its distance left to the fixed point (estimated from its last two steps)
/// is below 3 % of its own standard error (`TOLERANCE_OF_ERROR`), or its step below
/// 1e-4 px (`TOLERANCE`). A lone particle stops as soon as it has converged, whatever the others
/// do; iteration ends when every estimate has.
#[allow(clippy::too_many_arguments)]
pub fn refine_centroids_with_scratch(
    signal: &[f32],
    width: usize,
    height: usize,
    seeds: &[[f64; 2]],
    areas: &[f64],
    window: f64,
    noise_sigma: f64,
    scratch: &mut LocateScratch,
) -> Vec<Detection> {
    let mut out = Vec::with_capacity(seeds.len());
    let image = Image {
        signal,
        width,
        height,
    };
    refine(&image, seeds, areas, window, noise_sigma, &[], scratch, |d| {
        if let Some(d) = d {
            out.push(d);
        }
    });
    out
}

/// [`refine_centroids_with_scratch`] with each window also cut by fixed half-planes that move
/// with its estimate: `cuts[i]` holds seed `i`'s, each the unit normal pointing out of the
/// window and the cut's distance from the estimate along it (px), weighted as a neighbour's
/// split is (a ramp of one pixel centred there). Seeds past the end of `cuts` have none. A
/// cut and its opposite keep the window's weights symmetric about the estimate, so the
/// centroid of a point-symmetric particle stays unbiased (see `crate::spokes`). One entry a
/// seed, `None` for those dropped.
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine_centroids_with_cuts(
    signal: &[f32],
    width: usize,
    height: usize,
    seeds: &[[f64; 2]],
    areas: &[f64],
    window: f64,
    noise_sigma: f64,
    cuts: &[Vec<([f64; 2], f64)>],
    scratch: &mut LocateScratch,
) -> Vec<Option<Detection>> {
    let mut out = Vec::with_capacity(seeds.len());
    let image = Image {
        signal,
        width,
        height,
    };
    refine(&image, seeds, areas, window, noise_sigma, cuts, scratch, |d| {
        out.push(d)
    });
    out
}

/// The iteration of [`refine_centroids_with_cuts`]: `emit` gets each seed's detection in
/// order, `None` for those dropped (every seed's, where `image` is short of its size).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn refine(
    image: &Image<'_>,
    seeds: &[[f64; 2]],
    areas: &[f64],
    window: f64,
    noise_sigma: f64,
    cuts: &[Vec<([f64; 2], f64)>],
    scratch: &mut LocateScratch,
    mut emit: impl FnMut(Option<Detection>),
) {
    let n = seeds.len();
    if image.signal.len() < image.width * image.height {
        (0..n).for_each(|_| emit(None));
        return;
    }
    if n == 0 {
        return;
    }
    neighbour_lists(
        seeds,
        2.0 * window + 2.0,
        &mut scratch.neighbours,
        &mut scratch.offsets,
    );
    let mut pos: Vec<[f64; 2]> = seeds.to_vec();
    // Each estimate's previous step length (NaN before its first), px.
    let mut last_step = vec![f64::NAN; n];
    let mut alive = vec![true; n];
    let mut stats = vec![WindowStats::default(); n];
    let mut steps = vec![StepHistory::default(); n];
    // Seeds to measure in the coming iteration: at first all; then those that moved, or
    // whose neighbour moved or was dropped (their window split changed).
    let mut active = vec![true; n];
    let mut wake: Vec<u32> = Vec::with_capacity(n);
    let LocateScratch {
        neighbours,
        offsets,
        splits,
        rows,
    } = scratch;
    for _ in 0..MAX_ITERATIONS {
        wake.clear();
        for i in 0..n {
            if !active[i] || !alive[i] {
                continue;
            }
            collect_splits(splits, i, &pos, &alive, &neighbours[offsets[i]..offsets[i + 1]]);
            if let Some(c) = cuts.get(i) {
                splits.extend_from_slice(c);
            }
            let st = window_stats(image, pos[i], window, splits, rows);
            let c = [st.sx / st.mass, st.sy / st.mass];
            if st.mass <= 0.0 || norm([c[0] - seeds[i][0], c[1] - seeds[i][1]]) > window {
                alive[i] = false;
                wake.push(i as u32);
                continue;
            }
            let step = [c[0] - pos[i][0], c[1] - pos[i][1]];
            let length = norm(step);
            // Distance left from the new estimate to the fixed point: for steps that shrink
            // by a ratio `rho`, the rest of the geometric series, rho / (1 - rho) of the step
            // just taken (the standard a-posteriori bound of a contraction); unknown until
            // two steps are known.
            let rho = length / last_step[i];
            let left = if rho < 1.0 {
                length * rho / (1.0 - rho)
            } else {
                f64::INFINITY
            };
            last_step[i] = length;
            let ep = st.standard_error(noise_sigma);
            let tolerance = (TOLERANCE_OF_ERROR * ep).max(TOLERANCE);
            let mut c = c;
            if length > TOLERANCE && left > tolerance {
                wake.push(i as u32);
                c = accelerate(c, step, &mut steps[i]);
            } else {
                steps[i] = StepHistory::default();
            }
            // Gauss-Seidel: the neighbours measured after this one see its new position.
            pos[i] = c;
            stats[i] = st;
        }
        active.fill(false);
        if wake.is_empty() {
            break;
        }
        for &i in &wake {
            let i = i as usize;
            active[i] = true;
            for &j in &neighbours[offsets[i]..offsets[i + 1]] {
                active[j as usize] = true;
            }
        }
    }
    for i in 0..n {
        if !alive[i] {
            emit(None);
            continue;
        }
        // An estimate the next sweep would not measure (neither it nor a neighbour still
        // moving) has converged: its last window was centred within the tolerance of it, and
        // its neighbours then stood within the tolerance of where they are now, so its
        // statistics stand. The others, still moving when the sweeps ran out, are measured
        // once more where they stopped.
        let st = if !active[i] {
            stats[i]
        } else {
            collect_splits(splits, i, &pos, &alive, &neighbours[offsets[i]..offsets[i + 1]]);
            if let Some(c) = cuts.get(i) {
                splits.extend_from_slice(c);
            }
            window_stats(image, pos[i], window, splits, rows)
        };
        if st.mass <= 0.0 {
            emit(None);
            continue;
        }
        let [x, y] = pos[i];
        let rg2 = (st.sr2 / st.mass).max(0.0);
        emit(Some(Detection {
            x,
            y,
            mass: st.mass,
            size: rg2.sqrt(),
            ep: st.standard_error(noise_sigma),
            follow: st.follow(),
            area: areas.get(i).copied().unwrap_or(f64::NAN),
            clipped: st.clipped,
        }));
    }
}

/// The last plain centroid steps of one estimate, for [`accelerate`].
#[derive(Clone, Copy, Debug, Default)]
struct StepHistory {
    /// The previous step, px, if the estimate took a plain step last time.
    last: Option<[f64; 2]>,
}

/// Largest contraction per step that [`accelerate`] extrapolates (beyond it the steps are
/// too erratic to trust their ratio).
const MAX_CONTRACTION: f64 = 0.95;

/// The estimate after a plain centroid step `step` (px) that led to `c`, extrapolated to
/// the iteration's limit when two successive plain steps point the same way and shrink by a
/// steady factor λ (linear convergence, as when part of a blob lies in the window's edge
/// ramp): the remaining steps sum to `step λ / (1 − λ)` (Aitken's Δ² process). The fixed
/// point is unchanged, since iteration goes on until a plain step is below the tolerance;
/// only the slow creep towards it is skipped.
fn accelerate(c: [f64; 2], step: [f64; 2], history: &mut StepHistory) -> [f64; 2] {
    let Some(last) = history.last else {
        history.last = Some(step);
        return c;
    };
    let dot = step[0] * last[0] + step[1] * last[1];
    let last2 = last[0] * last[0] + last[1] * last[1];
    let step2 = step[0] * step[0] + step[1] * step[1];
    // Ratio along the previous step, and how well the two steps line up.
    let lambda = dot / last2;
    let aligned = dot * dot >= 0.9 * 0.9 * last2 * step2;
    if !(lambda > 0.0 && lambda < MAX_CONTRACTION && aligned) {
        history.last = Some(step);
        return c;
    }
    // The next step starts from an extrapolated point: no plain step to compare it with.
    history.last = None;
    let k = (lambda / (1.0 - lambda)).min(1.0 / step2.sqrt());
    [c[0] + k * step[0], c[1] + k * step[1]]
}

/// Length of `v`, px. Window offsets are a few pixels, far from overflow, so this skips
/// `hypot`'s guard against it (a library call that took 3 % of the tracker's time at
/// N = 1000, called for every step and every neighbour's split).
fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

/// The signal image a window reads.
struct Image<'a> {
    signal: &'a [f32],
    width: usize,
    height: usize,
}

#[derive(Clone, Copy, Debug, Default)]
struct WindowStats {
    mass: f64,
    /// Σ w s x (absolute column), so `sx / mass` is the centroid's x.
    sx: f64,
    /// Σ w s y (absolute row), so `sy / mass` is the centroid's y.
    sy: f64,
    /// Σ w s r² about the window centre.
    sr2: f64,
    /// Σ w² r² about the window centre.
    w2r2: f64,
    /// Σ f s r over the window's edge ramp (`0 < w < 1` before the split factor `f`): the
    /// derivative of `Σ w s (x − c)` with respect to the window's centre, summed over both
    /// axes.
    ramp_sr: f64,
    clipped: bool,
}

impl WindowStats {
    /// Standard error of the window's centroid on one axis, px, averaged over both, for
    /// pixel noise `noise_sigma` (grey levels).
    fn standard_error(&self, noise_sigma: f64) -> f64 {
        noise_sigma * (0.5 * self.w2r2).sqrt() / self.mass
    }

    /// How far the window's centroid follows the window, in `[0, MAX_FOLLOW]`.
    fn follow(&self) -> f64 {
        (0.5 * self.ramp_sr / self.mass).clamp(0.0, MAX_FOLLOW)
    }
}

/// Replaces `splits` with the bisectors between estimate `i` and each of its live
/// `neighbours` (indices into `pos`).
fn collect_splits(
    splits: &mut Vec<([f64; 2], f64)>,
    i: usize,
    pos: &[[f64; 2]],
    alive: &[bool],
    neighbours: &[u32],
) {
    splits.clear();
    for &j in neighbours {
        if alive[j as usize] {
            push_split(splits, pos[i], pos[j as usize]);
        }
    }
}

/// Adds the bisector between `c` and a neighbour at `o`: the unit normal towards the
/// neighbour and the bisector's offset along it from `c`.
fn push_split(splits: &mut Vec<([f64; 2], f64)>, c: [f64; 2], o: [f64; 2]) {
    let d = [o[0] - c[0], o[1] - c[1]];
    let len = norm(d);
    if len > 1e-9 {
        splits.push(([d[0] / len, d[1] / len], 0.5 * len));
    }
}

/// Weighted sums of the signal in the circular window of radius `window` about `c`.
///
/// Row by row, the weights `clamp(W + 1/2 − r, 0, 1)` (times the soft splits) and the
/// products are formed and summed lane-wise in `f32` (vectorised) relative to the centre:
/// offsets of a few pixels and at most a few hundred terms per lane, so single precision
/// costs about 1e-6 px on the centroid, far below the convergence tolerance.
fn window_stats(
    image: &Image<'_>,
    c: [f64; 2],
    window: f64,
    splits: &[([f64; 2], f64)],
    rows: &mut RowBuffers,
) -> WindowStats {
    let (width, height) = (image.width, image.height);
    let reach = window + 0.5;
    let x0 = (c[0] - reach).floor() as i64;
    let x1 = (c[0] + reach).ceil() as i64;
    let y0 = (c[1] - reach).floor() as i64;
    let y1 = (c[1] + reach).ceil() as i64;
    let mut st = WindowStats {
        clipped: x0 < 0 || y0 < 0 || x1 >= width as i64 || y1 >= height as i64,
        ..Default::default()
    };
    let xa = x0.max(0);
    let xb = x1.min(width as i64 - 1);
    let ya = y0.max(0);
    let yb = y1.min(height as i64 - 1);
    if xa > xb || ya > yb {
        return st;
    }
    let (xa, xb) = (xa as usize, xb as usize);
    let n = xb - xa + 1;
    let padded = n.div_ceil(LANES) * LANES;
    // Offsets from the centre; padding columns lie beyond the window's reach, so their
    // weight is 0 whatever signal they read.
    let dx0 = (xa as f64 - c[0]) as f32;
    rows.dx.clear();
    rows.dx.extend((0..padded).map(|k| dx0 + k as f32));
    rows.s.resize(padded, 0.0);
    let reach32 = reach as f32;
    let (dx_first, dx_last) = (rows.dx[0], rows.dx[n - 1]);
    rows.window_splits.clear();
    rows.window_splits.extend(splits.iter().map(|&(nv, half)| {
        let (n0, n1) = (nv[0] as f32, nv[1] as f32);
        WindowSplit {
            n: [n0, n1],
            offset: half as f32 + 0.5,
            reach_x: (dx_first * n0).max(dx_last * n0),
        }
    }));
    // Lane-wise sums over the whole window: Σ ws, Σ ws dx, Σ ws dy, Σ ws r², Σ w² r²,
    // Σ_ramp f s r.
    let mut acc = [[0.0f32; LANES]; SUMS];
    for y in ya as usize..=yb as usize {
        let dy = (y as f64 - c[1]) as f32;
        // Rows wholly outside the circle hold no weight.
        if dy.abs() >= reach32 {
            continue;
        }
        let start = y * width + xa;
        // Read the row in place when whole lanes fit in the image row (the extra columns
        // lie beyond the window's right edge, outside the circle), else from a zero-padded
        // copy.
        let srow: &[f32] = if xa + padded <= width {
            &image.signal[start..start + padded]
        } else {
            rows.s[..n].copy_from_slice(&image.signal[start..start + n]);
            rows.s[n..].fill(0.0);
            &rows.s
        };
        rows.splits.clear();
        for split in &rows.window_splits {
            let base = split.offset - dy * split.n[1];
            // The split is 1 along the whole row when the row's nearest pixel to the
            // neighbour is a pixel short of the bisector.
            if base - split.reach_x < 1.0 {
                rows.splits.push([split.n[0], base]);
            }
        }
        accumulate_row(
            &mut acc,
            &Row {
                dx: &rows.dx,
                s: srow,
                splits: &rows.splits,
                dy,
                reach: reach32,
            },
        );
    }
    let [mass, sdx, sdy, sr2, w2r2, ramp_sr] = acc.map(|a| a.iter().map(|&v| f64::from(v)).sum::<f64>());
    st.mass = mass;
    st.sx = sdx + c[0] * mass;
    st.sy = sdy + c[1] * mass;
    st.sr2 = sr2;
    st.w2r2 = w2r2;
    st.ramp_sr = ramp_sr;
    st
}

/// `x` clamped to `[0, 1]` as two selects, which vectorise (`f32::clamp`'s NaN rules made
/// the compiler test each lane with a branch).
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline(always)]
fn unit_ramp(x: f32) -> f32 {
    let x = if x > 1.0 { 1.0 } else { x };
    let positive = f32::from(u8::from(x > 0.0));
    x * positive
}

/// One window row as [`window_stats`] sums it, lane-padded alike: each pixel's offset from
/// the centre `dx` (px) and its signal `s` (grey levels), the splits that cut the row (each
/// `[n0, base]`: a pixel's split factor is `unit_ramp(base − dx n0)`, the product over the
/// row's splits), the row's offset `dy` (px) and the window's ramp end `reach` (px).
struct Row<'a> {
    dx: &'a [f32],
    s: &'a [f32],
    splits: &'a [[f32; 2]],
    dy: f32,
    reach: f32,
}

/// Adds `row` to the lane-wise sums `acc` of [`window_stats`]: per pixel the weight
/// `w = unit_ramp(reach − r)` (times the split factor `f`, formed first), then `w s`,
/// `w s dx`, `w s dy`, `w s r²`, `w² r²` and, on the ramp (`0 < unit_ramp(reach − r) < 1`),
/// `f s r`, each lane summing every fourth pixel.
#[inline(always)]
fn accumulate_row(acc: &mut [[f32; LANES]; SUMS], row: &Row<'_>) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86_64 baseline.
    unsafe {
        accumulate_row_sse2(acc, row)
    }
    #[cfg(not(target_arch = "x86_64"))]
    accumulate_row_portable(acc, row);
}

/// [`accumulate_row`] in plain Rust, the operations in the kernel's order.
#[cfg(any(test, not(target_arch = "x86_64")))]
fn accumulate_row_portable(acc: &mut [[f32; LANES]; SUMS], row: &Row<'_>) {
    let dy2 = row.dy * row.dy;
    let chunks = row.dx.len().min(row.s.len()) / LANES;
    for (at, (&dx, &signal)) in row.dx.iter().zip(row.s).enumerate().take(chunks * LANES) {
        let l = at % LANES;
        let r2 = dx * dx + dy2;
        let r = r2.sqrt();
        let ramp = unit_ramp(row.reach - r);
        let mut w = ramp;
        let mut split = 1.0;
        if let Some((&[n0, base], rest)) = row.splits.split_first() {
            let f = rest.iter().fold(unit_ramp(base - dx * n0), |f, &[n0, base]| {
                f * unit_ramp(base - dx * n0)
            });
            w *= f;
            split = f;
        }
        let ws = w * signal;
        acc[0][l] += ws;
        acc[1][l] += ws * dx;
        acc[2][l] += ws * row.dy;
        acc[3][l] += ws * r2;
        acc[4][l] += w * w * r2;
        let on_ramp = ramp > 0.0 && ramp < 1.0;
        acc[5][l] += if on_ramp { split * signal * r } else { 0.0 };
    }
}

/// [`accumulate_row`] four pixels at a time, the sums held in registers. The portable loop,
/// as compiled for x86_64, moved single lanes with shuffles: this kernel took a quarter off
/// the tracker's instructions at N = 1000. The same operations in the same order as the
/// portable loop, lane by lane, so the sums are equal to the bit (the ramp's `max(x, 0)`
/// gives +0 where the portable form gives −0, which adds nothing to a sum).
///
/// # Safety
/// The CPU must have SSE2 (every x86_64 does).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
unsafe fn accumulate_row_sse2(acc: &mut [[f32; LANES]; SUMS], row: &Row<'_>) {
    use std::arch::x86_64::{
        _mm_add_ps, _mm_and_ps, _mm_cmpgt_ps, _mm_cmplt_ps, _mm_loadu_ps, _mm_max_ps, _mm_min_ps, _mm_mul_ps,
        _mm_set1_ps, _mm_setzero_ps, _mm_sqrt_ps, _mm_storeu_ps, _mm_sub_ps,
    };
    let Row {
        dx,
        s,
        splits,
        dy,
        reach,
    } = *row;
    let chunks = dx.len().min(s.len()) / LANES;
    // SAFETY (all loads and stores): `acc`'s rows hold LANES values each, and chunk `c` reads
    // elements LANES c .. LANES (c + 1), within every slice by the bound on `chunks`.
    unsafe {
        let mut sums = acc.map(|lanes| _mm_loadu_ps(lanes.as_ptr()));
        let (dyv, dy2, reachv) = (_mm_set1_ps(dy), _mm_set1_ps(dy * dy), _mm_set1_ps(reach));
        let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
        for c in 0..chunks {
            let at = c * LANES;
            let d = _mm_loadu_ps(dx.as_ptr().add(at));
            let r2 = _mm_add_ps(_mm_mul_ps(d, d), dy2);
            let r = _mm_sqrt_ps(r2);
            let ramp = _mm_max_ps(_mm_min_ps(_mm_sub_ps(reachv, r), one), zero);
            let mut w = ramp;
            let signal = _mm_loadu_ps(s.as_ptr().add(at));
            // The split factor's share of the ramp sum: `f s r`, or `s r` without splits.
            let mut split_signal = signal;
            if let Some((&[n0, base], rest)) = splits.split_first() {
                let ramp = |n0: f32, base: f32| {
                    let x = _mm_sub_ps(_mm_set1_ps(base), _mm_mul_ps(d, _mm_set1_ps(n0)));
                    _mm_max_ps(_mm_min_ps(x, one), zero)
                };
                let f = rest
                    .iter()
                    .fold(ramp(n0, base), |f, &[n0, base]| _mm_mul_ps(f, ramp(n0, base)));
                w = _mm_mul_ps(w, f);
                split_signal = _mm_mul_ps(f, signal);
            }
            let ws = _mm_mul_ps(w, signal);
            sums[0] = _mm_add_ps(sums[0], ws);
            sums[1] = _mm_add_ps(sums[1], _mm_mul_ps(ws, d));
            sums[2] = _mm_add_ps(sums[2], _mm_mul_ps(ws, dyv));
            sums[3] = _mm_add_ps(sums[3], _mm_mul_ps(ws, r2));
            sums[4] = _mm_add_ps(sums[4], _mm_mul_ps(_mm_mul_ps(w, w), r2));
            let on_ramp = _mm_and_ps(_mm_cmpgt_ps(ramp, zero), _mm_cmplt_ps(ramp, one));
            sums[5] = _mm_add_ps(sums[5], _mm_and_ps(on_ramp, _mm_mul_ps(split_signal, r)));
        }
        for (lanes, v) in acc.iter_mut().zip(sums) {
            _mm_storeu_ps(lanes.as_mut_ptr(), v);
        }
    }
}

/// For each point, the indices of the other points closer than `reach` px, as
/// concatenated lists (`neighbours[offsets[i]..offsets[i + 1]]`).
fn neighbour_lists(points: &[[f64; 2]], reach: f64, neighbours: &mut Vec<u32>, offsets: &mut Vec<usize>) {
    let n = points.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| points[a][0].total_cmp(&points[b][0]));
    let r2 = reach * reach;
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            let dx = points[j][0] - points[i][0];
            if dx >= reach {
                break;
            }
            let dy = points[j][1] - points[i][1];
            if dx * dx + dy * dy < r2 {
                pairs.push((i as u32, j as u32));
                pairs.push((j as u32, i as u32));
            }
        }
    }
    pairs.sort_unstable();
    neighbours.clear();
    neighbours.extend(pairs.iter().map(|p| p.1));
    offsets.clear();
    offsets.resize(n + 1, 0);
    for p in &pairs {
        offsets[p.0 as usize + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The SSE2 row sums equal the portable loop's to the bit, with none, one and three
    /// splits (cutting the row or not), on rows that reach past the window and rows wholly
    /// inside it.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sse2_row_sums_equal_the_portable_loop() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
        for case in 0..40 {
            let n = 4 * (1 + case % 5);
            let dx0 = -(n as f32) / 2.0 + rng.gen::<f32>();
            let dx: Vec<f32> = (0..n).map(|k| dx0 + k as f32).collect();
            let s: Vec<f32> = (0..n).map(|_| rng.gen_range(-20.0..230.0)).collect();
            // Bisectors at random angles and offsets, cutting the row or not.
            let cuts: Vec<[f32; 2]> = (0..3)
                .map(|_| {
                    let angle = rng.gen_range(0.0..std::f32::consts::TAU);
                    [angle.cos(), rng.gen_range(-3.0..6.0)]
                })
                .collect();
            let (dy, reach) = (rng.gen_range(-3.0..3.0), rng.gen_range(2.0..6.0));
            for splits in [&cuts[..0], &cuts[..1], &cuts[..]] {
                let row = Row {
                    dx: &dx,
                    s: &s,
                    splits,
                    dy,
                    reach,
                };
                let start = [[0.5f32; LANES]; SUMS];
                let (mut a, mut b) = (start, start);
                accumulate_row_portable(&mut a, &row);
                // SAFETY: every x86_64 has SSE2.
                unsafe { accumulate_row_sse2(&mut b, &row) };
                let bits = |m: [[f32; LANES]; SUMS]| m.map(|r| r.map(f32::to_bits));
                assert_eq!(bits(a), bits(b), "case {case}, {} splits", splits.len());
            }
        }
    }

    /// A disc of radius `r` with exact area coverage from 16x16 supersampling.
    /// Adds a disc of amplitude `amp` with exact area coverage (the project's renderer), so
    /// the test image itself carries no centroid bias.
    pub(crate) fn render_disc(img: &mut [f32], w: usize, h: usize, c: [f64; 2], r: f64, amp: f32) {
        let mut plane = vec![0.0f32; w * h];
        physfit_render::add_disc_coverage(
            &mut plane,
            w as u32,
            h as u32,
            physfit_model::Vec2::new(c[0], c[1]),
            r,
        );
        for (p, cov) in img.iter_mut().zip(&plane) {
            *p += amp * cov;
        }
    }

    /// Scatter of the fixed point against `ep` (px, both averaged over the axes) for a
    /// Gaussian spot of standard deviation `sigma_g` px and peak 60 under white noise of 20
    /// grey levels, located with a window of `window` px from its true centre, over 400 noise
    /// draws.
    fn scatter_and_ep(sigma_g: f64, window: f64) -> (f64, f64) {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0f32, 20.0).expect("a normal law");
        let (w, h) = (160usize, 160usize);
        let c = [80.3, 79.6];
        let clean: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 - c[0], (i / w) as f64 - c[1]);
                (60.0 * (-(x * x + y * y) / (2.0 * sigma_g * sigma_g)).exp()) as f32
            })
            .collect();
        let (mut sum2, mut eps) = (0.0, Vec::new());
        for _ in 0..400 {
            let img: Vec<f32> = clean.iter().map(|v| v + noise.sample(&mut rng)).collect();
            let d = refine_centroids(&img, w, h, &[c], &[f64::NAN], window, 20.0);
            sum2 += 0.5 * ((d[0].x - c[0]).powi(2) + (d[0].y - c[1]).powi(2));
            eps.push(d[0].fixed_point_error());
        }
        eps.sort_by(f64::total_cmp);
        ((sum2 / 400.0).sqrt(), eps[200])
    }

    /// A window short of a Gaussian spot holds a nearly flat part of it and follows itself
    /// (`j` about 0.7 at one standard deviation): the fixed point scatters about three times
    /// the window's own error, and `ep` says so. A window reaching three standard deviations
    /// (`j` near 0) keeps its error. Each within 20 % of the scatter measured.
    #[test]
    fn ep_holds_the_scatter_of_a_window_that_follows_itself() {
        for (sigma_g, window) in [(20.0, 20.0), (8.0, 24.0)] {
            let (scatter, ep) = scatter_and_ep(sigma_g, window);
            let ratio = ep / scatter;
            assert!(
                (0.8..1.25).contains(&ratio),
                "spot {sigma_g} px, window {window} px: scatter {scatter:.3} px, ep {ep:.3} px"
            );
        }
    }

    #[test]
    fn no_pixel_locking_on_a_noise_free_disc() {
        let (w, h) = (32, 32);
        let mut worst: f64 = 0.0;
        let mut sum_sq = 0.0;
        for k in 0..10 {
            let c = [15.0 + 0.1 * k as f64, 16.0 - 0.07 * k as f64];
            let mut img = vec![0.0f32; w * h];
            render_disc(&mut img, w, h, c, 4.0, 200.0);
            let seed = [c[0].round(), c[1].round()];
            let d = refine_centroids(&img, w, h, &[seed], &[0.0], 5.0, 1.0);
            assert_eq!(d.len(), 1);
            worst = worst.max((d[0].x - c[0]).abs()).max((d[0].y - c[1]).abs());
            sum_sq += (d[0].x - c[0]).powi(2) + (d[0].y - c[1]).powi(2);
            // A uniform disc of radius R has radius of gyration R/sqrt(2).
            assert!((d[0].size - 4.0 / 2f64.sqrt()).abs() < 0.05, "size {}", d[0].size);
        }
        // The bar: trackpy reaches 0.004 px RMS per axis on noise-free discs.
        let rms = (sum_sq / 20.0).sqrt();
        assert!(rms < 4e-3 && worst < 4e-3, "rms {rms} worst {worst}");
    }

    #[test]
    fn touching_discs_are_located_without_pulling_each_other() {
        let (w, h) = (40, 30);
        let mut img = vec![0.0f32; w * h];
        let (a, b) = ([15.3, 14.8], [23.4, 15.1]);
        render_disc(&mut img, w, h, a, 4.0, 200.0);
        render_disc(&mut img, w, h, b, 4.0, 200.0);
        let d = refine_centroids(&img, w, h, &[[15.0, 15.0], [23.0, 15.0]], &[0.0, 0.0], 5.0, 1.0);
        assert_eq!(d.len(), 2);
        for (det, t) in d.iter().zip([a, b]) {
            assert!(
                (det.x - t[0]).abs() < 0.05 && (det.y - t[1]).abs() < 0.05,
                "{det:?} vs {t:?}"
            );
        }
    }
}
