//! The fast exact solver, stage 1: a linear least-squares estimate in *weak form*.
//!
//! For fixed positions every bond force is linear in `S`, `S L` (springs) and `T`, `T M`
//! (torsions): `f = S b_S(x) + (S L) b_SL(x)` with the basis forces `b` evaluated through
//! [`SpringGeometry::force_on_i`] and [`TorsionGeometry::forces`] at unit values (the force law
//! is never re-derived here). Newton's law `m x'' = sum_b theta_b b(x)` is then linear in the
//! unknowns `theta`.
//!
//! Accelerations from finite differences of frames are biased by several per cent when frames
//! are several integration substeps apart, and amplify noise. Instead the equation is
//! multiplied by smooth test functions `phi` with compact support over `W` frames and
//! integrated by parts twice (the weak form of Messenger & Bortz's WSINDy):
//!
//! ```text
//! integral m (x - x_c) phi'' dt = sum_b theta_b integral b(x(t)) phi(t) dt
//! ```
//!
//! with `phi(t) = (1 - s^2)^q`, `s` from -1 to 1 across the window, `q` = [`TEST_EXPONENT`].
//! `phi` and its first `q - 1` derivatives vanish at both ends, so the boundary terms drop out
//! and the trapezoid rule over the frames is accurate to high order (Euler-Maclaurin); `x_c`
//! (the window's central position) removes the quadrature error of a constant offset. No
//! derivative of the data is taken, so the noise is averaged rather than amplified. One
//! equation per free particle, coordinate and window (windows overlap by three quarters; a
//! window is used for a particle where that particle and its bond partners are tracked
//! throughout). Each equation is divided by the particle's mass so that every row carries the
//! same noise.
//!
//! The normal equations are solved with Jacobi (column) scaling: dense Cholesky (eigenvalue
//! pseudo-inverse if singular) for up to [`DENSE_LIMIT`] unknowns, sparse Cholesky after a
//! nested-dissection ordering beyond ([`crate::sparse_cholesky`]; the normal matrix is
//! assembled per particle: every equation of a particle has the same columns, so their outer
//! products are summed in one small dense block per particle and scattered once; conjugate
//! gradients if the factorisation fails), then once more with a weak prior that each
//! rest value lies within its bond's observed geometry (weighted by the weak form's own
//! residual noise, so it only decides directions the data leave open; see
//! `with_geometry_prior`). Then `L = (S L) / S`, `M = (T M) / T`.
//! The estimate is the starting point of the multi-step refinement ([`crate::refine`]).

use std::collections::HashMap;

use nalgebra::{DMatrix, DVector};
use physfit_model::{SpringGeometry, State, TorsionGeometry, Vec2};
use serde::Serialize;

use crate::sparse_cholesky::{nested_dissection, CholeskyFactor};
use crate::{stiffness_scales, BondRef, IdentifyError, Observations, ParameterKind, Problem};

/// Exponent `q` of the weak-form test function `(1 - s^2)^q`.
pub(crate) const TEST_EXPONENT: i32 = 6;

/// Largest number of linear unknowns solved densely.
pub(crate) const DENSE_LIMIT: usize = 200;

/// Smallest test-function window, frames.
pub(crate) const MIN_TEST_WINDOW: usize = 8;

/// The result of the linear (weak-form) stage.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LinearEstimate {
    /// Estimated parameter vector (clamped into the layout's bounds).
    pub params: Vec<f64>,
    /// Frames spanned by each test function.
    pub test_window: usize,
    /// Number of weak-form equations used.
    pub equation_count: usize,
    /// Number of linear unknowns (`S`, `S L`, `T`, `T M`, or single values where one is known).
    pub unknown_count: usize,
    /// What could not be estimated and was set from the data instead.
    pub warnings: Vec<String>,
}

/// A linear unknown: which bond value (or product) it is.
#[derive(Clone, Copy, Debug)]
enum Column {
    /// Spring stiffness with the rest length also unknown (paired with `SpringProduct`).
    SpringS(usize),
    /// `S L` of a spring.
    SpringProduct(usize),
    /// Spring stiffness with a known rest length.
    SpringSKnownL(usize, f64),
    /// Rest length with a known stiffness.
    SpringLKnownS(usize, f64),
    /// Torsion stiffness with the rest cosine also unknown.
    TorsionT(usize),
    /// `T M` of a torsion.
    TorsionProduct(usize),
    /// Torsion stiffness with a known rest cosine.
    TorsionTKnownM(usize, f64),
    /// Rest cosine with a known stiffness.
    TorsionMKnownT(usize, f64),
}

fn columns(problem: &Problem) -> Vec<Column> {
    let s = &problem.structure;
    let mut out = Vec::new();
    for b in &problem.layout.bonds {
        match b.bond {
            BondRef::Spring(k) => match (s.springs[k].rest_length, s.springs[k].stiffness) {
                (None, None) => out.extend([Column::SpringS(k), Column::SpringProduct(k)]),
                (Some(l), None) => out.push(Column::SpringSKnownL(k, l)),
                (None, Some(st)) => out.push(Column::SpringLKnownS(k, st)),
                (Some(_), Some(_)) => {}
            },
            BondRef::Torsion(k) => match (s.torsions[k].rest_cos, s.torsions[k].stiffness) {
                (None, None) => out.extend([Column::TorsionT(k), Column::TorsionProduct(k)]),
                (Some(m), None) => out.push(Column::TorsionTKnownM(k, m)),
                (None, Some(t)) => out.push(Column::TorsionMKnownT(k, t)),
                (Some(_), Some(_)) => {}
            },
        }
    }
    out
}

/// The particles a column's basis force acts on.
fn column_particles(problem: &Problem, c: Column) -> Vec<usize> {
    let s = &problem.structure;
    match c {
        Column::SpringS(k)
        | Column::SpringProduct(k)
        | Column::SpringSKnownL(k, _)
        | Column::SpringLKnownS(k, _) => {
            vec![s.springs[k].ends[0].index(), s.springs[k].ends[1].index()]
        }
        Column::TorsionT(k)
        | Column::TorsionProduct(k)
        | Column::TorsionTKnownM(k, _)
        | Column::TorsionMKnownT(k, _) => {
            let t = &s.torsions[k];
            vec![t.center.index(), t.ends[0].index(), t.ends[1].index()]
        }
    }
}

/// The column's basis force on each of its particles at positions `x`, via the model's force law.
fn basis_forces(c: Column, parts: &[usize], x: &[Vec2]) -> [Vec2; 3] {
    let spring = |f: &dyn Fn(&SpringGeometry) -> Vec2| {
        let g = SpringGeometry::new(x[parts[0]], x[parts[1]]);
        let fi = f(&g);
        [fi, -fi, Vec2::zeros()]
    };
    let torsion = |f: &dyn Fn(&TorsionGeometry) -> [Vec2; 3]| {
        f(&TorsionGeometry::new(x[parts[0]], x[parts[1]], x[parts[2]]))
    };
    match c {
        Column::SpringS(_) => spring(&|g| g.force_on_i(1.0, 0.0)),
        Column::SpringProduct(_) => spring(&|g| g.force_on_i(1.0, 1.0) - g.force_on_i(1.0, 0.0)),
        Column::SpringSKnownL(_, l) => spring(&|g| g.force_on_i(1.0, l)),
        Column::SpringLKnownS(_, s) => spring(&|g| g.force_on_i(s, 1.0) - g.force_on_i(s, 0.0)),
        Column::TorsionT(_) => torsion(&|g| g.forces(1.0, 0.0)),
        Column::TorsionProduct(_) => torsion(&|g| {
            let (a, b) = (g.forces(1.0, 1.0), g.forces(1.0, 0.0));
            [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
        }),
        Column::TorsionTKnownM(_, m) => torsion(&|g| g.forces(1.0, m)),
        Column::TorsionMKnownT(_, t) => torsion(&|g| {
            let (a, b) = (g.forces(t, 1.0), g.forces(t, 0.0));
            [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
        }),
    }
}

/// The test window (frames, even) from the data: about one typical oscillation period
/// (the test function's effective width is then matched to the motion), within
/// `[MIN_TEST_WINDOW, 64]` and the number of frames.
pub fn default_test_window(problem: &Problem, observations: &Observations) -> usize {
    let omega = stiffness_scales(&problem.structure, observations).omega;
    let period_frames = std::f64::consts::TAU / omega * observations.fps;
    let w = if period_frames.is_finite() {
        period_frames.round() as usize
    } else {
        16
    };
    let max = observations.frame_count().saturating_sub(1).min(64);
    let w = w.clamp(MIN_TEST_WINDOW, max.max(MIN_TEST_WINDOW));
    w - w % 2
}

/// The weak-form linear estimate of every unknown (see the module doc). `test_window` in
/// frames (even; `None`: [`default_test_window`]). Needs at least `test_window + 1` frames.
pub fn linear_estimate(
    problem: &Problem,
    observations: &Observations,
    test_window: Option<usize>,
) -> Result<LinearEstimate, IdentifyError> {
    let w = test_window
        .unwrap_or_else(|| default_test_window(problem, observations))
        .max(2);
    let w = w + w % 2;
    let frames = observations.frame_count();
    if frames < w + 1 {
        return Err(IdentifyError::TooFewFrames {
            method: format!("the least-squares solver (test window {w} frames)"),
            need: w + 1,
            have: frames,
        });
    }
    let n = observations.particle_count();
    let structure = &problem.structure;
    let cols = columns(problem);
    let col_parts: Vec<Vec<usize>> = cols.iter().map(|&c| column_particles(problem, c)).collect();
    // For each particle, the columns acting on it and its slot in each.
    let mut touching: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (c, parts) in col_parts.iter().enumerate() {
        for (slot, &p) in parts.iter().enumerate() {
            touching[p].push((c, slot));
        }
    }
    // The particles whose positions a particle's force depends on (all bonds, known ones too).
    let mut relevant: Vec<Vec<usize>> = (0..n).map(|p| vec![p]).collect();
    for s in &structure.springs {
        let [i, j] = [s.ends[0].index(), s.ends[1].index()];
        relevant[i].push(j);
        relevant[j].push(i);
    }
    for t in &structure.torsions {
        let ps = [t.center.index(), t.ends[0].index(), t.ends[1].index()];
        for &a in &ps {
            relevant[a].extend(ps.iter().copied());
        }
    }
    let pos = &observations.positions;
    let valid: Vec<Vec<bool>> = (0..frames)
        .map(|k| {
            (0..n)
                .map(|p| relevant[p].iter().all(|&q| pos[k][q].is_some()))
                .collect()
        })
        .collect();

    // Per frame: basis forces of every column, and the known forces (bonds with known values,
    // the structure's physics) from the model with every unknown at zero.
    let zero_model = problem.model(&vec![0.0; problem.dimension()]);
    let mut basis = vec![[Vec2::zeros(); 3]; frames * cols.len()];
    let mut known = vec![Vec2::zeros(); frames * n];
    for k in 0..frames {
        let x: Vec<Vec2> = pos[k].iter().map(|p| p.unwrap_or_else(Vec2::zeros)).collect();
        for (c, &col) in cols.iter().enumerate() {
            if col_parts[c].iter().all(|&q| pos[k][q].is_some()) {
                basis[k * cols.len() + c] = basis_forces(col, &col_parts[c], &x);
            }
        }
        let v: Vec<Vec2> = observations.velocities[k]
            .iter()
            .map(|v| v.unwrap_or_else(Vec2::zeros))
            .collect();
        zero_model.forces(&State::new(x, v), &mut known[k * n..(k + 1) * n]);
    }

    // Test function samples over one window: phi and phi'' (per s^2) at each frame offset.
    let dt = observations.frame_dt();
    let half = w as f64 / 2.0;
    let q = TEST_EXPONENT;
    let hs = half * dt;
    let (phi, phi2): (Vec<f64>, Vec<f64>) = (0..=w)
        .map(|i| {
            let s = (i as f64 - half) / half;
            let u = 1.0 - s * s;
            let qf = q as f64;
            let d2 = -2.0 * qf * u.powi(q - 1) + 4.0 * qf * (qf - 1.0) * s * s * u.powi(q - 2);
            (u.powi(q), d2 / (hs * hs))
        })
        .unzip();
    let stride = (w / 4).max(1);

    // Rows, as sparse (column, value) lists with their right-hand side.
    let mut rows: Vec<(Vec<(usize, f64)>, f64)> = Vec::new();
    let mut start = 0;
    while start + w < frames {
        for p in 0..n {
            if structure.particles[p].fixed || touching[p].is_empty() {
                continue;
            }
            if !(start..=start + w).all(|k| valid[k][p]) {
                continue;
            }
            let m = structure.particles[p].mass;
            let centre = pos[start + w / 2][p].unwrap_or_else(Vec2::zeros);
            let mut lhs = Vec2::zeros();
            let mut rhs_known = Vec2::zeros();
            let mut a = vec![Vec2::zeros(); touching[p].len()];
            for (i, k) in (start..=start + w).enumerate() {
                let x = pos[k][p].unwrap_or_else(Vec2::zeros) - centre;
                lhs += x * (phi2[i] * dt);
                rhs_known += known[k * n + p] * (phi[i] * dt / m);
                for (e, &(c, slot)) in a.iter_mut().zip(&touching[p]) {
                    *e += basis[k * cols.len() + c][slot] * (phi[i] * dt / m);
                }
            }
            for coord in 0..2 {
                let entries: Vec<(usize, f64)> = touching[p]
                    .iter()
                    .zip(&a)
                    .map(|(&(c, _), v)| (c, v[coord]))
                    .collect();
                rows.push((entries, lhs[coord] - rhs_known[coord]));
            }
        }
        start += stride;
    }
    let needed = cols.len();
    if rows.len() < needed {
        return Err(IdentifyError::TooFewFrames {
            method: format!(
                "the least-squares solver ({} unknowns, {} equations)",
                needed,
                rows.len()
            ),
            need: frames + (needed - rows.len()).div_ceil(2 * n.max(1)) * stride,
            have: frames,
        });
    }
    let paired: Vec<bool> = cols
        .iter()
        .map(|c| matches!(c, Column::SpringS(_) | Column::TorsionT(_)))
        .collect();
    let first = solve_normal_equations(&rows, needed, &paired);
    let equation_count = rows.len();
    let theta = with_geometry_prior(problem, &cols, rows, first);
    let mut warnings = Vec::new();
    let params = to_parameters(problem, &cols, &theta, &mut warnings);
    Ok(LinearEstimate {
        params,
        test_window: w,
        equation_count,
        unknown_count: needed,
        warnings,
    })
}

/// Re-solves with a weak prior that each rest value lies within the observed range of its
/// bond's geometry: one pseudo-equation `(S L - S L_obs) / sd(d_obs) = 0` per spring (and
/// `(T M - T M_obs) / sd(c_obs) = 0` per torsion), weighted as one equation with the weak
/// form's own residual noise. Over-braced objects have self-stress directions along which the
/// rest values trade against each other almost without changing any force; with noisy data
/// the plain solution wanders far along them (rest cosines past -1), which puts the multi-step
/// refinement in the wrong valley. The prior decides only those directions: elsewhere the
/// data outweigh it by the number of equations, and on exact data its weight is zero.
fn with_geometry_prior(
    problem: &Problem,
    cols: &[Column],
    mut rows: Vec<(Vec<(usize, f64)>, f64)>,
    first: Vec<f64>,
) -> Vec<f64> {
    let n = cols.len();
    if rows.len() <= n {
        return first;
    }
    let rss: f64 = rows
        .iter()
        .map(|(e, b)| {
            let pred: f64 = e.iter().map(|&(c, v)| v * first[c]).sum();
            (pred - b) * (pred - b)
        })
        .sum();
    let s = (rss / (rows.len() - n) as f64).sqrt();
    if s.is_nan() || s <= 0.0 {
        return first;
    }
    let stats = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
        let sd = (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len().max(1) as f64).sqrt();
        (m, sd)
    };
    let mut added = 0;
    for (k, c) in cols.iter().enumerate() {
        let (bond, floor) = match *c {
            Column::SpringS(b) => (BondRef::Spring(b), 1e-3),
            Column::TorsionT(b) => (BondRef::Torsion(b), 1e-3),
            _ => continue,
        };
        let Some(genes) = problem.layout.bonds.iter().find(|g| g.bond == bond) else {
            continue;
        };
        let (mean, sd) = stats(&genes.observed);
        let sd = sd.max(floor * mean.abs().max(1.0));
        let stiffness = first[k]
            .abs()
            .max(1e-3 * problem.layout.parameters[genes.params[1]].scale);
        // (product - mean * stiffness_coefficient) / (stiffness * sd), times s.
        let w = s / (stiffness * sd);
        rows.push((vec![(k + 1, w), (k, -w * mean)], 0.0));
        added += 1;
    }
    if added == 0 {
        return first;
    }
    let paired: Vec<bool> = cols
        .iter()
        .map(|c| matches!(c, Column::SpringS(_) | Column::TorsionT(_)))
        .collect();
    solve_normal_equations(&rows, n, &paired)
}

/// Least squares from sparse rows via the column-scaled normal equations.
/// `paired[k]` is true where columns `k` and `k + 1` belong to one bond (`S` and `S L`, or `T`
/// and `T M`): nearly collinear columns, preconditioned together.
fn solve_normal_equations(rows: &[(Vec<(usize, f64)>, f64)], n: usize, paired: &[bool]) -> Vec<f64> {
    solve_normal_equations_with(rows, n, paired, DENSE_LIMIT, true)
}

/// As [`solve_normal_equations`], dense up to `dense_limit` unknowns; beyond, by sparse
/// Cholesky if `direct` (conjugate gradients where it fails), else by conjugate gradients.
fn solve_normal_equations_with(
    rows: &[(Vec<(usize, f64)>, f64)],
    n: usize,
    paired: &[bool],
    dense_limit: usize,
    direct: bool,
) -> Vec<f64> {
    let mut diag = vec![0.0; n];
    for (e, _) in rows {
        for &(c, v) in e {
            diag[c] += v * v;
        }
    }
    let d: Vec<f64> = diag
        .iter()
        .map(|&s| if s > 0.0 { 1.0 / s.sqrt() } else { 0.0 })
        .collect();
    let mut rhs = vec![0.0; n];
    for (e, b) in rows {
        for &(c, v) in e {
            rhs[c] += v * d[c] * b;
        }
    }
    let y = if n <= dense_limit {
        let mut a = DMatrix::<f64>::zeros(n, n);
        for (e, _) in rows {
            for &(c, v) in e {
                for &(c2, v2) in e {
                    a[(c, c2)] += v * d[c] * v2 * d[c2];
                }
            }
        }
        let b = DVector::from_vec(rhs);
        match a.clone().cholesky() {
            Some(ch) => ch.solve(&b).as_slice().to_vec(),
            None => pseudo_inverse_solve(a, &b),
        }
    } else {
        // Every equation of one particle has the same columns (the bonds acting on it): sum
        // their outer products in one dense block per column pattern, then scatter the blocks.
        // Work: equations x (bonds per particle)^2, plus a sort of the blocks' entries.
        let mut groups: HashMap<Vec<usize>, Vec<f64>> = HashMap::new();
        for (e, _) in rows {
            let key: Vec<usize> = e.iter().map(|&(c, _)| c).collect();
            let k = key.len();
            let block = groups.entry(key).or_insert_with(|| vec![0.0; k * k]);
            for (a, &(c, v)) in e.iter().enumerate() {
                let vc = v * d[c];
                for (b, &(c2, v2)) in e.iter().enumerate() {
                    block[a * k + b] += vc * v2 * d[c2];
                }
            }
        }
        let mut triplets: Vec<(usize, usize, f64)> = Vec::new();
        for (key, block) in &groups {
            let k = key.len();
            for (a, &c) in key.iter().enumerate() {
                for (b, &c2) in key.iter().enumerate() {
                    triplets.push((c, c2, block[a * k + b]));
                }
            }
        }
        triplets.sort_unstable_by_key(|&(r, c, _)| (r, c));
        let mut sparse: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for (r, c, v) in triplets {
            match sparse[r].last_mut() {
                Some(last) if last.0 == c => last.1 += v,
                _ => sparse[r].push((c, v)),
            }
        }
        // A column that never acts (zero scale) is a zero row and column: a unit diagonal
        // there gives it the value 0, as the pseudo-inverse does.
        for (c, row) in sparse.iter_mut().enumerate() {
            if d[c] == 0.0 {
                row.retain(|e| e.0 != c);
                row.push((c, 1.0));
            }
        }
        direct
            .then(|| sparse_solve(&sparse, &rhs))
            .flatten()
            .unwrap_or_else(|| conjugate_gradients(&sparse, &rhs, paired))
    };
    y.iter().zip(&d).map(|(y, d)| y * d).collect()
}

/// Solves the unit-diagonal normal matrix `a` (full rows) by sparse Cholesky after a
/// nested-dissection ordering ([`crate::sparse_cholesky`]). A matrix that is not numerically
/// positive definite (directions the data leave open) is retried with a ridge of `1e-13`, then
/// `1e-10`, of the unit diagonal: the minimum-norm choice along those directions, as the dense
/// path's pseudo-inverse makes. `None` if even that fails.
fn sparse_solve(a: &[Vec<(usize, f64)>], b: &[f64]) -> Option<Vec<f64>> {
    let order = nested_dissection(a);
    [0.0, 1e-13, 1e-10]
        .into_iter()
        .find_map(|ridge| CholeskyFactor::new(a, order.clone(), ridge))
        .map(|f| f.solve(b))
}

/// Minimum-norm solution of a symmetric positive semi-definite system, dropping directions
/// with eigenvalues below `1e-13` of the largest.
fn pseudo_inverse_solve(a: DMatrix<f64>, b: &DVector<f64>) -> Vec<f64> {
    let eig = a.symmetric_eigen();
    let max = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut x = DVector::zeros(b.len());
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-13 * max {
            let v = eig.eigenvectors.column(k);
            x += v * (v.dot(b) / l);
        }
    }
    x.as_slice().to_vec()
}

/// Conjugate gradients on a sparse symmetric positive (semi-)definite matrix with unit
/// diagonal, preconditioned by the inverse of the 2x2 diagonal block of each bond's pair of
/// columns (their basis forces are nearly proportional, which plain CG converges on slowly).
fn conjugate_gradients(a: &[Vec<(usize, f64)>], b: &[f64], paired: &[bool]) -> Vec<f64> {
    let n = b.len();
    let entry = |r: usize, c: usize| a[r].iter().find(|e| e.0 == c).map_or(0.0, |e| e.1);
    // Block-diagonal preconditioner: (start, inverse entries [p00, p01, p11]) or a single.
    let mut blocks: Vec<(usize, [f64; 3], bool)> = Vec::new();
    let mut k = 0;
    while k < n {
        if k + 1 < n && paired.get(k).copied().unwrap_or(false) {
            let (a00, a01, a11) = (entry(k, k), entry(k, k + 1), entry(k + 1, k + 1));
            let det = a00 * a11 - a01 * a01;
            if det > 1e-12 * a00 * a11 {
                blocks.push((k, [a11 / det, -a01 / det, a00 / det], true));
                k += 2;
                continue;
            }
        }
        let d = entry(k, k);
        blocks.push((k, [if d > 0.0 { 1.0 / d } else { 1.0 }, 0.0, 0.0], false));
        k += 1;
    }
    let precondition = |r: &[f64], z: &mut [f64]| {
        for &(k, p, pair) in &blocks {
            if pair {
                z[k] = p[0] * r[k] + p[1] * r[k + 1];
                z[k + 1] = p[1] * r[k] + p[2] * r[k + 1];
            } else {
                z[k] = p[0] * r[k];
            }
        }
    };
    let mul = |x: &[f64], out: &mut [f64]| {
        for (o, row) in out.iter_mut().zip(a) {
            *o = row.iter().map(|&(c, v)| v * x[c]).sum();
        }
    };
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
    let mut x = vec![0.0; n];
    let mut r = b.to_vec();
    let mut z = vec![0.0; n];
    precondition(&r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = dot(&r, &z);
    // Relative residual 1e-10: the weak form's own error (about 1e-5 relative on exact data)
    // is reached long before; tighter targets only add iterations on the sloppy directions.
    let target = 1e-20 * dot(b, b);
    for _ in 0..20 * n.max(10) {
        if dot(&r, &r) <= target {
            break;
        }
        mul(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 {
            break;
        }
        let alpha = rz / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        precondition(&r, &mut z);
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    x
}

/// Maps the linear unknowns back to the parameter vector (`L = SL / S`, `M = TM / T`),
/// falling back to observed means where a stiffness comes out non-positive.
fn to_parameters(problem: &Problem, cols: &[Column], theta: &[f64], warnings: &mut Vec<String>) -> Vec<f64> {
    let layout = &problem.layout;
    let mut x = problem.initial_guess();
    let index = layout.parameter_index();
    let find = |bond: BondRef, kind: ParameterKind| index.get(&(bond, kind)).copied();
    let mut k = 0;
    while k < cols.len() {
        match cols[k] {
            Column::SpringS(b) | Column::TorsionT(b) => {
                let spring = matches!(cols[k], Column::SpringS(_));
                let (bond, stiff_kind, rest_kind) = if spring {
                    (
                        BondRef::Spring(b),
                        ParameterKind::SpringStiffness,
                        ParameterKind::RestLength,
                    )
                } else {
                    (
                        BondRef::Torsion(b),
                        ParameterKind::TorsionStiffness,
                        ParameterKind::RestCos,
                    )
                };
                let (s, prod) = (theta[k], theta[k + 1]);
                let (si, ri) = (find(bond, stiff_kind), find(bond, rest_kind));
                if let (Some(si), Some(ri)) = (si, ri) {
                    let rest = prod / s;
                    let bounds = layout.parameters[ri].bounds;
                    if s > 0.0 && rest.is_finite() {
                        x[si] = s;
                        x[ri] = rest.clamp(bounds[0], bounds[1]);
                    } else {
                        warnings.push(format!(
                            "{}: the linear stage found stiffness {s:.4e}; starting from the observed mean geometry instead",
                            problem.bond_label(bond)
                        ));
                    }
                }
                k += 2;
                continue;
            }
            Column::SpringSKnownL(b, _) | Column::TorsionTKnownM(b, _) => {
                let (bond, kind) = match cols[k] {
                    Column::SpringSKnownL(..) => (BondRef::Spring(b), ParameterKind::SpringStiffness),
                    _ => (BondRef::Torsion(b), ParameterKind::TorsionStiffness),
                };
                if let Some(i) = find(bond, kind) {
                    if theta[k] > 0.0 {
                        x[i] = theta[k];
                    }
                }
            }
            Column::SpringLKnownS(b, _) => {
                if let Some(i) = find(BondRef::Spring(b), ParameterKind::RestLength) {
                    if theta[k].is_finite() {
                        x[i] = theta[k];
                    }
                }
            }
            Column::TorsionMKnownT(b, _) => {
                if let Some(i) = find(BondRef::Torsion(b), ParameterKind::RestCos) {
                    if theta[k].is_finite() {
                        x[i] = theta[k];
                    }
                }
            }
            Column::SpringProduct(_) | Column::TorsionProduct(_) => {}
        }
        k += 1;
    }
    layout.clamp(&mut x);
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{max_relative_error, paper3, paper5, record, Timing};

    #[test]
    fn weak_form_is_nearly_unbiased_on_exact_data() {
        for truth in [paper3(Timing::default()), paper5(Timing::default())] {
            let obs = Observations::from_recording(&record(&truth), &truth, 0);
            let problem = Problem::new(&truth.structure(), &obs).unwrap();
            let est = linear_estimate(&problem, &obs, None).unwrap();
            let x = problem.params_of(&truth).unwrap();
            let (err, i) = max_relative_error(&est.params, &x);
            assert!(
                err < 0.01,
                "{}: {} off by {:.3}%",
                truth.name,
                problem.parameter_label(i),
                err * 100.0
            );
        }
    }

    #[test]
    fn sparse_cholesky_and_conjugate_gradients_match_the_dense_solution() {
        let truth = paper5(Timing::default());
        let obs = Observations::from_recording(&record(&truth), &truth, 0);
        let problem = Problem::new(&truth.structure(), &obs).unwrap();
        // Rows of a small least-squares problem with the bond-pair structure: column 2k is a
        // stiffness, 2k+1 its nearly collinear product.
        let n = problem.dimension();
        let mut rows = Vec::new();
        for r in 0..200usize {
            let mut e = Vec::new();
            for c in 0..n {
                let v = (((r * 31 + c * 17) % 13) as f64 - 6.0) * 0.1
                    + if c % 2 == 1 {
                        0.97 * (((r * 31 + (c - 1) * 17) % 13) as f64 - 6.0) * 0.1
                    } else {
                        0.0
                    };
                if (r + c) % 3 != 0 {
                    e.push((c, v));
                }
            }
            rows.push((e, ((r * 7) % 5) as f64 - 2.0));
        }
        let paired: Vec<bool> = (0..n).map(|c| c % 2 == 0).collect();
        let dense = solve_normal_equations_with(&rows, n, &paired, usize::MAX, true);
        for direct in [true, false] {
            let sparse = solve_normal_equations_with(&rows, n, &paired, 0, direct);
            for (a, b) in dense.iter().zip(&sparse) {
                assert!(
                    (a - b).abs() < 1e-8 * a.abs().max(1.0),
                    "direct {direct}: {a} vs {b}"
                );
            }
        }
    }
}
