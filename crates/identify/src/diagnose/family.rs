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

    /// The effects that act through effect `k` and mean nothing without it, in increasing
    /// order: the friction on the wall `k` adds, and the friction on the rail `k` adds
    /// (unless the structure holds that particle on a rail of its own).
    pub fn dependents(&self, k: usize) -> Vec<usize> {
        let on_wall = self.added_wall_index(k);
        let on_rail = match self.effects[k] {
            Effect::Rail { particle } => {
                let given = self
                    .structure
                    .physics
                    .rails
                    .iter()
                    .any(|r| r.particle.index() == particle);
                (!given).then_some(particle)
            }
            _ => None,
        };
        (0..self.effects.len())
            .filter(|&j| match self.effects[j] {
                Effect::WallFriction { wall } => Some(wall) == on_wall,
                Effect::RailFriction { particle } => Some(particle) == on_rail,
                _ => false,
            })
            .collect()
    }

    /// The model's index of the wall effect `k` adds (the structure's walls come first, then
    /// the added ones in effect order), if it adds one.
    fn added_wall_index(&self, k: usize) -> Option<usize> {
        self.effects[k].adds_wall().then(|| {
            self.structure.physics.walls.len() + self.effects[..k].iter().filter(|e| e.adds_wall()).count()
        })
    }

    /// The effects [`Family::without_effect`] takes out with `k`: `k` and its
    /// [`dependents`](Family::dependents), in decreasing order.
    pub fn removed_with(&self, k: usize) -> Vec<usize> {
        let mut out = self.dependents(k);
        out.push(k);
        out.sort_unstable_by(|a, b| b.cmp(a));
        out
    }

    /// The same family without effect `k` and the effects that depend on it (see
    /// [`Family::removed_with`]; their pins dropped, later ones re-indexed, and friction on a
    /// later added wall moved to that wall's new index).
    pub fn without_effect(&self, k: usize) -> Family {
        let removed = self.removed_with(k);
        let wall = self.added_wall_index(k);
        let effects = (0..self.effects.len())
            .filter(|j| !removed.contains(j))
            .map(|j| match (self.effects[j], wall) {
                (Effect::WallFriction { wall: w }, Some(gone)) if w > gone => {
                    Effect::WallFriction { wall: w - 1 }
                }
                (e, _) => e,
            })
            .collect();
        let shift = |e: usize| e - removed.iter().filter(|&&r| r < e).count();
        let pins = self
            .pins
            .iter()
            .filter(|(e, _, _)| !removed.contains(e))
            .map(|&(e, i, v)| (shift(e), i, v))
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
                Effect::SurfaceFriction => t.push(l / (s * s)),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball on a floor (the structure's wall 0) and on a rail of its own.
    fn family(effects: Vec<Effect>) -> Family {
        let text = r#"
name = "t"
[recording]
fps = 100.0
frames = 10
[[particles]]
id = "a"
mass = 1.0
position = [10.0, 10.0]
[[particles]]
id = "b"
mass = 1.0
position = [30.0, 10.0]
[[physics.walls]]
point = [0.0, 100.0]
normal = [0.0, -1.0]
restitution = 0.8
[[physics.rails]]
particle = "b"
point = [0.0, 10.0]
direction = [1.0, 0.0]
"#;
        let structure = Scene::from_toml_str(text, "t.toml").unwrap_or_else(|e| panic!("{e}"));
        Family {
            free: vec![0, 1],
            known: None,
            problem: None,
            structure,
            effects,
            pins: Vec::new(),
        }
    }

    #[test]
    fn an_added_wall_goes_with_its_friction_and_later_frictions_follow_their_walls() {
        // Model walls: 0 the structure's, 1 and 2 added by effects 0 and 2.
        let f = family(vec![
            Effect::Wall,
            Effect::WallFriction { wall: 1 },
            Effect::Wall,
            Effect::WallFriction { wall: 2 },
            Effect::WallFriction { wall: 0 },
        ]);
        assert_eq!(f.dependents(0), vec![1]);
        assert_eq!(f.dependents(2), vec![3]);
        assert_eq!(f.removed_with(0), vec![1, 0]);
        let g = f.without_effect(0);
        assert_eq!(
            g.effects,
            vec![
                Effect::Wall,
                Effect::WallFriction { wall: 1 },
                Effect::WallFriction { wall: 0 }
            ]
        );
        // A friction alone goes alone; the wall it acts on stays.
        assert_eq!(f.removed_with(3), vec![3]);
        assert_eq!(f.without_effect(3).effects.len(), 4);
        // A pin on a later effect follows it.
        let mut pinned = f.clone();
        pinned.pins = vec![(3, 0, 0.5), (1, 0, 0.2)];
        assert_eq!(pinned.without_effect(0).pins, vec![(1, 0, 0.5)]);
    }

    #[test]
    fn an_added_rail_goes_with_its_friction_but_a_given_rail_keeps_it() {
        let f = family(vec![
            Effect::Rail { particle: 0 },
            Effect::RailFriction { particle: 0 },
            Effect::Rail { particle: 1 },
            Effect::RailFriction { particle: 1 },
        ]);
        assert_eq!(f.removed_with(0), vec![1, 0]);
        assert_eq!(
            f.without_effect(0).effects,
            vec![Effect::Rail { particle: 1 }, Effect::RailFriction { particle: 1 }]
        );
        // Particle b has the structure's rail: its friction still has a rail to act on.
        assert_eq!(f.removed_with(2), vec![2]);
    }
}
