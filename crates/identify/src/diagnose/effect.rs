//! [`Effect`]: the library of candidate physics the diagnosis can add to a model.
//!
//! Each effect is a term the model crate simulates ([`physfit_model::Physics`], a per-spring
//! `damping`, an added spring, an added fixed particle) with a few parameters that the
//! identifier fits. This module says what each effect's parameters are, their admissible
//! ranges, and how a parameter vector becomes a model term; nothing here depends on data.

use physfit_model::{Model, ParticleId, Rail, Rope, Scene, Spring, State, Vec2, Wall};
use serde::Serialize;

/// A candidate effect, by the structure's particle and spring indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Effect {
    /// A uniform acceleration field `[gx, gy]` (px/s²) on every free particle.
    Gravity,
    /// Linear drag on every particle, `F = -c m v` (`c` in 1/s).
    Drag,
    /// Quadratic drag on every particle, `F = -c m |v| v` (`c` in 1/px).
    QuadraticDrag,
    /// A dashpot along every spring, `F_i = c ((v_j - v_i) . u) u` (`c` in mass/s).
    SpringDamping,
    /// A dashpot along one spring (`spring` indexes the structure's springs), on top of any
    /// global one.
    SpringDashpot {
        /// Index of the spring in the structure.
        spring: usize,
    },
    /// A spring `S (d - L)^2` between two particles the structure did not join.
    MissingSpring {
        /// First particle index.
        a: usize,
        /// Second particle index.
        b: usize,
    },
    /// A spring from a particle to a fixed point that is not among the structure's particles
    /// (a tether or pivot, possibly outside the image).
    Tether {
        /// The tethered particle's index.
        particle: usize,
    },
    /// A straight wall that particles' centres bounce off (position, direction, restitution).
    Wall,
    /// Linear drag per body, not scaled by the mass: `F = -b v` on every free particle
    /// (`b` in mass/s, shared: bodies of one shape and different masses in one medium).
    BodyDrag,
    /// Quadratic drag per body, not scaled by the mass: `F = -c |v| v` (`c` in mass/px).
    BodyQuadraticDrag,
    /// Dry friction of the surface under the motion (a puck on a table seen from above,
    /// [`physfit_model::Physics::surface_friction`]): every free particle that slides
    /// decelerates at `a` (px/s², `mu g`), `F = -a m v / |v|`, and one at rest sticks.
    SurfaceFriction,
    /// Coulomb friction at a wall (see [`physfit_model::Wall::apply_friction`]): bounces lose
    /// tangential speed, at most `mu` times their normal velocity change, and a particle
    /// sliding on it decelerates at `mu g_n`.
    WallFriction {
        /// Index of the wall among the model's walls: the structure's own first, then the
        /// added [`Effect::Wall`]s in effect order.
        wall: usize,
    },
    /// A spring bumper (see [`physfit_model::Wall::with_bumper`]): a straight line whose
    /// contact is a one-sided spring of stiffness `S` (energy/px², energy `S s^2` while the
    /// centre is `s < 0` beyond the line) and dashpot `c` (mass/s), by its normal angle
    /// (rad), offset (px), stiffness and damping.
    Bumper,
    /// A rail: `particle` is held on the line `n . x = offset`, `n = (cos a, sin a)`
    /// ([`physfit_model::Rail`]; parameters `normal_angle` rad, `offset` px).
    Rail {
        /// The particle held on the line.
        particle: usize,
    },
    /// Coulomb friction `mu` (dimensionless) on the rail of `particle` (an [`Effect::Rail`]
    /// of the same particle): it slides with deceleration `mu g_n`, `g_n` its push across.
    RailFriction {
        /// The particle on the rail.
        particle: usize,
    },
    /// A rigid rope (a rod, [`physfit_model::Rope`], not slack) of length `length` px
    /// between two of the structure's particles (one may be fixed).
    Rope {
        /// First particle index.
        a: usize,
        /// Second particle index.
        b: usize,
    },
    /// A rigid rope of length `length` px from `particle` to a fixed point
    /// (`anchor_x`, `anchor_y`, px) that is not among the structure's particles.
    AnchoredRope {
        /// The particle on the rope.
        particle: usize,
    },
}

impl Effect {
    /// The effect's name in `report.json` (`gravity`, `drag`, `quadratic_drag`,
    /// `spring_damping`, `missing_spring`, `wall`, `body_drag`, `body_quadratic_drag`,
    /// `surface_friction`,
    /// `wall_friction`, `bumper`, `rail`, `rail_friction`, `rope`).
    pub fn name(self) -> &'static str {
        match self {
            Effect::Gravity => "gravity",
            Effect::Drag => "drag",
            Effect::QuadraticDrag => "quadratic_drag",
            Effect::SpringDamping | Effect::SpringDashpot { .. } => "spring_damping",
            Effect::MissingSpring { .. } | Effect::Tether { .. } => "missing_spring",
            Effect::Wall => "wall",
            Effect::BodyDrag => "body_drag",
            Effect::BodyQuadraticDrag => "body_quadratic_drag",
            Effect::SurfaceFriction => "surface_friction",
            Effect::WallFriction { .. } => "wall_friction",
            Effect::Bumper => "bumper",
            Effect::Rail { .. } => "rail",
            Effect::RailFriction { .. } => "rail_friction",
            Effect::Rope { .. } | Effect::AnchoredRope { .. } => "rope",
        }
    }

    /// A readable label naming the particles or spring involved, e.g. `missing spring a-c`.
    pub fn label(self, structure: &Scene) -> String {
        let id = |p: usize| {
            structure
                .particles
                .get(p)
                .map_or_else(|| format!("#{p}"), |s| s.id.clone())
        };
        match self {
            Effect::Gravity => "uniform field (gravity)".into(),
            Effect::Drag => "linear drag".into(),
            Effect::QuadraticDrag => "quadratic drag".into(),
            Effect::SpringDamping => "dashpots on every spring".into(),
            Effect::SpringDashpot { spring } => match structure.springs.get(spring) {
                Some(_) => format!("dashpot on {}", structure.spring_label(spring)),
                None => format!("dashpot on spring #{spring}"),
            },
            Effect::MissingSpring { a, b } => format!("missing spring {}-{}", id(a), id(b)),
            Effect::Tether { particle } => format!("tether of {} to a fixed point", id(particle)),
            Effect::Wall => "wall".into(),
            Effect::BodyDrag => "linear drag per body".into(),
            Effect::BodyQuadraticDrag => "quadratic drag per body".into(),
            Effect::SurfaceFriction => "dry friction of the surface under the motion".into(),
            Effect::WallFriction { wall } => format!("friction at wall {}", wall + 1),
            Effect::Bumper => "spring bumper".into(),
            Effect::Rail { particle } => format!("rail of {}", id(particle)),
            Effect::RailFriction { particle } => format!("friction on the rail of {}", id(particle)),
            Effect::Rope { a, b } => format!("rope {}-{}", id(a), id(b)),
            Effect::AnchoredRope { particle } => format!("rope of {} to a fixed point", id(particle)),
        }
    }

    /// Names of the effect's parameters, in vector order (scene-file keys where there are).
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            Effect::Gravity => &["gravity_x", "gravity_y"],
            Effect::Drag => &["drag"],
            Effect::QuadraticDrag => &["quadratic_drag"],
            Effect::SpringDamping | Effect::SpringDashpot { .. } => &["damping"],
            Effect::MissingSpring { .. } => &["length", "stiffness"],
            Effect::Tether { .. } => &["anchor_x", "anchor_y", "length", "stiffness"],
            Effect::Wall => &["normal_angle", "offset", "restitution"],
            Effect::BodyDrag => &["body_drag"],
            Effect::BodyQuadraticDrag => &["body_quadratic_drag"],
            Effect::SurfaceFriction => &["surface_friction"],
            Effect::WallFriction { .. } | Effect::RailFriction { .. } => &["friction"],
            Effect::Rail { .. } => &["normal_angle", "offset"],
            Effect::Rope { .. } => &["length"],
            Effect::AnchoredRope { .. } => &["anchor_x", "anchor_y", "length"],
            Effect::Bumper => &["normal_angle", "offset", "stiffness", "damping"],
        }
    }

    /// Number of parameters the effect adds.
    pub fn parameter_count(self) -> usize {
        self.parameter_names().len()
    }

    /// Admissible range of each parameter (drag, dashpot and stiffness non-negative,
    /// restitution in [0, 1], lengths positive).
    pub fn bounds(self) -> Vec<[f64; 2]> {
        let free = [f64::NEG_INFINITY, f64::INFINITY];
        let positive = [0.0, f64::INFINITY];
        match self {
            Effect::Gravity => vec![free, free],
            Effect::Drag
            | Effect::QuadraticDrag
            | Effect::SpringDamping
            | Effect::SpringDashpot { .. }
            | Effect::BodyDrag
            | Effect::BodyQuadraticDrag
            | Effect::SurfaceFriction
            | Effect::WallFriction { .. }
            | Effect::RailFriction { .. } => vec![positive],
            Effect::MissingSpring { .. } => vec![[1e-6, f64::INFINITY], positive],
            Effect::Tether { .. } => vec![free, free, [1e-6, f64::INFINITY], positive],
            Effect::Wall => vec![free, free, [0.0, 1.0]],
            // A bumper of stiffness 0 is no wall at all.
            Effect::Bumper => vec![free, free, [f64::MIN_POSITIVE, f64::INFINITY], positive],
            Effect::Rail { .. } => vec![free, free],
            Effect::Rope { .. } => vec![[1e-6, f64::INFINITY]],
            Effect::AnchoredRope { .. } => vec![free, free, [1e-6, f64::INFINITY]],
        }
    }

    /// Returns true if and only if the effect is a smooth force the weak form can screen
    /// (every effect but the walls, bumpers and their friction, which act at contacts, and
    /// the constraints, which act by projection): one with a [`WeakShape`].
    pub fn is_smooth(self) -> bool {
        self.weak_shape().is_some()
    }

    /// How the effect's parameters stand against its weak-form columns; `None` for the
    /// effects that act at contacts or by projection.
    pub fn weak_shape(self) -> Option<WeakShape> {
        match self {
            Effect::Gravity => Some(WeakShape::Field),
            Effect::Drag
            | Effect::QuadraticDrag
            | Effect::SpringDamping
            | Effect::SpringDashpot { .. }
            | Effect::BodyDrag
            | Effect::BodyQuadraticDrag
            | Effect::SurfaceFriction => Some(WeakShape::Coefficient),
            Effect::MissingSpring { a, b } => Some(WeakShape::Spring { a, b }),
            Effect::Tether { particle } => Some(WeakShape::Tether { particle }),
            Effect::Wall
            | Effect::WallFriction { .. }
            | Effect::Bumper
            | Effect::Rail { .. }
            | Effect::RailFriction { .. }
            | Effect::Rope { .. }
            | Effect::AnchoredRope { .. } => None,
        }
    }

    /// Returns true if and only if the effect is a constraint or acts through one (a rail,
    /// its friction, a rope): the weak form cannot screen it, the fits hold it.
    pub fn is_constraint(self) -> bool {
        matches!(
            self,
            Effect::Rail { .. }
                | Effect::RailFriction { .. }
                | Effect::Rope { .. }
                | Effect::AnchoredRope { .. }
        )
    }

    /// Returns true if and only if the effect acts at contacts with a wall (the wall itself,
    /// its friction, a bumper): only where a wall is met, so its transfer is judged through
    /// the bounces.
    pub fn acts_at_contacts(self) -> bool {
        matches!(self, Effect::Wall | Effect::WallFriction { .. } | Effect::Bumper)
    }

    /// Returns true if and only if the effect adds a wall to the model (a rigid wall or a
    /// bumper): the model's walls are the structure's, then these in effect order.
    pub fn adds_wall(self) -> bool {
        matches!(self, Effect::Wall | Effect::Bumper)
    }
}

/// How a smooth effect's parameters stand against its weak-form columns (see
/// [`Effect::weak_shape`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeakShape {
    /// A field: its two components are the coefficients of its two columns, px/s².
    Field,
    /// One coefficient (a drag, a dashpot, a friction) of one column, its own parameter.
    Coefficient,
    /// A spring `S (d - L)^2` between two particles: columns for `S` and `S L`.
    Spring {
        /// First particle index.
        a: usize,
        /// Second particle index.
        b: usize,
    },
    /// A spring to a fixed point (anchor, length, stiffness): columns for `S` and `S L` at a
    /// given anchor.
    Tether {
        /// The tethered particle's index.
        particle: usize,
    },
}

/// A wall from its parameters `[normal_angle (rad), offset (px), restitution]`: the line
/// `n . x = offset` with `n = (cos a, sin a)` pointing into the allowed side.
pub fn wall_from_params(p: &[f64]) -> Option<Wall> {
    let n = Vec2::new(p[0].cos(), p[0].sin());
    Wall::new(n * p[1], n, p[2].clamp(0.0, 1.0))
}

/// A spring bumper from its parameters `[normal_angle (rad), offset (px), stiffness
/// (energy/px²), damping (mass/s)]`: the line as in [`wall_from_params`].
pub fn bumper_from_params(p: &[f64]) -> Option<Wall> {
    let n = Vec2::new(p[0].cos(), p[0].sin());
    Some(Wall::new(n * p[1], n, 1.0)?.with_bumper(p[2].max(f64::MIN_POSITIVE), p[3].max(0.0)))
}

/// Applies `effects` with their parameters (`params`, concatenated in effect order) to a
/// model of the structure and its state: physics fields, per-spring dashpots, added springs,
/// and added fixed particles (tether anchors, appended after the structure's particles with
/// zero velocity). `state` may be `None` when only the model is needed.
pub fn apply_effects(effects: &[Effect], params: &[f64], model: &mut Model, mut state: Option<&mut State>) {
    let mut offset = 0;
    let mut dashpots = Vec::new();
    let mut frictions = Vec::new();
    let mut rail_frictions = Vec::new();
    for &e in effects {
        let p = &params[offset..offset + e.parameter_count()];
        offset += e.parameter_count();
        match e {
            Effect::Gravity => model.physics.gravity += Vec2::new(p[0], p[1]),
            Effect::Drag => model.physics.drag += p[0],
            Effect::QuadraticDrag => model.physics.quadratic_drag += p[0],
            Effect::SpringDamping => model.physics.spring_damping += p[0],
            Effect::SpringDashpot { spring } => dashpots.push((spring, p[0])),
            Effect::MissingSpring { a, b } => {
                model.springs.push(Spring::new(
                    ParticleId(a as u32),
                    ParticleId(b as u32),
                    p[0],
                    p[1],
                ));
            }
            Effect::Tether { particle } => {
                let anchor = model.add_particle(1.0, true);
                model
                    .springs
                    .push(Spring::new(ParticleId(particle as u32), anchor, p[2], p[3]));
                if let Some(s) = state.as_deref_mut() {
                    s.positions.push(Vec2::new(p[0], p[1]));
                    s.velocities.push(Vec2::zeros());
                }
            }
            Effect::Wall => {
                if let Some(w) = wall_from_params(p) {
                    model.physics.walls.push(w);
                }
            }
            Effect::BodyDrag => model.physics.body_drag += p[0],
            Effect::BodyQuadraticDrag => model.physics.body_quadratic_drag += p[0],
            Effect::SurfaceFriction => model.physics.surface_friction += p[0],
            Effect::WallFriction { wall } => frictions.push((wall, p[0])),
            Effect::Bumper => model.physics.walls.extend(bumper_from_params(p)),
            Effect::Rail { particle } => {
                let n = Vec2::new(p[0].cos(), p[0].sin());
                let along = Vec2::new(-n.y, n.x);
                model
                    .physics
                    .rails
                    .extend(Rail::new(ParticleId(particle as u32), n * p[1], along));
            }
            Effect::RailFriction { particle } => rail_frictions.push((particle, p[0])),
            Effect::Rope { a, b } => model.physics.ropes.push(Rope {
                ends: [ParticleId(a as u32), ParticleId(b as u32)],
                length: p[0],
                slack: false,
            }),
            Effect::AnchoredRope { particle } => {
                let anchor = model.add_particle(1.0, true);
                model.physics.ropes.push(Rope {
                    ends: [ParticleId(particle as u32), anchor],
                    length: p[2],
                    slack: false,
                });
                if let Some(s) = state.as_deref_mut() {
                    s.positions.push(Vec2::new(p[0], p[1]));
                    s.velocities.push(Vec2::zeros());
                }
            }
        }
    }
    // Friction acts on the particle's rail (the structure's or an added one).
    for (particle, mu) in rail_frictions {
        let on = |r: &&mut Rail| r.particle.index() == particle;
        if let Some(r) = model.physics.rails.iter_mut().find(on) {
            r.friction += mu;
        }
    }
    // Friction acts on a wall however it came (the structure's or an added one); a bumper
    // has none (its contact is a force).
    for (k, mu) in frictions {
        if let Some(w) = model.physics.walls.get_mut(k).filter(|w| !w.is_bumper()) {
            w.friction += mu;
        }
    }
    // Per-spring dashpots add to whatever the spring had (its own value or the global one).
    let global = model.physics.spring_damping;
    for (k, c) in dashpots {
        if let Some(s) = model.springs.get_mut(k) {
            s.damping = Some(s.damping.unwrap_or(global) + c);
        }
    }
}
