//! Jolts: isolated frames where a particle's velocity jumps far beyond what smooth motion and
//! the track noise allow (a bounce), and the walls they suggest.
//!
//! Let `e[j] = x[j+1] - x[j] - sum_{i<=j} a[i] dt^2` be the frame differences with the model's
//! smooth accelerations `a` integrated out: for motion the model explains, `e` is constant up
//! to noise, and an impulse in the gap `k -> k + 1` makes it jump. The jump is estimated as
//! the mean of the [`JOLT_FIT_POINTS`] values after the gap minus the mean of as many before
//! it (the difference straddling the gap is left out), over `dt`: the unexplained impulse
//! per unit mass `J`, with noise `2 sigma / (m dt)` per coordinate for position noise `sigma`.
//! The scale used is the larger of that and a robust spread (median absolute value) of all
//! impulses, so a poor model does not make jolts of its misfit. A gap whose impulse exceeds
//! [`JOLT_THRESHOLD`] times the scale, is the largest within `m` frames, and reverses the
//! velocity along it (approaching, then leaving: a bounce, not a kick; along a direction within
//! [`JOLT_DIRECTION_ERRORS`] of the impulse's, whose angle is only known to the impulse's
//! relative noise) is a jolt.
//!
//! Within [`JOLT_FIT_POINTS`] frames of an end, the means take as many values as the short
//! side has (at least [`MIN_EDGE_POINTS`]), with the noise part of the scale grown to match
//! (`2 sigma / (m' dt)`): a bounce three frames into a 23-frame recording is seen. There a
//! contact that starts or ends with the recording (a ball leaving a shelf) also changes the
//! means, so a jolt near an end must also approach the wall at half its impulse or more
//! (within one scale): a wall's impulse is `1 + e` times the approach speed, `0 <= e <= 1`.
//!
//! A missing smooth force that turns a particle round (a stiff tether's radial oscillation)
//! also makes a large, locally largest, reversing jump of the means, but spread over the
//! gaps, not concentrated in one. The *local jump* `2 e[k+1] - 2 e[k-1] + e[k-2] - e[k+2]`
//! (the step across the gap less the two flanking second differences) is the full impulse
//! for a bounce and zero for any acceleration linear in time (a third-order remainder for a
//! curved one); its noise is `sqrt(28) sigma` per coordinate. A candidate whose local jumps
//! along its impulse, at its gap and at the two next to it (the means' peak can be a gap off
//! the bounce near the ends of the series), all fall short of half the jump of the means
//! (halfway between a bounce and smooth motion) by more than [`JOLT_THRESHOLD`] times that
//! noise is smooth motion, not a jolt.
//!
//! A wall reverses the normal velocity and keeps the tangential one, so its jolts have jumps
//! along its normal: jolts are grouped by jump direction, each group gives a normal (mean
//! jump direction), a restitution (median of `-v_n after / v_n before`) and a line position
//! from each bounce's two frames (the centre met the line in between, approaching at
//! `v_n before` and leaving at `-e v_n before`).

use physfit_model::Vec2;
use serde::Serialize;

use crate::Observations;

/// Frames averaged on each side of a gap.
pub const JOLT_FIT_POINTS: usize = 4;

/// Fewest frame differences averaged on each side of a gap within [`JOLT_FIT_POINTS`] frames
/// of an end of the recording.
pub const MIN_EDGE_POINTS: usize = 2;

/// A jump must exceed this many times its noise scale to be a jolt.
pub const JOLT_THRESHOLD: f64 = 5.0;

/// Angular standard errors of an impulse's direction within which a jolt must reverse the
/// velocity (see `reverses`).
pub const JOLT_DIRECTION_ERRORS: f64 = 3.0;

/// Least distance (px) a tracked centre may seem to cross a proposed wall before the wall is
/// dropped (also at least five track noises and a bounce's frame of travel): the line's
/// position from the bounces is only estimated to about this.
pub const WALL_CROSSING_PX: f64 = 2.0;

/// Largest angle between the jumps of one wall's jolts, degrees.
pub const WALL_GROUP_DEGREES: f64 = 25.0;

/// An impulsive velocity change of one particle.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Jolt {
    /// Particle index.
    pub particle: usize,
    /// Absolute frame index `k`: the jump happened between frames `k` and `k + 1`.
    pub frame: usize,
    /// Position at frame `k`, px.
    pub position: [f64; 2],
    /// Velocity before the jump, px/s.
    pub before: [f64; 2],
    /// Velocity after the jump, px/s.
    pub after: [f64; 2],
    /// Impulse per unit mass across the gap, beyond the model's smooth forces, px/s.
    pub impulse: [f64; 2],
    /// Jump size over its noise scale.
    pub significance: f64,
}

impl Jolt {
    /// A jolt of `particle` across the gap after absolute frame `frame`, at `position` (px),
    /// with velocities `before` and `after` (px/s), `impulse` (px/s) and `significance`.
    pub fn new(
        particle: usize,
        frame: usize,
        position: Vec2,
        before: Vec2,
        after: Vec2,
        impulse: Vec2,
        significance: f64,
    ) -> Self {
        Jolt {
            particle,
            frame,
            position: [position.x, position.y],
            before: [before.x, before.y],
            after: [after.x, after.y],
            impulse: [impulse.x, impulse.y],
            significance,
        }
    }
}

/// The means' impulse across one gap of one particle's series.
#[derive(Clone, Copy, Debug)]
struct Gap {
    /// Impulse per unit mass beyond the model's smooth forces, px/s.
    impulse: Vec2,
    /// Velocity before the gap, px/s.
    before: Vec2,
    /// Velocity after it, px/s.
    after: Vec2,
    /// Frame differences averaged on each side ([`JOLT_FIT_POINTS`], fewer near an end).
    points: usize,
}

/// A wall suggested by a group of jolts.
#[derive(Clone, Debug, PartialEq)]
pub struct WallGuess {
    /// `[normal_angle (rad), offset (px), restitution]` (see [`super::Effect::Wall`]).
    pub params: [f64; 3],
    /// The jolts it explains (copies: the jolt list is found again each round, so indices
    /// into it would go stale).
    pub jolts: Vec<Jolt>,
}

/// What one pass over a recording's frame differences finds (see [`scan_jolts`]).
#[derive(Clone, Debug, Default)]
pub struct Scan {
    /// The jolts: gaps that pass every test against the larger of the track noise and the
    /// robust spread of all impulses.
    pub jolts: Vec<Jolt>,
    /// The faint jolts: gaps that pass every test against the track noise alone, but not
    /// against the robust spread, while their local jump along the impulse exceeds
    /// [`JOLT_THRESHOLD`] times the larger of its noise and the robust spread of every gap's
    /// local jump. A poor smooth model (a short recording whose springs the weak form cannot
    /// tell) raises the means' spread over a bounce's impulse and partly absorbs it, while the
    /// local jump, blind to any acceleration linear in time, still holds the whole impulse.
    /// Their impulse is the local jump, and their significance its size over that scale.
    pub faint: Vec<Jolt>,
    /// The end jolts (see [`end_jolts`]).
    pub ends: Vec<Jolt>,
    /// The noise scale of the impulses, px/s.
    pub scale: f64,
}

/// The jolts, faint jolts and end jolts in `obs` (free particles only), from one computation
/// of the frame differences. Faint and end jolts only propose walls, which the multi-step fit
/// confirms or refuses.
///
/// `acc[k][p]`, when given, is the model's acceleration of particle `p` at frame offset `k`
/// (px/s²), removed from the impulses so that smooth forces are not mistaken for jolts.
pub fn scan_jolts(obs: &Observations, acc: Option<&[Option<Vec<Vec2>>]>) -> Scan {
    let differences: Vec<Option<Differences>> = (0..obs.particle_count())
        .map(|p| (!obs.fixed[p]).then(|| corrected_differences(obs, acc, p)))
        .collect();
    let (tagged, scale) = scan(obs, &differences);
    let (jolts, faint): (Vec<_>, Vec<_>) = tagged.into_iter().partition(|(_, strict)| *strict);
    Scan {
        jolts: jolts.into_iter().map(|(j, _)| j).collect(),
        faint: faint.into_iter().map(|(j, _)| j).collect(),
        ends: end_jolts(obs, &differences),
        scale,
    }
}

/// Every gap that passes the jolt tests, flagged `true` where it passes them against the
/// robust spread of all impulses and `false` where it is only faint (see [`Scan::faint`]);
/// and that robust scale (px/s). `differences[p]` are particle `p`'s corrected differences
/// (None for a fixed one).
fn scan(obs: &Observations, differences: &[Option<Differences>]) -> (Vec<(Jolt, bool)>, f64) {
    let m = JOLT_FIT_POINTS;
    let fps = obs.fps;
    // mean(x[k+1+m] - x[k+1]) / m - mean(x[k] - x[k-m]) / m: noise 2 sigma / m per coordinate.
    let noise_scale = 2.0 * obs.noise * fps / m as f64;
    // The local jump's noise per coordinate, px/s (see the module doc).
    let local_noise = 28f64.sqrt() * obs.noise * fps;
    let frames = obs.frame_count();
    // Per particle and gap: the means' impulse.
    let mut series: Vec<Vec<Option<Gap>>> = vec![vec![None; frames]; obs.particle_count()];
    // Per particle and gap: the local jump (see the module doc), px/s.
    let mut local: Vec<Vec<Option<Vec<Vec2>>>> = vec![vec![None; frames]; obs.particle_count()];
    let mut magnitudes = Vec::new();
    let mut local_magnitudes = Vec::new();
    for (p, (out, out_local)) in series.iter_mut().zip(local.iter_mut()).enumerate() {
        let Some((e, cum)) = &differences[p] else {
            continue;
        };
        // Within `m` frames of an end, as many differences as there are on the short side
        // (at least MIN_EDGE_POINTS): a bounce near an end of a short recording.
        for k in MIN_EDGE_POINTS..frames.saturating_sub(MIN_EDGE_POINTS + 1) {
            let mk = m.min(k).min(frames - 2 - k);
            if mk < MIN_EDGE_POINTS {
                continue;
            }
            let before: Option<Vec<Vec2>> = (k - mk..k).map(|j| e[j]).collect();
            let after: Option<Vec<Vec2>> = (k + 1..=k + mk).map(|j| e[j]).collect();
            if let (Some(b), Some(a)) = (before, after) {
                let mb = b.iter().sum::<Vec2>() / mk as f64;
                let ma = a.iter().sum::<Vec2>() / mk as f64;
                let impulse = (ma - mb) * fps;
                if mk == m {
                    magnitudes.push(impulse.x.abs());
                    magnitudes.push(impulse.y.abs());
                }
                out[k] = Some(Gap {
                    impulse,
                    before: (mb + cum[k - 1]) * fps,
                    after: (ma + cum[k + 1]) * fps,
                    points: mk,
                });
                // The bounce may lie in a neighbouring gap (the means' peak is shifted near the
                // ends of the series): the local jumps of gaps k - 1, k and k + 1.
                let at = |j: usize| e.get(j).copied().flatten();
                let jump = |g: usize| -> Option<Vec2> {
                    Some(
                        (2.0 * (at(g + 1)? - at(g.checked_sub(1)?)?) + at(g.checked_sub(2)?)? - at(g + 2)?)
                            * fps,
                    )
                };
                out_local[k] = [k - 1, k, k + 1]
                    .iter()
                    .map(|&g| jump(g))
                    .collect::<Option<Vec<Vec2>>>();
                if let Some(j) = jump(k) {
                    local_magnitudes.push(j.x.abs());
                    local_magnitudes.push(j.y.abs());
                }
            }
        }
    }
    if magnitudes.is_empty() {
        return (Vec::new(), noise_scale);
    }
    magnitudes.sort_by(|a, b| a.total_cmp(b));
    let robust = 1.4826 * magnitudes[magnitudes.len() / 2];
    local_magnitudes.sort_by(|a, b| a.total_cmp(b));
    let local_scale = local_magnitudes
        .get(local_magnitudes.len() / 2)
        .map_or(local_noise, |&m| local_noise.max(1.4826 * m));
    // A gap's scale: fewer differences averaged near an end leave more noise (the misfit's
    // part, which grows with the frames averaged, is kept at the interior's).
    // Exact tracks leave every impulse but the bounces' at zero: the scale's floor is relative
    // to the largest impulse, so that significances stay finite and comparable.
    let largest = series
        .iter()
        .flatten()
        .flatten()
        .map(|g| g.impulse.norm())
        .fold(0.0, f64::max);
    let floor = (1e-12 * largest).max(f64::MIN_POSITIVE);
    let noise_of = |mk: usize| (noise_scale * m as f64 / mk as f64).max(floor);
    let scale_of = |mk: usize| noise_of(mk).max(robust);
    let significance = |g: &Gap| g.impulse.norm() / scale_of(g.points);
    let mut out = Vec::new();
    for (p, series) in series.iter().enumerate() {
        for k in 0..frames {
            let Some(gap) = series[k] else { continue };
            let Gap {
                impulse: imp,
                before: vb,
                after: va,
                points: mk,
            } = gap;
            let size = imp.norm();
            let scale = noise_of(mk);
            if size < JOLT_THRESHOLD * scale {
                continue;
            }
            let full = scale_of(mk);
            let strict = size >= JOLT_THRESHOLD * full;
            let lo = k.saturating_sub(m);
            let hi = (k + m).min(frames - 1);
            let own = significance(&gap);
            let is_peak = (lo..=hi).all(|q| q == k || series[q].map_or(true, |i| significance(&i) < own));
            if !is_peak {
                continue;
            }
            // A bounce reverses the velocity along its impulse: approaching, then leaving.
            let n = imp / size;
            if !reverses(vb, va, n, full / size) {
                continue;
            }
            // Near an end, where the means see fewer frames and a contact that starts or ends
            // there (a ball leaving a shelf) also changes them: a wall's impulse is `1 + e`
            // times the approach speed along it (`0 <= e <= 1`), so the particle must approach
            // at least half the impulse, within one scale.
            let approaches = mk == m || -vb.dot(&n) >= 0.5 * size - full;
            // Spread over the gaps rather than concentrated in one: smooth motion.
            let local_jumps = local[p][k].as_deref().unwrap_or(&[]);
            let best_local = local_jumps
                .iter()
                .copied()
                .max_by(|a, b| a.dot(&n).total_cmp(&b.dot(&n)));
            let concentrated = best_local.map_or(true, |best| {
                best.dot(&n) + JOLT_THRESHOLD * local_noise >= 0.5 * size
            });
            let strict = strict && approaches && concentrated;
            // A faint one's local jump stands out of every gap's (see `Scan::faint`); it is
            // then the impulse, the means' being partly absorbed by the poor model.
            let faint = best_local.filter(|best| !strict && best.dot(&n) >= JOLT_THRESHOLD * local_scale);
            if !strict && faint.is_none() {
                continue;
            }
            let imp = faint.unwrap_or(imp);
            let own = faint.map_or(own, |best| best.norm() / local_scale);
            let x = obs.positions[k][p].unwrap_or_else(Vec2::zeros);
            out.push((Jolt::new(p, obs.first_frame + k, x, vb, va, imp, own), strict));
        }
    }
    (out, scale_of(m))
}

/// A particle's corrected frame differences and cumulative model term (see
/// [`corrected_differences`]), px.
type Differences = (Vec<Option<Vec2>>, Vec<Vec2>);

/// Particle `p`'s frame differences with the model's accelerations `acc` integrated out,
/// `e[j] = x[j+1] - x[j] - sum_{i<=j} a[i] dt^2` (None where a frame is missing), and the
/// cumulative model term `sum_{i<=j} a[i] dt^2` (px).
fn corrected_differences(obs: &Observations, acc: Option<&[Option<Vec<Vec2>>]>, p: usize) -> Differences {
    let frames = obs.frame_count();
    let dt = obs.frame_dt();
    let mut e = vec![None; frames];
    let mut cum = vec![Vec2::zeros(); frames];
    let mut total = Vec2::zeros();
    for j in 0..frames.saturating_sub(1) {
        let a = acc
            .and_then(|a| a.get(j)?.as_ref()?.get(p).copied())
            .unwrap_or_else(Vec2::zeros);
        total += a * (dt * dt);
        cum[j] = total;
        if let (Some(a), Some(b)) = (obs.positions[j][p], obs.positions[j + 1][p]) {
            e[j] = Some(b - a - total);
        }
    }
    (e, cum)
}

/// Bounces in the gaps the means of [`scan_jolts`] cannot reach (fewer than
/// [`MIN_EDGE_POINTS`] differences on one side): the first two and the last two. There the
/// jump is the one-step one, `e[k+1] - e[k-1]` (the difference straddling the gap left out;
/// in the last gap, which has none after it, `e[k] - e[k-1]`, the part of the impulse the last
/// frame shows; in the first, `e[1] - e[0]`), with noise `2 sigma` per coordinate. One above
/// [`JOLT_THRESHOLD`] times the larger of that and the robust spread of every gap's one-step
/// jump, that reverses the velocity along it and approaches at half its size or more (within
/// one scale; in the last gap only the approach is asked, in the first only a departure), is
/// an end jolt: a wall proposal only, like a faint one (a bounce in the last
/// frame of a 66-frame recording moved that frame 4.8 px against a track noise of 0.009 px).
fn end_jolts(obs: &Observations, differences: &[Option<Differences>]) -> Vec<Jolt> {
    let frames = obs.frame_count();
    if frames < 2 * MIN_EDGE_POINTS + 2 {
        return Vec::new();
    }
    let fps = obs.fps;
    let noise = 2.0 * obs.noise * fps;
    // The one-step jump across gap k: (before, after) differences, px/frame.
    let sides = |k: usize| -> (usize, usize) {
        if k == 0 {
            (0, 1)
        } else if k + 2 == frames {
            (k - 1, k)
        } else {
            (k - 1, k + 1)
        }
    };
    let mut magnitudes = Vec::new();
    for (e, _) in differences.iter().flatten() {
        for k in 1..frames - 2 {
            if let (Some(b), Some(a)) = (e[k - 1], e[k + 1]) {
                magnitudes.push(((a - b) * fps).x.abs());
                magnitudes.push(((a - b) * fps).y.abs());
            }
        }
    }
    magnitudes.sort_by(|a, b| a.total_cmp(b));
    let robust = magnitudes.get(magnitudes.len() / 2).map_or(0.0, |m| 1.4826 * m);
    let scale = noise.max(robust).max(f64::MIN_POSITIVE);
    let mut out = Vec::new();
    for (p, d) in differences.iter().enumerate() {
        let Some((e, cum)) = d else { continue };
        let ends = [0, 1, frames - 3, frames - 2];
        for &k in ends
            .iter()
            .filter(|&&k| k < MIN_EDGE_POINTS || k + MIN_EDGE_POINTS + 1 > frames - 1)
        {
            let (i, j) = sides(k);
            let (Some(b), Some(a)) = (e[i], e[j]) else {
                continue;
            };
            let impulse = (a - b) * fps;
            let size = impulse.norm();
            if size < JOLT_THRESHOLD * scale {
                continue;
            }
            let vb = (b + cum[i]) * fps;
            let va = (a + cum[j]) * fps;
            let n = impulse / size;
            // The difference straddling the bounce mixes approach and departure: in the last
            // gap only the approach is seen, in the first only the departure.
            let approaches = -vb.dot(&n) >= 0.5 * size - scale;
            let bounce = if k + 2 == frames {
                approaches
            } else if k == 0 {
                va.dot(&n) > 0.0
            } else {
                approaches && reverses(vb, va, n, scale / size)
            };
            if !bounce {
                continue;
            }
            let Some(x) = obs.positions[k][p] else { continue };
            out.push(Jolt::new(
                p,
                obs.first_frame + k,
                x,
                vb,
                va,
                impulse,
                size / scale,
            ));
        }
    }
    out
}

/// Returns true if and only if the velocity turns from approaching to leaving along some
/// direction within [`JOLT_DIRECTION_ERRORS`] angular standard errors of the impulse's
/// direction `n`, whose error is `relative` (the impulse's noise scale over its size) radians:
/// a shallow bounce at speed along the wall leaks tangential speed into the normal component
/// of a direction a few degrees off.
fn reverses(before: Vec2, after: Vec2, n: Vec2, relative: f64) -> bool {
    let spread = (JOLT_DIRECTION_ERRORS * relative).min(std::f64::consts::FRAC_PI_4);
    (-10..=10).any(|i| {
        let d = turned(n, spread * f64::from(i) / 10.0);
        before.dot(&d) < 0.0 && after.dot(&d) > 0.0
    })
}

/// The unit vector `n` turned by `angle` radians (counter-clockwise in image axes: towards
/// `(-n.y, n.x)`).
fn turned(n: Vec2, angle: f64) -> Vec2 {
    n * angle.cos() + Vec2::new(-n.y, n.x) * angle.sin()
}

/// Groups jolts by jump direction and proposes one wall per group (see the module doc).
pub fn propose_walls(jolts: &[Jolt], obs: &Observations) -> Vec<WallGuess> {
    let cos_limit = WALL_GROUP_DEGREES.to_radians().cos();
    let dir = |j: &Jolt| {
        let d = Vec2::new(j.impulse[0], j.impulse[1]);
        d / d.norm().max(f64::MIN_POSITIVE)
    };
    let mut groups: Vec<(Vec2, Vec<usize>)> = Vec::new();
    let mut order: Vec<usize> = (0..jolts.len()).collect();
    order.sort_by(|&a, &b| jolts[b].significance.total_cmp(&jolts[a].significance));
    for i in order {
        let d = dir(&jolts[i]);
        match groups.iter_mut().find(|(n, _)| n.dot(&d) > cos_limit) {
            Some((n, members)) => {
                members.push(i);
                let sum: Vec2 = members.iter().map(|&k| dir(&jolts[k])).sum();
                *n = sum / sum.norm().max(f64::MIN_POSITIVE);
            }
            None => groups.push((d, vec![i])),
        }
    }
    let dt = obs.frame_dt();
    // Restitution (median of `-v_n after / v_n before`) and line position along normal `n`.
    let line = |n: Vec2, members: &[usize]| -> (f64, f64) {
        let mut es: Vec<f64> = members
            .iter()
            .filter_map(|&k| {
                let j = &jolts[k];
                let vb = Vec2::new(j.before[0], j.before[1]).dot(&n);
                let va = Vec2::new(j.after[0], j.after[1]).dot(&n);
                (vb < 0.0).then(|| (-va / vb).clamp(0.0, 1.0))
            })
            .collect();
        es.sort_by(|a, b| a.total_cmp(b));
        let e = if es.is_empty() { 0.8 } else { es[es.len() / 2] };
        let offsets: Vec<f64> = members
            .iter()
            .filter_map(|&k| {
                let j = &jolts[k];
                let off = j.frame.checked_sub(obs.first_frame)?;
                let x0 = obs.positions.get(off)?[j.particle]?;
                let x1 = obs.positions.get(off + 1)?[j.particle]?;
                let speed = (-Vec2::new(j.before[0], j.before[1]).dot(&n)).max(1e-9);
                let drop = n.dot(&x0) - n.dot(&x1);
                let tau = ((drop + e * speed * dt) / (speed * (1.0 + e))).clamp(0.0, dt);
                Some(n.dot(&x0) - speed * tau)
            })
            .collect();
        let offset = if offsets.is_empty() {
            members
                .iter()
                .map(|&k| n.dot(&Vec2::new(jolts[k].position[0], jolts[k].position[1])))
                .fold(f64::INFINITY, f64::min)
        } else {
            offsets.iter().sum::<f64>() / offsets.len() as f64
        };
        (offset, e)
    };
    let deepest = |n: Vec2, offset: f64| deepest_beyond(obs, n, offset);
    groups
        .into_iter()
        // A wall is never crossed: a line that some tracked centre goes beyond by more than a
        // bounce's frame of travel is no wall; within that, the line moves to the deepest
        // centre. The normal is the jumps' mean direction, known to about one over the
        // jumps' combined significance (radians): within JOLT_DIRECTION_ERRORS of that, the
        // direction nearest the jumps' whose line no centre crosses (beyond three track
        // noises) is taken, else the least crossed (a shallow bounce along a long path tilts
        // a line by a few degrees across the whole frame).
        .filter_map(|(n, members)| {
            let combined = members
                .iter()
                .map(|&k| jolts[k].significance.powi(2))
                .sum::<f64>()
                .sqrt()
                .max(1.0);
            let spread = (JOLT_DIRECTION_ERRORS / combined).min(std::f64::consts::FRAC_PI_4);
            let travel = members
                .iter()
                .map(|&k| Vec2::new(jolts[k].before[0], jolts[k].before[1]).dot(&n).abs() * dt)
                .fold(0.0, f64::max);
            let tolerance = travel.max(5.0 * obs.noise).max(WALL_CROSSING_PX);
            // The lines no centre crosses beyond three track noises form a fan about the
            // bounce (between the approach's and the departure's directions): its middle is
            // taken; else the least crossed line within the tolerance.
            let mut clear: Vec<(f64, Vec2, f64, f64)> = Vec::new();
            let mut least: Option<(f64, Vec2, f64, f64)> = None;
            for i in -40..=40 {
                let angle = spread * f64::from(i) / 40.0;
                let normal = turned(n, angle);
                let (offset, e) = line(normal, &members);
                let depth = deepest(normal, offset);
                if depth >= -3.0 * obs.noise {
                    clear.push((depth, normal, offset, e));
                } else if depth >= -tolerance && least.as_ref().map_or(true, |l| depth > l.0) {
                    least = Some((depth, normal, offset, e));
                }
            }
            if !clear.is_empty() {
                least = Some(clear[clear.len() / 2]);
            }
            let (depth, normal, offset, e) = least?;
            Some(WallGuess {
                params: [normal.y.atan2(normal.x), offset + depth.min(0.0), e],
                jolts: members.iter().map(|&k| jolts[k].clone()).collect(),
            })
        })
        .collect()
}

/// How far the deepest tracked centre of a free particle in `obs` lies beyond the line
/// `n . x = offset` (px; negative when beyond it, infinite without positions).
pub fn deepest_beyond(obs: &Observations, n: Vec2, offset: f64) -> f64 {
    obs.positions
        .iter()
        .flat_map(|f| {
            f.iter()
                .zip(&obs.fixed)
                .filter(|(_, &fixed)| !fixed)
                .filter_map(|(x, _)| *x)
        })
        .map(|x| n.dot(&x) - offset)
        .fold(f64::INFINITY, f64::min)
}

/// `jolts` and those of `more` that are not already there (the same particle within one
/// frame).
pub fn merge_jolts(mut jolts: Vec<Jolt>, more: &[Jolt]) -> Vec<Jolt> {
    for j in more {
        if !jolts
            .iter()
            .any(|i| i.particle == j.particle && i.frame.abs_diff(j.frame) <= 1)
        {
            jolts.push(j.clone());
        }
    }
    jolts
}
