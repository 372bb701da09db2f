//! [`Family`]: a structure's unknown bond values plus a list of [`Effect`]s, as one flat
//! parameter vector that maps to a simulation-ready model.
//!
//! Vector order: the bond parameters of the core [`Problem`] layout (none when the structure
//! has no unknown bond value), then each effect's parameters in list order. The start state
//! (positions and velocities of the free particles) is packed after them where a fit frees it.

use physfit_model::{Model, Scene, State, Vec2};

use super::effect::{apply_effects, Effect};
use crate::{IdentifyError, Observations, Problem};

/// A model family: structure, unknown bond values and added effects.
#[derive(Clone, Debug)]
pub struct Family {
    /// The structure (masses, topology, known values).
    pub structure: Scene,
    /// The bond unknowns, when the structure has any.
    pub problem: Option<Problem>,
    /// The structure's model when nothing is unknown.
    known: Option<Model>,
    /// The added effects, in vector order.
    pub effects: Vec<Effect>,
    /// Parameters held at a value instead of fitted: `(effect index, parameter index within
    /// the effect, value)` (a tether taken as rigid: its stiffness).
    pub pins: Vec<(usize, usize, f64)>,
    /// Indices of the structure's free particles.
    pub free: Vec<usize>,
}

impl Family {
    /// The family of `structure` fitted to `observations`, with no effect added.
    pub fn new(structure: &Scene, observations: &Observations) -> Result<Family, IdentifyError> {
        let (problem, known) = match Problem::new(structure, observations) {
            Ok(p) => (Some(p), None),
            Err(IdentifyError::NoUnknowns) => (None, Some(structure.model()?)),
            Err(e) => return Err(e),
        };
        Ok(Family {
            structure: structure.clone(),
            problem,
            known,
            effects: Vec::new(),
            pins: Vec::new(),
            free: (0..structure.particles.len())
                .filter(|&p| !structure.particles[p].fixed)
                .collect(),
        })
    }

    /// The same family with `effects` instead.
    /// (Pins are kept where the effect at their index is unchanged.)
    pub fn with_effects(&self, effects: Vec<Effect>) -> Family {
        let pins = self
            .pins
            .iter()
            .filter(|(k, _, _)| effects.get(*k).is_some() && effects.get(*k) == self.effects.get(*k))
            .copied()
            .collect();
        Family {
            effects,
            pins,
            ..self.clone()
        }
    }

    /// The same family without effect `k` (its pins dropped, later ones re-indexed).
    pub fn without_effect(&self, k: usize) -> Family {
        let mut effects = self.effects.clone();
        effects.remove(k);
        let pins = self
            .pins
            .iter()
            .filter(|(e, _, _)| *e != k)
            .map(|&(e, i, v)| (if e > k { e - 1 } else { e }, i, v))
            .collect();
        Family {
            effects,
            pins,
            ..self.clone()
        }
    }

    /// Returns true if and only if parameter `i` of effect `k` is pinned.
    pub fn is_pinned(&self, k: usize, i: usize) -> bool {
        self.pins.iter().any(|&(e, j, _)| e == k && j == i)
    }

    /// Number of bond parameters.
    pub fn bond_dim(&self) -> usize {
        self.problem.as_ref().map_or(0, Problem::dimension)
    }

    /// Number of bond plus effect parameters.
    pub fn dim(&self) -> usize {
        self.bond_dim() + self.effects.iter().map(|e| e.parameter_count()).sum::<usize>()
    }

    /// Offset of effect `k`'s first parameter in the vector.
    pub fn effect_offset(&self, k: usize) -> usize {
        self.bond_dim()
            + self.effects[..k]
                .iter()
                .map(|e| e.parameter_count())
                .sum::<usize>()
    }

    /// The model for `params` (bond then effect values), with `state` (the structure's
    /// particles) extended by any added fixed particle.
    pub fn model(&self, params: &[f64], state: Option<&mut State>) -> Model {
        let nb = self.bond_dim();
        let mut model = match (&self.problem, &self.known) {
            (Some(p), _) => p.model(&params[..nb]),
            (None, Some(m)) => m.clone(),
            (None, None) => Model::default(),
        };
        apply_effects(&self.effects, &params[nb..], &mut model, state);
        model
    }

    /// Lower and upper bounds of every parameter.
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let mut lower = Vec::with_capacity(self.dim());
        let mut upper = Vec::with_capacity(self.dim());
        if let Some(p) = &self.problem {
            for q in &p.layout.parameters {
                lower.push(q.bounds[0]);
                upper.push(q.bounds[1]);
            }
        }
        for e in &self.effects {
            for b in e.bounds() {
                lower.push(b[0]);
                upper.push(b[1]);
            }
        }
        for &(k, i, v) in &self.pins {
            if k < self.effects.len() {
                let o = self.effect_offset(k) + i;
                lower[o] = v;
                upper[o] = v;
            }
        }
        (lower, upper)
    }

    /// Typical magnitude of every parameter (finite-difference scale), given a data scale:
    /// `length` (px), `time` (s) and the mean particle mass.
    pub fn typical(&self, scales: &DataScales) -> Vec<f64> {
        let mut t: Vec<f64> = self.problem.as_ref().map_or_else(Vec::new, |p| {
            p.layout.parameters.iter().map(|q| q.scale).collect()
        });
        let (l, s, m) = (scales.length, scales.time, scales.mass);
        for e in &self.effects {
            match e {
                Effect::Gravity => t.extend([l / (s * s); 2]),
                Effect::Drag => t.push(1.0 / s),
                Effect::QuadraticDrag => t.push(1.0 / l),
                Effect::SpringDamping | Effect::SpringDashpot { .. } => t.push(m / s),
                Effect::MissingSpring { .. } => t.extend([l, scales.stiffness]),
                Effect::Tether { .. } => t.extend([l, l, l, scales.stiffness]),
                Effect::Wall => t.extend([1.0, l, 1.0]),
                Effect::BodyDrag => t.push(m / s),
                Effect::BodyQuadraticDrag => t.push(m / l),
                Effect::WallFriction { .. } | Effect::RailFriction { .. } => t.push(1.0),
                Effect::Rail { .. } => t.extend([1.0, l]),
                Effect::Rope { .. } => t.push(l),
                Effect::AnchoredRope { .. } => t.extend([l, l, l]),
                Effect::Bumper => t.extend([1.0, l, m / (s * s), m / s]),
            }
        }
        t
    }

    /// Packs free particles' positions then velocities of `state` after `params`.
    pub fn pack(&self, params: &[f64], state: &State) -> Vec<f64> {
        let mut z = params.to_vec();
        for &p in &self.free {
            z.extend([state.positions[p].x, state.positions[p].y]);
        }
        for &p in &self.free {
            z.extend([state.velocities[p].x, state.velocities[p].y]);
        }
        z
    }

    /// Unpacks [`Family::pack`]'s vector onto `template` (which holds the fixed particles).
    pub fn unpack(&self, z: &[f64], template: &State) -> (Vec<f64>, State) {
        let dim = self.dim();
        let nf = self.free.len();
        let mut s = template.clone();
        for (k, &p) in self.free.iter().enumerate() {
            s.positions[p] = Vec2::new(z[dim + 2 * k], z[dim + 2 * k + 1]);
            s.velocities[p] = Vec2::new(z[dim + 2 * nf + 2 * k], z[dim + 2 * nf + 2 * k + 1]);
        }
        (z[..dim].to_vec(), s)
    }
}

/// Typical magnitudes of the data, for finite-difference steps and parameter scales.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DataScales {
    /// Typical length, px (the spread of the tracked positions).
    pub length: f64,
    /// Duration of the analysed frames, s.
    pub time: f64,
    /// Mean particle mass.
    pub mass: f64,
    /// Typical spring stiffness (from [`crate::stiffness_scales`]).
    pub stiffness: f64,
    /// Typical angular frequency of the motion, rad/s.
    pub omega: f64,
}

impl DataScales {
    /// The scales of `observations` of `structure`.
    pub fn of(structure: &Scene, observations: &Observations) -> DataScales {
        let mut lo = Vec2::repeat(f64::INFINITY);
        let mut hi = Vec2::repeat(f64::NEG_INFINITY);
        for f in &observations.positions {
            for x in f.iter().flatten() {
                lo = lo.inf(x);
                hi = hi.sup(x);
            }
        }
        let length = if lo.x.is_finite() {
            (hi - lo).norm().max(1.0)
        } else {
            1.0
        };
        let n = structure.particles.len().max(1) as f64;
        let sc = crate::stiffness_scales(structure, observations);
        DataScales {
            length,
            time: (observations.frame_count().max(2) - 1) as f64 / observations.fps,
            mass: structure.particles.iter().map(|p| p.mass).sum::<f64>() / n,
            stiffness: sc.spring,
            omega: sc.omega,
        }
    }
}
