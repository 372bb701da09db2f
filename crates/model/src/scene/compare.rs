//! A fitted model against the true scene it was recorded from: every value's error, and the
//! effects beyond a structure that each of them carries.
//!
//! Effects are named as the diagnosis names them (`gravity`, `drag`, `quadratic_drag`,
//! `spring_damping`, `wall`, `missing_spring`, and the contacts and constraints
//! `wall_friction`, `bumper`, `surface_friction`, `body_drag`, `body_quadratic_drag`, `rope`,
//! `rail`), so a run on a rendered scene can say which
//! concealed effects were found, which were missed and which were added without cause.

use serde::Serialize;

use super::{spring_name, torsion_name, Scene};
use crate::Vec2;

/// One value of the fitted model beside the truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ValueComparison {
    /// What the value belongs to, e.g. `spring a-b`, `torsion a-b-c`, `gravity`, `wall 1`.
    pub item: String,
    /// The value's name (`length`, `stiffness`, `rest_angle`, `damping`, `gravity_x`,
    /// `drag`, `offset`, `restitution`...).
    pub name: String,
    /// Fitted value, in `unit` (`null` when the fitted model lacks it).
    pub fitted: Option<f64>,
    /// True value, in `unit` (`null` when the truth lacks it).
    pub truth: Option<f64>,
    /// `fitted - truth`, in `unit`.
    pub error: Option<f64>,
    /// `(fitted - truth) / |truth|` (`null` for angles, positions and zero truths, where a
    /// relative error means nothing).
    pub relative_error: Option<f64>,
    /// Unit of the values: `px`, `mass/s^2` (stiffness), `deg`, `px/s^2`, `1/s`, `1/px`,
    /// `mass/s`, `1`.
    pub unit: String,
}

/// A fitted model compared with the true scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SceneComparison {
    /// Every value present in either model.
    pub values: Vec<ValueComparison>,
    /// Effects the truth carries beyond the structure (what a diagnosis should find).
    pub effects_concealed: Vec<String>,
    /// Effects the fitted model carries beyond the structure.
    pub effects_found: Vec<String>,
    /// Concealed effects the fitted model lacks.
    pub missed: Vec<String>,
    /// Effects the fitted model added that the truth lacks.
    pub spurious: Vec<String>,
    /// Largest `|relative error|` over the bond values (lengths, stiffnesses), `null` without.
    pub max_bond_relative_error: Option<f64>,
    /// Largest rest-angle error, degrees, `null` without torsions.
    pub max_angle_error_deg: Option<f64>,
}

/// Compares `fitted` with `truth`, both read against `structure` (the scene the fit started
/// from: its springs are the listed ones; every other spring or particle is an added effect).
pub fn compare_scenes(fitted: &Scene, truth: &Scene, structure: &Scene) -> SceneComparison {
    let mut values = Vec::new();
    let rigid = rope_tethers(fitted, truth);
    bond_values(fitted, truth, &rigid, &mut values);
    physics_values(fitted, truth, &rigid, &mut values);
    let effects_concealed = effects_beyond(truth, structure);
    let mut effects_found = effects_beyond(fitted, structure);
    // A rope standing for a stiff tether is that tether found.
    for _ in &rigid {
        if let Some(k) = effects_found.iter().position(|e| e == "rope") {
            effects_found[k] = "missing_spring".to_string();
        }
    }
    let missed = multiset_minus(&effects_concealed, &effects_found);
    let spurious = multiset_minus(&effects_found, &effects_concealed);
    let max_of = |pick: &dyn Fn(&ValueComparison) -> Option<f64>| {
        values.iter().filter_map(pick).map(f64::abs).reduce(f64::max)
    };
    // Bonds of the structure and missing springs between particles; a tether's stiffness is
    // often held rigid (not identified), and its anchor is scored apart.
    let anchored: Vec<&str> = values
        .iter()
        .filter(|v| v.name == "anchor")
        .map(|v| v.item.as_str())
        .collect();
    let max_bond_relative_error = max_of(&|v| {
        (v.item.starts_with("spring ")
            && !anchored.contains(&v.item.as_str())
            && (v.name == "length" || v.name == "stiffness"))
            .then_some(v.relative_error)
            .flatten()
    });
    let max_angle_error_deg = max_of(&|v| (v.name == "rest_angle").then_some(v.error).flatten());
    SceneComparison {
        values,
        effects_concealed,
        effects_found,
        missed,
        spurious,
        max_bond_relative_error,
        max_angle_error_deg,
    }
}

/// The effects `scene` carries beyond `structure`, one entry per instance (a scene with two
/// walls lists `wall` twice), in the diagnosis's names: `gravity`, `drag`, `quadratic_drag`,
/// `spring_damping`, `surface_friction`, `body_drag` and `body_quadratic_drag` (once per body
/// with a coefficient),
/// `wall` (every wall, rigid or bumper), `wall_friction` (a wall with Coulomb friction),
/// `bumper` (a wall with a stiffness), `rope`, `rail`, `missing_spring`.
pub fn effects_beyond(scene: &Scene, structure: &Scene) -> Vec<String> {
    let mut out = multiset_minus(&physics_effects(scene), &physics_effects(structure));
    let listed = spring_keys(structure);
    for key in spring_keys(scene) {
        if !listed.contains(&key) {
            out.push("missing_spring".to_string());
        }
    }
    out
}

/// The `[physics]` effects and per-body drags of `scene` (see [`effects_beyond`]).
fn physics_effects(scene: &Scene) -> Vec<String> {
    let mut out = Vec::new();
    let p = &scene.physics;
    let mut push = |on: bool, name: &str| {
        if on {
            out.push(name.to_string());
        }
    };
    push(p.gravity.norm() > 0.0, "gravity");
    push(p.drag > 0.0, "drag");
    push(p.quadratic_drag > 0.0, "quadratic_drag");
    push(p.surface_friction > 0.0, "surface_friction");
    push(
        p.spring_damping > 0.0 || scene.springs.iter().any(|s| s.damping.is_some_and(|d| d > 0.0)),
        "spring_damping",
    );
    for particle in scene.particles.iter().filter(|q| !q.fixed) {
        push(particle.body_drag.unwrap_or(p.body_drag) > 0.0, "body_drag");
        push(
            particle.body_quadratic_drag.unwrap_or(p.body_quadratic_drag) > 0.0,
            "body_quadratic_drag",
        );
    }
    for w in &p.walls {
        push(true, "wall");
        push(w.friction > 0.0, "wall_friction");
        push(w.is_bumper(), "bumper");
    }
    for _ in &p.ropes {
        push(true, "rope");
    }
    for _ in &p.rails {
        push(true, "rail");
    }
    out
}

fn multiset_minus(a: &[String], b: &[String]) -> Vec<String> {
    let mut rest: Vec<&String> = b.iter().collect();
    let mut out = Vec::new();
    for x in a {
        match rest.iter().position(|y| *y == x) {
            Some(k) => {
                rest.swap_remove(k);
            }
            None => out.push(x.clone()),
        }
    }
    out
}

/// A spring's ends as ids, in a canonical order.
fn spring_keys(scene: &Scene) -> Vec<[String; 2]> {
    scene
        .springs
        .iter()
        .map(|s| {
            let mut ends = s.ends.map(|e| scene.particles[e.index()].id.clone());
            ends.sort();
            ends
        })
        .collect()
}

fn compared(
    item: &str,
    name: &str,
    unit: &str,
    fitted: Option<f64>,
    truth: Option<f64>,
    relative: bool,
) -> ValueComparison {
    let error = fitted.zip(truth).map(|(f, t)| f - t);
    let relative_error = if relative {
        error
            .zip(truth)
            .and_then(|(e, t)| (t.abs() > 0.0).then(|| e / t.abs()))
    } else {
        None
    };
    ValueComparison {
        item: item.to_string(),
        name: name.to_string(),
        fitted,
        truth,
        error,
        relative_error,
        unit: unit.to_string(),
    }
}

fn bond_values(fitted: &Scene, truth: &Scene, rigid: &[(usize, usize, f64)], out: &mut Vec<ValueComparison>) {
    let f_keys = spring_keys(fitted);
    let t_keys = spring_keys(truth);
    let mut seen = Vec::new();
    let tethers = matched_tethers(fitted, truth, &f_keys, &t_keys);
    for (k, key) in f_keys.iter().enumerate() {
        let fs = &fitted.springs[k];
        let tether = tethers.iter().find(|m| m.0 == k);
        let ts = t_keys
            .iter()
            .position(|t| t == key)
            .or(tether.map(|m| m.1))
            .map(|j| &truth.springs[j]);
        let item = spring_name(key);
        if let Some(&(_, j, offset)) = tether {
            out.push(compared(&item, "anchor", "px", Some(offset), Some(0.0), false));
            seen.push(t_keys[j].clone());
        }
        out.push(compared(
            &item,
            "length",
            "px",
            fs.rest_length,
            ts.and_then(|s| s.rest_length),
            true,
        ));
        out.push(compared(
            &item,
            "stiffness",
            "mass/s^2",
            fs.stiffness,
            ts.and_then(|s| s.stiffness),
            true,
        ));
        let damping =
            |s: &super::SpringSpec, scene: &Scene| s.damping.unwrap_or(scene.physics.spring_damping);
        let (fd, td) = (damping(fs, fitted), ts.map(|s| damping(s, truth)));
        if fd > 0.0 || td.is_some_and(|d| d > 0.0) {
            out.push(compared(&item, "damping", "mass/s", Some(fd), td, true));
        }
        seen.push(key.clone());
    }
    for (j, key) in t_keys.iter().enumerate() {
        if !seen.contains(key) {
            let ts = &truth.springs[j];
            let item = spring_name(key);
            // A tether found as a rope: its anchor and length, and no stiffness (rigid).
            let rope = rigid.iter().find(|m| m.1 == j);
            if let Some(&(_, _, offset)) = rope {
                out.push(compared(&item, "anchor", "px", Some(offset), Some(0.0), false));
            }
            let length = rope.map(|m| fitted.physics.ropes[m.0].length);
            out.push(compared(&item, "length", "px", length, ts.rest_length, true));
            out.push(compared(&item, "stiffness", "mass/s^2", None, ts.stiffness, true));
        }
    }
    let torsion_key = |scene: &Scene, k: usize| {
        let t = &scene.torsions[k];
        let id = |p: crate::ParticleId| scene.particles[p.index()].id.clone();
        let mut ends = [id(t.ends[0]), id(t.ends[1])];
        ends.sort();
        (id(t.center), ends)
    };
    for k in 0..fitted.torsions.len() {
        let key = torsion_key(fitted, k);
        let tt = (0..truth.torsions.len())
            .find(|&j| torsion_key(truth, j) == key)
            .map(|j| &truth.torsions[j]);
        let ft = &fitted.torsions[k];
        let item = torsion_name(&key.0, &key.1);
        let angle = |c: Option<f64>| c.map(|c| c.clamp(-1.0, 1.0).acos().to_degrees());
        out.push(compared(
            &item,
            "rest_angle",
            "deg",
            angle(ft.rest_cos),
            angle(tt.and_then(|t| t.rest_cos)),
            false,
        ));
        out.push(compared(
            &item,
            "stiffness",
            "mass px^2/s^2",
            ft.stiffness,
            tt.and_then(|t| t.stiffness),
            true,
        ));
    }
}

/// `(moving id, fixed id, fixed position)` of a bond or rope with `ends` in `scene` when
/// exactly one end is fixed.
fn tether_ends(scene: &Scene, ends: [crate::ParticleId; 2]) -> Option<(String, String, Vec2)> {
    let ends = ends.map(|e| &scene.particles[e.index()]);
    match (ends[0].fixed, ends[1].fixed) {
        (true, false) => Some((ends[1].id.clone(), ends[0].id.clone(), ends[0].position)),
        (false, true) => Some((ends[0].id.clone(), ends[1].id.clone(), ends[1].position)),
        _ => None,
    }
}

/// Ropes of `fitted` that stand for a stiff spring of `truth` from a fixed point to a moving
/// particle (a diagnosis takes a tether whose length stays constant within the noise as a
/// rope to the anchor it adds, `anchor-N`): paired by their moving end when the fixed end's
/// id is not in `truth`. Returns `(fitted rope, truth spring, anchor distance in px)`; each
/// truth spring is paired once, with the nearest anchor.
fn rope_tethers(fitted: &Scene, truth: &Scene) -> Vec<(usize, usize, f64)> {
    let mut pairs: Vec<(usize, usize, f64)> = Vec::new();
    for (k, rope) in fitted.physics.ropes.iter().enumerate() {
        let Some((moving, anchor_id, anchor)) = tether_ends(fitted, rope.ends) else {
            continue;
        };
        if truth.particles.iter().any(|p| p.id == anchor_id) {
            continue;
        }
        let best = (0..truth.springs.len())
            .filter(|&j| pairs.iter().all(|p| p.1 != j))
            .filter_map(|j| {
                let (m, _, a) = tether_ends(truth, truth.springs[j].ends)?;
                (m == moving).then(|| (j, (a - anchor).norm()))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((j, offset)) = best {
            pairs.push((k, j, offset));
        }
    }
    pairs
}

/// Tethers named differently in `fitted` and `truth`: a spring from a fixed particle to a
/// moving one, whose fixed end has another id in each (a diagnosis names the anchor it adds
/// `anchor-N`; the scene, `pivot`), paired by their moving end when neither key is in the
/// other scene. Returns `(fitted spring, truth spring, anchor distance in px)`; each truth
/// spring is paired once, with the nearest anchor.
fn matched_tethers(
    fitted: &Scene,
    truth: &Scene,
    f_keys: &[[String; 2]],
    t_keys: &[[String; 2]],
) -> Vec<(usize, usize, f64)> {
    let tether = |scene: &Scene, k: usize| {
        let (moving, _, anchor) = tether_ends(scene, scene.springs[k].ends)?;
        Some((moving, anchor))
    };
    let mut pairs: Vec<(usize, usize, f64)> = Vec::new();
    for (k, key) in f_keys.iter().enumerate() {
        let Some((moving, anchor)) = tether(fitted, k).filter(|_| !t_keys.contains(key)) else {
            continue;
        };
        let best = (0..truth.springs.len())
            .filter(|&j| !f_keys.contains(&t_keys[j]) && pairs.iter().all(|p| p.1 != j))
            .filter_map(|j| {
                let (m, a) = tether(truth, j)?;
                (m == moving).then(|| (j, (a - anchor).norm()))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((j, offset)) = best {
            pairs.push((k, j, offset));
        }
    }
    pairs
}

fn physics_values(
    fitted: &Scene,
    truth: &Scene,
    rigid: &[(usize, usize, f64)],
    out: &mut Vec<ValueComparison>,
) {
    let (f, t) = (&fitted.physics, &truth.physics);
    if f.gravity.norm() > 0.0 || t.gravity.norm() > 0.0 {
        out.push(compared(
            "gravity",
            "gravity_x",
            "px/s^2",
            Some(f.gravity.x),
            Some(t.gravity.x),
            false,
        ));
        out.push(compared(
            "gravity",
            "gravity_y",
            "px/s^2",
            Some(f.gravity.y),
            Some(t.gravity.y),
            false,
        ));
        out.push(compared(
            "gravity",
            "magnitude",
            "px/s^2",
            Some(f.gravity.norm()),
            Some(t.gravity.norm()),
            true,
        ));
    }
    for (name, unit, fv, tv) in [
        ("drag", "1/s", f.drag, t.drag),
        ("quadratic_drag", "1/px", f.quadratic_drag, t.quadratic_drag),
        (
            "surface_friction",
            "px/s^2",
            f.surface_friction,
            t.surface_friction,
        ),
    ] {
        if fv > 0.0 || tv > 0.0 {
            out.push(compared(name, name, unit, Some(fv), Some(tv), true));
        }
    }
    // A bumper's restitution depends on the mass it meets: the scene's mean free mass.
    let free: Vec<f64> = truth
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass)
        .collect();
    let mass = free.iter().sum::<f64>() / free.len().max(1) as f64;
    // Walls: each true wall against the fitted wall facing the same way (largest normal dot
    // product above cos 25 degrees); its position error is the distance from the fitted line
    // to the true wall's point, px.
    let mut used = vec![false; f.walls.len()];
    for (k, tw) in t.walls.iter().enumerate() {
        let item = format!("wall {}", k + 1);
        let best = f
            .walls
            .iter()
            .enumerate()
            .filter(|(j, w)| !used[*j] && w.normal.dot(&tw.normal) > 25f64.to_radians().cos())
            .max_by(|a, b| a.1.normal.dot(&tw.normal).total_cmp(&b.1.normal.dot(&tw.normal)));
        match best {
            Some((j, fw)) => {
                used[j] = true;
                let distance = fw.signed_distance(tw.point).abs();
                out.push(ValueComparison {
                    item: item.clone(),
                    name: "position".into(),
                    fitted: None,
                    truth: None,
                    error: Some(distance),
                    relative_error: None,
                    unit: "px".into(),
                });
                let angle = |n: Vec2| n.y.atan2(n.x).to_degrees();
                out.push(compared(
                    &item,
                    "normal_angle",
                    "deg",
                    Some(angle(fw.normal)),
                    Some(angle(tw.normal)),
                    false,
                ));
                contact_values(&item, Some(fw), Some(tw), mass, out);
            }
            None => contact_values(&item, None, Some(tw), mass, out),
        }
    }
    for (j, fw) in f.walls.iter().enumerate() {
        if !used[j] {
            contact_values("added wall", Some(fw), None, mass, out);
        }
    }
    body_values(fitted, truth, out);
    constraint_values(fitted, truth, rigid, out);
}

/// A wall's contact values: its restitution (a bumper's for the scene's mean free mass, see
/// [`crate::Wall::bumper_restitution`]), and where either wall has them its Coulomb
/// `friction` and its bumper `stiffness` and `damping`.
fn contact_values(
    item: &str,
    fitted: Option<&crate::Wall>,
    truth: Option<&crate::Wall>,
    mass: f64,
    out: &mut Vec<ValueComparison>,
) {
    let restitution = |w: &crate::Wall| w.bumper_restitution(mass);
    out.push(compared(
        item,
        "restitution",
        "1",
        fitted.map(restitution),
        truth.map(restitution),
        false,
    ));
    let either =
        |pick: &dyn Fn(&crate::Wall) -> f64| fitted.map_or(0.0, pick) > 0.0 || truth.map_or(0.0, pick) > 0.0;
    if either(&|w| w.friction) {
        let mu = |w: &crate::Wall| w.friction;
        out.push(compared(
            item,
            "friction",
            "1",
            fitted.map(mu),
            truth.map(mu),
            true,
        ));
    }
    if either(&|w| w.stiffness) {
        let (s, c) = (|w: &crate::Wall| w.stiffness, |w: &crate::Wall| w.damping);
        out.push(compared(
            item,
            "stiffness",
            "mass/s^2",
            fitted.map(s),
            truth.map(s),
            true,
        ));
        out.push(compared(
            item,
            "damping",
            "mass/s",
            fitted.map(c),
            truth.map(c),
            true,
        ));
    }
}

/// Per-body drag (`body_drag`, `body_quadratic_drag`: a body's own or the shared value), each
/// free body of the truth against the fitted body of the same id, where either has one.
fn body_values(fitted: &Scene, truth: &Scene, out: &mut Vec<ValueComparison>) {
    for tp in truth.particles.iter().filter(|p| !p.fixed) {
        let fp = fitted.particles.iter().find(|p| p.id == tp.id);
        let item = format!("body {}", tp.id);
        let linear = |p: &super::ParticleSpec, s: &Scene| p.body_drag.unwrap_or(s.physics.body_drag);
        let quadratic = |p: &super::ParticleSpec, s: &Scene| {
            p.body_quadratic_drag.unwrap_or(s.physics.body_quadratic_drag)
        };
        for (name, unit, law) in [
            (
                "body_drag",
                "mass/s",
                &linear as &dyn Fn(&super::ParticleSpec, &Scene) -> f64,
            ),
            ("body_quadratic_drag", "mass/px", &quadratic),
        ] {
            let (f, t) = (fp.map(|p| law(p, fitted)), law(tp, truth));
            if t > 0.0 || f.is_some_and(|f| f > 0.0) {
                out.push(compared(&item, name, unit, f, Some(t), true));
            }
        }
    }
}

/// Ropes (matched by their ends' ids: `length`) and rails (matched by their particle's id:
/// `position`, the distance of the true rail's point from the fitted line, px; `direction`,
/// deg; `friction`).
fn constraint_values(
    fitted: &Scene,
    truth: &Scene,
    rigid: &[(usize, usize, f64)],
    out: &mut Vec<ValueComparison>,
) {
    let rope_key = |scene: &Scene, r: &crate::Rope| {
        let mut ends = r.ends.map(|e| scene.particles[e.index()].id.clone());
        ends.sort();
        ends
    };
    let (fr, tr) = (&fitted.physics.ropes, &truth.physics.ropes);
    for tw in tr {
        let key = rope_key(truth, tw);
        let fw = fr.iter().find(|r| rope_key(fitted, r) == key);
        let item = format!("rope {}-{}", key[0], key[1]);
        out.push(compared(
            &item,
            "length",
            "px",
            fw.map(|r| r.length),
            Some(tw.length),
            true,
        ));
    }
    for (k, fw) in fr.iter().enumerate() {
        let key = rope_key(fitted, fw);
        if !tr.iter().any(|r| rope_key(truth, r) == key) && !rigid.iter().any(|m| m.0 == k) {
            let item = format!("added rope {}-{}", key[0], key[1]);
            out.push(compared(&item, "length", "px", Some(fw.length), None, true));
        }
    }
    let id = |scene: &Scene, r: &crate::Rail| scene.particles[r.particle.index()].id.clone();
    let (fl, tl) = (&fitted.physics.rails, &truth.physics.rails);
    for tw in tl {
        let item = format!("rail {}", id(truth, tw));
        let Some(fw) = fl.iter().find(|r| id(fitted, r) == id(truth, tw)) else {
            out.push(compared(&item, "friction", "1", None, Some(tw.friction), true));
            continue;
        };
        let across = Vec2::new(-fw.direction.y, fw.direction.x);
        out.push(ValueComparison {
            item: item.clone(),
            name: "position".into(),
            fitted: None,
            truth: None,
            error: Some((tw.point - fw.point).dot(&across).abs()),
            relative_error: None,
            unit: "px".into(),
        });
        // A line's direction is defined up to its sign: the angle is compared modulo 180.
        let angle = |d: Vec2| d.y.atan2(d.x).to_degrees();
        let turn = (angle(fw.direction) - angle(tw.direction) + 90.0).rem_euclid(180.0) - 90.0;
        out.push(compared(
            &item,
            "direction",
            "deg",
            Some(angle(tw.direction) + turn),
            Some(angle(tw.direction)),
            false,
        ));
        if fw.friction > 0.0 || tw.friction > 0.0 {
            out.push(compared(
                &item,
                "friction",
                "1",
                Some(fw.friction),
                Some(tw.friction),
                true,
            ));
        }
    }
    for fw in fl {
        if !tl.iter().any(|r| id(truth, r) == id(fitted, fw)) {
            let item = format!("added rail {}", id(fitted, fw));
            out.push(compared(&item, "friction", "1", Some(fw.friction), None, true));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRUTH: &str = r#"
name = "t"
[recording]
fps = 50
frames = 10
[[particles]]
id = "a"
mass = 1
position = [10, 10]
[[particles]]
id = "b"
mass = 1
position = [30, 10]
[[particles]]
id = "c"
mass = 1
position = [20, 30]
[[springs]]
between = ["a", "b"]
length = 20
stiffness = 100
[[springs]]
between = ["b", "c"]
length = 22
stiffness = 50
[[springs]]
between = ["a", "c"]
length = 22
stiffness = 40
[physics]
gravity = [0, 100]
drag = 0.5
[[physics.walls]]
point = [0, 200]
normal = [0, -1]
restitution = 0.8
"#;

    fn truth_and_structure() -> (Scene, Scene) {
        let truth = Scene::from_toml_str(TRUTH, "truth").unwrap();
        let mut structure = truth.structure();
        structure.springs.pop();
        (truth, structure)
    }

    #[test]
    fn the_truth_against_itself_has_no_error_and_every_effect_found() {
        let (truth, structure) = truth_and_structure();
        let c = compare_scenes(&truth, &truth, &structure);
        assert_eq!(c.effects_concealed, ["gravity", "drag", "wall", "missing_spring"]);
        assert_eq!(c.effects_found, c.effects_concealed);
        assert!(c.missed.is_empty() && c.spurious.is_empty());
        assert!(c.values.iter().all(|v| v.error.is_some_and(|e| e.abs() < 1e-12)));
        assert!(c.max_bond_relative_error.is_some_and(|e| e < 1e-12));
    }

    /// A tether a diagnosis adds (`anchor-1`, fixed) is scored against the truth's spring to
    /// its own fixed pivot: the anchor's distance, the length and the stiffness, which stays
    /// out of the largest bond error.
    #[test]
    fn a_tether_is_scored_against_the_truths_spring_to_another_fixed_particle() {
        let pendulum = |pivot: &str, at: [f64; 2], length: f64, stiffness: f64| {
            let text = format!(
                "name = \"p\"\n[recording]\nfps = 60\nframes = 10\n\
                 [[particles]]\nid = \"bob\"\nmass = 1\nposition = [0, 100]\n\
                 [[particles]]\nid = \"{pivot}\"\nmass = 1\nposition = [{}, {}]\nfixed = true\n\
                 [[springs]]\nbetween = [\"bob\", \"{pivot}\"]\nlength = {length}\nstiffness = {stiffness}\n",
                at[0], at[1]
            );
            Scene::from_toml_str(&text, "p").unwrap()
        };
        let truth = pendulum("pivot", [0.0, -200.0], 300.0, 2.0e4);
        let fitted = pendulum("anchor-1", [3.0, -196.0], 297.0, 3.0e5);
        let mut structure = truth.structure();
        structure.springs.clear();
        structure.particles.truncate(1);
        let c = compare_scenes(&fitted, &truth, &structure);
        assert_eq!(c.effects_concealed, ["missing_spring"]);
        assert!(c.missed.is_empty() && c.spurious.is_empty(), "{c:?}");
        let value = |name: &str| c.values.iter().find(|v| v.name == name).unwrap();
        assert!((value("anchor").error.unwrap() - 5.0).abs() < 1e-12);
        assert!((value("length").relative_error.unwrap() + 0.01).abs() < 1e-12);
        assert!((value("stiffness").relative_error.unwrap() - 14.0).abs() < 1e-12);
        assert_eq!(c.max_bond_relative_error, None);
    }

    /// A stiff tether a diagnosis found as a rope to the anchor it adds is that tether found:
    /// its anchor distance and length scored against the truth's spring, no stiffness, and no
    /// rope added without cause.
    #[test]
    fn a_rope_to_an_added_anchor_is_scored_as_the_truths_stiff_tether() {
        let text = |pivot: &str, at: [f64; 2], bond: &str| {
            let text = format!(
                "name = \"p\"\n[recording]\nfps = 60\nframes = 10\n\
                 [[particles]]\nid = \"bob\"\nmass = 1\nposition = [0, 100]\n\
                 [[particles]]\nid = \"{pivot}\"\nmass = 1\nposition = [{}, {}]\nfixed = true\n{bond}",
                at[0], at[1]
            );
            Scene::from_toml_str(&text, "p").unwrap()
        };
        let truth = text(
            "pivot",
            [0.0, -200.0],
            "[[springs]]\nbetween = [\"bob\", \"pivot\"]\nlength = 300\nstiffness = 2e5\n",
        );
        let fitted = text(
            "anchor-1",
            [0.0, -203.0],
            "[[physics.ropes]]\nbetween = [\"anchor-1\", \"bob\"]\nlength = 303\n",
        );
        let mut structure = truth.structure();
        structure.springs.clear();
        structure.particles.truncate(1);
        let c = compare_scenes(&fitted, &truth, &structure);
        assert_eq!(c.effects_concealed, ["missing_spring"]);
        assert_eq!(c.effects_found, ["missing_spring"]);
        assert!(c.missed.is_empty() && c.spurious.is_empty(), "{c:?}");
        let value = |name: &str| c.values.iter().find(|v| v.name == name).unwrap();
        assert_eq!(value("anchor").item, "spring bob-pivot");
        assert!((value("anchor").error.unwrap() - 3.0).abs() < 1e-12);
        assert!((value("length").relative_error.unwrap() - 0.01).abs() < 1e-12);
        assert_eq!(value("stiffness").fitted, None);
        assert!(
            !c.values.iter().any(|v| v.item.starts_with("added rope")),
            "{c:?}"
        );
        assert_eq!(c.max_bond_relative_error, None);
    }

    #[test]
    fn errors_missed_and_spurious_effects_are_reported() {
        let (truth, structure) = truth_and_structure();
        let mut fitted = structure.clone();
        for (s, (l, k)) in fitted.springs.iter_mut().zip([(20.2, 99.0), (22.0, 55.0)]) {
            s.rest_length = Some(l);
            s.stiffness = Some(k);
        }
        fitted.physics.gravity = Vec2::new(0.0, 98.0);
        fitted.physics.quadratic_drag = 0.01;
        fitted
            .physics
            .walls
            .push(crate::Wall::new(Vec2::new(5.0, 201.5), Vec2::new(0.0, -1.0), 0.75).unwrap());
        let c = compare_scenes(&fitted, &truth, &structure);
        assert_eq!(c.missed, ["drag", "missing_spring"]);
        assert_eq!(c.spurious, ["quadratic_drag"]);
        let get = |item: &str, name: &str| {
            c.values
                .iter()
                .find(|v| v.item == item && v.name == name)
                .unwrap()
        };
        assert!((get("spring a-b", "length").relative_error.unwrap() - 0.01).abs() < 1e-12);
        assert!((get("spring b-c", "stiffness").relative_error.unwrap() - 0.1).abs() < 1e-12);
        assert!((get("gravity", "magnitude").relative_error.unwrap() + 0.02).abs() < 1e-12);
        assert!((get("wall 1", "position").error.unwrap() - 1.5).abs() < 1e-12);
        assert!((get("wall 1", "restitution").error.unwrap() + 0.05).abs() < 1e-12);
        assert!(get("spring a-c", "length").fitted.is_none());
        assert!((c.max_bond_relative_error.unwrap() - 0.1).abs() < 1e-12);
    }

    const CONTACTS: &str = r#"
name = "contacts"
[recording]
fps = 50
frames = 10
[[particles]]
id = "a"
mass = 2
position = [10, 10]
body_drag = 0.3
[[particles]]
id = "b"
mass = 2
position = [30, 10]
[[particles]]
id = "pivot"
mass = 1
position = [30, 0]
fixed = true
[physics]
gravity = [0, 100]
body_quadratic_drag = 0.001
[[physics.walls]]
point = [0, 200]
normal = [0, -1]
restitution = 0.8
friction = 0.4
[[physics.walls]]
point = [300, 0]
normal = [-1, 0]
stiffness = 500
damping = 6
[[physics.ropes]]
between = ["b", "pivot"]
length = 10
[[physics.rails]]
particle = "a"
point = [0, 10]
direction = [1, 0]
friction = 0.2
"#;

    #[test]
    fn contacts_and_constraints_are_effects_with_their_values() {
        let truth = Scene::from_toml_str(CONTACTS, "truth").unwrap();
        // The structure keeps the constraints: given there, they are not concealed.
        let given = truth.structure();
        assert_eq!(given.physics.ropes, truth.physics.ropes);
        assert_eq!(given.physics.rails, truth.physics.rails);
        let c = compare_scenes(&truth, &truth, &given);
        assert!(!c.effects_concealed.iter().any(|e| e == "rope" || e == "rail"));
        let mut structure = given.clone();
        structure.physics.ropes.clear();
        structure.physics.rails.clear();
        let c = compare_scenes(&truth, &truth, &structure);
        assert_eq!(
            c.effects_concealed,
            [
                "gravity",
                "body_drag",
                "body_quadratic_drag",
                "body_quadratic_drag",
                "wall",
                "wall_friction",
                "wall",
                "bumper",
                "rope",
                "rail"
            ]
        );
        assert!(c.missed.is_empty() && c.spurious.is_empty());
        assert!(c.values.iter().all(|v| v.error.is_some_and(|e| e.abs() < 1e-12)));

        // The fitted model: the bumper found as a rigid wall, the friction 10 % high, one
        // body's drag and the rope and rail missed.
        let mut fitted = truth.clone();
        fitted.particles[0].body_drag = None;
        fitted.physics.walls[0].friction = 0.44;
        fitted.physics.walls[1] = crate::Wall::new(Vec2::new(300.0, 0.0), Vec2::new(-1.0, 0.0), 0.5).unwrap();
        fitted.physics.ropes.clear();
        fitted.physics.rails.clear();
        let c = compare_scenes(&fitted, &truth, &structure);
        assert_eq!(c.missed, ["body_drag", "bumper", "rope", "rail"]);
        assert!(c.spurious.is_empty());
        let get = |item: &str, name: &str| {
            c.values
                .iter()
                .find(|v| v.item == item && v.name == name)
                .unwrap_or_else(|| panic!("no {item} {name} in {:?}", c.values))
        };
        assert!((get("wall 1", "friction").relative_error.unwrap() - 0.1).abs() < 1e-12);
        // The bumper's restitution for the mean free mass 2: zeta = 6 / (2 sqrt(2000)).
        let zeta = 6.0 / (2.0 * 2000f64.sqrt());
        let e = (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp();
        assert!((get("wall 2", "restitution").truth.unwrap() - e).abs() < 1e-12);
        assert!((get("wall 2", "restitution").error.unwrap() - (0.5 - e)).abs() < 1e-12);
        assert!((get("wall 2", "stiffness").error.unwrap() + 500.0).abs() < 1e-12);
        assert!((get("body a", "body_drag").error.unwrap() + 0.3).abs() < 1e-12);
        assert!(get("body b", "body_quadratic_drag").error.unwrap().abs() < 1e-15);
        assert!(get("rope b-pivot", "length").fitted.is_none());
        assert!(get("rail a", "friction").fitted.is_none());
    }
}
