//! Supports: runs of frames where a particle does not accelerate along a uniform field that
//! acts on it everywhere else (a ball rolling on a shelf before it falls, resting on a floor).
//!
//! A support is a contact force (a shelf, a table, a hand) that the model crate cannot
//! simulate: it is not a candidate effect but a statement about the recording, reported in the
//! localisation, and its frames are left out of the smooth analysis (as bounces are). When a
//! support holds a particle from the first analysed frame, the diagnosis analyses the frames
//! from its release on (a simulation started on the shelf would fall through it).
//!
//! The test, per free particle and frame gap `k` (frames `k - 1, k, k + 1` tracked and not
//! around a bounce): the observed acceleration `a = (x[k+1] - 2 x[k] + x[k-1]) fps^2` minus the
//! structure's forces (a rough model's, its field removed) is the acceleration `a_free` that
//! external forces cause. With `g` the rough model's field and `s` the acceleration noise
//! scale (the larger of `sqrt(6) sigma fps^2` for track noise `sigma` and a robust spread of
//! the rough model's acceleration residuals), frame gap `k` is supported when the field is
//! significant (`|g| > SUPPORT_THRESHOLD s`), the particle does not accelerate along it
//! (`|a_free . g/|g|| <= 3 s`) and the model's field is rejected there
//! (`|g| - a_free . g/|g| > SUPPORT_THRESHOLD s`). At least [`MIN_SUPPORT_GAPS`] consecutive
//! supported gaps `k0..=k1` make a support over frames `k0 - 1 ..= k1 + 1`.

use physfit_model::Vec2;
use serde::Serialize;

use crate::Observations;

/// Significance (in acceleration noise scales) a field and its rejection must reach.
pub const SUPPORT_THRESHOLD: f64 = 5.0;

/// Least consecutive supported frame gaps that make a support.
pub const MIN_SUPPORT_GAPS: usize = 2;

/// A run of frames in which a particle is held against a uniform field.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Support {
    /// Particle id.
    pub particle: String,
    /// First and last frames held (absolute, inclusive).
    pub frames: [usize; 2],
    /// Mean observed acceleration beyond the structure's forces in those frames, px/s².
    pub observed_acceleration: [f64; 2],
    /// The field the rest of the recording shows, px/s².
    pub field: [f64; 2],
    /// Noise of the mean acceleration along the field over the run, px/s².
    pub noise: f64,
    /// In words.
    pub text: String,
}

/// The supports in `obs` (see the module doc). `acc[k][p]` is the rough model's acceleration
/// (structure plus the field `field`, px/s²) at frame offset `k`; `excluded[k]` marks frames
/// around bounces.
pub fn find_supports(
    obs: &Observations,
    acc: &[Option<Vec<Vec2>>],
    field: Vec2,
    excluded: &[bool],
) -> Vec<Support> {
    let fps = obs.fps;
    let frames = obs.frame_count();
    let g = field.norm();
    if frames < 3 || g.is_nan() || g <= 0.0 {
        return Vec::new();
    }
    let down = field / g;
    // Per particle and gap: the acceleration beyond the structure's forces.
    let mut free: Vec<Vec<Option<Vec2>>> = vec![vec![None; frames]; obs.particle_count()];
    let mut residuals = Vec::new();
    for (p, series) in free.iter_mut().enumerate() {
        if obs.fixed[p] {
            continue;
        }
        for k in 1..frames - 1 {
            if excluded[k - 1] || excluded[k] || excluded[k + 1] {
                continue;
            }
            let (Some(a), Some(b), Some(c)) = (
                obs.positions[k - 1][p],
                obs.positions[k][p],
                obs.positions[k + 1][p],
            ) else {
                continue;
            };
            let Some(model) = acc.get(k).and_then(|f| f.as_ref()).and_then(|f| f.get(p)) else {
                continue;
            };
            let observed = (a - b * 2.0 + c) * (fps * fps);
            let r = observed - model;
            residuals.push(r.x.abs());
            residuals.push(r.y.abs());
            series[k] = Some(observed - model + field);
        }
    }
    if residuals.is_empty() {
        return Vec::new();
    }
    residuals.sort_by(|a, b| a.total_cmp(b));
    let robust = 1.4826 * residuals[residuals.len() / 2];
    let scale = (6f64.sqrt() * obs.noise * fps * fps)
        .max(robust)
        .max(f64::MIN_POSITIVE);
    // A gap nearer to no acceleration along the field than to the field is a candidate.
    let candidate = |a: Vec2| a.dot(&down) < g / 3.0;
    let mut out = Vec::new();
    for (p, series) in free.iter().enumerate() {
        let mut k = 1;
        while k + 1 < frames {
            if !series[k].is_some_and(candidate) {
                k += 1;
                continue;
            }
            let k0 = k;
            while k + 1 < frames && series[k].is_some_and(candidate) {
                k += 1;
            }
            let k1 = k - 1;
            let n = k1 + 1 - k0;
            if n >= MIN_SUPPORT_GAPS {
                let run: Vec<Vec2> = (k0..=k1).filter_map(|j| series[j]).collect();
                let mean = run.iter().sum::<Vec2>() / run.len() as f64;
                let along = mean.dot(&down);
                let mean_noise = scale / (n as f64).sqrt();
                if along.abs() > 3.0 * mean_noise || g - along <= SUPPORT_THRESHOLD * mean_noise {
                    continue;
                }
                let first = obs.first_frame + k0 - 1;
                let last = obs.first_frame + k1 + 1;
                let id = &obs.particle_ids[p];
                out.push(Support {
                    particle: id.clone(),
                    frames: [first, last],
                    observed_acceleration: [mean.x, mean.y],
                    field: [field.x, field.y],
                    noise: mean_noise,
                    text: format!(
                        "{id} is supported in frames {first}-{last}: its acceleration along the field is {:.0} px/s^2 (noise {:.0}) where the rest of the recording shows {:.0} px/s^2 towards {:.0} degrees; a contact the model cannot simulate holds it",
                        along,
                        mean_noise,
                        g,
                        down.y.atan2(down.x).to_degrees()
                    ),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball on a shelf for frames 0..=3, then falling at 900 px/s² (30 fps).
    fn shelf(noise_free_frames: usize) -> (Observations, Vec<Option<Vec<Vec2>>>) {
        let fps = 30.0;
        let g = 900.0;
        let positions: Vec<Vec<Option<Vec2>>> = (0..noise_free_frames)
            .map(|k| {
                let t = k as f64 / fps;
                let fall = if k <= 3 {
                    0.0
                } else {
                    let tf = t - 3.0 / fps;
                    0.5 * g * tf * tf
                };
                vec![Some(Vec2::new(20.0 + 90.0 * t, 16.0 + fall))]
            })
            .collect();
        let obs = Observations::from_positions(vec!["ball".into()], vec![false], fps, 0, positions);
        let acc = vec![Some(vec![Vec2::new(0.0, g)]); noise_free_frames];
        (obs, acc)
    }

    #[test]
    fn a_ball_on_a_shelf_is_supported_until_it_falls() {
        let (obs, acc) = shelf(20);
        let s = find_supports(&obs, &acc, Vec2::new(0.0, 900.0), &[false; 20]);
        assert_eq!(s.len(), 1, "{s:?}");
        assert_eq!(s[0].frames, [0, 3]);
        assert!(s[0].observed_acceleration[1].abs() < 1e-6);
        assert!(s[0].text.contains("frames 0-3"), "{}", s[0].text);
    }

    #[test]
    fn a_falling_ball_is_not_supported() {
        let (obs, acc) = shelf(20);
        let falling = obs.restrict(4, 19).unwrap_or_else(|e| panic!("{e}"));
        let s = find_supports(&falling, &acc[4..], Vec2::new(0.0, 900.0), &[false; 16]);
        assert!(s.is_empty(), "{s:?}");
    }

    #[test]
    fn no_field_means_no_support() {
        let (obs, acc) = shelf(20);
        let zero = vec![Some(vec![Vec2::zeros()]); 20];
        let _ = acc;
        assert!(find_supports(&obs, &zero, Vec2::zeros(), &[false; 20]).is_empty());
    }

    #[test]
    fn bounce_frames_are_not_tested() {
        let (obs, acc) = shelf(20);
        let mut excluded = [false; 20];
        excluded[..3].iter_mut().for_each(|e| *e = true);
        assert!(find_supports(&obs, &acc, Vec2::new(0.0, 900.0), &excluded).is_empty());
    }
}
