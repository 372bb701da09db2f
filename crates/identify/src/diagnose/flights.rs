//! The uniform field seen in free flights, for recordings whose bounces leave the weak form
//! no window (a ball bouncing every few frames at a low frame rate).
//!
//! Between impulses a particle's second difference `(x[k+1] - 2 x[k] + x[k-1]) / dt²` is its
//! acceleration, with noise `sqrt(6) sigma / dt²` per coordinate. Less the structure's own
//! forces, what remains on every free particle is the field: its median over the frames away
//! from jolts is robust to the few differences a missed bounce or contact spoils (a median
//! fails only when half of them are spoiled).

use physfit_model::Vec2;

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

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
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
}
