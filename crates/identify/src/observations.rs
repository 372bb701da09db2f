//! [`Observations`]: the tracked positions of a structure's particles over the analysed frames,
//! with velocity estimates and the measured position noise.
//!
//! Velocities are estimated by local polynomial (Savitzky-Golay) fits: at each frame, a cubic in
//! time is fitted by least squares to the particle's [`VELOCITY_FIT_POINTS`] nearest tracked
//! frames (fewer near gaps and ends, with the degree lowered to keep the fit determined), and its
//! derivative is the velocity. At an interior frame with no gap this is the 7-point cubic
//! Savitzky-Golay derivative `(22 x[-3] - 67 x[-2] - 58 x[-1] + 58 x[1] + 67 x[2] - 22 x[3]) / 252`
//! per frame, whose noise is `0.51 sigma fps` for independent position noise `sigma`.
//!
//! The position noise `sigma` (px, per coordinate) is measured from the tracks themselves: the
//! residual of a cubic fitted to five consecutive frames is proportional to the fourth difference
//! `x[-2] - 4 x[-1] + 6 x[0] - 4 x[1] + x[2]`, whose variance is `70 sigma^2` for white noise; a
//! median over all tracks and both coordinates (robust to the few frames where the motion itself
//! is not cubic) gives `sigma`. On noise-free data it measures how far the motion departs from a
//! local cubic, so it is an upper bound of the noise, never zero by assumption.

use physfit_model::{Recording, Scene, State, Vec2};
use physfit_tracks::stats::median;
use physfit_tracks::TrackTable;

use crate::IdentifyError;

/// Tracked frames used by each local velocity fit.
pub(crate) const VELOCITY_FIT_POINTS: usize = 7;

/// Positions (px) and estimated velocities (px/s) of every structure particle over the analysed
/// frames `first_frame ..= last_frame()`, with gaps as `None`.
#[derive(Clone, Debug, PartialEq)]
pub struct Observations {
    /// Particle ids, in structure order (`ParticleId(k)` is `particle_ids[k]`).
    pub particle_ids: Vec<String>,
    /// True for the structure's pinned particles.
    pub fixed: Vec<bool>,
    /// Frames per second of the recording; frame `k` is at `t = k / fps`.
    pub fps: f64,
    /// Frame index of `positions[0]` (the first analysed frame `A`).
    pub first_frame: usize,
    /// `positions[k][p]`: position of particle `p` at frame `first_frame + k`, px.
    pub positions: Vec<Vec<Option<Vec2>>>,
    /// `velocities[k][p]`: estimated velocity, px/s (local polynomial fit; see the module doc).
    pub velocities: Vec<Vec<Option<Vec2>>>,
    /// Measured position noise, px per coordinate (see the module doc).
    pub noise: f64,
    /// Standard deviation of an interior velocity estimate due to `noise`, px/s.
    pub velocity_noise: f64,
    /// What was noticed and worked around (gaps, duplicate points, untracked pinned particles).
    pub warnings: Vec<String>,
}

/// The warning that rows of tracks `structure_ids` does not name are left out, naming each
/// such track (the first 12) and its row count; `None` when every row is named.
fn unnamed_rows_warning(
    by_name: &std::collections::BTreeMap<&str, Vec<&physfit_tracks::TrackPoint>>,
    structure_ids: &[String],
) -> Option<String> {
    let unnamed: Vec<(&str, usize)> = by_name
        .iter()
        .filter(|(name, _)| !structure_ids.iter().any(|id| id == *name))
        .map(|(name, rows)| (*name, rows.len()))
        .collect();
    if unnamed.is_empty() {
        return None;
    }
    let rows: usize = unnamed.iter().map(|(_, n)| n).sum();
    let mut listed: Vec<String> = unnamed
        .iter()
        .take(12)
        .map(|(name, n)| format!("\"{name}\" ({n} row{})", if *n == 1 { "" } else { "s" }))
        .collect();
    if unnamed.len() > 12 {
        listed.push(format!("and {} more", unnamed.len() - 12));
    }
    Some(format!(
        "{rows} rows of {} tracks the structure does not name were left out: {}",
        unnamed.len(),
        listed.join(", ")
    ))
}

impl Observations {
    /// The observations of `structure`'s particles in `tracks`, over the analysed window
    /// `window = (A, B)` (inclusive frame indices; all tracked frames when `None`).
    ///
    /// Tracks are matched to particles by name. A free particle with no track is an error naming
    /// it; a pinned one with no track stays at its structure position (with a warning). Gaps are
    /// kept as `None` and listed in [`Observations::warnings`]; velocities near them use the
    /// frames that are there. Velocities are estimated over all tracked frames, then cut to the
    /// window, so the window's ends get centred estimates where the data allow.
    pub fn from_tracks(
        tracks: &TrackTable,
        structure: &Scene,
        window: Option<(usize, usize)>,
    ) -> Result<Observations, IdentifyError> {
        let ids: Vec<String> = structure.particles.iter().map(|p| p.id.clone()).collect();
        let n = ids.len();
        let by_name = tracks.by_particle();
        let mut warnings = Vec::new();
        warnings.extend(unnamed_rows_warning(&by_name, &ids));
        let mut start = usize::MAX;
        let mut end = 0;
        for id in &ids {
            if let Some(points) = by_name.get(id.as_str()) {
                for p in points {
                    if !(p.x.is_finite() && p.y.is_finite()) {
                        return Err(IdentifyError::NonFinite {
                            frame: p.frame,
                            particle: id.clone(),
                            x: p.x,
                            y: p.y,
                        });
                    }
                    start = start.min(p.frame);
                    end = end.max(p.frame + 1);
                }
            }
        }
        for (k, id) in ids.iter().enumerate() {
            if !by_name.contains_key(id.as_str()) && !structure.particles[k].fixed {
                let mut names: Vec<&str> = by_name.keys().copied().collect();
                names.truncate(12);
                let available = if names.is_empty() {
                    "no track at all".to_string()
                } else {
                    format!(
                        "tracks {}",
                        names
                            .iter()
                            .map(|s| format!("\"{s}\""))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                return Err(IdentifyError::MissingTrack {
                    particle: id.clone(),
                    available,
                });
            }
        }
        if start >= end {
            // Only untracked pinned particles: nothing moves, nothing to analyse.
            return Err(IdentifyError::TooFewFrames {
                method: "identification".into(),
                need: 3,
                have: 0,
            });
        }
        let frames = end - start;
        let mut positions = vec![vec![None; n]; frames];
        for (k, id) in ids.iter().enumerate() {
            match by_name.get(id.as_str()) {
                Some(points) => {
                    let mut duplicates = 0;
                    for p in points {
                        let slot = &mut positions[p.frame - start][k];
                        if slot.is_some() {
                            duplicates += 1;
                        } else {
                            *slot = Some(Vec2::new(p.x, p.y));
                        }
                    }
                    if duplicates > 0 {
                        warnings.push(format!(
                            "particle \"{id}\" has {duplicates} frame(s) with more than one track point; the first of each is used"
                        ));
                    }
                }
                None => {
                    warnings.push(format!(
                        "pinned particle \"{id}\" has no track; its structure position is used in every frame"
                    ));
                    let x = structure.particles[k].position;
                    for f in positions.iter_mut() {
                        f[k] = Some(x);
                    }
                }
            }
        }
        let fixed: Vec<bool> = structure.particles.iter().map(|p| p.fixed).collect();
        let mut obs = Observations::from_positions(ids, fixed, structure.recording.fps, start, positions);
        obs.warnings.splice(0..0, warnings);
        match window {
            None => Ok(obs),
            Some((a, b)) => {
                if a > b || a < start || b >= end {
                    return Err(IdentifyError::BadWindow {
                        first: a,
                        last: b,
                        start,
                        end,
                    });
                }
                obs.restrict(a, b)
            }
        }
    }

    /// Observations from complete positions (`positions[k][p]`, frame `first_frame + k`, gaps as
    /// `None`): estimates velocities and noise and lists the gaps.
    pub fn from_positions(
        particle_ids: Vec<String>,
        fixed: Vec<bool>,
        fps: f64,
        first_frame: usize,
        positions: Vec<Vec<Option<Vec2>>>,
    ) -> Observations {
        let n = particle_ids.len();
        let frames = positions.len();
        let mut velocities = vec![vec![None; n]; frames];
        let mut fourth_differences = Vec::new();
        for p in 0..n {
            let track: Vec<Option<Vec2>> = positions.iter().map(|f| f[p]).collect();
            for k in 0..frames {
                if fixed[p] {
                    velocities[k][p] = track[k].map(|_| Vec2::zeros());
                } else if track[k].is_some() {
                    velocities[k][p] = local_velocity(&track, k, fps);
                }
                if k + 4 < frames && !fixed[p] {
                    if let [Some(a), Some(b), Some(c), Some(d), Some(e)] =
                        [track[k], track[k + 1], track[k + 2], track[k + 3], track[k + 4]]
                    {
                        let d4 = a - b * 4.0 + c * 6.0 - d * 4.0 + e;
                        fourth_differences.push(d4.x.abs());
                        fourth_differences.push(d4.y.abs());
                    }
                }
            }
        }
        let noise = if fourth_differences.is_empty() {
            0.0
        } else {
            median(&mut fourth_differences) / (0.674_489_75 * 70f64.sqrt())
        };
        let velocity_noise = noise * fps * interior_velocity_gain();
        let mut obs = Observations {
            particle_ids,
            fixed,
            fps,
            first_frame,
            positions,
            velocities,
            noise,
            velocity_noise,
            warnings: Vec::new(),
        };
        obs.warnings = obs.gap_warnings();
        obs
    }

    /// Exact observations of a simulated recording (positions and the simulator's own
    /// velocities), frames `first_frame ..` of it; the noise is measured as for tracks.
    pub fn from_recording(recording: &Recording, structure: &Scene, first_frame: usize) -> Observations {
        let ids = structure.particles.iter().map(|p| p.id.clone()).collect();
        let fixed = structure.particles.iter().map(|p| p.fixed).collect();
        let frames = recording.frame_count().saturating_sub(first_frame);
        let positions = (0..frames)
            .map(|k| {
                recording
                    .frame(first_frame + k)
                    .iter()
                    .map(|&x| Some(x))
                    .collect()
            })
            .collect();
        let mut obs =
            Observations::from_positions(ids, fixed, structure.recording.fps, first_frame, positions);
        for k in 0..frames {
            let s = recording.state(first_frame + k);
            obs.velocities[k] = s.velocities.into_iter().map(Some).collect();
        }
        obs
    }

    /// Number of analysed frames.
    pub fn frame_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.particle_ids.len()
    }

    /// The last analysed frame `B` (inclusive).
    pub fn last_frame(&self) -> usize {
        self.first_frame + self.frame_count().saturating_sub(1)
    }

    /// Time between frames, s.
    pub fn frame_dt(&self) -> f64 {
        1.0 / self.fps
    }

    /// Returns true if and only if every particle's position and velocity are known at offset `k`.
    pub fn is_complete(&self, k: usize) -> bool {
        self.positions[k].iter().all(Option::is_some) && self.velocities[k].iter().all(Option::is_some)
    }

    /// Number of frames where every particle is tracked.
    pub fn complete_frame_count(&self) -> usize {
        (0..self.frame_count()).filter(|&k| self.is_complete(k)).count()
    }

    /// The observed state (positions and estimated velocities) at offset `k`, if complete.
    pub fn state(&self, k: usize) -> Option<State> {
        let x: Option<Vec<Vec2>> = self.positions[k].iter().copied().collect();
        let v: Option<Vec<Vec2>> = self.velocities[k].iter().copied().collect();
        Some(State::new(x?, v?))
    }

    /// Errors with [`IdentifyError::TooFewFrames`] unless at least `need` frames are complete.
    pub fn require_frames(&self, method: &str, need: usize) -> Result<(), IdentifyError> {
        let have = self.complete_frame_count();
        if have < need {
            return Err(IdentifyError::TooFewFrames {
                method: method.to_string(),
                need,
                have,
            });
        }
        Ok(())
    }

    /// The sub-window of frames `first ..= last` (absolute indices), keeping the velocities
    /// estimated on the longer sequence.
    pub fn restrict(&self, first: usize, last: usize) -> Result<Observations, IdentifyError> {
        if first > last || first < self.first_frame || last > self.last_frame() {
            return Err(IdentifyError::BadWindow {
                first,
                last,
                start: self.first_frame,
                end: self.last_frame() + 1,
            });
        }
        let r = first - self.first_frame..last - self.first_frame + 1;
        let mut out = Observations {
            particle_ids: self.particle_ids.clone(),
            fixed: self.fixed.clone(),
            fps: self.fps,
            first_frame: first,
            positions: self.positions[r.clone()].to_vec(),
            velocities: self.velocities[r].to_vec(),
            noise: self.noise,
            velocity_noise: self.velocity_noise,
            warnings: Vec::new(),
        };
        let gaps = out.gap_warnings();
        out.warnings = self
            .warnings
            .iter()
            .filter(|w| !w.contains("missing in frames"))
            .cloned()
            .collect();
        out.warnings.extend(gaps);
        Ok(out)
    }

    /// One warning per particle with gaps, naming the particle and its missing frames.
    fn gap_warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (p, id) in self.particle_ids.iter().enumerate() {
            let missing: Vec<usize> = (0..self.frame_count())
                .filter(|&k| self.positions[k][p].is_none())
                .map(|k| k + self.first_frame)
                .collect();
            if missing.is_empty() {
                continue;
            }
            out.push(format!(
                "particle \"{id}\" is missing in frames {} ({} frame(s)); terms needing it there are left out",
                frame_ranges(&missing),
                missing.len()
            ));
        }
        out
    }
}

/// `1, 2, 3, 7` as `1-3, 7`.
fn frame_ranges(frames: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut k = 0;
    while k < frames.len() {
        let mut e = k;
        while e + 1 < frames.len() && frames[e + 1] == frames[e] + 1 {
            e += 1;
        }
        parts.push(if e == k {
            frames[k].to_string()
        } else {
            format!("{}-{}", frames[k], frames[e])
        });
        if parts.len() == 20 && e + 1 < frames.len() {
            parts.push("...".into());
            break;
        }
        k = e + 1;
    }
    parts.join(", ")
}

/// `sqrt(sum c_i^2)` of the interior 7-point cubic derivative filter (per frame).
fn interior_velocity_gain() -> f64 {
    let c = [-22.0f64, 67.0, 58.0];
    (2.0 * c.iter().map(|x| x * x).sum::<f64>()).sqrt() / 252.0
}

/// Velocity at index `k` of `track` (px/s) from a local polynomial fit (see the module doc).
fn local_velocity(track: &[Option<Vec2>], k: usize, fps: f64) -> Option<Vec2> {
    // The nearest tracked frames, by distance in time, up to VELOCITY_FIT_POINTS of them.
    let mut picked: Vec<usize> = Vec::with_capacity(VELOCITY_FIT_POINTS);
    let reach = 2 * VELOCITY_FIT_POINTS;
    for d in 0..=reach {
        for j in [k.checked_sub(d), if d > 0 { Some(k + d) } else { None }]
            .into_iter()
            .flatten()
        {
            if j < track.len() && track[j].is_some() && picked.len() < VELOCITY_FIT_POINTS {
                picked.push(j);
            }
        }
        if picked.len() == VELOCITY_FIT_POINTS {
            break;
        }
    }
    if picked.len() < 2 {
        return None;
    }
    let degree = (picked.len() - 1).min(3);
    let cols = degree + 1;
    // Least squares in the time offset tau (frames) from k; the velocity is the tau^1 coefficient.
    let mut ata = nalgebra::DMatrix::<f64>::zeros(cols, cols);
    let mut atb = nalgebra::DMatrix::<f64>::zeros(cols, 2);
    for &j in &picked {
        let tau = j as f64 - k as f64;
        let x = track[j]?;
        let mut row = [0.0; 4];
        let mut pw = 1.0;
        for r in row.iter_mut().take(cols) {
            *r = pw;
            pw *= tau;
        }
        for a in 0..cols {
            for b in 0..cols {
                ata[(a, b)] += row[a] * row[b];
            }
            atb[(a, 0)] += row[a] * x.x;
            atb[(a, 1)] += row[a] * x.y;
        }
    }
    let sol = ata.cholesky()?.solve(&atb);
    Some(Vec2::new(sol[(1, 0)], sol[(1, 1)]) * fps)
}

#[cfg(test)]
mod tests {
    use super::*;
    use physfit_tracks::TrackPoint;

    fn scene() -> Scene {
        Scene::from_toml_str(
            r#"
            [recording]
            fps = 50.0
            frames = 20
            [[particles]]
            id = "a"
            mass = 1.0
            position = [0.0, 0.0]
            [[particles]]
            id = "b"
            mass = 1.0
            position = [10.0, 0.0]
            [[springs]]
            between = ["a", "b"]
            "#,
            "t.toml",
        )
        .unwrap()
    }

    #[test]
    fn missing_track_names_the_particle() {
        let t = TrackTable {
            points: (0..10).map(|k| TrackPoint::new(k, "a", k as f64, 0.0)).collect(),
        };
        let e = Observations::from_tracks(&t, &scene(), None).unwrap_err();
        assert!(
            matches!(&e, IdentifyError::MissingTrack { particle, .. } if particle == "b"),
            "{e}"
        );
        assert!(e.to_string().contains("\"b\""), "{e}");
    }

    #[test]
    fn non_finite_position_names_frame_and_particle() {
        let mut points: Vec<TrackPoint> = (0..10).map(|k| TrackPoint::new(k, "a", k as f64, 0.0)).collect();
        points.extend((0..10).map(|k| TrackPoint::new(k, "b", 10.0, if k == 4 { f64::NAN } else { 0.0 })));
        let e = Observations::from_tracks(&TrackTable { points }, &scene(), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame 4") && e.contains("\"b\""), "{e}");
    }

    #[test]
    fn gaps_are_warnings_naming_particle_and_frames() {
        let mut points: Vec<TrackPoint> = (0..20).map(|k| TrackPoint::new(k, "a", k as f64, 0.0)).collect();
        points.extend(
            (0..20)
                .filter(|k| !(5..=7).contains(k))
                .map(|k| TrackPoint::new(k, "b", 10.0, 0.0)),
        );
        let o = Observations::from_tracks(&TrackTable { points }, &scene(), None).unwrap();
        assert_eq!(o.frame_count(), 20);
        assert!(o.positions[6][1].is_none());
        assert!(
            o.warnings
                .iter()
                .any(|w| w.contains("\"b\"") && w.contains("5-7")),
            "{:?}",
            o.warnings
        );
        assert_eq!(o.complete_frame_count(), 17);
        // Velocities next to the gap still come from the frames that are there.
        assert!((o.velocities[4][0].unwrap().x - 50.0).abs() < 1e-9);
        assert!(o.velocities[4][1].unwrap().norm() < 1e-9);
    }

    #[test]
    fn velocity_of_a_cubic_is_exact_and_noise_is_measured() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let fps = 30.0;
        let f = |k: usize| {
            let t = k as f64 / fps;
            Vec2::new(3.0 * t * t * t - t + 2.0, 5.0 * t * t)
        };
        let df = |k: usize| {
            let t = k as f64 / fps;
            Vec2::new(9.0 * t * t - 1.0, 10.0 * t)
        };
        let pos: Vec<Vec<Option<Vec2>>> = (0..40).map(|k| vec![Some(f(k))]).collect();
        let o = Observations::from_positions(vec!["a".into()], vec![false], fps, 0, pos);
        for k in [0, 1, 20, 39] {
            assert!((o.velocities[k][0].unwrap() - df(k)).norm() < 1e-8, "frame {k}");
        }
        assert!(o.noise < 1e-9);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let normal = Normal::new(0.0, 0.2).unwrap();
        let pos: Vec<Vec<Option<Vec2>>> = (0..2000)
            .map(|_| vec![Some(Vec2::new(normal.sample(&mut rng), normal.sample(&mut rng)))])
            .collect();
        let o = Observations::from_positions(vec!["a".into()], vec![false], fps, 0, pos);
        assert!((o.noise - 0.2).abs() < 0.02, "noise {}", o.noise);
    }

    #[test]
    fn window_is_cut_and_checked() {
        let mut points: Vec<TrackPoint> = (0..20).map(|k| TrackPoint::new(k, "a", k as f64, 0.0)).collect();
        points.extend((0..20).map(|k| TrackPoint::new(k, "b", 10.0, 0.0)));
        let t = TrackTable { points };
        let o = Observations::from_tracks(&t, &scene(), Some((5, 9))).unwrap();
        assert_eq!((o.first_frame, o.last_frame(), o.frame_count()), (5, 9, 5));
        assert!((o.positions[0][0].unwrap().x - 5.0).abs() < 1e-12);
        let e = Observations::from_tracks(&t, &scene(), Some((5, 30))).unwrap_err();
        assert!(matches!(e, IdentifyError::BadWindow { .. }));
        assert!(matches!(
            o.require_frames("lsq", 8),
            Err(IdentifyError::TooFewFrames { need: 8, have: 5, .. })
        ));
    }
}
