//! Turning the search's fits into the [`super::Diagnosis`] parts: findings with standard
//! errors, the diagnosed scene, whole-sequence costs and residual series.

use physfit_model::scene::{ParticleSpec, SpringSpec};
use physfit_model::{ParticleId, Scene, Vec2};

use super::costs::{model_costs, standard_errors};
use super::effect::Effect;
use super::family::{DataScales, Family};
use super::jolts::Jolt;
use super::localise::localise;
use super::report::{
    Evidence, Finding, FittedValue, Localisation, ModelSummary, Predictions, ResidualSeries, Seen,
};
use super::search::Proposal;
use super::shooting::{Shot, ShotFit};
use super::support::Support;
use super::weak::WeakForm;
use crate::Observations;

/// What [`assemble`] needs.
pub struct Inputs<'a> {
    pub structure: &'a Scene,
    pub obs: &'a Observations,
    pub sequence: &'a Observations,
    pub scales: &'a DataScales,
    pub base_family: &'a Family,
    pub base_fit: &'a ShotFit,
    pub final_family: &'a Family,
    pub final_fit: &'a ShotFit,
    pub anchor: usize,
    pub accepted: &'a [(Proposal, Evidence, usize)],
    pub jolts: &'a [Jolt],
    pub supports: &'a [Support],
    pub weak: &'a WeakForm,
    pub seed: u64,
}

/// The assembled parts.
pub struct Outcome {
    pub findings: Vec<Finding>,
    pub scene: Scene,
    pub base: ModelSummary,
    pub final_model: ModelSummary,
    pub residuals: ResidualSeries,
    pub localisation: Localisation,
    pub warnings: Vec<String>,
    pub predictions: Option<Predictions>,
}

fn unit(effect: Effect, name: &str) -> &'static str {
    match (effect, name) {
        (Effect::Gravity | Effect::SurfaceFriction, _) => "px/s^2",
        (Effect::Drag, _) => "1/s",
        (Effect::QuadraticDrag, _) => "1/px",
        (Effect::SpringDamping | Effect::SpringDashpot { .. } | Effect::BodyDrag, _) => "mass/s",
        (Effect::BodyQuadraticDrag, _) => "mass/px",
        (Effect::WallFriction { .. } | Effect::RailFriction { .. }, _) => "1",
        (Effect::Rail { .. }, "normal_angle") => "rad",
        (Effect::Bumper, "damping") => "mass/s",
        (Effect::Bumper, "normal_angle") => "rad",
        (_, "stiffness") => "energy/px^2",
        (_, "restitution") => "1",
        (_, "normal_x" | "normal_y") => "1",
        _ => "px",
    }
}

fn summary(
    family: &Family,
    fit: &ShotFit,
    anchor_frame: usize,
    sequence: &Observations,
    scales: &DataScales,
) -> (ModelSummary, Option<(ShotFit, usize)>) {
    let (costs, seq_fit) = model_costs(
        family,
        &fit.params,
        sequence,
        scales,
        Some((&fit.state, anchor_frame)),
    );
    (
        ModelSummary {
            effects: family.effects.iter().map(|e| e.name().to_string()).collect(),
            parameter_count: family.dim(),
            costs,
            window_rms: (fit.sum_squares / fit.residual_count.max(1) as f64).sqrt(),
        },
        seq_fit,
    )
}

/// Multi-step predicted positions over the whole sequence, `[frame][particle]` (`None`
/// before the anchor frame), from the sequence fit `seq`; `None` if it cannot be simulated.
fn prediction(
    family: &Family,
    seq: Option<&(ShotFit, usize)>,
    sequence: &Observations,
) -> Option<Vec<Vec<Option<Vec2>>>> {
    let (fit, _) = seq?;
    let shot = Shot::new(sequence, family, None).ok()?;
    let traj = shot.trajectory(family, &fit.params, &fit.state)?;
    let n = sequence.particle_count();
    Some(
        traj.into_iter()
            .map(|f| match f {
                Some(x) => x.into_iter().take(n).map(Some).collect(),
                None => vec![None; n],
            })
            .collect(),
    )
}

/// Observed minus predicted positions over the whole sequence, `[frame][particle]` (`None`
/// for pinned particles, untracked ones and frames without a prediction).
fn residual_series(
    predicted: Option<&Vec<Vec<Option<Vec2>>>>,
    sequence: &Observations,
) -> Vec<Vec<Option<[f64; 2]>>> {
    let n = sequence.particle_count();
    let frames = sequence.frame_count();
    let mut out = vec![vec![None; n]; frames];
    let Some(pred) = predicted else { return out };
    for (k, row) in out.iter_mut().enumerate() {
        for (p, r) in row.iter_mut().enumerate() {
            if let (Some(o), Some(x), false) = (sequence.positions[k][p], pred[k][p], sequence.fixed[p]) {
                let e = o - x;
                *r = Some([e.x, e.y]);
            }
        }
    }
    out
}

/// A tether's anchor farther from its particle than this many times the particle's motion
/// extent "runs off": over the motion its pull is a uniform field plus a linear spring, and
/// the anchor, length and stiffness are not separately determined.
pub const TETHER_RUNS_OFF: f64 = 10.0;

/// Assembles findings, scene, summaries and residuals.
pub fn assemble(inp: Inputs<'_>) -> Outcome {
    let mut warnings = Vec::new();
    let fam = inp.final_family;
    let fit = inp.final_fit;
    let errors = standard_errors(&fit.jacobian, fit.sum_squares, fam.dim());
    let id = |p: usize| {
        inp.structure
            .particles
            .get(p)
            .map_or_else(|| format!("#{p}"), |s| s.id.clone())
    };
    let window = [inp.obs.first_frame, inp.obs.last_frame()];

    // Findings, in acceptance order (the family's effects are in that order too).
    let mut findings = Vec::new();
    for (k, (proposal, evidence, round)) in inp.accepted.iter().enumerate() {
        let effect = fam.effects[k];
        let o = fam.effect_offset(k);
        let values = &fit.params[o..o + effect.parameter_count()];
        let errs: Vec<Option<f64>> = (0..effect.parameter_count())
            .map(|i| errors.get(o + i).copied().flatten())
            .collect();
        let mut parameters: Vec<FittedValue> = Vec::new();
        let mut push = |name: &str, value: f64, std_error: Option<f64>| {
            parameters.push(FittedValue::new(name, value, std_error, unit(effect, name)))
        };
        let mut seen = Seen::default();
        let all_free: Vec<String> = fam.free.iter().map(|&p| id(p)).collect();
        match effect {
            Effect::Wall => {
                let n = Vec2::new(values[0].cos(), values[0].sin());
                push("normal_x", n.x, errs[0].map(|e| e * n.y.abs()));
                push("normal_y", n.y, errs[0].map(|e| e * n.x.abs()));
                push("offset", values[1], errs[1]);
                push("restitution", values[2], errs[2]);
                let contacts: Vec<&Jolt> = proposal.jolts.iter().collect();
                let mut particles: Vec<String> = contacts.iter().map(|j| id(j.particle)).collect();
                particles.sort();
                particles.dedup();
                seen.particles = particles;
                seen.frames = contacts.iter().map(|j| [j.frame, j.frame + 1]).collect();
                seen.region = bbox(contacts.iter().map(|j| Vec2::new(j.position[0], j.position[1])));
                seen.text = format!(
                    "{} bounce(s) where the normal velocity reverses, on the line n.x = {:.2} px with n = ({:.3}, {:.3})",
                    contacts.len(),
                    values[1],
                    n.x,
                    n.y
                );
            }
            Effect::Gravity => {
                push("gravity_x", values[0], errs[0]);
                push("gravity_y", values[1], errs[1]);
                seen.particles = all_free;
                seen.frames = vec![window];
                let g = Vec2::new(values[0], values[1]);
                seen.text = format!(
                    "a steady acceleration of {:.2} px/s^2 towards {:.0} degrees (image axes, y down) on every free particle",
                    g.norm(),
                    g.y.atan2(g.x).to_degrees()
                );
            }
            Effect::Drag
            | Effect::QuadraticDrag
            | Effect::SpringDamping
            | Effect::BodyDrag
            | Effect::BodyQuadraticDrag
            | Effect::SurfaceFriction => {
                push(
                    effect.parameter_names()[0].trim_start_matches("spring_"),
                    values[0],
                    errs[0],
                );
                seen.particles = all_free;
                seen.frames = vec![window];
                if effect == Effect::SpringDamping {
                    seen.springs = inp
                        .structure
                        .springs
                        .iter()
                        .map(|s| [id(s.ends[0].index()), id(s.ends[1].index())])
                        .collect();
                }
                seen.text = if matches!(effect, Effect::BodyDrag | Effect::BodyQuadraticDrag) {
                    let masses: Vec<f64> = fam
                        .free
                        .iter()
                        .map(|&p| inp.structure.particles[p].mass)
                        .collect();
                    super::contact::body_drag_seen_text(&effect.label(inp.structure), &masses)
                } else if effect == Effect::SurfaceFriction {
                    format!(
                        "every free particle decelerates at {:.2} px/s^2 against its motion while it slides, whatever its speed, and stays put once stopped: Coulomb friction with a surface under the motion (mu g; mu alone cannot be known without g)",
                        values[0]
                    )
                } else {
                    format!(
                        "{} acting throughout, against the motion",
                        effect.label(inp.structure)
                    )
                };
            }
            Effect::Bumper => {
                let n = Vec2::new(values[0].cos(), values[0].sin());
                push("normal_x", n.x, errs[0].map(|e| e * n.y.abs()));
                push("normal_y", n.y, errs[0].map(|e| e * n.x.abs()));
                push("offset", values[1], errs[1]);
                push("stiffness", values[2], errs[2]);
                push("damping", values[3], errs[3]);
                let (wall, contacts) = super::bumper::bumper_contacts(inp.obs, fam, values);
                let mut particles: Vec<String> = contacts.iter().map(|c| id(c.particle)).collect();
                particles.sort();
                particles.dedup();
                seen.particles = particles;
                let first = inp.obs.first_frame;
                seen.frames = contacts
                    .iter()
                    .map(|c| [first + c.window.0, first + c.window.1])
                    .collect();
                seen.region = bbox(
                    contacts
                        .iter()
                        .filter_map(|c| inp.obs.positions[c.frame][c.particle]),
                );
                let masses: Vec<f64> = contacts
                    .iter()
                    .map(|c| inp.structure.particles[c.particle].mass)
                    .collect();
                let mass = masses.iter().sum::<f64>() / masses.len().max(1) as f64;
                seen.text = wall.map_or_else(String::new, |w| {
                    super::bumper::bumper_seen_text(&w, mass, &contacts)
                });
            }
            Effect::WallFriction { wall } => {
                push("friction", values[0], errs[0]);
                let model_wall = fam.model(&fit.params, None).physics.walls.get(wall).cloned();
                let normal = model_wall.as_ref().map_or_else(Vec2::zeros, |w| w.normal);
                let sliding = model_wall
                    .map(|w| super::contact::sliding_on(inp.obs, fam, &fit.params, &w, &fam.free))
                    .unwrap_or_default();
                let mut particles: Vec<String> = proposal
                    .jolts
                    .iter()
                    .map(|j| j.particle)
                    .chain(sliding.frames.iter().map(|f| f.0))
                    .map(id)
                    .collect();
                particles.sort();
                particles.dedup();
                seen.particles = particles;
                seen.frames = proposal.jolts.iter().map(|j| [j.frame, j.frame + 1]).collect();
                seen.region = bbox(
                    proposal
                        .jolts
                        .iter()
                        .map(|j| Vec2::new(j.position[0], j.position[1])),
                );
                if proposal.jolts.is_empty() {
                    seen.frames = sliding.frames.iter().map(|f| [f.1, f.1]).collect();
                }
                seen.text =
                    super::contact::friction_seen_text(wall, values[0], normal, &proposal.jolts, &sliding);
            }
            Effect::SpringDashpot { spring } => {
                push("damping", values[0], errs[0]);
                if let Some(s) = inp.structure.springs.get(spring) {
                    let [a, b] = [s.ends[0].index(), s.ends[1].index()];
                    seen.particles = vec![id(a), id(b)];
                    seen.springs = vec![[id(a), id(b)]];
                }
                seen.frames = vec![window];
                seen.text = format!("{} only", effect.label(inp.structure));
            }
            Effect::MissingSpring { a, b } => {
                push("length", values[0], errs[0]);
                push("stiffness", values[1], errs[1]);
                seen.particles = vec![id(a), id(b)];
                seen.springs = vec![[id(a), id(b)]];
                seen.frames = vec![window];
                seen.text = format!(
                    "a force along the line between {} and {} that the structure does not join",
                    id(a),
                    id(b)
                );
            }
            Effect::Tether { particle } => {
                push("anchor_x", values[0], errs[0]);
                push("anchor_y", values[1], errs[1]);
                push("length", values[2], errs[2]);
                push("stiffness", values[3], errs[3]);
                seen.particles = vec![id(particle)];
                seen.springs = vec![[id(particle), anchor_id(inp.structure, k)]];
                seen.frames = vec![window];
                seen.region = Some([values[0], values[1], values[0], values[1]]);
                seen.text = format!(
                    "{} is pulled towards a fixed point at ({:.1}, {:.1}) px that is not among the structure's particles",
                    id(particle),
                    values[0],
                    values[1]
                );
            }
            Effect::Rail { particle }
            | Effect::RailFriction { particle }
            | Effect::AnchoredRope { particle } => {
                for (i, name) in effect.parameter_names().iter().enumerate() {
                    push(name, values[i], errs[i]);
                }
                seen.particles = vec![id(particle)];
                seen.frames = vec![window];
                seen.text = super::constraints::seen_text(inp.obs, fam, &fit.params, k, &id);
            }
            Effect::Rope { a, b } => {
                push("length", values[0], errs[0]);
                seen.particles = vec![id(a), id(b)];
                seen.frames = vec![window];
                seen.text = super::constraints::seen_text(inp.obs, fam, &fit.params, k, &id);
            }
        }
        // Held values carry no standard error; values the tracks do not pin down are named.
        let mut notes = Vec::new();
        for (i, v) in parameters.iter_mut().enumerate() {
            if fam.is_pinned(k, i) {
                v.std_error = None;
            }
        }
        // Magnitudes are compared with their standard errors; positions (an anchor, a wall's
        // line) and directions are not magnitudes: a field is judged by its length, an anchor
        // by its distance from the particle (below), a wall by its bounces.
        let magnitude = |name: &str| {
            !matches!(
                name,
                "gravity_x"
                    | "gravity_y"
                    | "normal_x"
                    | "normal_y"
                    | "normal_angle"
                    | "offset"
                    | "anchor_x"
                    | "anchor_y"
            )
        };
        let mut unidentified: Vec<String> = parameters
            .iter()
            .filter(|v| magnitude(&v.name))
            .filter(|v| v.std_error.is_some_and(|e| e.is_nan() || e > v.value.abs()))
            .map(|v| {
                format!(
                    "{} ({:.4} ± {:.2e})",
                    v.name,
                    v.value,
                    v.std_error.unwrap_or(f64::NAN)
                )
            })
            .collect();
        if effect == Effect::Gravity {
            let g = values[0].hypot(values[1]);
            let e = errs[0].unwrap_or(0.0).hypot(errs[1].unwrap_or(0.0));
            if e.is_nan() || e > g {
                unidentified.push(format!("the field's strength ({g:.4} ± {e:.2e})"));
            }
        }
        let mut identified = unidentified.is_empty();
        if effect == Effect::Gravity
            && against_the_motion(inp.obs, &fam.free, Vec2::new(values[0], values[1]))
        {
            notes.push(
                "every free particle moves on a straight line against this field and never turns back: a steady deceleration along the path, which the tracks cannot tell from the dry friction of a surface under the motion (a puck slowing on a table); a stop, and staying stopped, would show friction"
                    .to_string(),
            );
        }
        if !unidentified.is_empty() {
            notes.push(format!(
                "not identified by the tracks: {} (standard error above the value)",
                unidentified.join(", ")
            ));
        }
        if let Effect::Tether { particle } = effect {
            if fam.is_pinned(k, 3) {
                notes.push(format!(
                    "taken as rigid: an elastic tether fits no better, so its stiffness is held at {:.4e} (a stretch of a tenth of the track noise under the field)",
                    values[3]
                ));
            }
            let xs: Vec<Vec2> = inp
                .obs
                .positions
                .iter()
                .filter_map(|f| f.get(particle).copied().flatten())
                .collect();
            if !xs.is_empty() {
                let mean = xs.iter().sum::<Vec2>() / xs.len() as f64;
                let extent = xs.iter().map(|x| (x - mean).norm()).fold(0.0, f64::max).max(1e-9);
                let to_anchor = Vec2::new(values[0], values[1]) - mean;
                let distance = to_anchor.norm();
                let e = errs[0].unwrap_or(0.0).hypot(errs[1].unwrap_or(0.0));
                if e.is_nan() || e > distance {
                    identified = false;
                    notes.push(format!(
                        "the anchor is not located by the tracks (± {e:.2e} px on a distance of {distance:.1} px)"
                    ));
                }
                if distance > TETHER_RUNS_OFF * extent {
                    identified = false;
                    let mass = inp.structure.particles.get(particle).map_or(1.0, |p| p.mass);
                    let pull = 2.0 * values[3] * (distance - values[2]) / mass;
                    // The field points towards the anchor when the tether is stretched.
                    let u = to_anchor / distance * pull.signum();
                    notes.push(format!(
                        "the anchor runs off ({distance:.0} px away, {:.0} times the motion's extent): over the motion this tether is a uniform field of {:.2} px/s^2 towards ({:.3}, {:.3}) plus a restoring acceleration of {:.3} /s^2 per px along that line",
                        distance / extent,
                        pull.abs(),
                        u.x,
                        u.y,
                        2.0 * values[3] / mass
                    ));
                }
            }
        }
        findings.push(Finding {
            effect: effect.name().into(),
            label: effect.label(inp.structure),
            tether: matches!(effect, Effect::Tether { .. }),
            parameters,
            seen,
            evidence: evidence.clone(),
            round: *round,
            identified,
            note: (!notes.is_empty()).then(|| notes.join("; ")),
            inclusion_rate: None,
        });
    }

    // Costs on the whole sequence and residual series.
    let anchor_frame = inp.obs.first_frame + inp.anchor;
    let (base, base_seq) = summary(
        inp.base_family,
        inp.base_fit,
        anchor_frame,
        inp.sequence,
        inp.scales,
    );
    let (final_model, final_seq) = summary(fam, fit, anchor_frame, inp.sequence, inp.scales);
    let frames: Vec<usize> = (0..inp.sequence.frame_count())
        .map(|k| inp.sequence.first_frame + k)
        .collect();
    let base_prediction = prediction(inp.base_family, base_seq.as_ref(), inp.sequence);
    let final_prediction = prediction(fam, final_seq.as_ref(), inp.sequence);
    let particles: Vec<String> = inp.structure.particles.iter().map(|p| p.id.clone()).collect();
    let residuals = ResidualSeries {
        particles: particles.clone(),
        frames: frames.clone(),
        before: residual_series(base_prediction.as_ref(), inp.sequence),
        after: residual_series(final_prediction.as_ref(), inp.sequence),
    };
    let predictions = match (base_prediction, final_prediction) {
        (Some(base), Some(final_model)) => Some(Predictions {
            frames,
            particles,
            observed: inp.sequence.positions.clone(),
            base,
            final_model,
        }),
        _ => None,
    };
    let localisation = localise(
        inp.base_family,
        inp.obs,
        inp.weak,
        &residuals,
        inp.jolts,
        inp.supports,
        inp.seed,
    );

    let scene = final_scene(inp.structure, fam, fit, inp.anchor, inp.obs, &mut warnings);
    Outcome {
        findings,
        scene,
        base,
        final_model,
        residuals,
        localisation,
        warnings,
        predictions,
    }
}

fn bbox(points: impl Iterator<Item = Vec2>) -> Option<[f64; 4]> {
    let mut b: Option<[f64; 4]> = None;
    for p in points {
        b = Some(match b {
            None => [p.x, p.y, p.x, p.y],
            Some(r) => [r[0].min(p.x), r[1].min(p.y), r[2].max(p.x), r[3].max(p.y)],
        });
    }
    b
}

/// The id of the fixed particle a tether (effect `k`) adds: `anchor`, `anchor-2`, ... avoiding
/// the structure's ids.
fn anchor_id(structure: &Scene, k: usize) -> String {
    let mut name = if k == 0 {
        "anchor".to_string()
    } else {
        format!("anchor-{}", k + 1)
    };
    while structure.particles.iter().any(|p| p.id == name) {
        name.push('_');
    }
    name
}

/// The diagnosed model as a scene (see [`super::Diagnosis::final_scene`]).
fn final_scene(
    structure: &Scene,
    fam: &Family,
    fit: &ShotFit,
    anchor: usize,
    obs: &Observations,
    warnings: &mut Vec<String>,
) -> Scene {
    let nb = fam.bond_dim();
    let mut scene = match &fam.problem {
        Some(p) => p.fitted_scene(&fit.params[..nb]),
        None => structure.clone(),
    };
    let mut state = fit.state.clone();
    let model = fam.model(&fit.params, Some(&mut state));
    scene.physics = model.physics.clone();
    for (k, s) in scene.springs.iter_mut().enumerate() {
        s.damping = model.springs[k].damping;
    }
    for (k, &e) in fam.effects.iter().enumerate() {
        let o = fam.effect_offset(k);
        let v = &fit.params[o..o + e.parameter_count()];
        match e {
            Effect::MissingSpring { a, b } => scene.springs.push(SpringSpec {
                ends: [ParticleId(a as u32), ParticleId(b as u32)],
                rest_length: Some(v[0]),
                stiffness: Some(v[1]),
                damping: None,
            }),
            Effect::Tether { particle } => {
                let id = anchor_id(structure, k);
                scene.particles.push(ParticleSpec {
                    id,
                    mass: 1.0,
                    position: Vec2::new(v[0], v[1]),
                    velocity: Vec2::zeros(),
                    fixed: true,
                    ..Default::default()
                });
                let pid = ParticleId((scene.particles.len() - 1) as u32);
                scene.springs.push(SpringSpec {
                    ends: [ParticleId(particle as u32), pid],
                    rest_length: Some(v[2]),
                    stiffness: Some(v[3]),
                    damping: None,
                });
            }
            // The rope itself is in the model's physics (its anchor's index is this one's).
            Effect::AnchoredRope { .. } => scene.particles.push(ParticleSpec {
                id: anchor_id(structure, k),
                mass: 1.0,
                position: Vec2::new(v[0], v[1]),
                velocity: Vec2::zeros(),
                fixed: true,
                ..Default::default()
            }),
            _ => {}
        }
    }
    if obs.first_frame + anchor == 0 {
        for p in &fam.free {
            scene.particles[*p].position = fit.state.positions[*p];
            scene.particles[*p].velocity = fit.state.velocities[*p];
        }
    } else {
        warnings.push(format!(
            "the fit starts at frame {}; the scene's frame-0 state is the structure's (dissipative models cannot be run backwards)",
            obs.first_frame + anchor
        ));
    }
    scene
}

/// Returns true if and only if every one of `free`'s particles moves against `g` in every
/// frame it moves (its estimated velocity, `Observations::velocities`, above ten velocity
/// noises): the mean cosine of its velocity with `g` below -0.995, none above 0 (it never
/// turns back), in 10 frames or more in all. Such a field is a steady deceleration along
/// straight paths.
fn against_the_motion(obs: &Observations, free: &[usize], g: Vec2) -> bool {
    let gn = g.norm();
    if gn == 0.0 || free.is_empty() {
        return false;
    }
    let floor = 10.0 * obs.velocity_noise.max(f64::MIN_POSITIVE);
    let cosines: Vec<f64> = obs
        .velocities
        .iter()
        .flat_map(|frame| free.iter().filter_map(|&p| frame[p]))
        .filter(|v| v.norm() > floor)
        .map(|v| v.dot(&g) / (v.norm() * gn))
        .collect();
    cosines.len() >= 10
        && cosines.iter().all(|&c| c < 0.0)
        && cosines.iter().sum::<f64>() / (cosines.len() as f64) < -0.995
}
