//! The diagnosis in words: the plain-text summary printed by the binary and the Markdown
//! sections of `report.md` (shared by `physfit diagnose` and `physfit run`).

use physfit_identify::diagnose::{Diagnosis, FittedValue};

use crate::report;

/// One fitted value with its standard error and unit, e.g. `drag = 0.301 ± 2.1e-3 1/s`.
pub fn value_text(v: &FittedValue) -> String {
    match v.std_error {
        Some(e) => format!("{} = {:.6} ± {:.2e} {}", v.name, v.value, e, v.unit),
        None => format!("{} = {:.6} {}", v.name, v.value, v.unit),
    }
}

/// A plain-text account: each finding with its values, and the costs before and after.
pub fn summary(d: &Diagnosis) -> String {
    let mut s = String::new();
    if d.findings.is_empty() {
        s.push_str("no missing physics found: the structure explains the tracks to the noise level\n");
    }
    for f in &d.findings {
        let values: Vec<String> = f.parameters.iter().map(value_text).collect();
        s.push_str(&format!(
            "found {}: {}\n  seen: {}\n",
            f.label,
            values.join(", "),
            f.seen.text
        ));
    }
    s.push_str(&format!(
        "multi-step RMS over the sequence: base {:.4} px, diagnosed {:.4} px (track noise {:.4} px)\n",
        d.base.costs.multi_step.rms, d.final_model.costs.multi_step.rms, d.track_noise
    ));
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
             its parameters; the structure explains the tracks to the noise level.\n",
        );
    } else {
        let rows: Vec<Vec<String>> = d
            .findings
            .iter()
            .map(|f| {
                let e = &f.evidence;
                vec![
                    f.label.clone(),
                    f.parameters.iter().map(value_text).collect::<Vec<_>>().join("; "),
                    f.seen.text.clone(),
                    e.held_out_cost_before.map_or("-".into(), |v| format!("{v:.4}")),
                    e.held_out_cost_after.map_or("-".into(), |v| format!("{v:.4}")),
                    improvement(e.held_out_cost_before, e.held_out_cost_after),
                    e.score.map_or("-".into(), |v| format!("{v:.1}")),
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
            ],
            &rows,
        ));
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
            format!("{:.4}", m.costs.one_step),
            format!("{:.4}", m.costs.multi_step.sum_squares),
            format!("{:.4}", m.costs.multi_step.rms),
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

/// `report.md` of `physfit diagnose`.
pub fn markdown(d: &Diagnosis, pictures: &str) -> String {
    let mut s = format!("# physfit diagnosis: {}\n\n", d.structure);
    s.push_str(&format!(
        "Frames {}..{} analysed; track noise {:.4} px per coordinate; {:.1} s.\n\n## Findings\n\n",
        d.window[0], d.window[1], d.track_noise, d.seconds
    ));
    s.push_str(&findings(d));
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
