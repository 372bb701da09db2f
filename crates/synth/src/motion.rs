//! The particles' paths: smooth random walks that keep apart and inside the frame.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::style::Style;

/// A standard normal draw (Box-Muller).
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.gen::<f64>();
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Draws the paths of `style`'s particles, frame-major: `paths[k][i]` is particle `i`'s
/// centre in frame `k`, px.
///
/// Each velocity is smoothed (`v <- 0.85 v + 0.35 speed z`, `z` standard normal per axis)
/// and capped at `style.speed` px per frame. A step that would bring a particle nearer than
/// [`Style::separation`] to another, or nearer than [`Style::margin`] to the frame's edge,
/// is drawn again (up to 16 times, with a random velocity), else the particle stays put that
/// frame. Starting positions are uniform over the allowed area, drawn again until apart.
pub fn draw_paths(style: &Style) -> Vec<Vec<[f64; 2]>> {
    let mut rng = ChaCha8Rng::seed_from_u64(style.seed ^ 0x9a7b_5eed);
    let radii = style.radii();
    let (w, h) = (f64::from(style.width), f64::from(style.height));
    let bounds: Vec<([f64; 2], [f64; 2])> = radii
        .iter()
        .map(|&r| {
            let m = style.margin(r);
            ([m, m], [w - 1.0 - m, h - 1.0 - m])
        })
        .collect();
    let fits = |p: [f64; 2], i: usize, placed: &[[f64; 2]]| -> bool {
        let (lo, hi) = bounds[i];
        p[0] >= lo[0]
            && p[1] >= lo[1]
            && p[0] <= hi[0]
            && p[1] <= hi[1]
            && placed.iter().enumerate().all(|(j, q)| {
                j == i || {
                    let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
                    d >= style.separation(radii[i], radii[j])
                }
            })
    };
    let mut pos: Vec<[f64; 2]> = Vec::with_capacity(radii.len());
    for (i, &(lo, hi)) in bounds.iter().enumerate() {
        let mut p = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        for _ in 0..10_000 {
            let q = [
                lo[0] + (hi[0] - lo[0]).max(0.0) * rng.gen::<f64>(),
                lo[1] + (hi[1] - lo[1]).max(0.0) * rng.gen::<f64>(),
            ];
            // `pos` holds the particles placed so far, all with other indices.
            let mut placed = pos.clone();
            placed.push([f64::INFINITY; 2]);
            if fits(q, i, &placed) {
                p = q;
                break;
            }
        }
        pos.push(p);
    }
    let mut vel: Vec<[f64; 2]> = (0..radii.len())
        .map(|_| {
            let a = std::f64::consts::TAU * rng.gen::<f64>();
            let s = style.speed * rng.gen_range(0.3..1.0);
            [s * a.cos(), s * a.sin()]
        })
        .collect();
    let mut paths = vec![pos.clone()];
    let cap = |v: [f64; 2]| {
        let n = (v[0] * v[0] + v[1] * v[1]).sqrt();
        if n > style.speed {
            [v[0] * style.speed / n, v[1] * style.speed / n]
        } else {
            v
        }
    };
    for _ in 1..style.frame_count {
        for i in 0..radii.len() {
            let mut v = vel[i];
            v = cap([
                0.85 * v[0] + 0.35 * style.speed * normal(&mut rng),
                0.85 * v[1] + 0.35 * style.speed * normal(&mut rng),
            ]);
            let mut moved = false;
            for attempt in 0..=16 {
                if attempt > 0 {
                    let a = std::f64::consts::TAU * rng.gen::<f64>();
                    let s = style.speed * rng.gen::<f64>();
                    v = [s * a.cos(), s * a.sin()];
                }
                let q = [pos[i][0] + v[0], pos[i][1] + v[1]];
                if fits(q, i, &pos) {
                    pos[i] = q;
                    vel[i] = v;
                    moved = true;
                    break;
                }
            }
            if !moved {
                vel[i] = [0.0, 0.0];
            }
        }
        paths.push(pos.clone());
    }
    paths
}
