//! The diagnosis repeated with other seeds of its search (which blocks of frames are held
//! out, the noise replicas): a finding that comes and goes with the seed rests on the choice
//! of frames, not on the recording.

use rayon::prelude::*;

use super::report::{Diagnosis, SeedAgreement, Stability};
use super::{diagnose_observations, DiagnoseOptions};
use crate::{IdentifyError, Observations};
use physfit_model::Scene;
use physfit_tracks::TrackTable;

/// Diagnoses `tracks` again with the `count - 1` seeds after `options.seed` and records in
/// `first` (the diagnosis at `options.seed`) how many of the `count` seeds found each of its
/// findings, and what the others found that it did not. Findings are compared by label (a
/// wall by how many walls were found).
pub fn check_seeds(
    structure: &Scene,
    tracks: &TrackTable,
    options: &DiagnoseOptions,
    count: usize,
    first: &mut Diagnosis,
) -> Result<(), IdentifyError> {
    if count < 2 {
        return Ok(());
    }
    let sequence = &Observations::from_tracks(tracks, structure, None)?;
    let seeds: Vec<u64> = (0..count as u64).map(|i| options.seed.wrapping_add(i)).collect();
    let others: Vec<Vec<String>> = seeds[1..]
        .par_iter()
        .map(|&seed| {
            let o = DiagnoseOptions {
                seed,
                ..options.clone()
            };
            diagnose_observations(structure, sequence, &o, &()).map(|d| labels(&d))
        })
        .collect::<Result<_, _>>()?;
    first.stability = Some(agreement(seeds, &labels(first), &others));
    Ok(())
}

/// Labels of a diagnosis's findings, a wall's numbered by its order (`wall`, `wall 2`, ...).
fn labels(d: &Diagnosis) -> Vec<String> {
    let mut walls = 0;
    d.findings
        .iter()
        .map(|f| {
            if f.effect == "wall" {
                walls += 1;
                if walls > 1 {
                    return format!("{} {walls}", f.label);
                }
            }
            f.label.clone()
        })
        .collect()
}

/// The agreement of `first`'s labels with `others'`, over `seeds` (first's seed first).
fn agreement(seeds: Vec<u64>, first: &[String], others: &[Vec<String>]) -> Stability {
    let count_of = |label: &String| 1 + others.iter().filter(|o| o.contains(label)).count();
    let findings: Vec<SeedAgreement> = first
        .iter()
        .map(|l| SeedAgreement {
            label: l.clone(),
            seeds: count_of(l),
        })
        .collect();
    let mut elsewhere: Vec<SeedAgreement> = Vec::new();
    for label in others.iter().flatten() {
        if !first.contains(label) && !elsewhere.iter().any(|e| &e.label == label) {
            elsewhere.push(SeedAgreement {
                label: label.clone(),
                seeds: others.iter().filter(|o| o.contains(label)).count(),
            });
        }
    }
    let same = findings.iter().all(|f| f.seeds == seeds.len()) && elsewhere.is_empty();
    Stability {
        seeds,
        findings,
        elsewhere,
        same_findings: same,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn l(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn agreement_counts_each_finding_over_the_seeds_and_names_the_others() {
        let s = agreement(
            vec![1, 2, 3],
            &l(&["uniform field (gravity)", "wall"]),
            &[
                l(&["uniform field (gravity)", "wall"]),
                l(&["uniform field (gravity)", "linear drag"]),
            ],
        );
        assert_eq!(s.findings[0].seeds, 3);
        assert_eq!(s.findings[1].seeds, 2);
        assert_eq!(s.elsewhere.len(), 1);
        assert_eq!(s.elsewhere[0].label, "linear drag");
        assert_eq!(s.elsewhere[0].seeds, 1);
        assert!(!s.same_findings);
    }

    #[test]
    fn identical_findings_are_the_same_findings() {
        let s = agreement(vec![4, 5], &l(&["wall", "wall 2"]), &[l(&["wall", "wall 2"])]);
        assert!(s.same_findings);
        assert!(s.findings.iter().all(|f| f.seeds == 2));
    }
}
