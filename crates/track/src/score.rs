//! Scoring tracks against ground truth: recall, precision, localisation error and
//! identity switches.
//!
//! In each frame, track points and truth points are matched one to one by optimal
//! assignment (minimum total squared distance), pairs farther apart than the match radius
//! not allowed. An identity switch is counted each time the track matched to a truth
//! particle differs from the track matched to it the previous time it was matched (the
//! IDSW count of the CLEAR MOT metrics, Bernardin & Stiefelhagen 2008).

use std::collections::{BTreeMap, HashMap, HashSet};

use crate::assignment::{solve_sparse, SparseProblem};
use crate::track_table::{PointFlag, TrackTable};

/// How well a track table matches the truth.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TrackScore {
    /// Frames scored (truth frames within the tracked range).
    pub frame_count: usize,
    /// Truth points in the scored frames.
    pub truth_count: usize,
    /// Track points in the scored frames.
    pub track_count: usize,
    /// Matched pairs.
    pub matched_count: usize,
    /// Matched pairs whose track point was bridged or split rather than detected.
    pub matched_bridged_count: usize,
    /// Fraction of truth points matched (0..1).
    pub recall: f64,
    /// Fraction of track points matched (0..1).
    pub precision: f64,
    /// Root mean square x error over matched pairs, px.
    pub rms_x: f64,
    /// Root mean square y error over matched pairs, px.
    pub rms_y: f64,
    /// Root mean square x error over matched detected (not bridged or split) points, px.
    pub rms_x_detected: f64,
    /// Root mean square y error over matched detected points, px.
    pub rms_y_detected: f64,
    /// Largest distance of a matched pair, px.
    pub max_error: f64,
    /// Identity switches (see the module doc).
    pub id_switches: usize,
    /// When tracks are named after truth particles: matched pairs whose names differ.
    pub name_mismatches: Option<usize>,
    /// The match radius used, px.
    pub match_radius: f64,
}

/// Scores `tracks` against `truth` (both `frame,particle,x,y`); pairs farther than
/// `match_radius` px never match. Truth frames outside the first to last frame of
/// `tracks` are not scored.
pub fn score_tracks(tracks: &TrackTable, truth: &TrackTable, match_radius: f64) -> TrackScore {
    let lo = tracks.points.iter().map(|p| p.frame).min().unwrap_or(0);
    let hi = tracks.points.iter().map(|p| p.frame).max().unwrap_or(0);
    let mut by_frame: BTreeMap<usize, (Vec<usize>, Vec<usize>)> = BTreeMap::new();
    for (i, p) in truth.points.iter().enumerate() {
        if !tracks.points.is_empty() && (lo..=hi).contains(&p.frame) {
            by_frame.entry(p.frame).or_default().0.push(i);
        }
    }
    for (i, p) in tracks.points.iter().enumerate() {
        if let Some(e) = by_frame.get_mut(&p.frame) {
            e.1.push(i);
        }
    }
    let truth_names: HashSet<&str> = truth.points.iter().map(|p| p.particle.as_str()).collect();
    let named = tracks
        .points
        .iter()
        .any(|p| truth_names.contains(p.particle.as_str()));
    let r2 = match_radius * match_radius;
    let mut s = TrackScore {
        frame_count: by_frame.len(),
        truth_count: 0,
        track_count: 0,
        matched_count: 0,
        matched_bridged_count: 0,
        recall: 0.0,
        precision: 0.0,
        rms_x: 0.0,
        rms_y: 0.0,
        rms_x_detected: 0.0,
        rms_y_detected: 0.0,
        max_error: 0.0,
        id_switches: 0,
        name_mismatches: named.then_some(0),
        match_radius,
    };
    let (mut sx, mut sy, mut dx2, mut dy2, mut nd) = (0.0, 0.0, 0.0, 0.0, 0usize);
    let mut last_match: HashMap<&str, &str> = HashMap::new();
    for (tr, tk) in by_frame.values() {
        s.truth_count += tr.len();
        s.track_count += tk.len();
        let mut problem = SparseProblem {
            pairs: Vec::new(),
            row_miss: vec![r2; tr.len()],
            col_miss: vec![r2; tk.len()],
        };
        for (a, &i) in tr.iter().enumerate() {
            let t = &truth.points[i];
            for (b, &j) in tk.iter().enumerate() {
                let k = &tracks.points[j];
                let d2 = (t.x - k.x).powi(2) + (t.y - k.y).powi(2);
                if d2 <= r2 {
                    problem.pairs.push((a, b, d2));
                }
            }
        }
        for (a, m) in solve_sparse(&problem).into_iter().enumerate() {
            let Some(b) = m else { continue };
            let t = &truth.points[tr[a]];
            let k = &tracks.points[tk[b]];
            let (ex, ey) = (k.x - t.x, k.y - t.y);
            s.matched_count += 1;
            sx += ex * ex;
            sy += ey * ey;
            s.max_error = s.max_error.max(ex.hypot(ey));
            if k.flag == PointFlag::Detected {
                dx2 += ex * ex;
                dy2 += ey * ey;
                nd += 1;
            } else {
                s.matched_bridged_count += 1;
            }
            if let Some(prev) = last_match.insert(t.particle.as_str(), k.particle.as_str()) {
                if prev != k.particle {
                    s.id_switches += 1;
                }
            }
            if let Some(n) = &mut s.name_mismatches {
                *n += usize::from(t.particle != k.particle);
            }
        }
    }
    let m = s.matched_count.max(1) as f64;
    s.rms_x = (sx / m).sqrt();
    s.rms_y = (sy / m).sqrt();
    s.rms_x_detected = (dx2 / nd.max(1) as f64).sqrt();
    s.rms_y_detected = (dy2 / nd.max(1) as f64).sqrt();
    s.recall = s.matched_count as f64 / s.truth_count.max(1) as f64;
    s.precision = s.matched_count as f64 / s.track_count.max(1) as f64;
    s
}

impl TrackScore {
    /// The score as a two-column Markdown table.
    pub fn to_markdown(&self) -> String {
        let mut rows: Vec<(String, String)> = vec![
            ("frames scored".to_string(), self.frame_count.to_string()),
            (
                "recall".into(),
                format!(
                    "{:.4} ({} of {} truth points)",
                    self.recall, self.matched_count, self.truth_count
                ),
            ),
            (
                "precision".into(),
                format!("{:.4} ({} track points)", self.precision, self.track_count),
            ),
        ];
        // Errors are only measured on matched points: with none, there is nothing to show.
        let detected = self.matched_count - self.matched_bridged_count;
        let none = |what: &str| format!("none: no {what} matched a truth point");
        let error = |v: f64, n: usize, what: &str| if n == 0 { none(what) } else { format!("{v:.4}") };
        rows.extend([
            (
                "RMS error x, px".into(),
                error(self.rms_x, self.matched_count, "track point"),
            ),
            (
                "RMS error y, px".into(),
                error(self.rms_y, self.matched_count, "track point"),
            ),
            (
                "RMS error x, detected points only, px".into(),
                error(self.rms_x_detected, detected, "detected point"),
            ),
            (
                "RMS error y, detected points only, px".into(),
                error(self.rms_y_detected, detected, "detected point"),
            ),
            (
                "largest error, px".into(),
                if self.matched_count == 0 {
                    none("track point")
                } else {
                    format!("{:.3}", self.max_error)
                },
            ),
            (
                "matched points bridged or split".into(),
                self.matched_bridged_count.to_string(),
            ),
            ("identity switches".into(), self.id_switches.to_string()),
        ]);
        if let Some(n) = self.name_mismatches {
            rows.push(("points named after the wrong particle".into(), n.to_string()));
        }
        rows.push(("match radius, px".into(), format!("{}", self.match_radius)));
        let mut out = String::from("| measure | value |\n| --- | --- |\n");
        for (k, v) in rows {
            out.push_str(&format!("| {k} | {v} |\n"));
        }
        out
    }
}

impl std::fmt::Display for TrackScore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.to_markdown())
    }
}

/// RMS offset per axis, px, of the points of `to` from those of `from` with the same frame
/// and particle, over the points of `from` that `to` has; zero where none has a partner.
/// (What a table of intensity centroids leans from the true centres of the points scored.)
pub fn rms_offset(from: &TrackTable, to: &TrackTable) -> [f64; 2] {
    let at: HashMap<(usize, &str), [f64; 2]> = to
        .points
        .iter()
        .map(|p| ((p.frame, p.particle.as_str()), [p.x, p.y]))
        .collect();
    let mut sum = [0.0; 2];
    let mut n = 0usize;
    for p in &from.points {
        if let Some(c) = at.get(&(p.frame, p.particle.as_str())) {
            sum[0] += (c[0] - p.x).powi(2);
            sum[1] += (c[1] - p.y).powi(2);
            n += 1;
        }
    }
    sum.map(|s| (s / n.max(1) as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track_table::TrackPoint;

    #[test]
    fn the_offset_is_taken_over_the_points_both_tables_hold() {
        let from = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 0.0, 0.0),
                TrackPoint::new(1, "a", 1.0, 0.0),
                TrackPoint::new(1, "b", 5.0, 5.0),
            ],
        };
        let to = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 0.3, -0.4),
                TrackPoint::new(1, "a", 0.9, 0.0),
                // Not in `from`: left out.
                TrackPoint::new(2, "a", 9.0, 9.0),
            ],
        };
        let [x, y] = rms_offset(&from, &to);
        assert!((x - ((0.09 + 0.01) / 2.0f64).sqrt()).abs() < 1e-12, "{x}");
        assert!((y - (0.16 / 2.0f64).sqrt()).abs() < 1e-12, "{y}");
        assert!(rms_offset(&TrackTable::default(), &to)
            .iter()
            .all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn no_error_is_printed_when_nothing_matched() {
        let truth = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 0.0, 0.0),
                TrackPoint::new(1, "a", 1.0, 0.0),
            ],
        };
        let far = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 50.0, 0.0),
                TrackPoint::new(1, "a", 51.0, 0.0),
            ],
        };
        let score = score_tracks(&far, &truth, 3.0);
        assert_eq!(score.matched_count, 0);
        let md = score.to_markdown();
        assert!(
            md.contains("| RMS error x, px | none: no track point matched a truth point |"),
            "{md}"
        );
        assert!(
            md.contains("| largest error, px | none: no track point matched a truth point |"),
            "{md}"
        );
        assert!(
            !md.lines().any(|l| l.contains("error") && l.contains("0.0")),
            "{md}"
        );
        let near = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 0.5, 0.0),
                TrackPoint::new(1, "a", 1.5, 0.0),
            ],
        };
        let md = score_tracks(&near, &truth, 3.0).to_markdown();
        assert!(md.contains("| RMS error x, px | 0.5000 |"), "{md}");
    }

    #[test]
    fn counts_a_swap_and_errors() {
        let truth = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 0.0, 0.0),
                TrackPoint::new(0, "b", 10.0, 0.0),
                TrackPoint::new(1, "a", 1.0, 0.0),
                TrackPoint::new(1, "b", 11.0, 0.0),
            ],
        };
        let tracks = TrackTable {
            points: vec![
                TrackPoint::new(0, "0", 0.1, 0.0),
                TrackPoint::new(0, "1", 10.0, 0.2),
                TrackPoint::new(1, "1", 1.1, 0.0),
                TrackPoint::new(1, "0", 11.0, 0.2),
                TrackPoint::new(1, "2", 50.0, 50.0),
            ],
        };
        let s = score_tracks(&tracks, &truth, 2.0);
        assert_eq!(s.id_switches, 2);
        assert_eq!(s.matched_count, 4);
        assert!((s.recall - 1.0).abs() < 1e-12);
        assert!((s.precision - 0.8).abs() < 1e-12);
        assert!((s.rms_x - (0.01f64 * 2.0 / 4.0).sqrt()).abs() < 1e-12);
        assert!((s.rms_y - (0.04f64 * 2.0 / 4.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.name_mismatches, None);
    }
}
