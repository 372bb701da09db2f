//! Findings the data cannot decide: an accepted finding whose parameters the tracks do not
//! identify is tested against a smooth track bias of the same size. The fourth differences
//! that measure the track noise do not see a tracker's slow bias (blur, perspective, a
//! centroid pulled by the background), and a finding whose parameters are not determined is
//! a flexible shape that can fit such a bias. When a polynomial bias in time, with at least
//! as many new degrees of freedom as the finding, added to the model without the finding
//! explains the tracks about as well as the finding does (the finding does not beat it on the
//! Bayesian information criterion), the tracks cannot tell the finding from a tracking bias:
//! it leaves the model and is reported as "not enough data".

use nalgebra::DMatrix;

use super::family::Family;
use super::shooting::{Shot, ShotFit};

/// Sum of squares left when the model `fit` of `family` on `shot` is refitted linearly
/// together with a polynomial bias in time per free particle and coordinate, of the lowest
/// degree adding at least `extra` degrees of freedom beyond those of the model's own
/// Jacobian; with the degrees of freedom added. `None` when the residuals cannot be
/// computed or the frames do not carry that many degrees of freedom.
pub fn bias_cost(shot: &Shot<'_>, family: &Family, fit: &ShotFit, extra: usize) -> Option<(f64, usize)> {
    let mut r = Vec::new();
    if !shot.residuals(family, &fit.params, &fit.state, usize::MAX, &mut r) {
        return None;
    }
    // Rows: (frame, particle, coordinate) in the residuals' order.
    let obs = shot.obs;
    let mut rows = Vec::new();
    for k in shot.anchor..obs.frame_count() {
        if !shot.mask[k] {
            continue;
        }
        for (slot, &p) in family.free.iter().enumerate() {
            if obs.positions[k][p].is_some() {
                rows.push((k, slot, 0));
                rows.push((k, slot, 1));
            }
        }
    }
    let n = r.len();
    if rows.len() != n || fit.jacobian.nrows() != n || n == 0 {
        return None;
    }
    let (k0, k1) = (rows[0].0 as f64, rows[n - 1].0 as f64);
    let half = ((k1 - k0) / 2.0).max(1.0);
    let mid = (k0 + k1) / 2.0;
    let j = &fit.jacobian;
    let rank_j = rank(j);
    let slots = family.free.len() * 2;
    for degree in 0..n {
        let cols = j.ncols() + slots * (degree + 1);
        if cols >= n {
            return None;
        }
        let mut a = DMatrix::zeros(n, cols);
        a.columns_mut(0, j.ncols()).copy_from(j);
        for (i, &(k, slot, c)) in rows.iter().enumerate() {
            let t = (k as f64 - mid) / half;
            for d in 0..=degree {
                a[(i, j.ncols() + (slot * 2 + c) * (degree + 1) + d)] = legendre(d, t);
            }
        }
        let added = rank(&a).saturating_sub(rank_j);
        if added < extra {
            continue;
        }
        let rv = nalgebra::DVector::from_vec(r.clone());
        let svd = a.clone().svd(true, true);
        let tol = svd.singular_values.max() * 1e-10;
        let x = svd.solve(&rv, tol).ok()?;
        let left = (&rv - &a * x).norm_squared();
        return left.is_finite().then_some((left, added));
    }
    None
}

/// Legendre polynomial of degree `d` at `t` in [-1, 1].
fn legendre(d: usize, t: f64) -> f64 {
    let (mut p0, mut p1) = (1.0, t);
    if d == 0 {
        return p0;
    }
    for n in 1..d {
        let n = n as f64;
        let p2 = ((2.0 * n + 1.0) * t * p1 - n * p0) / (n + 1.0);
        p0 = p1;
        p1 = p2;
    }
    p1
}

/// Numerical rank, columns scaled to unit norm first (parameters differ in units).
fn rank(m: &DMatrix<f64>) -> usize {
    let mut s = m.clone();
    for mut c in s.column_iter_mut() {
        let norm = c.norm();
        if norm > 0.0 {
            c /= norm;
        }
    }
    let sv = s.svd(false, false).singular_values;
    let top = sv.max();
    sv.iter().filter(|&&v| v > top * 1e-8).count()
}
