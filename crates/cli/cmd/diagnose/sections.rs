//! The diagnosis in words: the plain-text summary printed by the binary and the Markdown
//! sections of `report.md` (shared by `physfit diagnose` and `physfit run`).

use physfit_identify::diagnose::{Diagnosis, FittedValue};

use crate::report;

/// One fitted value rounded to its standard error, with its SI value when a scale is known,
/// e.g. `drag = 0.3011 ± 0.0021 1/s`, `gravity_y = 1770 ± 5 px/s^2 (9.73 ± 0.03 m/s^2)`.
pub fn value_text(v: &FittedValue) -> String {
    v.text()
}

/// A finding's values, and for a field its strength `g` (what a pendulum's or a falling
/// ball's g is), each rounded to its standard error.
pub fn values_text(f: &physfit_identify::Finding) -> Vec<String> {
    let mut out: Vec<String> = f.parameters.iter().map(value_text).collect();
    if let Some(g) = f.field_strength() {
        out.push(g.text());
    }
    out
}

/// A length, px, with its SI value when a scale is known: `0.0412 px (0.000226 m)`.
pub fn length_text(px: f64, d: &Diagnosis) -> String {
    match &d.units {
        Some(u) if px.is_finite() => format!(
            "{} px ({} m)",
            number(px),
            physfit_identify::units::significant(px * u.metres_per_px, 3)
        ),
        _ => format!("{} px", number(px)),
    }
}

/// A plain-text account: each finding with its values, and the costs before and after.
pub fn summary(d: &Diagnosis) -> String {
    let mut s = String::new();
    if d.findings.is_empty() {
        s.push_str("no missing physics found\n");
    }
    for f in &d.findings {
        let values = values_text(f);
        s.push_str(&format!(
            "found {}: {}\n  seen: {}\n",
            f.label,
            values.join(", "),
            f.seen.text
        ));
        if let Some(note) = &f.note {
            s.push_str(&format!("  note: {note}\n"));
        }
    }
    s.push_str(&format!(
        "multi-step RMS over the sequence: base {}, diagnosed {} (track noise {})\n",
        length_text(d.base.costs.multi_step.rms, d),
        length_text(d.final_model.costs.multi_step.rms, d),
        length_text(d.track_noise, d)
    ));
    if let Some(u) = &d.units {
        s.push_str(&format!("units: {}\n", u.text));
    }
    s.push_str(&format!("verdict: {}\n", d.verdict.text));
    s
}

/// A value with four decimals, or `not measured` where it is not finite (no NaN or inf in
/// a report).
pub fn number(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4}")
    } else {
        "not measured".into()
    }
}

/// The verdict as a Markdown section body: explained or not, and where the residual lives.
pub fn verdict(d: &Diagnosis) -> String {
    let v = &d.verdict;
    let mut chars = v.text.chars();
    let text: String = chars
        .next()
        .map(|c| c.to_uppercase().chain(chars).collect())
        .unwrap_or_default();
    let mut s = format!("**{text}.**\n");
    if !v.explained && !v.particles.is_empty() {
        s.push('\n');
        let rows: Vec<Vec<String>> = v
            .particles
            .iter()
            .map(|p| {
                vec![
                    p.particle.clone(),
                    number(p.rms),
                    format!("{:.1}", p.rms_over_noise),
                ]
            })
            .collect();
        s.push_str(&report::markdown_table(
            &["particle", "final multi-step RMS, px", "over the noise"],
            &rows,
        ));
    }
    s.push_str(&format!(
        "\nThe search stopped after {} round(s): {}.\n",
        d.search.rounds, d.search.stop_reason
    ));
    for r in &d.replaced {
        s.push_str(&format!(
            "- {} (accepted in round {}) was taken out in round {}{}.\n",
            r.label,
            r.added_round,
            r.round,
            if let Some(reason) = &r.reason {
                format!(": {reason}")
            } else if r.by.is_empty() {
                ": the effects that joined after it made it redundant".to_string()
            } else {
                format!(", replaced by {}", r.by.join(" and "))
            }
        ));
    }
    for u in &d.undecided {
        s.push_str(&format!("- **Not enough data**: {}.\n", u.text));
    }
    s
}

/// How much of the held-out cost a finding removed, as a percentage, when both are known.
fn improvement(before: Option<f64>, after: Option<f64>) -> String {
    match (before, after) {
        (Some(b), Some(a)) if b > 0.0 => format!("{:.1} %", 100.0 * (b - a) / b),
        _ => "-".into(),
    }
}

/// The findings table (effect, values, where seen, held-out costs, score) and the rejected
/// candidates, as Markdown.
pub fn findings(d: &Diagnosis) -> String {
    let mut s = String::new();
    if d.findings.is_empty() {
        s.push_str(
            "Nothing added: no candidate effect explained enough of the held-out frames to pay for \
             its parameters.\n",
        );
    } else {
        let rows: Vec<Vec<String>> = d
            .findings
            .iter()
            .map(|f| {
                let e = &f.evidence;
                vec![
                    f.label.clone(),
                    values_text(f).join("; "),
                    f.seen.text.clone(),
                    e.held_out_cost_before.map_or("-".into(), |v| format!("{v:.4}")),
                    e.held_out_cost_after.map_or("-".into(), |v| format!("{v:.4}")),
                    improvement(e.held_out_cost_before, e.held_out_cost_after),
                    e.score.map_or("-".into(), |v| format!("{v:.1}")),
                    f.inclusion_rate
                        .map_or("-".into(), |v| format!("{:.0} %", 100.0 * v)),
                ]
            })
            .collect();
        s.push_str(&report::markdown_table(
            &[
                "effect",
                "fitted values",
                "where it was seen",
                "held-out cost before, px²",
                "after, px²",
                "held-out improvement",
                "score",
                "inclusion over resampled frames",
            ],
            &rows,
        ));
        for f in &d.findings {
            if let Some(t) = &f.evidence.transfer {
                s.push_str(&format!(
                    "\n- {}, judged from other start states: {}.",
                    f.label, t.text
                ));
            }
            if let Some(note) = &f.note {
                s.push_str(&format!(
                    "\n- {}{}: {note}.",
                    f.label,
                    if f.identified { "" } else { " (not identified)" }
                ));
            }
        }
        s.push('\n');
    }
    if !d.rejected.is_empty() {
        s.push_str(
            "\nCandidates that did not earn their place (screened in the weak form and by the score \
             test; the best verified by multi-step fits, accepted only with a positive score):\n\n",
        );
        let num = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.1}"));
        let rows: Vec<Vec<String>> = d
            .rejected
            .iter()
            .map(|r| {
                vec![
                    r.label.clone(),
                    r.round.to_string(),
                    num(r.evidence.screen_score),
                    num(r.evidence.score_test),
                    num(r.evidence.score),
                ]
            })
            .collect();
        s.push_str(&report::markdown_table(
            &["candidate", "round", "screen score", "score test", "score"],
            &rows,
        ));
        for r in &d.rejected {
            if let Some(reason) = &r.reason {
                s.push_str(&format!("\n- rejected: {} {reason}.", r.label));
            }
        }
        if d.rejected.iter().any(|r| r.reason.is_some()) {
            s.push('\n');
        }
    }
    s
}

/// How many seeds of the search found each finding, as Markdown.
pub fn stability(st: &physfit_identify::diagnose::Stability) -> String {
    let n = st.seeds.len();
    let mut s = format!(
        "{} with {n} seeds ({}):\n\n",
        if st.same_findings {
            "The same findings"
        } else {
            "Findings that depend on the seed"
        },
        st.seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")
    );
    for f in &st.findings {
        s.push_str(&format!("- {}: found with {} of {n} seeds\n", f.label, f.seeds));
    }
    for f in &st.elsewhere {
        s.push_str(&format!(
            "- {}: not found with this seed, found with {} of the other {}\n",
            f.label,
            f.seeds,
            n - 1
        ));
    }
    s
}

/// Where the base model disagreed with the tracks, as a Markdown list.
pub fn localisation(d: &Diagnosis) -> String {
    let mut s = String::new();
    for line in &d.localisation.summary {
        s.push_str(&format!("- {line}\n"));
    }
    if s.is_empty() {
        s.push_str("- every residual is within the track noise.\n");
    }
    s
}

/// The one-step and multi-step costs of the base and diagnosed models over the whole sequence.
pub fn costs(d: &Diagnosis) -> String {
    let row = |name: &str, m: &physfit_identify::diagnose::ModelSummary| {
        vec![
            name.to_string(),
            if m.effects.is_empty() {
                "-".to_string()
            } else {
                m.effects.join(", ")
            },
            m.parameter_count.to_string(),
            number(m.costs.one_step),
            number(m.costs.multi_step.sum_squares),
            number(m.costs.multi_step.rms),
        ]
    };
    report::markdown_table(
        &[
            "model",
            "effects",
            "parameters",
            "one-step, px²",
            "multi-step, px²",
            "multi-step RMS, px",
        ],
        &[row("base", &d.base), row("diagnosed", &d.final_model)],
    )
}

/// The units paragraph of a report: the scale and the mass unit of the SI values, or that
/// values are in px because no scale was given.
pub fn units_line(d: &Diagnosis) -> String {
    match &d.units {
        Some(u) => format!("Units: {}; values are rounded to their standard error.\n\n", u.text),
        None => "Units: px, s and the structure's mass unit (no scale given: `[recording] metres_per_px` or `--scale` adds SI values); values are rounded to their standard error.\n\n".into(),
    }
}

/// `report.md` of `physfit diagnose`.
pub fn markdown(d: &Diagnosis, pictures: &str) -> String {
    let mut s = format!("# physfit diagnosis: {}\n\n", d.structure);
    s.push_str(&format!(
        "Frames {}..{} analysed; track noise {} per coordinate; {:.1} s.\n\n",
        d.window[0],
        d.window[1],
        length_text(d.track_noise, d),
        d.seconds
    ));
    s.push_str(&units_line(d));
    s.push_str("## Verdict\n\n");
    s.push_str(&verdict(d));
    s.push_str("\n## Findings\n\n");
    s.push_str(&findings(d));
    if let Some(st) = &d.stability {
        s.push_str("\n## Other seeds of the search\n\n");
        s.push_str(&stability(st));
    }
    s.push_str("\n## Where the base model disagreed\n\n");
    s.push_str(&localisation(d));
    s.push_str("\n## Costs over the whole sequence\n\n");
    s.push_str(&costs(d));
    for w in &d.warnings {
        s.push_str(&format!("\n- warning: {w}"));
    }
    s.push_str("\n\n## Pictures\n\n");
    s.push_str(pictures);
    s
}
