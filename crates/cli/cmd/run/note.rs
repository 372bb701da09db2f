//! `report.md` of a run, written as a short lab note: what was given, what was tracked, the
//! base fit, each finding, the final model, the truth (when known), warnings, pictures.

use std::path::Path;

use physfit_identify::units::{format_quantity, format_value_se, significant};
use physfit_identify::{BondKeys, FitReport};
use physfit_model::scene::SceneComparison;

use super::{RunReport, Tracking};
use crate::cmd::diagnose::sections;
use crate::report::markdown_table;

/// The one-line account of tracking printed by the binary.
pub fn tracking_line(t: &Tracking, path: &Path) -> String {
    let mut s = format!(
        "track: {} tracks, {} points over frames {}..{} ({} bridged, {} split), median position error {:.3} px",
        t.tracks, t.points, t.frames[0], t.frames[1], t.interpolated, t.split, t.median_position_error
    );
    if let Some(score) = &t.score {
        s.push_str(&format!(
            "; against truth.csv: RMS {:.4} px (x) {:.4} px (y), {} identity switches",
            score.rms_x, score.rms_y, score.id_switches
        ));
    }
    s.push_str(&format!(" -> {}", path.display()));
    s
}

/// The one-line account of the truth comparison printed by the binary.
pub fn truth_line(c: &SceneComparison) -> String {
    let list = |v: &[String]| {
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(", ")
        }
    };
    format!(
        "truth: concealed {}; found {}; missed {}; added without cause {}; largest bond error {}",
        list(&c.effects_concealed),
        list(&c.effects_found),
        list(&c.missed),
        list(&c.spurious),
        c.max_bond_relative_error
            .map_or("-".into(), |e| format!("{:.2} %", 100.0 * e))
    )
}

fn bond_name(keys: &BondKeys) -> String {
    match keys {
        BondKeys::Spring { between } => format!("spring {}-{}", between[0], between[1]),
        BondKeys::Torsion { at, between } => format!("torsion {}-{}-{}", between[0], at, between[1]),
    }
}

/// The base fit's values with standard errors (rest cosines also as angles).
fn base_fit(fit: &FitReport) -> String {
    let with_truth = fit.parameters.iter().any(|p| p.relative_error.is_some());
    let si = fit.units.is_some();
    let mut header = vec!["bond", "value ± standard error", "unit", "rest angle, deg"];
    if si {
        header.insert(3, "SI value");
    }
    if with_truth {
        header.push("error against the truth");
    }
    let rows: Vec<Vec<String>> = fit
        .parameters
        .iter()
        .map(|p| {
            let mut row = vec![
                format!("{} {}", bond_name(&p.bond), p.name),
                format_value_se(p.value, p.std_error),
                p.unit().to_string(),
                match p.rest_angle_deg {
                    Some(a) => format_value_se(a, p.rest_angle_std_error_deg),
                    None => String::new(),
                },
            ];
            if si {
                row.insert(
                    3,
                    match (p.value_si, &p.unit_si) {
                        (Some(v), Some(u)) => format_quantity(v, p.std_error_si, u),
                        _ => "-".into(),
                    },
                );
            }
            if with_truth {
                row.push(match (p.angle_error_deg, p.relative_error) {
                    (Some(a), _) => format!("{a:+.3} deg"),
                    (None, Some(r)) => format!("{:+.3} %", 100.0 * r),
                    _ => "-".into(),
                });
            }
            if !p.identifiable {
                row[0].push_str(" (not determined by this recording)");
            }
            row
        })
        .collect();
    let mut s = if rows.is_empty() {
        "The structure lists no bonds: nothing to fit but the motion itself.\n".to_string()
    } else {
        markdown_table(&header, &rows)
    };
    let c = &fit.costs;
    s.push_str(&format!(
        "\nOne-step cost {:.4} px² over the analysed frames; multi-step RMS {:.4} px over the whole \
         sequence (the model run from its fitted start state), against a track noise of {:.4} px.\n",
        c.one_step_window, c.multi_step_sequence.rms, fit.track_noise
    ));
    s
}

/// The diagnosed model's bond values, with SI values when the scene has a scale.
fn final_bonds(scene: &physfit_model::Scene) -> String {
    // `v unit`, and `(v_si unit_si)` beside it with a scale.
    let q = |v: f64, unit: &str| -> String {
        let mut s = format!("{} {unit}", significant(v, 6));
        let si = scene
            .recording
            .metres_per_px
            .and_then(|m| physfit_identify::units::to_si(v, None, unit, m));
        if let Some((v, _, u)) = si.filter(|si| si.2 != unit) {
            s.push_str(&format!(" ({} {u})", significant(v, 6)));
        }
        s
    };
    let mut rows = Vec::new();
    for k in 0..scene.springs.len() {
        let sp = &scene.springs[k];
        let damping = sp.damping.unwrap_or(scene.physics.spring_damping);
        rows.push(vec![
            scene.spring_label(k),
            sp.rest_length.map_or("-".into(), |v| q(v, "px")),
            sp.stiffness.map_or("-".into(), |v| q(v, "energy/px^2")),
            if damping > 0.0 {
                format!("damping {}", q(damping, "mass/s"))
            } else {
                String::new()
            },
        ]);
    }
    for k in 0..scene.torsions.len() {
        let t = &scene.torsions[k];
        rows.push(vec![
            scene.torsion_label(k),
            t.rest_cos.map_or("-".into(), |c| {
                format!(
                    "rest cos {c:.5} ({:.3} deg)",
                    c.clamp(-1.0, 1.0).acos().to_degrees()
                )
            }),
            t.stiffness.map_or("-".into(), |v| q(v, "energy")),
            String::new(),
        ]);
    }
    if rows.is_empty() {
        return String::new();
    }
    markdown_table(&["bond", "rest value", "stiffness", ""], &rows)
}

/// The truth comparison: effects and every value's error.
fn truth_section(c: &SceneComparison) -> String {
    let list = |v: &[String]| {
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(", ")
        }
    };
    let mut s = format!(
        "The scene was rendered here, so the truth is known (no stage before this one saw it).\n\n\
         - effects concealed: {}\n- effects found: {}\n- missed: {}\n- added without cause: {}\n\n",
        list(&c.effects_concealed),
        list(&c.effects_found),
        list(&c.missed),
        list(&c.spurious)
    );
    let num = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.5}"));
    let rows: Vec<Vec<String>> = c
        .values
        .iter()
        .map(|v| {
            vec![
                format!("{} {}", v.item, v.name),
                num(v.fitted),
                num(v.truth),
                v.error.map_or("-".into(), |e| format!("{e:+.5}")),
                v.unit.clone(),
                v.relative_error
                    .map_or("-".into(), |r| format!("{:+.3} %", 100.0 * r)),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &["value", "diagnosed", "true", "error", "unit", "relative error"],
        &rows,
    ));
    s
}

/// The whole lab note.
pub fn lab_note(r: &RunReport, pictures: &str) -> String {
    let g = r.given;
    let t = r.tracking;
    let d = r.diagnosis;
    let mut s = format!("# physfit report: {}\n\n", g.structure);
    let found: Vec<&str> = d.findings.iter().map(|f| f.label.as_str()).collect();
    let verdict = if d.verdict.explained {
        format!("explained to the noise level ({})", d.verdict.text)
    } else {
        d.verdict.text.clone()
    };
    s.push_str(&if found.is_empty() {
        format!(
            "**In short:** nothing was added; the structure alone: {verdict}.\n\n"
        )
    } else {
        format!(
            "**In short:** the structure alone left the model {} px RMS from the tracks; physfit found {} and, with {}, the diagnosed model comes within {} px RMS (track noise {} px). Verdict: {verdict}.\n\n",
            sections::number(d.base.costs.multi_step.rms),
            found.join(", "),
            if found.len() == 1 { "it" } else { "them" },
            sections::number(d.final_model.costs.multi_step.rms),
            sections::number(d.track_noise)
        )
    });

    s.push_str(&sections::units_line(d));
    s.push_str("## What was given\n\n");
    s.push_str(&format!(
        "- {}: `{}`; frames in `{}` at {} frames/s{}.\n- Structure `{}`: {} particles, {} springs, {} torsions, {} unknown bond values; no physics beyond the bonds.\n- Seed {}.\n\n",
        if g.kind == "scene" { "Scene" } else { "Recording, structure" },
        g.source,
        g.frames,
        g.fps,
        g.window.map_or(String::new(), |w| format!(", frames {}..{} analysed", w[0], w[1])),
        g.structure,
        g.particles,
        g.springs,
        g.torsions,
        g.unknowns,
        g.seed
    ));

    s.push_str("## What was tracked\n\n");
    s.push_str(&format!(
        "- {} tracks, {} points over frames {}..{}; {} points bridged from the motion, {} split from merged blobs; {} frames with a particle missing.\n\
         - Localisation: median estimated error {:.4} px per point; track noise measured from the tracks {:.4} px per coordinate.\n\
         - Detection: {}, particle radius {:.2} px ({}), pixel noise {:.2} grey levels.\n",
        t.tracks,
        t.points,
        t.frames[0],
        t.frames[1],
        t.interpolated,
        t.split,
        t.frames_with_gaps,
        t.median_position_error,
        d.track_noise,
        t.polarity,
        t.radius,
        if t.radius_estimated { "measured" } else { "given" },
        t.pixel_noise
    ));
    for a in t.ambiguities.iter().take(10) {
        s.push_str(&format!("- ambiguity bridged: {a}\n"));
    }
    if t.ambiguities.len() > 10 {
        s.push_str(&format!(
            "- ... and {} more ambiguities (report.json)\n",
            t.ambiguities.len() - 10
        ));
    }
    if let Some(score) = &t.score {
        s.push_str("\nAgainst the true centres (`truth.csv`):\n\n");
        s.push_str(&score.to_markdown());
    }

    s.push_str("\n## Base fit: the structure alone\n\n");
    match r.fit {
        Some(fit) => s.push_str(&base_fit(fit)),
        None => s.push_str(&format!(
            "The structure has no unknown bond values: the base model is its particles moving freely \
             from their fitted start state, multi-step RMS {:.4} px over the sequence.\n",
            d.base.costs.multi_step.rms
        )),
    }

    s.push_str("\n## Where the base model disagreed\n\n");
    s.push_str(&sections::localisation(d));

    s.push_str("\n## Verdict\n\n");
    s.push_str(&sections::verdict(d));

    s.push_str("\n## Findings\n\n");
    s.push_str(&sections::findings(d));

    s.push_str("\n## The diagnosed model\n\n");
    s.push_str(&format!(
        "Written to `fitted.toml` (a scene: it renders again). Effects: {}.\n\n",
        if d.final_model.effects.is_empty() {
            "none".to_string()
        } else {
            d.final_model.effects.join(", ")
        }
    ));
    s.push_str(&final_bonds(&d.final_scene));
    s.push_str("\nCosts over the whole tracked sequence, base against diagnosed:\n\n");
    s.push_str(&sections::costs(d));

    if let Some(c) = r.truth {
        s.push_str("\n## Against the truth\n\n");
        s.push_str(&truth_section(c));
    }

    let fit_warnings = r.fit.map(|f| f.warnings.as_slice()).unwrap_or_default();
    let warnings: Vec<&String> = t.warnings.iter().chain(fit_warnings).chain(&d.warnings).collect();
    s.push_str("\n## Warnings\n\n");
    if warnings.is_empty() {
        s.push_str("None.\n");
    }
    for w in warnings {
        s.push_str(&format!("- {w}\n"));
    }

    s.push_str(&format!(
        "\n## Time\n\nrender {:.1} s, track {:.1} s, fit {:.1} s, diagnose {:.1} s, report {:.1} s; total {:.1} s.\n",
        r.times.render, r.times.track, r.times.fit, r.times.diagnose, r.times.report, r.times.total
    ));
    s.push_str("\n## Pictures\n\n");
    s.push_str(pictures);
    s
}
