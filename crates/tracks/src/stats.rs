//! Robust statistics shared by the stages: the median and the robust spread (1.4826 times the
//! median absolute deviation, MAD), and the normal upper-tail quantile that turns a false-alarm
//! rate into a threshold in noise sigmas.
//!
//! A key design decision: there is one convention for an even count, named in each function.
//! [`median`] and [`robust_spread`] take the *midpoint* of the two middle values, the textbook
//! median, used everywhere a summary is reported or a scale is set once. The tracker's
//! linking gates use the *upper* of the two middle values ([`median_upper`],
//! [`robust_spread_upper`]): its per-frame appearance windows keep their values sorted and
//! read the middle element without averaging, and the batch estimates it compares them
//! with must agree with those to the bit (tracks are byte-identical to the ones before the
//! statistics were gathered here). Both pick the middle by selection (`O(n)`), ordering with
//! [`f64::total_cmp`], so a NaN sorts above every number (a negative NaN below).
//!
//! Every function reorders its slice and returns NaN for an empty one.
//!
//! They live in this crate, not in `physfit-model`, because it is the lowest crate every
//! user depends on: the tracker sees only pixels and does not depend on the model.
//!
//! # Example
//! ```
//! use physfit_tracks::stats::{median, median_upper, robust_spread};
//! assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
//! assert_eq!(median_upper(&mut [4.0, 1.0, 3.0, 2.0]), 3.0);
//! assert!((robust_spread(&mut [1.0, 2.0, 3.0, 100.0]) - 1.4826).abs() < 1e-12);
//! assert!(median(&mut []).is_nan());
//! ```

/// The ratio of a normal distribution's standard deviation to its median absolute
/// deviation, `1 / Phi^-1(3/4)`, to four places: the factor of the robust spreads.
pub const MAD_TO_SIGMA: f64 = 1.4826;

/// The median of `v`: the middle value of an odd count, the midpoint of the two middle
/// values of an even count; NaN when `v` is empty. Reorders `v`.
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let n = v.len();
    let (lower, m, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let m = *m;
    if n % 2 == 1 {
        m
    } else {
        // The largest of the lower half is the other middle value.
        let lo = lower.iter().copied().max_by(f64::total_cmp).unwrap_or(m);
        0.5 * (lo + m)
    }
}

/// The upper median of `v`: the middle value of an odd count, the upper of the two middle
/// values of an even count (element `len / 2` of `v` sorted); NaN when `v` is empty.
/// Reorders `v`.
pub fn median_upper(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The robust spread of `v`: [`MAD_TO_SIGMA`] times the [`median`] of the absolute
/// deviations from the [`median`] (the standard deviation of normal values, unmoved by a
/// few outliers); NaN when `v` is empty. Replaces `v`'s values by those deviations.
pub fn robust_spread(v: &mut [f64]) -> f64 {
    spread_about(v, median)
}

/// [`robust_spread`] with [`median_upper`] for both medians. Replaces `v`'s values by their
/// absolute deviations from the upper median.
pub fn robust_spread_upper(v: &mut [f64]) -> f64 {
    spread_about(v, median_upper)
}

/// `MAD_TO_SIGMA * centre(|v - centre(v)|)`, the one robust spread of both conventions.
fn spread_about(v: &mut [f64], centre: fn(&mut [f64]) -> f64) -> f64 {
    let m = centre(v);
    v.iter_mut().for_each(|x| *x = (*x - m).abs());
    MAD_TO_SIGMA * centre(v)
}

/// The standard normal upper-tail quantile: the `z` with `P(Z > z) = tail` for a standard
/// normal `Z` (`tail` in `(0, 1)`; NaN outside it). The tail is the Abramowitz and Stegun
/// 26.2.17 form `φ(z) t (b1 + b2 t + ... + b5 t⁴)`, `t = 1 / (1 + 0.2316419 |z|)`: within
/// 7.5e-8 of the tail absolutely and, as a product with the density, within 0.4 % of it
/// relatively up to `z = 6` (1 % at 8), which moves `z` by under 1e-3 (the relative error
/// over `z`). Found by bisection.
pub fn normal_upper_quantile(tail: f64) -> f64 {
    if !(tail > 0.0 && tail < 1.0) {
        return f64::NAN;
    }
    let upper = |z: f64| {
        let t = 1.0 / (1.0 + 0.231_641_9 * z.abs());
        let poly = t
            * (0.319_381_530
                + t * (-0.356_563_782 + t * (1.781_477_937 + t * (-1.821_255_978 + t * 1.330_274_429))));
        let q = (-z * z / 2.0).exp() / (2.0 * std::f64::consts::PI).sqrt() * poly;
        if z >= 0.0 {
            q
        } else {
            1.0 - q
        }
    };
    let (mut lo, mut hi) = (-40.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if upper(mid) > tail {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference: sort, then read the middle (or average the two middle) values.
    fn sorted_median(v: &[f64], upper: bool) -> f64 {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let n = s.len();
        if n % 2 == 1 || upper {
            s[n / 2]
        } else {
            0.5 * (s[n / 2 - 1] + s[n / 2])
        }
    }

    #[test]
    fn odd_counts_agree_and_even_counts_follow_their_convention() {
        let mut odd = [5.0, -1.0, 3.0];
        assert_eq!(median(&mut odd.clone()).to_bits(), 3.0f64.to_bits());
        assert_eq!(median_upper(&mut odd).to_bits(), 3.0f64.to_bits());
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]).to_bits(), 2.5f64.to_bits());
        assert_eq!(
            median_upper(&mut [4.0, 1.0, 3.0, 2.0]).to_bits(),
            3.0f64.to_bits()
        );
        assert_eq!(median(&mut [7.0]).to_bits(), 7.0f64.to_bits());
        assert_eq!(median(&mut [2.0, 1.0]).to_bits(), 1.5f64.to_bits());
    }

    #[test]
    fn empty_input_is_nan_not_a_panic() {
        assert!(median(&mut []).is_nan());
        assert!(median_upper(&mut []).is_nan());
        assert!(robust_spread(&mut []).is_nan());
        assert!(robust_spread_upper(&mut []).is_nan());
    }

    #[test]
    fn selection_matches_sorting_to_the_bit() {
        // A fixed pseudo-random sequence (xorshift) with ties, signed zeros and every length
        // up to 40: the selection-based medians equal the sorted reference bit for bit.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for n in 1..=40 {
            let v: Vec<f64> = (0..n)
                .map(|_| match next() % 7 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => 1.0,
                    _ => (next() % 10_000) as f64 / 37.0 - 100.0,
                })
                .collect();
            assert_eq!(
                median(&mut v.clone()).to_bits(),
                sorted_median(&v, false).to_bits(),
                "{v:?}"
            );
            assert_eq!(
                median_upper(&mut v.clone()).to_bits(),
                sorted_median(&v, true).to_bits(),
                "{v:?}"
            );
        }
    }

    #[test]
    fn the_upper_quantile_matches_tabled_values_far_into_the_tail() {
        // Tabled: P(Z > 1.644854) = 0.05, P(Z > 3.090232) = 1e-3, P(Z > 4.753424) = 1e-6,
        // P(Z > 5.997807) = 1e-9.
        for (tail, z) in [
            (0.05, 1.644_854),
            (1e-3, 3.090_232),
            (1e-6, 4.753_424),
            (1e-9, 5.997_807),
        ] {
            assert!((normal_upper_quantile(tail) - z).abs() < 1e-3, "{tail}");
        }
        assert!((normal_upper_quantile(0.5)).abs() < 1e-6);
        assert!((normal_upper_quantile(0.95) + 1.644_854).abs() < 1e-5);
        assert!(normal_upper_quantile(0.0).is_nan() && normal_upper_quantile(1.0).is_nan());
    }

    #[test]
    fn robust_spread_ignores_an_outlier_and_scales_to_a_standard_deviation() {
        // Deviations from the median 2.5 are 1.5, 0.5, 0.5, 97.5: their median is 1.0.
        assert!((robust_spread(&mut [1.0, 2.0, 3.0, 100.0]) - MAD_TO_SIGMA).abs() < 1e-12);
        // Upper: median 3, deviations 2, 1, 0, 97, upper median 2.
        assert!((robust_spread_upper(&mut [1.0, 2.0, 3.0, 100.0]) - 2.0 * MAD_TO_SIGMA).abs() < 1e-12);
        let mut v = [1.0, 2.0, 3.0, 4.0, 5.0, 1e9];
        assert!((robust_spread(&mut v) - 1.5 * MAD_TO_SIGMA).abs() < 1e-12);
        // The values were replaced by their absolute deviations.
        assert!(v.iter().all(|x| *x >= 0.0));
        // Evenly spaced normal quantiles: the spread is close to the standard deviation.
        let sigma = 3.0;
        let mut normal: Vec<f64> = (1..200)
            .map(|k| sigma * inverse_normal_cdf(k as f64 / 200.0))
            .collect();
        assert!((robust_spread(&mut normal) / sigma - 1.0).abs() < 0.01);
    }

    /// The standard normal quantile, from the upper tail.
    fn inverse_normal_cdf(p: f64) -> f64 {
        -normal_upper_quantile(p)
    }
}
