//! The weak-form linear system used to screen candidate effects cheaply.
//!
//! As in the core least-squares stage ([`crate::linear_estimate`], after Messenger & Bortz's
//! WSINDy), Newton's law per unit mass is multiplied by smooth test functions
//! `phi(t) = (1 - s^2)^q` spanning `W` frames and integrated by parts twice:
//!
//! ```text
//! integral (x - x_c) phi'' dt  -  integral a_known phi dt  =  sum_c theta_c integral a_c phi dt
//! ```
//!
//! one row per free particle, coordinate and window (windows overlap by three quarters). The
//! columns `a_c` are accelerations per unit parameter: the bond basis forces (`S`, `S L`,
//! `T`, `T M`, through the model crate's force law) and each candidate effect's (a uniform
//! field: `integral phi dt`; linear drag `-v`: `integral (x - x_c) phi' dt` after one more
//! integration by parts, so no velocity is differentiated or even used; dashpots and
//! quadratic drag from the smoothed velocities; a missing spring's `S` and `S L` basis
//! forces). Windows touching an impulsive frame (a bounce) are left out, and each row is
//! assigned to the fitted or the held-out frames when its window lies wholly in one of them.

use nalgebra::{DMatrix, DVector};
use physfit_model::{dashpot_force_on_i, ParticleId, SpringGeometry, State, TorsionGeometry, Vec2};

use super::effect::Effect;
use super::family::Family;
use crate::{BondRef, Observations, ParameterKind, TEST_EXPONENT};

/// One weak-form equation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Row {
    /// The particle.
    pub particle: usize,
    /// 0 for x, 1 for y.
    pub coord: usize,
    /// Offset of the window's first frame.
    pub start: usize,
    /// The window lies in the fitted frames.
    pub train: bool,
    /// The window lies in the held-out frames.
    pub held: bool,
}

/// A linear unknown of the bond forces.
#[derive(Clone, Copy, Debug)]
enum BondColumn {
    SpringS(usize),
    SpringProduct(usize),
    SpringSKnownL(usize, f64),
    SpringLKnownS(usize, f64),
    TorsionT(usize),
    TorsionProduct(usize),
    TorsionTKnownM(usize, f64),
    TorsionMKnownT(usize, f64),
}

/// The weak-form system of a family's structure over the observations.
#[derive(Clone, Debug)]
pub struct WeakForm {
    /// Frames spanned by each test function.
    pub window: usize,
    /// The equations.
    pub rows: Vec<Row>,
    /// Left-hand sides minus the known forces' term.
    pub rhs: Vec<f64>,
    /// `integral phi dt` of each row's window (s): a row divided by it is a mean acceleration.
    pub phi_integral: f64,
    /// Bond columns (linear unknowns), one vector of length `rows` each.
    bond_columns: Vec<Vec<f64>>,
    bond_kinds: Vec<BondColumn>,
    /// Positions and velocities per frame offset (complete frames only; `None` otherwise).
    states: Vec<Option<State>>,
    phi: Vec<f64>,
    dphi: Vec<f64>,
    masses: Vec<f64>,
    /// The frames left out and held out, as given.
    excluded: Vec<bool>,
    held: Vec<bool>,
}

impl WeakForm {
    /// The system for `family` (its bond unknowns and known forces) over `obs`, with windows
    /// of `window` frames (even), leaving out windows that touch a frame with `excluded[k]`,
    /// and splitting rows by `held[k]` (frame offset `k` is held out of fits).
    pub fn new(
        family: &Family,
        obs: &Observations,
        window: usize,
        excluded: &[bool],
        held: &[bool],
    ) -> WeakForm {
        let w = (window.max(4) + 1) & !1;
        let n = obs.particle_count();
        let frames = obs.frame_count();
        let structure = &family.structure;
        let masses: Vec<f64> = structure.particles.iter().map(|p| p.mass).collect();
        let states: Vec<Option<State>> = (0..frames).map(|k| obs.state(k)).collect();
        let dt = obs.frame_dt();
        let half = w as f64 / 2.0;
        let hs = half * dt;
        let q = TEST_EXPONENT;
        let qf = q as f64;
        let mut phi = Vec::with_capacity(w + 1);
        let mut dphi = Vec::with_capacity(w + 1);
        let mut ddphi = Vec::with_capacity(w + 1);
        for i in 0..=w {
            let s = (i as f64 - half) / half;
            let u = 1.0 - s * s;
            phi.push(u.powi(q) * dt);
            dphi.push(-2.0 * qf * s * u.powi(q - 1) / hs * dt);
            ddphi.push(
                (-2.0 * qf * u.powi(q - 1) + 4.0 * qf * (qf - 1.0) * s * s * u.powi(q - 2)) / (hs * hs) * dt,
            );
        }
        let phi_integral = phi.iter().sum();

        let stride = (w / 4).max(1);
        let mut rows = Vec::new();
        let mut lhs = Vec::new();
        let mut start = 0;
        while start + w < frames {
            let span = start..=start + w;
            let usable = span
                .clone()
                .all(|k| states[k].is_some() && !excluded.get(k).copied().unwrap_or(false));
            if usable {
                let train = span.clone().all(|k| !held.get(k).copied().unwrap_or(false));
                let is_held = span.clone().all(|k| held.get(k).copied().unwrap_or(false));
                for &p in &family.free {
                    let centre = obs.positions[start + w / 2][p].unwrap_or_else(Vec2::zeros);
                    let mut l = Vec2::zeros();
                    for (i, k) in span.clone().enumerate() {
                        l += (obs.positions[k][p].unwrap_or(centre) - centre) * ddphi[i];
                    }
                    for coord in 0..2 {
                        rows.push(Row {
                            particle: p,
                            coord,
                            start,
                            train,
                            held: is_held,
                        });
                        lhs.push(l[coord]);
                    }
                }
            }
            start += stride;
        }
        let mut form = WeakForm {
            window: w,
            rows,
            rhs: lhs,
            phi_integral,
            bond_columns: Vec::new(),
            bond_kinds: Vec::new(),
            states,
            phi,
            dphi,
            masses,
            excluded: excluded.to_vec(),
            held: held.to_vec(),
        };
        // Known forces: the structure's model with every unknown at zero (known values and any
        // physics the structure gives).
        let zero = family.with_effects(Vec::new());
        let known_model = zero.model(&vec![0.0; zero.bond_dim()], None);
        let known = form.column(|state, acc| {
            known_model.forces(state, acc);
        });
        for (r, k) in form.rhs.iter_mut().zip(&known) {
            *r -= k;
        }
        form.bond_kinds = bond_columns(family);
        form.bond_columns = form
            .bond_kinds
            .iter()
            .map(|&c| form.bond_column(family, c))
            .collect();
        let _ = n;
        form
    }

    /// The same system (window, left-out and held-out frames) over other observations of the
    /// same frames, e.g. with extra noise: rows correspond where the same frames are complete.
    pub fn rebuild(&self, family: &Family, obs: &Observations) -> WeakForm {
        WeakForm::new(family, obs, self.window, &self.excluded, &self.held)
    }

    /// The state (positions, velocities) at frame offset `k`, if complete.
    pub fn state(&self, k: usize) -> Option<&State> {
        self.states.get(k)?.as_ref()
    }

    /// Number of bond columns.
    pub fn bond_column_count(&self) -> usize {
        self.bond_columns.len()
    }

    /// The bond columns.
    pub fn bond_columns(&self) -> &[Vec<f64>] {
        &self.bond_columns
    }

    /// A column from a force field: `force(state, out)` writes the force (mass·px/s²) on every
    /// particle per unit parameter; rows get `integral F / m phi dt`.
    pub fn column(&self, mut force: impl FnMut(&State, &mut [Vec2])) -> Vec<f64> {
        let n = self.masses.len();
        let mut per_frame: Vec<Option<Vec<Vec2>>> = vec![None; self.states.len()];
        let needed = self.needed_frames();
        for (k, s) in self.states.iter().enumerate() {
            if let (true, Some(state)) = (needed[k], s) {
                let mut f = vec![Vec2::zeros(); state.len().max(n)];
                force(state, &mut f);
                per_frame[k] = Some(f);
            }
        }
        self.rows
            .iter()
            .map(|r| {
                let mut sum = 0.0;
                for i in 0..=self.window {
                    if let Some(f) = &per_frame[r.start + i] {
                        sum += f[r.particle][r.coord] / self.masses[r.particle] * self.phi[i];
                    }
                }
                sum
            })
            .collect()
    }

    /// The per-body linear-drag column: [`WeakForm::drag_column`] over each row's mass
    /// (`F = -b v`, so the acceleration is `-b v / m`).
    pub fn body_drag_column(&self) -> Vec<f64> {
        self.drag_column()
            .into_iter()
            .zip(&self.rows)
            .map(|(c, r)| c / self.masses[r.particle])
            .collect()
    }

    fn needed_frames(&self) -> Vec<bool> {
        let mut needed = vec![false; self.states.len()];
        for r in &self.rows {
            for n in &mut needed[r.start..=r.start + self.window] {
                *n = true;
            }
        }
        needed
    }

    /// The linear-drag column `-integral v phi dt = integral (x - x_c) phi' dt` (per unit
    /// drag coefficient).
    pub fn drag_column(&self) -> Vec<f64> {
        self.rows
            .iter()
            .map(|r| {
                let x = |k: usize| {
                    self.states[k]
                        .as_ref()
                        .map_or(0.0, |s| s.positions[r.particle][r.coord])
                };
                let centre = x(r.start + self.window / 2);
                (0..=self.window)
                    .map(|i| (x(r.start + i) - centre) * self.dphi[i])
                    .sum()
            })
            .collect()
    }

    fn bond_column(&self, family: &Family, c: BondColumn) -> Vec<f64> {
        let s = &family.structure;
        self.column(|state, f| {
            f.iter_mut().for_each(|v| *v = Vec2::zeros());
            let x = &state.positions;
            let spring = |k: usize, f: &mut [Vec2], law: &dyn Fn(&SpringGeometry) -> Vec2| {
                let [i, j] = [s.springs[k].ends[0].index(), s.springs[k].ends[1].index()];
                let fi = law(&SpringGeometry::new(x[i], x[j]));
                f[i] += fi;
                f[j] -= fi;
            };
            let torsion = |k: usize, f: &mut [Vec2], law: &dyn Fn(&TorsionGeometry) -> [Vec2; 3]| {
                let t = &s.torsions[k];
                let ps = [t.center.index(), t.ends[0].index(), t.ends[1].index()];
                let fs = law(&TorsionGeometry::new(x[ps[0]], x[ps[1]], x[ps[2]]));
                for (p, fp) in ps.iter().zip(fs) {
                    f[*p] += fp;
                }
            };
            let diff = |a: [Vec2; 3], b: [Vec2; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            match c {
                BondColumn::SpringS(k) => spring(k, f, &|g| g.force_on_i(1.0, 0.0)),
                BondColumn::SpringProduct(k) => {
                    spring(k, f, &|g| g.force_on_i(1.0, 1.0) - g.force_on_i(1.0, 0.0))
                }
                BondColumn::SpringSKnownL(k, l) => spring(k, f, &|g| g.force_on_i(1.0, l)),
                BondColumn::SpringLKnownS(k, st) => {
                    spring(k, f, &|g| g.force_on_i(st, 1.0) - g.force_on_i(st, 0.0))
                }
                BondColumn::TorsionT(k) => torsion(k, f, &|g| g.forces(1.0, 0.0)),
                BondColumn::TorsionProduct(k) => {
                    torsion(k, f, &|g| diff(g.forces(1.0, 1.0), g.forces(1.0, 0.0)))
                }
                BondColumn::TorsionTKnownM(k, m) => torsion(k, f, &|g| g.forces(1.0, m)),
                BondColumn::TorsionMKnownT(k, t) => {
                    torsion(k, f, &|g| diff(g.forces(t, 1.0), g.forces(t, 0.0)))
                }
            }
        })
    }

    /// The columns of a smooth effect (see the module doc); a tether needs its anchor.
    pub fn effect_columns(&self, family: &Family, effect: Effect, anchor: Option<Vec2>) -> Vec<Vec<f64>> {
        let s = &family.structure;
        let fixed: Vec<bool> = s.particles.iter().map(|p| p.fixed).collect();
        let masses = &self.masses;
        // A spring's `S` column (`product` false) or `S L` column (true), by the force law.
        let law = |g: &SpringGeometry, product: bool| {
            if product {
                g.force_on_i(1.0, 1.0) - g.force_on_i(1.0, 0.0)
            } else {
                g.force_on_i(1.0, 0.0)
            }
        };
        let pair = |a: usize, b: usize, product: bool| {
            self.column(|state, f| {
                f.iter_mut().for_each(|v| *v = Vec2::zeros());
                let fi = law(
                    &SpringGeometry::new(state.positions[a], state.positions[b]),
                    product,
                );
                f[a] += fi;
                f[b] -= fi;
            })
        };
        match effect {
            Effect::Gravity => (0..2)
                .map(|c| {
                    self.column(|_, f| {
                        for (p, v) in f.iter_mut().enumerate() {
                            *v = Vec2::zeros();
                            if !fixed.get(p).copied().unwrap_or(true) {
                                v[c] = masses[p];
                            }
                        }
                    })
                })
                .collect(),
            Effect::Drag => vec![self.drag_column()],
            Effect::QuadraticDrag => vec![self.column(|state, f| {
                for (p, v) in f.iter_mut().enumerate() {
                    let vel = state.velocities[p];
                    *v = -vel * (vel.norm() * masses[p]);
                }
            })],
            Effect::SpringDamping => vec![self.column(|state, f| {
                f.iter_mut().for_each(|v| *v = Vec2::zeros());
                for sp in &s.springs {
                    dashpot(state, sp.ends, f);
                }
            })],
            Effect::SpringDashpot { spring } => vec![self.column(|state, f| {
                f.iter_mut().for_each(|v| *v = Vec2::zeros());
                if let Some(sp) = s.springs.get(spring) {
                    dashpot(state, sp.ends, f);
                }
            })],
            Effect::MissingSpring { a, b } => vec![pair(a, b, false), pair(a, b, true)],
            Effect::Tether { particle } => {
                let Some(anchor) = anchor else {
                    return Vec::new();
                };
                let tether = |product: bool| {
                    self.column(|state, f| {
                        f.iter_mut().for_each(|v| *v = Vec2::zeros());
                        f[particle] = law(&SpringGeometry::new(state.positions[particle], anchor), product);
                    })
                };
                vec![tether(false), tether(true)]
            }
            Effect::BodyDrag => vec![self.body_drag_column()],
            Effect::BodyQuadraticDrag => vec![self.column(|state, f| {
                for (p, v) in f.iter_mut().enumerate() {
                    let vel = state.velocities[p];
                    *v = -vel * vel.norm();
                }
            })],
            // Sliding only: at rest the friction holds whatever the other forces leave, which
            // the weak form does not see.
            Effect::SurfaceFriction => vec![self.column(|state, f| {
                for (p, v) in f.iter_mut().enumerate() {
                    let vel = state.velocities[p];
                    let speed = vel.norm();
                    *v = if speed > 0.0 {
                        -vel * (masses[p] / speed)
                    } else {
                        Vec2::zeros()
                    };
                }
            })],
            Effect::Wall
            | Effect::WallFriction { .. }
            | Effect::Rail { .. }
            | Effect::RailFriction { .. }
            | Effect::Rope { .. }
            | Effect::Bumper
            | Effect::AnchoredRope { .. } => Vec::new(),
        }
    }

    /// Bond parameters from bond-column coefficients (`L = S L / S`, `M = T M / T`), falling
    /// back to `fallback`'s values where a stiffness comes out non-positive.
    pub fn bond_parameters(&self, family: &Family, theta: &[f64], fallback: &[f64]) -> Vec<f64> {
        let Some(problem) = &family.problem else {
            return Vec::new();
        };
        let layout = &problem.layout;
        let mut x = fallback.to_vec();
        let index = layout.parameter_index();
        let find = |bond: BondRef, kind: ParameterKind| index.get(&(bond, kind)).copied();
        let mut k = 0;
        while k < self.bond_kinds.len() {
            match self.bond_kinds[k] {
                BondColumn::SpringS(b) | BondColumn::TorsionT(b) => {
                    let (bond, sk, rk) = if matches!(self.bond_kinds[k], BondColumn::SpringS(_)) {
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
                    if let (Some(si), Some(ri)) = (find(bond, sk), find(bond, rk)) {
                        let (s, prod) = (theta[k], theta[k + 1]);
                        if s > 0.0 && (prod / s).is_finite() {
                            x[si] = s;
                            x[ri] = prod / s;
                        }
                    }
                    k += 2;
                    continue;
                }
                BondColumn::SpringSKnownL(b, _) | BondColumn::TorsionTKnownM(b, _) => {
                    let (bond, kind) = match self.bond_kinds[k] {
                        BondColumn::SpringSKnownL(..) => (BondRef::Spring(b), ParameterKind::SpringStiffness),
                        _ => (BondRef::Torsion(b), ParameterKind::TorsionStiffness),
                    };
                    if let (Some(i), true) = (find(bond, kind), theta[k] > 0.0) {
                        x[i] = theta[k];
                    }
                }
                BondColumn::SpringLKnownS(b, _) => {
                    if let Some(i) = find(BondRef::Spring(b), ParameterKind::RestLength) {
                        x[i] = theta[k];
                    }
                }
                BondColumn::TorsionMKnownT(b, _) => {
                    if let Some(i) = find(BondRef::Torsion(b), ParameterKind::RestCos) {
                        x[i] = theta[k];
                    }
                }
                BondColumn::SpringProduct(_) | BondColumn::TorsionProduct(_) => {}
            }
            k += 1;
        }
        layout.clamp(&mut x);
        x
    }
}

/// Adds the unit dashpot force of a spring between `ends` to `f`.
fn dashpot(state: &State, ends: [ParticleId; 2], f: &mut [Vec2]) {
    let [i, j] = [ends[0].index(), ends[1].index()];
    let g = SpringGeometry::new(state.positions[i], state.positions[j]);
    let fi = dashpot_force_on_i(g, state.velocities[j] - state.velocities[i], 1.0);
    f[i] += fi;
    f[j] -= fi;
}

fn bond_columns(family: &Family) -> Vec<BondColumn> {
    let Some(problem) = &family.problem else {
        return Vec::new();
    };
    let s = &family.structure;
    let mut out = Vec::new();
    for b in &problem.layout.bonds {
        match b.bond {
            BondRef::Spring(k) => match (s.springs[k].rest_length, s.springs[k].stiffness) {
                (None, None) => out.extend([BondColumn::SpringS(k), BondColumn::SpringProduct(k)]),
                (Some(l), None) => out.push(BondColumn::SpringSKnownL(k, l)),
                (None, Some(st)) => out.push(BondColumn::SpringLKnownS(k, st)),
                (Some(_), Some(_)) => {}
            },
            BondRef::Torsion(k) => match (s.torsions[k].rest_cos, s.torsions[k].stiffness) {
                (None, None) => out.extend([BondColumn::TorsionT(k), BondColumn::TorsionProduct(k)]),
                (Some(m), None) => out.push(BondColumn::TorsionTKnownM(k, m)),
                (None, Some(t)) => out.push(BondColumn::TorsionMKnownT(k, t)),
                (Some(_), Some(_)) => {}
            },
        }
    }
    out
}

/// Least squares `min |A theta - b|` over the rows `rows`, with Jacobi column scaling and a
/// pseudo-inverse for (nearly) dependent columns.
pub fn solve(columns: &[&[f64]], b: &[f64], rows: &[usize]) -> Vec<f64> {
    let n = columns.len();
    if n == 0 {
        return Vec::new();
    }
    let mut d = vec![0.0; n];
    for (c, col) in columns.iter().enumerate() {
        let s: f64 = rows.iter().map(|&r| col[r] * col[r]).sum();
        d[c] = if s > 0.0 { 1.0 / s.sqrt() } else { 0.0 };
    }
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut g = DVector::<f64>::zeros(n);
    for i in 0..n {
        for j in 0..=i {
            let v: f64 = rows.iter().map(|&r| columns[i][r] * columns[j][r]).sum::<f64>() * d[i] * d[j];
            a[(i, j)] = v;
            a[(j, i)] = v;
        }
        g[i] = rows.iter().map(|&r| columns[i][r] * b[r]).sum::<f64>() * d[i];
    }
    let eig = a.symmetric_eigen();
    let max = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut y = DVector::zeros(n);
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-12 * max {
            let v = eig.eigenvectors.column(k);
            y += v * (v.dot(&g) / l);
        }
    }
    y.iter().zip(&d).map(|(y, d)| y * d).collect()
}

/// Residuals `b - A theta` at every row.
pub fn residuals(columns: &[&[f64]], theta: &[f64], b: &[f64]) -> Vec<f64> {
    let mut r = b.to_vec();
    for (col, t) in columns.iter().zip(theta) {
        for (ri, ci) in r.iter_mut().zip(col.iter()) {
            *ri -= ci * t;
        }
    }
    r
}
