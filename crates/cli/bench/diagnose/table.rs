//! The Markdown report of `physfit bench diagnose`: rates per concealed class, per effect,
//! and one line per recording not diagnosed exactly right.

use std::collections::BTreeMap;
use std::fmt::Write;

use physfit_tracks::stats::median;

use super::draw::Kind;
use super::score::{Detectability, DETECTABLE, MARGINAL};
use super::{BenchOptions, RecordingResult};

/// The median of `values` (`None` when empty).
fn median_of(values: &mut [f64]) -> Option<f64> {
    (!values.is_empty()).then(|| median(values))
}

/// `k` of `n` as a whole percentage (`-` when `n` is 0).
fn percent(k: usize, n: usize) -> String {
    if n == 0 {
        "-".into()
    } else {
        format!("{:.0} %", 100.0 * k as f64 / n as f64)
    }
}

/// One row of the class table.
fn class_row(label: &str, rows: &[&RecordingResult]) -> String {
    let n = rows.len();
    let count = |pred: &dyn Fn(&RecordingResult) -> bool| rows.iter().filter(|r| pred(r)).count();
    let judged = |pred: &dyn Fn(&super::score::Judgement) -> bool| {
        count(&|r: &RecordingResult| r.judgement.as_ref().is_some_and(pred))
    };
    let mut times: Vec<f64> = rows
        .iter()
        .filter(|r| r.judgement.is_some())
        .map(|r| r.times.diagnose)
        .collect();
    format!(
        "| {label} | {n} | {} | {} | {} | {} | {} | {} | {} |\n",
        percent(judged(&|j| j.exactly_right), n),
        percent(judged(&|j| j.missed), n),
        percent(judged(&|j| j.falsely_added), n),
        percent(judged(&|j| j.unsure), n),
        percent(judged(&|j| !j.exactly_right && !j.unsure), n),
        count(&|r| r.judgement.is_none()),
        median_of(&mut times).map_or("-".into(), |t| format!("{t:.1}")),
    )
}

/// The class table: none, each single effect, each pair seen, then the totals.
fn class_table(results: &[RecordingResult]) -> String {
    let mut out = String::from(
        "| concealed | recordings | exactly right | missed | falsely added | unsure | wrong, called explained | failed to run | median diagnosis (s) |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mut by_class: BTreeMap<(usize, String), Vec<&RecordingResult>> = BTreeMap::new();
    for r in results {
        by_class
            .entry((r.effect_count, r.class.clone()))
            .or_default()
            .push(r);
    }
    for ((_, class), rows) in &by_class {
        let label = if class.is_empty() { "(not drawn)" } else { class };
        out.push_str(&class_row(label, rows));
    }
    for (count, label) in [(1, "**one effect**"), (2, "**two effects**")] {
        let rows: Vec<&RecordingResult> = results.iter().filter(|r| r.effect_count == count).collect();
        out.push_str(&class_row(label, &rows));
    }
    let all: Vec<&RecordingResult> = results.iter().collect();
    out.push_str(&class_row("**all**", &all));
    out
}

/// The effect table: how often each class was concealed, how detectable, how often found,
/// and the median error of what was found.
fn effect_table(results: &[RecordingResult]) -> String {
    let mut out = String::from(
        "| effect | concealed | detectable | marginal | undetectable | found, detectable | found, marginal | found, undetectable | median errors (found, detectable) |\n|---|---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for kind in Kind::ALL {
        let effects: Vec<_> = results
            .iter()
            .filter_map(|r| r.judgement.as_ref())
            .flat_map(|j| j.effects.iter())
            .filter(|e| e.concealed.kind() == kind)
            .collect();
        let of = |d: Detectability| effects.iter().filter(|e| e.detectability == d).count();
        let found = |d: Detectability| {
            let n = of(d);
            let k = effects
                .iter()
                .filter(|e| e.detectability == d && e.found.is_some())
                .count();
            if n == 0 {
                "-".into()
            } else {
                format!("{k}/{n}")
            }
        };
        // Each named error's median over the detectable effects found, in order.
        let mut named: Vec<(&str, &str, Vec<f64>)> = Vec::new();
        for e in effects
            .iter()
            .filter(|e| e.detectability == Detectability::Detectable)
        {
            for x in &e.errors {
                match named.iter_mut().find(|(name, _, _)| *name == x.name) {
                    Some((_, _, values)) => values.push(x.value),
                    None => named.push((x.name, x.unit, vec![x.value])),
                }
            }
        }
        let error = named
            .iter_mut()
            .filter_map(|(name, unit, values)| {
                median_of(values).map(|m| match *unit {
                    "relative" => format!("{name} {:.2} %", 100.0 * m),
                    "px" => format!("{name} {m:.2} px"),
                    _ => format!("{name} {m:.3}"),
                })
            })
            .collect::<Vec<_>>()
            .join(", ");
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            kind.name(),
            effects.len(),
            of(Detectability::Detectable),
            of(Detectability::Marginal),
            of(Detectability::Undetectable),
            found(Detectability::Detectable),
            found(Detectability::Marginal),
            found(Detectability::Undetectable),
            if error.is_empty() { "-" } else { &error },
        );
    }
    out
}

/// The command that reproduces recording `seed`.
fn command(seed: u64, small: bool) -> String {
    format!(
        "physfit bench diagnose --seed {seed} --count 1{}",
        if small { " --small" } else { "" }
    )
}

/// One line for a recording not diagnosed exactly right.
fn failure_line(r: &RecordingResult, small: bool) -> String {
    let mut s = format!("- seed {} (`{}`): ", r.seed, command(r.seed, small));
    let Some(j) = &r.judgement else {
        let _ = write!(
            s,
            "{}: {}",
            if r.class.is_empty() { "not drawn" } else { &r.class },
            r.error.as_deref().unwrap_or("no result")
        );
        return s;
    };
    let concealed: Vec<String> = j
        .effects
        .iter()
        .map(|e| {
            format!(
                "{} [{}, {:.1} noises{}]",
                e.concealed.describe(),
                e.detectability.name(),
                e.ratio,
                match (&e.found, e.undecided) {
                    (Some(_), _) if e.errors.is_empty() => ", found".to_string(),
                    (Some(_), _) => format!(
                        ", found: {}",
                        e.errors
                            .iter()
                            .map(|x| x.text.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                    (None, true) => ", undecided".to_string(),
                    (None, false) => ", not found".to_string(),
                }
            )
        })
        .collect();
    let list = |v: &[String]| {
        if v.is_empty() {
            "nothing".to_string()
        } else {
            v.join(", ")
        }
    };
    let _ = write!(s, "concealed {}; found {}", list(&concealed), list(&j.found));
    if !j.false_additions.is_empty() {
        let _ = write!(s, "; falsely added {}", j.false_additions.join(", "));
    }
    if !j.undecided.is_empty() {
        let _ = write!(s, "; undecided {}", j.undecided.join(", "));
    }
    let _ = write!(s, "; verdict \"{}\"", j.verdict);
    if let Some(regime) = &r.regime {
        let _ = write!(s, "; {}, position noise {:.3} px", regime.describe(), j.noise);
    }
    s
}

/// One progress line: seed, class, result, diagnosis time.
pub fn progress_line(r: &RecordingResult) -> String {
    let status = match &r.judgement {
        None => format!("failed: {}", r.error.as_deref().unwrap_or("no result")),
        Some(j) if j.exactly_right => "exactly right".to_string(),
        Some(j) => {
            let mut parts = Vec::new();
            if j.missed {
                parts.push("missed");
            }
            if j.falsely_added {
                parts.push("falsely added");
            }
            if j.unsure {
                parts.push("unsure");
            }
            parts.join(", ")
        }
    };
    let found = r
        .judgement
        .as_ref()
        .map_or(String::new(), |j| format!(" (found: {})", j.found.join(", ")));
    format!(
        "seed {}: {}: {status}{found}; diagnosis {:.1} s",
        r.seed,
        if r.class.is_empty() { "-" } else { &r.class },
        r.times.diagnose
    )
}

/// The whole report: the class table, the effect table and the failure lines.
pub fn markdown(options: &BenchOptions, results: &[RecordingResult], elapsed: f64) -> String {
    let mut out = String::new();
    let last = options
        .first_seed
        .wrapping_add(results.len().saturating_sub(1) as u64);
    let _ = writeln!(
        out,
        "### Diagnosis benchmark: {} random recordings, seeds {}..={}{}\n",
        results.len(),
        options.first_seed,
        last,
        if options.small {
            " (small: at most 4 particles, 150 frames)"
        } else {
            ""
        }
    );
    if results.len() < options.count {
        let _ = writeln!(
            out,
            "Stopped after {} of the {} recordings asked for (time limit).\n",
            results.len(),
            options.count
        );
    }
    let _ = writeln!(
        out,
        "An effect is demanded (detectable) when leaving it out moves the best-fitting simulation more than {DETECTABLE} position noises RMS from the true centres, may be found or not (marginal) from {MARGINAL} to {DETECTABLE}, and is undetectable below. *Exactly right*: every detectable effect found and nothing added that was not concealed. *Unsure*: the verdict says \"not explained\" or some finding is undecided (\"not enough data\"). Total time {:.1} min.\n",
        elapsed / 60.0
    );
    out.push_str(&class_table(results));
    out.push('\n');
    out.push_str(&effect_table(results));
    out.push('\n');
    out.push_str(&time_table(results));
    out.push('\n');
    out.push_str(&inclusion_line(results));
    if options.search_seeds > 1 {
        let checked: Vec<&super::Stability> = results.iter().filter_map(|r| r.stability.as_ref()).collect();
        let same = checked.iter().filter(|s| s.same_findings).count();
        let _ = writeln!(
            out,
            "Same findings for all {} search seeds: {same} of {} recordings ({}).",
            options.search_seeds,
            checked.len(),
            percent(same, checked.len())
        );
    }
    let failures: Vec<&RecordingResult> = results.iter().filter(|r| !r.exactly_right()).collect();
    let _ = writeln!(out, "\n#### Not exactly right ({})\n", failures.len());
    for r in failures {
        out.push_str(&failure_line(r, options.small));
        out.push('\n');
    }
    out
}

/// The findings' inclusion rates over resampled frames, right findings against false
/// additions: how many, their median and how many fall below one half.
fn inclusion_line(results: &[RecordingResult]) -> String {
    let gather = |pick: &dyn Fn(&super::score::Judgement) -> &Vec<f64>| -> Vec<f64> {
        results
            .iter()
            .filter_map(|r| r.judgement.as_ref())
            .flat_map(|j| pick(j).iter().copied())
            .collect()
    };
    let describe = |mut rates: Vec<f64>| {
        let below = rates.iter().filter(|&&r| r < 0.5).count();
        let n = rates.len();
        format!(
            "{n} (median {}, {below} below 50 %)",
            median_of(&mut rates).map_or("-".into(), |m| format!("{:.0} %", 100.0 * m))
        )
    };
    format!(
        "Inclusion over resampled frames: right findings {}, false additions {}.\n",
        describe(gather(&|j| &j.inclusion_right)),
        describe(gather(&|j| &j.inclusion_false))
    )
}

/// Particle counts and frame counts grouping the diagnosis times.
const TIME_PARTICLES: [(usize, usize); 3] = [(1, 3), (4, 6), (7, 10)];
const TIME_FRAMES: [(usize, usize); 3] = [(10, 99), (100, 299), (300, 600)];

/// Diagnosis time by recording size: count, median and longest per cell (issue 21's target:
/// a 300-frame, 5-particle recording in under 10 s).
fn time_table(results: &[RecordingResult]) -> String {
    let mut out = String::from(
        "Diagnosis time by recording size (recordings: median / longest, s; under 10 s):\n\n| particles |",
    );
    for (lo, hi) in TIME_FRAMES {
        let _ = write!(out, " {lo}-{hi} frames |");
    }
    out.push_str("\n|---|");
    for _ in TIME_FRAMES {
        out.push_str("---:|");
    }
    out.push('\n');
    for (plo, phi) in TIME_PARTICLES {
        let _ = write!(out, "| {plo}-{phi} |");
        for (flo, fhi) in TIME_FRAMES {
            let mut times: Vec<f64> = results
                .iter()
                .filter(|r| r.error.is_none())
                .filter_map(|r| {
                    let g = r.regime.as_ref()?;
                    ((plo..=phi).contains(&g.particles) && (flo..=fhi).contains(&g.frames))
                        .then_some(r.times.diagnose)
                })
                .collect();
            let n = times.len();
            let under = times.iter().filter(|&&t| t < 10.0).count();
            let longest = times.iter().copied().fold(f64::NAN, f64::max);
            match median_of(&mut times) {
                Some(m) => {
                    let _ = write!(out, " {n}: {m:.1} / {longest:.1}; {under} of {n} |");
                }
                None => out.push_str(" - |"),
            }
        }
        out.push('\n');
    }
    out
}
