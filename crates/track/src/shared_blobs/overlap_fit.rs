//! The joint Levenberg-Marquardt fit of overlapping particle images to a group's pixels.
//!
//! Why a second Levenberg-Marquardt beside physfit-identify's `lm.rs`: the tracker must not
//! depend on the identifier, and this fit is small (two coordinates for each particle of a
//! group, at most one brightness scale, an analytic Jacobian of the image model, no bounds,
//! no secant updates), so its solver is a few lines of normal equations on nalgebra. The fit is what makes split points
//! accurate: on the dense crossing, soft Voronoi centroids put them 1.0-1.5 px RMS off where
//! particles were within 3 px, the fit 0.02 px (docs/tracking.md). The `levenberg-marquardt`
//! crate was timed against the identifier's solver (2.1 times the simulations, its module
//! doc), not against this one.

use super::profile::Profile;
use nalgebra::{DMatrix, DVector};

/// How overlapping particle images combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Composition {
    /// Light adds (fluorescent or glowing spots).
    Sum,
    /// Each image covers a fraction `s / peak` of what lies below (opaque objects, discs
    /// drawn one over the other).
    Cover,
}
/// One pixel of a group's fit.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pixel {
    /// Column and row of the pixel centre, px.
    pub(super) x: f64,
    pub(super) y: f64,
    /// Measured signal, grey levels.
    pub(super) signal: f64,
    /// Light of the particles held in place: their sum, grey levels (for [`Composition::Sum`]).
    pub(super) held_sum: f64,
    /// The fraction of the pixel they leave uncovered (for [`Composition::Cover`]).
    pub(super) held_clear: f64,
}

/// A group's fitted positions.
#[derive(Clone, Debug)]
pub(super) struct Fit {
    /// Positions, px.
    pub(super) positions: Vec<[f64; 2]>,
    /// Standard error of each position (per axis, px), from the residuals' spread: where the
    /// model misses the image (blur, a composition it does not know) the residuals grow, and
    /// so do the errors.
    pub(super) errors: Vec<f64>,
    /// Sum of squared residuals, grey levels².
    pub(super) sse: f64,
}

/// Fits the positions of particles seeded at `seeds` (px) to `pixels` by
/// Levenberg-Marquardt (with a brightness scale common to them when the profile is a disc).
pub(super) fn fit_positions(
    pixels: &[Pixel],
    seeds: &[[f64; 2]],
    profile: &Profile,
    composition: Composition,
) -> Fit {
    let k = seeds.len();
    // Unknowns: each position (x, y), then, for a profile that was not measured (a disc), one
    // brightness scale for the group (its level is only estimated). A measured profile's
    // level is the recording's own: a free scale would only let overlapping particles trade
    // light for position.
    let free_scale = !profile.measured;
    let m = 2 * k + usize::from(free_scale);
    let clear = |t: f64| profile.clear(t);
    // Sum of squared residuals at `u`; with `normal`, also the Gauss-Newton normal
    // equations (JᵀJ and Jᵀr, r = measured − model).
    let evaluate = |u: &[f64], mut normal: Option<(&mut DMatrix<f64>, &mut DVector<f64>)>| -> f64 {
        let scale = if free_scale { u[2 * k] } else { 1.0 };
        let mut sse = 0.0;
        let mut grad = vec![0.0; m];
        // Each fitted particle's value and its derivatives along its own x and y.
        let mut vals = vec![(0.0, 0.0, 0.0); k];
        if let Some((a, b)) = normal.as_mut() {
            a.fill(0.0);
            b.fill(0.0);
        }
        for px in pixels {
            for (j, v) in vals.iter_mut().enumerate() {
                let (dx, dy) = (px.x - u[2 * j], px.y - u[2 * j + 1]);
                let r = dx.hypot(dy);
                let (t, dt) = profile.at(r);
                *v = if r > 1e-9 {
                    (t, -dt * dx / r, -dt * dy / r)
                } else {
                    (t, 0.0, 0.0)
                };
            }
            let shape = match composition {
                Composition::Sum => {
                    for (j, v) in vals.iter().enumerate() {
                        grad[2 * j] = scale * v.1;
                        grad[2 * j + 1] = scale * v.2;
                    }
                    px.held_sum + vals.iter().map(|v| v.0).sum::<f64>()
                }
                Composition::Cover => {
                    let all_clear = px.held_clear * vals.iter().map(|v| clear(v.0)).product::<f64>();
                    for (j, v) in vals.iter().enumerate() {
                        let rest: f64 = px.held_clear
                            * vals
                                .iter()
                                .enumerate()
                                .filter(|&(i, _)| i != j)
                                .map(|(_, w)| clear(w.0))
                                .product::<f64>();
                        grad[2 * j] = scale * rest * v.1;
                        grad[2 * j + 1] = scale * rest * v.2;
                    }
                    profile.peak * (1.0 - all_clear)
                }
            };
            if free_scale {
                grad[2 * k] = shape;
            }
            let res = px.signal - scale * shape;
            sse += res * res;
            if let Some((a, b)) = normal.as_mut() {
                for i in (0..m).filter(|&i| grad[i] != 0.0) {
                    b[i] += grad[i] * res;
                    for j in 0..m {
                        a[(i, j)] += grad[i] * grad[j];
                    }
                }
            }
        }
        sse
    };
    let mut u: Vec<f64> = seeds
        .iter()
        .flat_map(|p| [p[0], p[1]])
        .chain(free_scale.then_some(1.0))
        .collect();
    let mut a = DMatrix::zeros(m, m);
    let mut b = DVector::zeros(m);
    let mut sse = evaluate(&u, Some((&mut a, &mut b)));
    let mut lambda = 1e-3;
    for _ in 0..FIT_ITERATIONS {
        let mut damped = a.clone();
        for i in 0..m {
            damped[(i, i)] += lambda * a[(i, i)].max(1e-9);
        }
        let Some(step) = damped.cholesky().map(|c| c.solve(&b)) else {
            lambda *= 10.0;
            continue;
        };
        let trial: Vec<f64> = u.iter().zip(step.iter()).map(|(v, d)| v + d).collect();
        let trial_sse = evaluate(&trial, None);
        if trial_sse < sse {
            u = trial;
            sse = evaluate(&u, Some((&mut a, &mut b)));
            lambda = (lambda * 0.3).max(1e-9);
            if step.rows(0, 2 * k).amax() < FIT_STEP_TOLERANCE {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e9 {
                break;
            }
        }
    }
    let pos: Vec<[f64; 2]> = u[..2 * k].chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    // Covariance s² (JᵀJ)⁻¹, with s² the residual variance.
    let dof = pixels.len().saturating_sub(m).max(1) as f64;
    let inverse = a.try_inverse();
    let errors = (0..k)
        .map(|j| {
            inverse.as_ref().map_or(f64::INFINITY, |c| {
                (0.5 * (c[(2 * j, 2 * j)] + c[(2 * j + 1, 2 * j + 1)]) * sse / dof)
                    .max(0.0)
                    .sqrt()
            })
        })
        .collect();
    Fit {
        positions: pos,
        errors,
        sse,
    }
}

/// Most Levenberg-Marquardt iterations of a group's fit.
const FIT_ITERATIONS: usize = 50;
/// A group's fit stops once a step moves no position more than this, px.
const FIT_STEP_TOLERANCE: f64 = 1e-3;
