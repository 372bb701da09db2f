//! The uniform field seen in free flights, for recordings whose bounces leave the weak form
//! no window (a ball bouncing every few frames at a low frame rate).
//!
//! Between impulses a particle's second difference `(x[k+1] - 2 x[k] + x[k-1]) / dt²` is its
//! acceleration, with noise `s = sqrt(6) sigma / dt²` per coordinate. Less the structure's own
//! forces, what remains on every free particle in flight is the field. Two kinds of frame
//! spoil it: a bounce the jolt test missed (a lone outlier) and a contact that holds the
//! particle (a ball come to rest on the floor reads no acceleration at all, frame after
//! frame). So the samples are grouped, densest first: a group is a sample and every other
//! within `3 s` of it (per coordinate), removed before the next is sought; groups of at least
//! a fifth of the samples (and three) are consistent accelerations, and the field is the
//! median of the strongest group, the one whose median acceleration is largest: a contact
//! can only cancel the field, never add one. Where flights and contacts are closer than `3 s`
//! they form one group and the estimate is the plain median; with no field, every group is
//! near zero and so is the estimate.

use physfit_model::Vec2;
use physfit_tracks::stats::median;

use crate::Observations;

/// The median residual acceleration (px/s²) over free particles and frames `k` whose
/// neighbours `k - 1 ..= k + 1` are tracked and not `excluded`, with `structure_acc[k][p]`
/// (the structure's own forces per unit mass) removed, and its standard error per coordinate
/// (`1.2533` times the robust spread `1.4826 MAD` over the square root of the count: a
/// median's); `None` with fewer than three samples.
pub fn field_from_flights(
    obs: &Observations,
    structure_acc: &[Option<Vec<Vec2>>],
    excluded: &[bool],
) -> Option<(Vec2, Vec2)> {
    let frames = obs.frame_count();
    let dt = obs.frame_dt();
    if frames < 3 || dt.is_nan() || dt <= 0.0 {
        return None;
    }
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for p in 0..obs.particle_count() {
        if obs.fixed.get(p).copied().unwrap_or(true) {
            continue;
        }
        for k in 1..frames - 1 {
            if excluded.get(k - 1..=k + 1).map_or(true, |e| e.iter().any(|&v| v)) {
                continue;
            }
            let (Some(a), Some(b), Some(c)) = (
                obs.positions[k - 1][p],
                obs.positions[k][p],
                obs.positions[k + 1][p],
            ) else {
                continue;
            };
            let known = structure_acc
                .get(k)
                .and_then(|f| f.as_ref()?.get(p).copied())
                .unwrap_or_else(Vec2::zeros);
            let acc = (c - 2.0 * b + a) / (dt * dt) - known;
            if acc.x.is_finite() && acc.y.is_finite() {
                xs.push(acc.x);
                ys.push(acc.y);
            }
        }
    }
    if xs.len() < 3 {
        return None;
    }
    // The strongest consistent group (see the module doc): groups are taken densest first
    // (the sample with the most others within `3 s`, and those others), each removed before
    // the next is sought, while they hold at least a fifth of the samples.
    let s = 3.0 * 6f64.sqrt() * obs.noise / (dt * dt);
    let least = (xs.len() / 5).max(3);
    if s > 0.0 {
        let near = |i: usize, j: usize| (xs[j] - xs[i]).abs() <= s && (ys[j] - ys[i]).abs() <= s;
        let mut remaining: Vec<usize> = (0..xs.len()).collect();
        let mut strongest: Option<(f64, Vec<usize>)> = None;
        while remaining.len() >= least {
            let group = remaining
                .iter()
                .map(|&i| {
                    remaining
                        .iter()
                        .copied()
                        .filter(|&j| near(i, j))
                        .collect::<Vec<usize>>()
                })
                .max_by_key(Vec::len)
                .unwrap_or_default();
            if group.len() < least {
                break;
            }
            let mut gx: Vec<f64> = group.iter().map(|&j| xs[j]).collect();
            let mut gy: Vec<f64> = group.iter().map(|&j| ys[j]).collect();
            let size = median(&mut gx).hypot(median(&mut gy));
            remaining.retain(|j| !group.contains(j));
            if strongest.as_ref().map_or(true, |b| size > b.0) {
                strongest = Some((size, group));
            }
        }
        if let Some((_, group)) = strongest {
            xs = group.iter().map(|&j| xs[j]).collect();
            ys = group.iter().map(|&j| ys[j]).collect();
        }
    }
    let n = xs.len() as f64;
    let (mx, my) = (median(&mut xs), median(&mut ys));
    let mut dx: Vec<f64> = xs.iter().map(|v| (v - mx).abs()).collect();
    let mut dy: Vec<f64> = ys.iter().map(|v| (v - my).abs()).collect();
    let se = |mad: f64| 1.2533 * 1.4826 * mad / n.sqrt();
    Some((
        Vec2::new(mx, my),
        Vec2::new(se(median(&mut dx)), se(median(&mut dy))),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_parabola_with_bounces_gives_its_field() {
        // A ball under (0, 900) px/s² at 30 frames/s, its velocity reversed every 7 frames: the
        // median ignores the spoiled differences around each reversal.
        let fps = 30.0;
        let dt = 1.0 / fps;
        let g = Vec2::new(0.0, 900.0);
        let mut x = Vec2::new(10.0, 10.0);
        let mut v = Vec2::new(20.0, 0.0);
        let mut positions = Vec::new();
        for k in 0..40 {
            positions.push(vec![Some(x)]);
            if k % 7 == 6 {
                v.y = -0.8 * v.y.abs();
            }
            x += v * dt + 0.5 * g * dt * dt;
            v += g * dt;
        }
        let obs = Observations::from_positions(vec!["ball".into()], vec![false], fps, 0, positions);
        let (f, _) = field_from_flights(&obs, &[], &[false; 40]).unwrap_or_default();
        assert!((f - g).norm() < 1e-6, "{f:?}");
    }

    #[test]
    fn a_ball_come_to_rest_still_gives_its_field() {
        // 15 frames of flight under (0, 900) px/s², then 25 frames at rest on a floor (no
        // acceleration at all), with a little noise: the rest frames are the majority, and the
        // field is still the flights'.
        let fps = 30.0;
        let dt = 1.0 / fps;
        let g = Vec2::new(0.0, 900.0);
        let mut positions = Vec::new();
        let mut seed = 5u64;
        let mut jitter = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.1
        };
        for k in 0..40 {
            let t = k.min(14) as f64 * dt;
            let x = Vec2::new(10.0 + 20.0 * t, 10.0 + 0.5 * g.y * t * t);
            positions.push(vec![Some(x + Vec2::new(jitter(), jitter()))]);
        }
        let obs = Observations::from_positions(vec!["ball".into()], vec![false], fps, 0, positions);
        let (f, _) = field_from_flights(&obs, &[], &[false; 40]).unwrap_or_default();
        assert!((f - g).norm() < 0.05 * g.norm(), "{f:?}");
    }
}
