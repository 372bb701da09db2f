//! Each finding's inclusion rate over bootstrap resamples of the frames.
//!
//! The final model is refitted on every analysed frame without each finding in turn. Per
//! frame, the finding's worth is the multi-step cost it removes there (without minus with,
//! px²). A resample draws blocks of consecutive frames (one weak-form test window long, so
//! that the residuals' correlation in time is kept) with replacement until it holds as many
//! frames as the recording; the finding is included in that resample when the cost it removes
//! there, over the residual variance, still exceeds its penalty (parameters times
//! `ln(residual count)`), the criterion the search accepted it by. The rate is the share of
//! [`RESAMPLES`] resamples that include it: near 1 when every part of the recording supports
//! the finding, near 1/2 when it rests on a few frames or barely pays.
//!
//! Both fits are held fixed over the resamples (a fit per resample and finding would cost
//! hundreds of refits): the rate measures how the evidence is spread over the frames, not
//! the search's sensitivity to them.

use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use super::family::Family;
use super::search::{Context, Current};
use super::shooting::{Shot, ShotFit};

/// Bootstrap resamples drawn per finding.
pub const RESAMPLES: usize = 200;

/// Share of the resamples a finding must be kept by to stay in the model (the conventional
/// 95 % level): below it, it rests on a few frames and is reported as undecided.
pub const INCLUSION_LEVEL: f64 = 0.95;

/// Stream of the seed the resamples are drawn from (kept apart from the held-out blocks').
const SEED_STREAM: u64 = 0x1bc1_0de5;

/// One finding's support over the frames.
pub struct Inclusion {
    /// Share of the resamples that include it, in `[0, 1]`.
    pub rate: f64,
    /// Over all frames: the cost it removes over the residual variance, less its penalty
    /// (negative: it does not pay for its parameters on the whole recording).
    pub worth: f64,
    /// The model without it, fitted on every frame.
    pub without: Current,
}

/// The support of each effect of `family` (`None` where the model without it cannot be
/// fitted or simulated). `fit` is `family`'s fit on every frame of `shot`, `variance` the
/// residual variance the costs are divided by (px²), `block` the resampled block length
/// (frames).
pub fn inclusion_rates(
    ctx: &Context<'_>,
    shot: &Shot<'_>,
    family: &Family,
    fit: &ShotFit,
    variance: f64,
    block: usize,
    seed: u64,
) -> Vec<Option<Inclusion>> {
    let Some(with) = shot.frame_costs(family, &fit.params, &fit.state) else {
        return (0..family.effects.len()).map(|_| None).collect();
    };
    let current = Current {
        family: family.clone(),
        fit: fit.clone(),
        held_cost: 0.0,
    };
    let frames: Vec<usize> = (shot.anchor..with.len()).collect();
    let coordinates: usize = frames.iter().map(|&k| with[k].1).sum();
    let ln_n = (coordinates.max(2) as f64).ln();
    (0..family.effects.len())
        .into_par_iter()
        .map(|k| {
            let mut reduced = ctx.without(&current, k);
            let refit = super::shooting::fit_shot(
                shot,
                &reduced.family,
                &reduced.fit.params,
                &reduced.fit.state,
                ctx.scales,
                super::search::SHOT_ITERATIONS,
                true,
                &(),
            )?;
            let without = shot.frame_costs(&reduced.family, &refit.params, &refit.state)?;
            let worth: Vec<f64> = frames
                .iter()
                .map(|&f| (without[f].0 - with[f].0) / variance)
                .collect();
            let penalty = family.effects[k].parameter_count() as f64 * ln_n;
            let stream = seed ^ SEED_STREAM ^ (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            let rate = rate(&worth, penalty, block, stream);
            reduced.fit = refit;
            Some(Inclusion {
                rate,
                worth: worth.iter().sum::<f64>() - penalty,
                without: reduced,
            })
        })
        .collect()
}

/// Share of [`RESAMPLES`] moving-block resamples of `worth` (per frame) whose sum exceeds
/// `penalty`.
fn rate(worth: &[f64], penalty: f64, block: usize, seed: u64) -> f64 {
    let n = worth.len();
    if n == 0 || worth.iter().any(|w| !w.is_finite()) {
        return 0.0;
    }
    let block = block.clamp(1, n);
    // Prefix sums: a block's worth in one subtraction.
    let mut prefix = vec![0.0; n + 1];
    for (i, w) in worth.iter().enumerate() {
        prefix[i + 1] = prefix[i] + w;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut included = 0;
    for _ in 0..RESAMPLES {
        let mut total = 0.0;
        let mut left = n;
        while left > 0 {
            let len = block.min(left);
            let start = rng.gen_range(0..=n - len);
            total += prefix[start + len] - prefix[start];
            left -= len;
        }
        if total > penalty {
            included += 1;
        }
    }
    included as f64 / RESAMPLES as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evenly_spread_worth_is_always_included() {
        let worth = vec![1.0; 300];
        assert!((rate(&worth, 10.0, 20, 1) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn worth_below_the_penalty_is_never_included() {
        let worth = vec![0.01; 300];
        assert!(rate(&worth, 10.0, 20, 1).abs() < 1e-12);
    }

    #[test]
    fn worth_on_one_block_is_included_about_as_often_as_resamples_draw_it() {
        // 300 frames, the worth all on frames 100..120: a resample of 15 blocks of 20
        // includes it when some block overlaps it enough; the share lies well inside (0, 1).
        let mut worth = vec![0.0; 300];
        for w in &mut worth[100..120] {
            *w = 5.0;
        }
        let r = rate(&worth, 50.0, 20, 3);
        assert!(r > 0.3 && r < 0.95, "rate {r}");
    }

    #[test]
    fn the_same_seed_gives_the_same_rate() {
        let worth: Vec<f64> = (0..200).map(|i| ((i as f64) * 0.37).sin()).collect();
        assert_eq!(
            rate(&worth, 0.5, 10, 9).to_bits(),
            rate(&worth, 0.5, 10, 9).to_bits()
        );
    }
}
