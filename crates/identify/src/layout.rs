//! [`Layout`]: how a structure's unknown bond values map to a flat parameter vector.

use physfit_model::{ParticleId, Scene, SpringGeometry, TorsionGeometry};
use serde::Serialize;

use crate::Observations;

/// Which bond a parameter belongs to, by index in the structure's lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum BondRef {
    /// `scene.springs[k]`.
    Spring(usize),
    /// `scene.torsions[k]`.
    Torsion(usize),
}

/// What a parameter is, physically.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum ParameterKind {
    /// Spring rest length `L`, px.
    RestLength,
    /// Spring stiffness `S`.
    SpringStiffness,
    /// Torsion rest cosine `M`, in [-1, 1].
    RestCos,
    /// Torsion angular stiffness `T`.
    TorsionStiffness,
}

impl ParameterKind {
    /// The scene-file key of this parameter (`length`, `stiffness`, `rest_cos`).
    pub fn key(self) -> &'static str {
        match self {
            ParameterKind::RestLength => "length",
            ParameterKind::SpringStiffness | ParameterKind::TorsionStiffness => "stiffness",
            ParameterKind::RestCos => "rest_cos",
        }
    }
}

/// One entry of the parameter vector.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Parameter {
    /// The bond it belongs to.
    pub bond: BondRef,
    /// What it is.
    pub kind: ParameterKind,
    /// Physically admissible range `[lower, upper]` (stiffnesses non-negative, cosines in
    /// [-1, 1], lengths positive).
    pub bounds: [f64; 2],
    /// A typical magnitude from the data (mutation and finite-difference scale).
    pub scale: f64,
}

/// A bond's unknowns, kept together: the genetic algorithms cross over a bond's couple of
/// values as a unit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BondGenes {
    /// The bond.
    pub bond: BondRef,
    /// Indices of its unknown parameters in the vector (one or two).
    pub params: Vec<usize>,
    /// The particles it touches (2 for a spring, 3 for a torsion).
    pub particles: Vec<usize>,
    /// The bond's observed geometry over the analysed frames: distances (px) for a spring,
    /// cosines for a torsion. Rest-length mutation draws from these.
    pub observed: Vec<f64>,
}

/// The parameter vector of an identification problem.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Layout {
    /// The parameters, in vector order.
    pub parameters: Vec<Parameter>,
    /// The bonds with at least one unknown.
    pub bonds: Vec<BondGenes>,
}

impl Layout {
    /// Length of the parameter vector.
    pub fn dimension(&self) -> usize {
        self.parameters.len()
    }

    /// Where each parameter sits in the vector, by its bond and kind: built once for lookups
    /// over many bonds (searching the parameter list for each would be quadratic in the bonds).
    pub fn parameter_index(&self) -> std::collections::HashMap<(BondRef, ParameterKind), usize> {
        self.parameters
            .iter()
            .enumerate()
            .map(|(i, p)| ((p.bond, p.kind), i))
            .collect()
    }

    /// Clamps `params` into every parameter's bounds.
    pub fn clamp(&self, params: &mut [f64]) {
        for (p, info) in params.iter_mut().zip(&self.parameters) {
            *p = p.clamp(info.bounds[0], info.bounds[1]);
        }
    }
}

/// Typical stiffness magnitudes measured from the data (see [`stiffness_scales`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StiffnessScales {
    /// Typical spring stiffness `S`, energy per px².
    pub spring: f64,
    /// Typical transverse stiffness of the torsions, energy per px² (a torsion's `T` scale is
    /// this times the product of its arm lengths).
    pub torsion_per_px2: f64,
    /// Typical angular frequency of the bonds' oscillations, rad/s.
    pub omega: f64,
}

/// Order-of-magnitude stiffness from the observed motion: for each spring, the ratio of the
/// RMS relative acceleration along the bond (second differences of the tracks) to the standard
/// deviation of its length is `omega^2 ~ 2 S / mu` (reduced mass `mu`); the median over springs
/// of `mu omega^2 / 2` is the spring scale. Torsions are scaled by the equivalent transverse
/// stiffness `T ~ S d_ij d_ik`. Falls back to one oscillation per ten frames when nothing moves.
pub fn stiffness_scales(structure: &Scene, observations: &Observations) -> StiffnessScales {
    let mass = |p: ParticleId| structure.particles[p.index()].mass;
    let pos = &observations.positions;
    let fps = observations.fps;
    let mut estimates = Vec::new();
    let mut omegas = Vec::new();
    for s in &structure.springs {
        let [i, j] = [s.ends[0].index(), s.ends[1].index()];
        let mut d = Vec::new();
        let mut acc = Vec::new();
        for k in 0..pos.len() {
            if let (Some(a), Some(b)) = (pos[k][i], pos[k][j]) {
                d.push((b - a).norm());
                if k >= 1 && k + 1 < pos.len() {
                    if let (Some(a0), Some(b0), Some(a2), Some(b2)) =
                        (pos[k - 1][i], pos[k - 1][j], pos[k + 1][i], pos[k + 1][j])
                    {
                        let rel = ((b2 - a2) - (b - a) * 2.0 + (b0 - a0)) * (fps * fps);
                        let u = SpringGeometry::new(a, b).direction;
                        acc.push(rel.dot(&u));
                    }
                }
            }
        }
        if d.len() < 3 || acc.len() < 3 {
            continue;
        }
        let sd = std_dev(&d);
        let sa = std_dev(&acc);
        if sd > 0.0 && sa > 0.0 {
            let (mi, mj) = (mass(s.ends[0]), mass(s.ends[1]));
            let mu = if structure.particles[i].fixed {
                mj
            } else if structure.particles[j].fixed {
                mi
            } else {
                mi * mj / (mi + mj)
            };
            estimates.push(0.5 * mu * sa / sd);
            omegas.push((sa / sd).sqrt());
        }
    }
    let fallback_omega = std::f64::consts::TAU * fps / 10.0;
    let spring = if estimates.is_empty() {
        let m =
            structure.particles.iter().map(|p| p.mass).sum::<f64>() / structure.particles.len().max(1) as f64;
        0.25 * m * fallback_omega * fallback_omega
    } else {
        estimates.sort_by(|a, b| a.total_cmp(b));
        estimates[estimates.len() / 2]
    };
    let omega = if omegas.is_empty() {
        fallback_omega
    } else {
        omegas.sort_by(|a, b| a.total_cmp(b));
        omegas[omegas.len() / 2]
    };
    StiffnessScales {
        spring,
        torsion_per_px2: spring,
        omega,
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn std_dev(v: &[f64]) -> f64 {
    let m = mean(v);
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// How far the stiffness bounds reach above the data's stiffness scale.
pub(crate) const STIFFNESS_BOUND_FACTOR: f64 = 1.0e4;

/// The parameter vector of `structure`'s unknown bond values, with bounds and scales from the
/// observations: rest lengths in `(0, 4 * max observed distance]` (scale: mean observed
/// distance), stiffnesses in `[0, 1e4 * scale]` (scale from [`stiffness_scales`]), rest
/// cosines in `[-1, 1]` (scale 1). Order: springs in file order (`length` then `stiffness`),
/// then torsions (`rest_cos` then `stiffness`), unknown values only.
pub fn layout_for(structure: &Scene, observations: &Observations) -> Layout {
    let scales = stiffness_scales(structure, observations);
    let pos = &observations.positions;
    let mut layout = Layout::default();
    let push = |layout: &mut Layout, bond, kind, bounds: [f64; 2], scale: f64| {
        layout.parameters.push(Parameter {
            bond,
            kind,
            bounds,
            scale,
        });
        layout.parameters.len() - 1
    };
    for (k, s) in structure.springs.iter().enumerate() {
        if s.rest_length.is_some() && s.stiffness.is_some() {
            continue;
        }
        let [i, j] = [s.ends[0].index(), s.ends[1].index()];
        let observed: Vec<f64> = pos.iter().filter_map(|f| Some((f[j]? - f[i]?).norm())).collect();
        let dmax = observed.iter().copied().fold(0.0, f64::max);
        let dmean = mean(&observed);
        let bond = BondRef::Spring(k);
        let mut params = Vec::new();
        if s.rest_length.is_none() {
            let upper = if dmax > 0.0 { 4.0 * dmax } else { 1.0e6 };
            params.push(push(
                &mut layout,
                bond,
                ParameterKind::RestLength,
                [upper * 1e-9, upper],
                dmean.max(upper * 1e-3),
            ));
        }
        if s.stiffness.is_none() {
            params.push(push(
                &mut layout,
                bond,
                ParameterKind::SpringStiffness,
                [0.0, STIFFNESS_BOUND_FACTOR * scales.spring],
                scales.spring,
            ));
        }
        layout.bonds.push(BondGenes {
            bond,
            params,
            particles: vec![i, j],
            observed,
        });
    }
    for (k, t) in structure.torsions.iter().enumerate() {
        if t.rest_cos.is_some() && t.stiffness.is_some() {
            continue;
        }
        let [i, j, l] = [t.center.index(), t.ends[0].index(), t.ends[1].index()];
        let mut observed = Vec::new();
        let mut arms = Vec::new();
        for f in pos {
            if let (Some(xi), Some(xj), Some(xk)) = (f[i], f[j], f[l]) {
                observed.push(TorsionGeometry::new(xi, xj, xk).cos);
                arms.push((xj - xi).norm() * (xk - xi).norm());
            }
        }
        let arm2 = if arms.is_empty() {
            1.0
        } else {
            mean(&arms).max(1e-12)
        };
        let bond = BondRef::Torsion(k);
        let mut params = Vec::new();
        if t.rest_cos.is_none() {
            params.push(push(&mut layout, bond, ParameterKind::RestCos, [-1.0, 1.0], 1.0));
        }
        if t.stiffness.is_none() {
            let scale = scales.torsion_per_px2 * arm2;
            params.push(push(
                &mut layout,
                bond,
                ParameterKind::TorsionStiffness,
                [0.0, STIFFNESS_BOUND_FACTOR * scale],
                scale,
            ));
        }
        layout.bonds.push(BondGenes {
            bond,
            params,
            particles: vec![i, j, l],
            observed,
        });
    }
    layout
}
