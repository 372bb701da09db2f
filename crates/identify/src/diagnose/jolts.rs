//! Jolts: isolated frames where a particle's velocity jumps far beyond what smooth motion and
//! the track noise allow (a bounce), and the walls they suggest.
//!
//! Across every frame gap `k -> k + 1` the two second differences that contain it sum to
//! `x[k+2] - x[k+1] - x[k] + x[k-1]`, which is the whole velocity change of an impulse that
//! happened in the gap, times `dt`; minus what the model's smooth forces account for
//! (`(a[k] + a[k+1]) dt^2`) it is the unexplained impulse `J`. Its noise is `2 sigma / dt` per
//! coordinate for position noise `sigma`; the scale used is the larger of that and a robust
//! spread (median absolute value) of all impulses, so a poor model does not make jolts of its
//! misfit. A gap whose impulse exceeds [`JOLT_THRESHOLD`] times the scale and is the largest
//! within two frames is a jolt if the velocity along it reverses (one-sided quadratic fits over
//! [`JOLT_FIT_POINTS`] frames give the velocities before and after): a bounce, not a kick.
//!
//! A wall reverses the normal velocity and keeps the tangential one, so its jolts have jumps
//! along its normal: jolts are grouped by jump direction, each group gives a normal (mean
//! jump direction), a restitution (median of `-v_n after / v_n before`) and a line position
//! from each bounce's two frames (the centre met the line in between, approaching at
//! `v_n before` and leaving at `-e v_n before`).

use physfit_model::Vec2;
use serde::Serialize;

use crate::Observations;

/// Frames in each one-sided velocity fit.
pub const JOLT_FIT_POINTS: usize = 4;

/// A jump must exceed this many times its noise scale to be a jolt.
pub const JOLT_THRESHOLD: f64 = 5.0;

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

/// A wall suggested by a group of jolts.
#[derive(Clone, Debug, PartialEq)]
pub struct WallGuess {
    /// `[normal_angle (rad), offset (px), restitution]` (see [`super::Effect::Wall`]).
    pub params: [f64; 3],
    /// Indices of the jolts it explains.
    pub jolts: Vec<usize>,
}

/// Least-squares weights giving the velocity (per frame) at `tau = 0` from samples at `taus`.
fn derivative_weights(taus: &[f64]) -> Vec<f64> {
    let m = taus.len();
    let a = nalgebra::DMatrix::from_fn(m, 3, |i, j| taus[i].powi(j as i32));
    let ata = a.transpose() * &a;
    match ata.try_inverse() {
        Some(inv) => {
            let w = inv * a.transpose();
            (0..m).map(|i| w[(1, i)]).collect()
        }
        None => vec![0.0; m],
    }
}

/// The jolts in `obs` (free particles only) and the noise scale of the impulses (px/s).
///
/// `acc[k][p]`, when given, is the model's acceleration of particle `p` at frame offset `k`
/// (px/s²), removed from the impulses so that smooth forces are not mistaken for jolts.
pub fn find_jolts(obs: &Observations, acc: Option<&[Option<Vec<Vec2>>]>) -> (Vec<Jolt>, f64) {
    let m = JOLT_FIT_POINTS;
    let fps = obs.fps;
    let dt = obs.frame_dt();
    let left_taus: Vec<f64> = (0..m).map(|i| -(m as f64) + 0.5 + i as f64).collect();
    let right_taus: Vec<f64> = (0..m).map(|i| 0.5 + i as f64).collect();
    let wl = derivative_weights(&left_taus);
    let wr = derivative_weights(&right_taus);
    // x[k+2] - x[k+1] - x[k] + x[k-1] has noise 2 sigma per coordinate.
    let noise_scale = 2.0 * obs.noise * fps;
    let frames = obs.frame_count();
    let model_acc = |k: usize, p: usize| {
        acc.and_then(|a| a.get(k)?.as_ref()?.get(p).copied())
            .unwrap_or_else(Vec2::zeros)
    };
    // impulses[p][k]: impulse per unit mass across the gap k -> k+1, px/s.
    let mut impulses: Vec<Vec<Option<Vec2>>> = vec![vec![None; frames]; obs.particle_count()];
    let mut magnitudes = Vec::new();
    for (p, series) in impulses.iter_mut().enumerate() {
        if obs.fixed[p] {
            continue;
        }
        for (k, slot) in series.iter_mut().enumerate().take(frames.saturating_sub(2)).skip(1) {
            let x = |q: usize| obs.positions[q][p];
            if let (Some(a), Some(b), Some(c), Some(d)) = (x(k - 1), x(k), x(k + 1), x(k + 2)) {
                let i = (d - c - b + a) * fps - (model_acc(k, p) + model_acc(k + 1, p)) * dt;
                magnitudes.push(i.x.abs());
                magnitudes.push(i.y.abs());
                *slot = Some(i);
            }
        }
    }
    if magnitudes.is_empty() {
        return (Vec::new(), noise_scale);
    }
    magnitudes.sort_by(|a, b| a.total_cmp(b));
    let robust = 1.4826 * magnitudes[magnitudes.len() / 2];
    let scale = noise_scale.max(robust).max(f64::MIN_POSITIVE);
    let mut out = Vec::new();
    for (p, series) in impulses.iter().enumerate() {
        for k in 0..frames {
            let Some(imp) = series[k] else { continue };
            let size = imp.norm();
            if size < JOLT_THRESHOLD * scale {
                continue;
            }
            let lo = k.saturating_sub(2);
            let hi = (k + 2).min(frames - 1);
            let is_peak = (lo..=hi).all(|q| q == k || series[q].map_or(true, |i| i.norm() < size));
            if !is_peak {
                continue;
            }
            // One-sided quadratic fits give the velocities before and after the gap.
            let side = |first: usize, w: &[f64]| -> Option<Vec2> {
                let pts: Option<Vec<Vec2>> = (0..m).map(|i| obs.positions.get(first + i)?[p]).collect();
                Some(pts?.iter().zip(w).map(|(x, w)| x * *w).sum::<Vec2>() * fps)
            };
            let before = (k + 1).checked_sub(m).and_then(|f| side(f, &wl));
            let after = side(k + 1, &wr);
            let (vb, va) = match (before, after) {
                (Some(b), Some(a)) => (b, a),
                // Near the ends: split the impulse around the observed velocity.
                _ => {
                    let v = obs.velocities[k][p].unwrap_or_else(Vec2::zeros);
                    (v - imp * 0.5, v + imp * 0.5)
                }
            };
            // A bounce reverses the velocity along its impulse: approaching, then leaving.
            let n = imp / size;
            if !(vb.dot(&n) < 0.0 && va.dot(&n) > 0.0) {
                continue;
            }
            let x = obs.positions[k][p].unwrap_or_else(Vec2::zeros);
            out.push(Jolt {
                particle: p,
                frame: obs.first_frame + k,
                position: [x.x, x.y],
                before: [vb.x, vb.y],
                after: [va.x, va.y],
                impulse: [imp.x, imp.y],
                significance: size / scale,
            });
        }
    }
    (out, scale)
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
    groups
        .into_iter()
        .map(|(n, members)| {
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
            WallGuess {
                params: [n.y.atan2(n.x), offset, e],
                jolts: members,
            }
        })
        .collect()
}
