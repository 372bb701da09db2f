//! The verdict: does the diagnosed model explain the tracks to their noise level, and if not,
//! where the residual lives and what it looks like.
//!
//! The yardstick is the final model's multi-step RMS over the whole sequence (from its
//! best-fitting start state) against the track noise `sigma` measured from the tracks
//! (fourth differences; where the tracks are exact, [`noise_floor`]'s floor). The model
//! explains the tracks when its RMS is within [`EXPLAINED_RMS_RATIO`] times `sigma`, that is
//! its mean square within four times `sigma²`: the same rule that makes a particle's residual
//! significant in the localisation. Beyond that the verdict says "not explained", with the
//! particles and frames that carry the residual and its pattern.

use physfit_model::Vec2;

use super::jolts::Jolt;
use super::report::{ResidualSeries, Verdict, VerdictParticle};
use super::search::{noise_floor, EXPLAINED_VARIANCE_RATIO};

/// The model explains the tracks when its multi-step RMS is within this many track noises.
pub const EXPLAINED_RMS_RATIO: f64 = 2.0;

/// Frames either side of a jolt that count as "around a bounce".
const BOUNCE_FRAMES: usize = 2;

/// The verdict on a final model whose multi-step RMS over the sequence is `rms` (px), with
/// residual series `residuals` (`after`: observed minus predicted), track noise `noise` and
/// data length scale `length` (px), and the jolts found.
pub fn verdict(rms: f64, noise: f64, length: f64, residuals: &ResidualSeries, jolts: &[Jolt]) -> Verdict {
    debug_assert!((EXPLAINED_RMS_RATIO * EXPLAINED_RMS_RATIO - EXPLAINED_VARIANCE_RATIO).abs() < 1e-12);
    let sigma = noise_floor(noise, length);
    let series = &residuals.after;
    let n_particles = residuals.particles.len();
    // Per particle and per frame sums of squares.
    let mut particle_ss = vec![(0.0, 0usize); n_particles];
    let mut frame_ms: Vec<Option<f64>> = Vec::with_capacity(series.len());
    let mut mean = Vec2::zeros();
    let mut count = 0usize;
    for frame in series {
        let mut ss = 0.0;
        let mut c = 0;
        for (p, r) in frame.iter().enumerate() {
            let Some([dx, dy]) = *r else { continue };
            if !(dx.is_finite() && dy.is_finite()) {
                continue;
            }
            let e = dx * dx + dy * dy;
            if let Some(ps) = particle_ss.get_mut(p) {
                ps.0 += e;
                ps.1 += 2;
            }
            ss += e;
            c += 2;
            mean += Vec2::new(dx, dy);
            count += 1;
        }
        frame_ms.push((c > 0).then(|| ss / c as f64));
    }
    let rms = if rms.is_finite() {
        rms
    } else {
        let (ss, c) = particle_ss.iter().fold((0.0, 0), |a, p| (a.0 + p.0, a.1 + p.1));
        if c > 0 {
            (ss / c as f64).sqrt()
        } else {
            0.0
        }
    };
    let ratio = rms / sigma;
    let explained = ratio <= EXPLAINED_RMS_RATIO;
    let particles: Vec<VerdictParticle> = residuals
        .particles
        .iter()
        .zip(&particle_ss)
        .filter(|(_, s)| s.1 > 0)
        .map(|(id, s)| {
            let r = (s.0 / s.1 as f64).sqrt();
            VerdictParticle {
                particle: id.clone(),
                rms: r,
                rms_over_noise: r / sigma,
            }
        })
        .collect();
    // Frame runs whose RMS exceeds the threshold (gaps of up to two frames bridged).
    let limit = EXPLAINED_VARIANCE_RATIO * sigma * sigma;
    let mut frames: Vec<[usize; 2]> = Vec::new();
    for (k, ms) in frame_ms.iter().enumerate() {
        if !ms.is_some_and(|m| m > limit) {
            continue;
        }
        let f = residuals.frames.get(k).copied().unwrap_or(k);
        match frames.last_mut() {
            Some(last) if f <= last[1] + 3 => last[1] = f,
            _ => frames.push([f, f]),
        }
    }
    let pattern = pattern(residuals, &frame_ms, mean, count, rms, jolts);
    let worst = particles
        .iter()
        .max_by(|a, b| a.rms.total_cmp(&b.rms))
        .map(|p| format!("; largest on {} ({:.3} px RMS)", p.particle, p.rms))
        .unwrap_or_default();
    let text = if explained {
        format!(
            "explained to the noise level: {rms:.4} px RMS against a noise of {sigma:.4} px ({ratio:.2} times, within {EXPLAINED_RMS_RATIO})"
        )
    } else {
        let span = match frames.as_slice() {
            [] => String::new(),
            [one] if one[0] == one[1] => format!(", beyond {EXPLAINED_RMS_RATIO} noises at frame {}", one[0]),
            [one] => format!(
                ", beyond {EXPLAINED_RMS_RATIO} noises over frames {}-{}",
                one[0], one[1]
            ),
            many => {
                let total: usize = many.iter().map(|r| r[1] - r[0] + 1).sum();
                format!(
                    ", beyond {EXPLAINED_RMS_RATIO} noises in {total} frames ({} runs, frames {}-{})",
                    many.len(),
                    many[0][0],
                    many[many.len() - 1][1]
                )
            }
        };
        format!(
            "not explained: {rms:.4} px RMS against a noise of {sigma:.4} px ({ratio:.1} times){worst}{span}; {pattern}"
        )
    };
    Verdict {
        explained,
        rms,
        noise: sigma,
        ratio,
        threshold: EXPLAINED_RMS_RATIO,
        particles,
        frames,
        pattern,
        text,
    }
}

/// What the residual looks like, in words.
fn pattern(
    residuals: &ResidualSeries,
    frame_ms: &[Option<f64>],
    mean: Vec2,
    count: usize,
    rms: f64,
    jolts: &[Jolt],
) -> String {
    let total: f64 = frame_ms.iter().flatten().sum();
    if total.is_nan() || total <= 0.0 || count == 0 {
        return "no residual".into();
    }
    // Around the bounces.
    let near_bounce = |f: usize| {
        jolts
            .iter()
            .any(|j| f + BOUNCE_FRAMES >= j.frame && f <= j.frame + 1 + BOUNCE_FRAMES)
    };
    let bounce_share: f64 = frame_ms
        .iter()
        .enumerate()
        .filter(|(k, _)| near_bounce(residuals.frames.get(*k).copied().unwrap_or(*k)))
        .filter_map(|(_, m)| *m)
        .sum::<f64>()
        / total;
    if !jolts.is_empty() && bounce_share > 0.5 {
        return format!(
            "concentrated around the bounces ({:.0} % of the squared residual within {BOUNCE_FRAMES} frames of a jolt)",
            100.0 * bounce_share
        );
    }
    let mean = mean / count as f64;
    if mean.norm() > 0.5 * rms {
        return format!(
            "a steady offset of ({:.3}, {:.3}) px (the model's track runs beside the observed one)",
            mean.x, mean.y
        );
    }
    let thirds: Vec<f64> = (0..3)
        .map(|t| {
            let n = frame_ms.len();
            let part: Vec<f64> = frame_ms[t * n / 3..(t + 1) * n / 3]
                .iter()
                .flatten()
                .copied()
                .collect();
            if part.is_empty() {
                0.0
            } else {
                (part.iter().sum::<f64>() / part.len() as f64).sqrt()
            }
        })
        .collect();
    if thirds[2] > 2.0 * thirds[0] && thirds[2] >= thirds[1] {
        return format!(
            "growing over the sequence ({:.3} px RMS in its first third, {:.3} in its last: a drift the model accumulates)",
            thirds[0], thirds[2]
        );
    }
    // Sign changes of the dominant coordinate of the first particle with the largest residual.
    let mut changes = 0;
    let mut samples = 0;
    let mut last: Option<f64> = None;
    let axis = {
        let (mut sx, mut sy) = (0.0, 0.0);
        for frame in &residuals.after {
            for [dx, dy] in frame.iter().flatten() {
                sx += dx * dx;
                sy += dy * dy;
            }
        }
        usize::from(sy > sx)
    };
    for frame in &residuals.after {
        let vals: Vec<f64> = frame.iter().flatten().map(|r| r[axis]).collect();
        if vals.is_empty() {
            continue;
        }
        let v = vals.iter().sum::<f64>() / vals.len() as f64 - if axis == 0 { mean.x } else { mean.y };
        samples += 1;
        if let Some(l) = last {
            if l * v < 0.0 {
                changes += 1;
            }
        }
        if v != 0.0 {
            last = Some(v);
        }
    }
    // White noise changes sign every other frame; a systematic misfit far less often.
    if changes >= 4 && (changes as f64) < 0.25 * samples as f64 {
        return format!(
            "oscillating ({changes} sign changes of its {} component over {samples} frames: a period or phase the model misses)",
            if axis == 0 { "x" } else { "y" }
        );
    }
    "scattered over the sequence".into()
}
