//! Localisation: where the base model's residuals live, judged against what track noise
//! alone produces.
//!
//! Two residuals are used. The *position* residual (observed minus predicted, from the base
//! model simulated from its best start state) shows which frames disagree; it is compared
//! with the measured track noise. The *acceleration* residual is the weak-form equation's
//! residual of the base model divided by `integral phi dt`: a mean unexplained acceleration
//! per particle and window, in px/s². Its noise level is measured by replicas: the tracks
//! are perturbed by fresh Gaussian noise of the measured level (seeded), the weak form is
//! rebuilt and the change of each residual gives the spread that noise alone causes. A
//! particle or bond is reported only when its residual is well beyond that spread.

use physfit_model::Vec2;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::family::Family;
use super::jolts::Jolt;
use super::report::{BondResidual, Localisation, ParticleResidual, ResidualSeries};
use super::support::Support;
use super::weak::{residuals, solve, WeakForm};
use crate::Observations;

/// Noise replicas used to measure the residual accelerations' noise level.
pub const NOISE_REPLICAS: usize = 4;

/// A residual is significant when its mean square exceeds this many times noise's.
pub const SIGNIFICANT_RATIO: f64 = 4.0;

/// The base model's weak-form residual (per row, px/s²) with its bond values re-solved on
/// every row.
fn acceleration_residuals(family: &Family, weak: &WeakForm, theta: Option<&[f64]>) -> (Vec<f64>, Vec<f64>) {
    let cols: Vec<&[f64]> = weak.bond_columns().iter().map(|c| c.as_slice()).collect();
    let all: Vec<usize> = (0..weak.rows.len()).collect();
    let theta = theta.map_or_else(|| solve(&cols, &weak.rhs, &all), <[f64]>::to_vec);
    let _ = family;
    let r = residuals(&cols, &theta, &weak.rhs);
    (r.iter().map(|v| v / weak.phi_integral).collect(), theta)
}

/// The localisation of the base model's residuals (see the module doc).
pub fn localise(
    family: &Family,
    obs: &Observations,
    weak: &WeakForm,
    series: &ResidualSeries,
    jolts: &[Jolt],
    supports: &[Support],
    seed: u64,
) -> Localisation {
    let structure = &family.structure;
    let n = obs.particle_count();
    let sigma = obs.noise;
    // Ratios to the noise use its floor where the tracks are exact (noise 0).
    let sigma_ratio = super::search::noise_floor(sigma, super::family::DataScales::of(structure, obs).length);
    let (acc, theta) = acceleration_residuals(family, weak, None);

    // Noise replicas: the change of every row's residual under fresh noise.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_10ca);
    let normal = Normal::new(0.0, sigma.max(1e-12)).ok();
    let mut noise_sq = vec![0.0; n];
    let mut noise_count = vec![0usize; n];
    let mut along_noise: Vec<(f64, usize)> = vec![(0.0, 0); structure.springs.len()];
    for _ in 0..NOISE_REPLICAS {
        let Some(normal) = normal else { break };
        let positions: Vec<Vec<Option<Vec2>>> = obs
            .positions
            .iter()
            .map(|f| {
                f.iter()
                    .enumerate()
                    .map(|(p, x)| {
                        let dx = Vec2::new(normal.sample(&mut rng), normal.sample(&mut rng));
                        x.map(|x| if obs.fixed[p] { x } else { x + dx })
                    })
                    .collect()
            })
            .collect();
        let noisy = Observations::from_positions(
            obs.particle_ids.clone(),
            obs.fixed.clone(),
            obs.fps,
            obs.first_frame,
            positions,
        );
        let replica = weak.rebuild(family, &noisy);
        if replica.rows != weak.rows {
            continue;
        }
        let (acc_r, _) = acceleration_residuals(family, &replica, Some(&theta));
        for (r, (a, b)) in weak.rows.iter().zip(acc.iter().zip(&acc_r)) {
            noise_sq[r.particle] += (a - b) * (a - b);
            noise_count[r.particle] += 1;
        }
        for (k, s) in structure.springs.iter().enumerate() {
            let along = along_bond(weak, &acc, s.ends[0].index(), s.ends[1].index());
            let along_r = along_bond(weak, &acc_r, s.ends[0].index(), s.ends[1].index());
            for (a, b) in along.iter().zip(&along_r) {
                along_noise[k].0 += (a.1 - b.1) * (a.1 - b.1);
                along_noise[k].1 += 1;
            }
        }
    }

    let id = |p: usize| obs.particle_ids[p].clone();
    let mut particles = Vec::new();
    let mut summary = Vec::new();
    for &p in &family.free {
        let rows: Vec<usize> = (0..weak.rows.len())
            .filter(|&r| weak.rows[r].particle == p)
            .collect();
        // Pair the x and y rows of each window.
        let mut points: Vec<(usize, Vec2)> = Vec::new();
        for pair in rows.chunks(2) {
            if let [a, b] = pair {
                points.push((weak.rows[*a].start + weak.window / 2, Vec2::new(acc[*a], acc[*b])));
            }
        }
        let count = points.len().max(1) as f64;
        let mean: Vec2 = points.iter().map(|(_, a)| a).sum::<Vec2>() / count;
        let ms: f64 = points.iter().map(|(_, a)| a.norm_squared()).sum::<f64>() / count / 2.0;
        let noise = if noise_count[p] > 0 {
            (noise_sq[p] / noise_count[p] as f64).sqrt()
        } else {
            f64::NAN
        };
        let rms = ms.sqrt();
        let pos: Vec<f64> = series
            .before
            .iter()
            .filter_map(|f| f.get(p).copied().flatten())
            .flat_map(|e| [e[0] * e[0], e[1] * e[1]])
            .collect();
        let position_rms = (pos.iter().sum::<f64>() / pos.len().max(1) as f64).sqrt();
        // Beyond noise: a mean square residual acceleration above SIGNIFICANT_RATIO times
        // noise's, a mean (bias) above five standard errors (windows overlap by three quarters,
        // so a quarter of them are independent), or a position residual above
        // sqrt(SIGNIFICANT_RATIO) track noises.
        let independent = (points.len() as f64 / 4.0).max(1.0);
        let bias_z = mean.norm() / (noise / independent.sqrt()).max(f64::MIN_POSITIVE);
        let significant = noise.is_finite()
            && (ms > SIGNIFICANT_RATIO * noise * noise
                || bias_z > 5.0
                || position_rms > SIGNIFICANT_RATIO.sqrt() * sigma);
        let velocity_correlation = {
            let mut num = 0.0;
            let (mut aa, mut vv) = (0.0, 0.0);
            for (k, a) in &points {
                if let Some(s) = weak.state(*k) {
                    let v = s.velocities[p];
                    num += a.dot(&v);
                    aa += a.norm_squared();
                    vv += v.norm_squared();
                }
            }
            if aa > 0.0 && vv > 0.0 {
                num / (aa * vv).sqrt()
            } else {
                0.0
            }
        };
        let has_jolts = jolts.iter().any(|j| j.particle == p);
        // The pattern, each test against its noise: a bias of three standard errors, a
        // correlation with the velocity three standard errors below zero, a straight-line trend
        // explaining half the variance of a residual beyond noise; a position residual beyond
        // noise whose accelerations are each within it accumulates from a small force.
        let velocity_z = velocity_correlation * independent.sqrt();
        let beyond = noise.is_finite() && ms > SIGNIFICANT_RATIO * noise * noise;
        let pattern = if !significant {
            if has_jolts {
                "isolated jolts"
            } else {
                "noise"
            }
        } else if has_jolts && !beyond {
            "isolated jolts"
        } else if velocity_z < -3.0 {
            "against the motion"
        } else if bias_z > 3.0 {
            "steady bias"
        } else if beyond && trend_fraction(&points) > 0.5 {
            "slow trend"
        } else if beyond {
            "oscillating"
        } else {
            "accumulated drift"
        };
        let mut region: Option<[f64; 4]> = None;
        if noise.is_finite() {
            for (k, a) in &points {
                if a.norm() > 3.0 * noise * std::f64::consts::SQRT_2 {
                    if let Some(x) = obs.positions[*k][p] {
                        region = Some(match region {
                            None => [x.x, x.y, x.x, x.y],
                            Some(r) => [r[0].min(x.x), r[1].min(x.y), r[2].max(x.x), r[3].max(x.y)],
                        });
                    }
                }
            }
        }

        if significant || has_jolts {
            summary.push(if rms.is_finite() && noise.is_finite() {
                format!(
                    "{}: {pattern}, residual acceleration {:.2} px/s^2 RMS against {:.2} from noise, mean {:.2} px/s^2 towards {:.0} degrees",
                    id(p),
                    rms,
                    noise,
                    mean.norm(),
                    mean.y.atan2(mean.x).to_degrees()
                )
            } else {
                format!(
                    "{}: {pattern}, position residual {:.3} px RMS ({:.1} track noises); no weak-form window free of bounces measures its acceleration",
                    id(p),
                    position_rms,
                    position_rms / sigma_ratio
                )
            });
        }
        particles.push(ParticleResidual {
            particle: id(p),
            position_rms,
            position_rms_over_noise: position_rms / sigma_ratio,
            acceleration_rms: rms,
            acceleration_noise: noise,
            mean_acceleration: [mean.x, mean.y],
            direction_deg: mean.y.atan2(mean.x).to_degrees(),
            velocity_correlation,
            significant,
            pattern: pattern.into(),
            region,
        });
    }

    let mut bonds = Vec::new();
    for (k, s) in structure.springs.iter().enumerate() {
        let [i, j] = [s.ends[0].index(), s.ends[1].index()];
        let mut sq = Vec::new();
        for (f, res) in series.before.iter().enumerate() {
            let (Some(xi), Some(xj)) = (obs_at(obs, series, f, i), obs_at(obs, series, f, j)) else {
                continue;
            };
            let pi = xi
                - res
                    .get(i)
                    .copied()
                    .flatten()
                    .map_or_else(Vec2::zeros, |e| Vec2::new(e[0], e[1]));
            let pj = xj
                - res
                    .get(j)
                    .copied()
                    .flatten()
                    .map_or_else(Vec2::zeros, |e| Vec2::new(e[0], e[1]));
            let e = (xj - xi).norm() - (pj - pi).norm();
            sq.push(e * e);
        }
        let length_rms = (sq.iter().sum::<f64>() / sq.len().max(1) as f64).sqrt();
        let along = along_bond(weak, &acc, i, j);
        let along_rms = (along.iter().map(|a| a.1 * a.1).sum::<f64>() / along.len().max(1) as f64).sqrt();
        let along_noise = if along_noise[k].1 > 0 {
            (along_noise[k].0 / along_noise[k].1 as f64).sqrt()
        } else {
            f64::NAN
        };
        let significant =
            along_noise.is_finite() && along_rms * along_rms > SIGNIFICANT_RATIO * along_noise * along_noise;
        if significant {
            summary.push(format!(
                "{}: unexplained stretching acceleration {:.2} px/s^2 RMS against {:.2} from noise",
                structure.spring_label(k),
                along_rms,
                along_noise
            ));
        }
        bonds.push(BondResidual {
            between: [id(i), id(j)],
            length_rms,
            length_rms_over_noise: length_rms / (sigma_ratio * std::f64::consts::SQRT_2),
            along_acceleration_rms: along_rms,
            along_acceleration_noise: along_noise,
            significant,
        });
    }

    // Frames where some position residual exceeds three noise levels.
    let limit = 3.0 * sigma.max(f64::MIN_POSITIVE);
    let mut frames = Vec::new();
    let mut open: Option<[usize; 2]> = None;
    for (f, res) in series.before.iter().enumerate() {
        let bad = res
            .iter()
            .flatten()
            .any(|e| e[0].abs() > limit || e[1].abs() > limit);
        let frame = series.frames.get(f).copied().unwrap_or(f);
        match (bad, &mut open) {
            (true, Some(r)) => r[1] = frame,
            (true, None) => open = Some([frame, frame]),
            (false, Some(r)) => {
                frames.push(*r);
                open = None;
            }
            (false, None) => {}
        }
    }
    frames.extend(open);
    if !jolts.is_empty() {
        summary.push(format!("{} jolt(s) (bounces) found in the tracks", jolts.len()));
    }
    summary.extend(supports.iter().map(|s| s.text.clone()));
    if summary.is_empty() {
        summary.push("the base model's residuals are at the level of the track noise".into());
    }
    Localisation {
        particles,
        bonds,
        frames,
        jolts: jolts.to_vec(),
        supports: supports.to_vec(),
        summary,
    }
}

fn obs_at(obs: &Observations, series: &ResidualSeries, f: usize, p: usize) -> Option<Vec2> {
    let frame = *series.frames.get(f)?;
    let k = frame.checked_sub(obs.first_frame)?;
    obs.positions.get(k)?[p]
}

/// Relative residual acceleration along the bond `i-j` per window: `(r_j - r_i) . u`.
fn along_bond(weak: &WeakForm, acc: &[f64], i: usize, j: usize) -> Vec<(usize, f64)> {
    let mut by_window: std::collections::BTreeMap<usize, [Option<f64>; 4]> =
        std::collections::BTreeMap::new();
    for (r, row) in weak.rows.iter().enumerate() {
        let slot = if row.particle == i {
            0
        } else if row.particle == j {
            2
        } else {
            continue;
        };
        by_window.entry(row.start).or_insert([None; 4])[slot + row.coord] = Some(acc[r]);
    }
    let mut out = Vec::new();
    for (start, v) in by_window {
        let centre = start + weak.window / 2;
        let Some(s) = weak.state(centre) else { continue };
        let d = s.positions[j] - s.positions[i];
        let u = d / d.norm().max(f64::MIN_POSITIVE);
        let ri = Vec2::new(v[0].unwrap_or(0.0), v[1].unwrap_or(0.0));
        let rj = Vec2::new(v[2].unwrap_or(0.0), v[3].unwrap_or(0.0));
        out.push((centre, (rj - ri).dot(&u)));
    }
    out
}

/// Fraction of the residual's variance (about its mean) explained by a straight line in time.
fn trend_fraction(points: &[(usize, Vec2)]) -> f64 {
    if points.len() < 3 {
        return 0.0;
    }
    let n = points.len() as f64;
    let tm = points.iter().map(|(k, _)| *k as f64).sum::<f64>() / n;
    let am: Vec2 = points.iter().map(|(_, a)| a).sum::<Vec2>() / n;
    let stt: f64 = points.iter().map(|(k, _)| (*k as f64 - tm).powi(2)).sum();
    let sta: Vec2 = points.iter().map(|(k, a)| (a - am) * (*k as f64 - tm)).sum();
    let saa: f64 = points.iter().map(|(_, a)| (a - am).norm_squared()).sum();
    if stt <= 0.0 || saa <= 0.0 {
        return 0.0;
    }
    sta.norm_squared() / stt / saa
}
