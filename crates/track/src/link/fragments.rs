//! A named particle found as two blobs in one frame.
//!
//! A faint, broad particle (a disc of 1.5 px blurred by 2.5 px, 15 grey levels over noise
//! 5.5) can rise above the noise as two peaks more than a radius apart; the locator splits
//! its light between their windows, and each centroid sits on one half. The track takes one
//! half, 2.5 px off the particle's centre (fresh style 8321, frame 12: halves of mass 513
//! and 465 where one particle's is 780), and the other half is left to nobody. With a
//! structure every particle is tracked, so a blob no track takes, within two radii of a blob
//! one track takes, where both are light (each between a quarter and three quarters of one
//! particle's mass) and together weigh one particle (their mass in particles' rounds to one), is the rest of that particle:
//! the track's point is the two blobs' joint centroid (their mass-weighted mean, 0.15 px
//! from 8321's centre). Without a structure an untaken blob may be a particle of its own,
//! and nothing is joined.

use super::claimants::Claimants;
use super::single_particle::SingleParticle;
use crate::locate::Detection;
use crate::point_grid::PointGrid;

/// Least and largest share of one particle's mass a fragment holds.
const FRAGMENT_SHARE: [f64; 2] = [0.25, 0.75];

/// The detections of a frame (`dets`, claimed as `claims` says) that are each taken by one
/// track and have the rest of their particle in an untaken blob nearby (see the module
/// documentation), each as `(taken detection, joined detection)`; `predictions` are the live
/// tracks' predicted positions, px, indexed as the claims' tracks (a fragment within `radius`
/// px of another track's prediction may be that particle, and is left alone), `radius` the
/// radius in use, px.
pub(super) fn join_fragments(
    dets: &[Detection],
    claims: &[Claimants],
    predictions: &[[f64; 2]],
    one: &SingleParticle,
    radius: f64,
) -> Vec<(usize, Detection)> {
    if !(one.mass.is_finite() && one.mass > 0.0) {
        return Vec::new();
    }
    let light = |m: f64| m >= FRAGMENT_SHARE[0] * one.mass && m <= FRAGMENT_SHARE[1] * one.mass;
    let untaken: Vec<usize> = (0..dets.len())
        .filter(|&j| claims[j].is_empty() && light(dets[j].mass) && !dets[j].clipped)
        .collect();
    if untaken.is_empty() {
        return Vec::new();
    }
    let points: Vec<[f64; 2]> = untaken.iter().map(|&j| [dets[j].x, dets[j].y]).collect();
    let grid = PointGrid::new(&points);
    let mut used = vec![false; untaken.len()];
    let mut joined = Vec::new();
    for (j, d) in dets.iter().enumerate() {
        if claims[j].len() != 1 || !light(d.mass) || d.clipped {
            continue;
        }
        let mut best: Option<(usize, f64)> = None;
        grid.within(&[d.x, d.y], 2.0 * radius, |f, d2| {
            let frag = &dets[untaken[f]];
            let total = d.mass + frag.mass;
            // Together one particle, by their mass rounded (the halves' windows overlap, and
            // each holds its own noise: fresh 8426's weighed 0.70 and 0.62 of one).
            let whole = one.capacity(total) == 1;
            if !used[f] && whole && best.map_or(true, |b| d2 < b.1) {
                best = Some((f, d2));
            }
        });
        let Some((f, _)) = best else { continue };
        let frag = &dets[untaken[f]];
        let taker = claims[j][0];
        let near_other = (predictions.iter().enumerate())
            .any(|(k, p)| k != taker && (p[0] - frag.x).hypot(p[1] - frag.y) < radius);
        if near_other {
            continue;
        }
        used[f] = true;
        let total = d.mass + frag.mass;
        let (a, b) = (d.mass / total, frag.mass / total);
        let apart = (d.x - frag.x).hypot(d.y - frag.y);
        joined.push((
            j,
            Detection {
                x: a * d.x + b * frag.x,
                y: a * d.y + b * frag.y,
                mass: total,
                // The joint light's spread: each half's about its own centre plus the halves'
                // distance from the joint one.
                size: (a * d.size * d.size + b * frag.size * frag.size + a * b * apart * apart).sqrt(),
                // The joint centroid's error from each half's.
                ep: (a * a * d.ep * d.ep + b * b * frag.ep * frag.ep).sqrt(),
                follow: a * d.follow + b * frag.follow,
                area: d.area + frag.area,
                clipped: false,
            },
        ));
    }
    joined
}

#[cfg(test)]
mod tests {
    use super::super::link_detections::link_detections;
    use super::super::options::{FrameDetections, LinkOptions};
    use crate::locate::Detection;
    use crate::track_table::PointFlag;

    /// A detection of `mass` at `(x, y)` (one particle's mass is 100).
    fn det(x: f64, y: f64, mass: f64) -> Detection {
        Detection {
            x,
            y,
            mass,
            size: 2.0,
            ep: 0.05,
            follow: 0.0,
            area: 12.0,
            clipped: false,
        }
    }

    /// Three particles of radius 3 px moving right by 1 px a frame for 8 frames, their masses
    /// 100 give or take 30 (faint particles' masses scatter); in frame `split` the first is
    /// found as `pieces` instead (and the others as themselves).
    fn frames(split: usize, pieces: &[Detection]) -> Vec<FrameDetections> {
        let mass = |k: usize, i: usize| 100.0 * (1.0 + 0.3 * (1.7 * k as f64 + 2.1 * i as f64).sin());
        (0..8)
            .map(|k| {
                let x = 20.0 + k as f64;
                let mut detections = vec![det(x, 60.0, mass(k, 1)), det(x, 20.0, mass(k, 2))];
                if k == split {
                    detections.extend_from_slice(pieces);
                } else {
                    detections.push(det(x, 40.0, mass(k, 0)));
                }
                FrameDetections { frame: k, detections }
            })
            .collect()
    }

    fn options(named: bool) -> LinkOptions {
        LinkOptions {
            named_start: named.then(|| {
                vec![
                    ("a".to_string(), [20.0, 40.0]),
                    ("b".to_string(), [20.0, 60.0]),
                    ("c".to_string(), [20.0, 20.0]),
                ]
            }),
            radius: 3.0,
            width: 100,
            height: 100,
            memory: 3,
        }
    }

    fn point_of(
        frames: &[FrameDetections],
        named: bool,
        particle: &str,
        frame: usize,
    ) -> (f64, f64, PointFlag) {
        let out = link_detections(frames, &options(named));
        let p = out
            .table
            .points
            .iter()
            .find(|p| p.particle == particle && p.frame == frame)
            .unwrap_or_else(|| panic!("{particle} in frame {frame}: {:?}", out.table.points));
        (p.x, p.y, p.flag)
    }

    /// A named particle found as two light halves 5 px apart is placed at their joint
    /// centroid, in a later frame and in the first; without a structure the half it took
    /// stays where it was found.
    #[test]
    fn a_named_particle_found_as_two_halves_is_placed_between_them() {
        let halves = [det(24.0, 37.4, 55.0), det(24.0, 43.0, 50.0)];
        let joint = (37.4 * 55.0 + 43.0 * 50.0) / 105.0;
        let (x, y, flag) = point_of(&frames(4, &halves), true, "a", 4);
        assert_eq!(flag, PointFlag::Detected);
        assert!((x - 24.0).abs() < 1e-9 && (y - joint).abs() < 1e-9, "({x}, {y})");
        // In the first frame, about the start.
        let first = [det(20.0, 37.4, 55.0), det(20.0, 43.0, 50.0)];
        let (_, y, _) = point_of(&frames(0, &first), true, "a", 0);
        assert!((y - joint).abs() < 1e-9, "first frame: {y}");
        // Unnamed: one half is the track's.
        let out = link_detections(&frames(4, &halves), &options(false));
        let at_4: Vec<f64> = (out.table.points.iter())
            .filter(|p| p.frame == 4 && (p.y - 40.0).abs() < 5.0)
            .map(|p| p.y)
            .collect();
        assert!(
            at_4.iter()
                .all(|y| (y - 37.4).abs() < 1e-9 || (y - 43.0).abs() < 1e-9),
            "{at_4:?}"
        );
    }

    /// Not joined: a speck (a fifth of a particle) beside a particle found whole, an untaken
    /// blob of a whole particle's mass beside a light one, and halves farther apart than two
    /// radii.
    #[test]
    fn specks_whole_blobs_and_far_blobs_are_not_joined() {
        let speck = [det(24.0, 40.0, 95.0), det(24.0, 43.5, 20.0)];
        let (_, y, _) = point_of(&frames(4, &speck), true, "a", 4);
        assert!((y - 40.0).abs() < 1e-9, "speck joined: {y}");
        let whole = [det(24.0, 38.0, 60.0), det(24.0, 43.0, 100.0)];
        let (_, y, _) = point_of(&frames(4, &whole), true, "a", 4);
        assert!(
            (y - 38.0).abs() < 1e-9 || (y - 43.0).abs() < 1e-9,
            "whole blob joined: {y}"
        );
        let far = [det(24.0, 37.0, 55.0), det(24.0, 44.5, 50.0)];
        let (_, y, _) = point_of(&frames(4, &far), true, "a", 4);
        assert!(
            (y - 37.0).abs() < 1e-9 || (y - 44.5).abs() < 1e-9,
            "far halves joined: {y}"
        );
    }
}
