//! What a recording conceals: the classes of effect and each effect with its true values.

use physfit_model::{ParticleId, Scene, Vec2};
use serde::Serialize;

use super::PIVOT;

/// A class of concealed effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// A uniform field (gravity) in any direction.
    Field,
    /// Linear drag.
    Drag,
    /// Quadratic drag.
    QuadraticDrag,
    /// Dashpots on every spring.
    SpringDamping,
    /// A spring between two listed particles that the structure does not list.
    MissingSpring,
    /// A spring from one particle to a fixed point outside the structure.
    Tether,
    /// A wall (or floor) the particles' centres bounce off.
    Wall,
}

impl Kind {
    /// Every class, in table order.
    pub const ALL: [Kind; 7] = [
        Kind::Field,
        Kind::Drag,
        Kind::QuadraticDrag,
        Kind::SpringDamping,
        Kind::MissingSpring,
        Kind::Tether,
        Kind::Wall,
    ];

    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Field => "field",
            Kind::Drag => "linear drag",
            Kind::QuadraticDrag => "quadratic drag",
            Kind::SpringDamping => "spring damping",
            Kind::MissingSpring => "missing spring",
            Kind::Tether => "tether",
            Kind::Wall => "wall",
        }
    }
}

/// The class label of a set of concealed kinds: `none`, `field`, `field + wall`...
pub fn class_label(kinds: &[Kind]) -> String {
    if kinds.is_empty() {
        "none".into()
    } else {
        kinds.iter().map(|k| k.name()).collect::<Vec<_>>().join(" + ")
    }
}

/// One concealed effect with its true values (positions in the frame's pixels).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "effect", rename_all = "snake_case")]
pub enum Concealed {
    /// A uniform field.
    Field {
        /// Acceleration, px/s².
        gravity: [f64; 2],
    },
    /// Linear drag.
    Drag {
        /// Coefficient, 1/s.
        drag: f64,
    },
    /// Quadratic drag.
    QuadraticDrag {
        /// Coefficient, 1/px.
        quadratic_drag: f64,
    },
    /// Dashpots on every spring.
    SpringDamping {
        /// Coefficient, mass/s.
        damping: f64,
    },
    /// A spring the structure leaves out.
    MissingSpring {
        /// Its two particles.
        between: [String; 2],
        /// Rest length, px.
        length: f64,
        /// Stiffness, mass/s².
        stiffness: f64,
    },
    /// A spring to a fixed point.
    Tether {
        /// The tethered particle.
        particle: String,
        /// The fixed point, px.
        anchor: [f64; 2],
        /// Rest length, px.
        length: f64,
        /// Stiffness, mass/s².
        stiffness: f64,
        /// True when the fixed point's disc is (partly) in the frame.
        in_view: bool,
    },
    /// A wall: the line `normal . x = offset`.
    Wall {
        /// Unit normal into the allowed side.
        normal: [f64; 2],
        /// Offset of the line along the normal, px.
        offset: f64,
        /// Restitution of the normal velocity.
        restitution: f64,
    },
}

impl Concealed {
    /// Its class.
    pub fn kind(&self) -> Kind {
        match self {
            Concealed::Field { .. } => Kind::Field,
            Concealed::Drag { .. } => Kind::Drag,
            Concealed::QuadraticDrag { .. } => Kind::QuadraticDrag,
            Concealed::SpringDamping { .. } => Kind::SpringDamping,
            Concealed::MissingSpring { .. } => Kind::MissingSpring,
            Concealed::Tether { .. } => Kind::Tether,
            Concealed::Wall { .. } => Kind::Wall,
        }
    }

    /// In words, with its true values.
    pub fn describe(&self) -> String {
        match self {
            Concealed::Field { gravity: g } => format!("field ({:.1}, {:.1}) px/s^2", g[0], g[1]),
            Concealed::Drag { drag } => format!("linear drag {drag:.4} /s"),
            Concealed::QuadraticDrag { quadratic_drag } => {
                format!("quadratic drag {quadratic_drag:.3e} /px")
            }
            Concealed::SpringDamping { damping } => format!("spring damping {damping:.4} mass/s"),
            Concealed::MissingSpring {
                between,
                length,
                stiffness,
            } => format!(
                "missing spring {}-{} (L {length:.1} px, S {stiffness:.4})",
                between[0], between[1]
            ),
            Concealed::Tether {
                particle,
                anchor,
                length,
                stiffness,
                in_view,
            } => format!(
                "tether of {particle} to ({:.1}, {:.1}) px{} (L {length:.1} px, S {stiffness:.4})",
                anchor[0],
                anchor[1],
                if *in_view { "" } else { ", out of view" }
            ),
            Concealed::Wall {
                normal,
                offset,
                restitution,
            } => format!(
                "wall n ({:.3}, {:.3}) . x = {offset:.1} px, e {restitution:.3}",
                normal[0], normal[1]
            ),
        }
    }

    /// `scene` without this effect (a tether's fixed point goes with its spring).
    pub fn remove_from(&self, scene: &Scene) -> Scene {
        let mut s = scene.clone();
        match self {
            Concealed::Field { .. } => s.physics.gravity = Vec2::zeros(),
            Concealed::Drag { .. } => s.physics.drag = 0.0,
            Concealed::QuadraticDrag { .. } => s.physics.quadratic_drag = 0.0,
            Concealed::SpringDamping { .. } => {
                s.physics.spring_damping = 0.0;
                for spring in &mut s.springs {
                    spring.damping = None;
                }
            }
            Concealed::MissingSpring { between, .. } => {
                let ids = [scene.particle_id(&between[0]), scene.particle_id(&between[1])];
                s.springs.retain(|sp| {
                    let ends = [Some(sp.ends[0]), Some(sp.ends[1])];
                    !(ends == ids || ends == [ids[1], ids[0]])
                });
            }
            Concealed::Tether { .. } => remove_particle(&mut s, PIVOT),
            // A recording holds one wall at most.
            Concealed::Wall { .. } => s.physics.walls.clear(),
        }
        s
    }
}

/// Removes particle `id` and every bond that touches it, renumbering the others.
pub(super) fn remove_particle(scene: &mut Scene, id: &str) {
    let Some(gone) = scene.particle_id(id) else {
        return;
    };
    scene.springs.retain(|s| !s.ends.contains(&gone));
    scene
        .torsions
        .retain(|t| t.center != gone && !t.ends.contains(&gone));
    scene.particles.remove(gone.index());
    let renumber = |p: &mut ParticleId| {
        if p.0 > gone.0 {
            p.0 -= 1;
        }
    };
    for s in &mut scene.springs {
        s.ends.iter_mut().for_each(renumber);
    }
    for t in &mut scene.torsions {
        renumber(&mut t.center);
        t.ends.iter_mut().for_each(renumber);
    }
}

/// The concealed effect of class `kind` as `truth` holds it.
pub fn concealed_of(
    kind: Kind,
    truth: &Scene,
    missing: Option<&[String; 2]>,
    tethered: Option<&str>,
) -> Option<Concealed> {
    let ph = &truth.physics;
    Some(match kind {
        Kind::Field => Concealed::Field {
            gravity: [ph.gravity.x, ph.gravity.y],
        },
        Kind::Drag => Concealed::Drag { drag: ph.drag },
        Kind::QuadraticDrag => Concealed::QuadraticDrag {
            quadratic_drag: ph.quadratic_drag,
        },
        Kind::SpringDamping => Concealed::SpringDamping {
            damping: ph.spring_damping,
        },
        Kind::MissingSpring => {
            let between = missing?.clone();
            let spring = truth.springs.last()?;
            let spring = if truth.particle_id(PIVOT).is_some() {
                truth.springs.get(truth.springs.len().checked_sub(2)?)?
            } else {
                spring
            };
            Concealed::MissingSpring {
                between,
                length: spring.rest_length?,
                stiffness: spring.stiffness?,
            }
        }
        Kind::Tether => {
            let pivot = truth.particles.last()?;
            let spring = truth.springs.last()?;
            let (r, w, h) = (
                truth.render.radius,
                truth.render.width as f64,
                truth.render.height as f64,
            );
            let a = pivot.position;
            Concealed::Tether {
                particle: tethered?.to_string(),
                anchor: [a.x, a.y],
                length: spring.rest_length?,
                stiffness: spring.stiffness?,
                in_view: a.x > -r && a.y > -r && a.x < w + r && a.y < h + r,
            }
        }
        Kind::Wall => {
            let wall = ph.walls.first()?;
            Concealed::Wall {
                normal: [wall.normal.x, wall.normal.y],
                offset: wall.normal.dot(&wall.point),
                restitution: wall.restitution,
            }
        }
    })
}
