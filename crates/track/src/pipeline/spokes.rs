//! Tracked particles with lines leaving them (drawn springs, a string, a rod; see
//! [`crate::spokes`]), located again with each line and the side opposite it cut out of the
//! centroid window.
//!
//! Lines are looked for about each tracked point in a few of the sample frames; a particle
//! with lines in at least a quarter of those (two at least) is one whose lines stay (a spring
//! drawn from it, its string, seen where it stands out), and each of its detected points in
//! every frame is located again: its lines found about it there, cut out with their
//! opposites, the frame's other detections located with it (their windows share pixels with
//! its own). A point whose frame shows no line keeps its place, and a particle that the cuts
//! move towards its lines as often as away keeps its centroids (named in a warning with the
//! size of the moves). A moved point's error becomes the cut window's where that is larger,
//! with the cuts' own added (about `0.06 / R` px per line cut, see
//! [`crate::spokes::cut_sampling_error`]: a cut crosses the particle's edge); its mass and
//! size stay those of the whole window, which describe the particle's image.

use super::finder::locate_window;
use super::window_frames::ClassFrames;
use crate::locate::refine_centroids_with_cuts;
use crate::point_grid::PointGrid;
use crate::spokes::{cut_sampling_error, mark_pull, spoke_cuts, About, SpokeSearch};
use crate::{Detection, FrameDetections, LocateScratch, PointFlag, TrackError, TrackPoint, TrackTable};
use physfit_tracks::stats::median;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};

/// Sample frames the lines are looked for in, at most: a line that stays is seen in most
/// of any few, and each costs a look about every point (8 frames took 2.3 % of the N = 1000
/// benchmark's instructions, most of it the coarse look).
const SPOKE_FRAMES: usize = 4;

/// A point located again with its lines cut out.
struct Moved {
    /// Its index in the table.
    point: usize,
    /// Where the cut window puts it, px.
    at: [f64; 2],
    /// The cut window's fixed-point error with the cuts' own ([`cut_sampling_error`]), px.
    error: f64,
    /// The sum of its lines' directions (unit vectors, y down): where they pull it.
    pull: [f64; 2],
}

/// What the look about one point in a sample frame found.
struct Look {
    /// Its index in the table.
    point: usize,
    /// Whether lines leave it.
    lines: bool,
    /// How far a mark inside it pulls its centroid, px ([`mark_pull`] over the window's
    /// mass), where one stands out.
    mark: Option<f64>,
}

/// Multiple of a point's own error by which a mark inside it must pull its centroid to
/// count ([`mark_warnings`]).
const MARK_SIGMAS: f64 = 3.0;

/// Warnings naming the particles (the first [`NAMED`] of them, and how many more) whose
/// centroid a mark inside them pulls by over [`MARK_SIGMAS`] times their error in at least
/// half of the sample frames looked at (two at least): a line drawn from the centre for the
/// body's angle, a texture's bump, a highlight. The centroid follows the mark, and the
/// warning gives the median pull over those frames.
fn mark_warnings(looked: &[Vec<Look>], table: &TrackTable) -> Vec<String> {
    let mut by_particle: BTreeMap<&str, (usize, Vec<f64>)> = BTreeMap::new();
    for look in looked.iter().flatten() {
        let p = &table.points[look.point];
        let e = by_particle.entry(p.particle.as_str()).or_default();
        e.0 += 1;
        if let Some(pull) = look.mark.filter(|&m| m > MARK_SIGMAS * p.ep) {
            e.1.push(pull);
        }
    }
    let mut out = Vec::new();
    let mut more = 0;
    for (name, (n, mut pulls)) in by_particle {
        if pulls.len() < 2 || 2 * pulls.len() < n {
            continue;
        }
        if out.len() == NAMED {
            more += 1;
            continue;
        }
        out.push(format!(
            "{name}: a mark inside it (a line drawn for its angle, a texture, a highlight) stands out from its even \
             parts in {} of {n} sample frames looked at and pulls its centroid about {:.3} px (median) off the centre \
             of its outline",
            pulls.len(),
            median(&mut pulls)
        ));
    }
    if more > 0 {
        out.push(format!("{more} more particles with a mark inside them, as above"));
    }
    out
}

/// Particles named in the warning, at most.
const NAMED: usize = 8;

/// What [`mask_spokes`] did.
#[derive(Debug, Default)]
pub(super) struct SpokesMasked {
    /// Points moved by the cuts.
    pub(super) moved: usize,
    /// Warnings naming the particles located so.
    pub(super) warnings: Vec<String>,
}

/// A particle's mean level over its disc of radius `radius` px, from its window's `mass`
/// (grey levels · px²), grey levels: what a sector's deviation is measured against.
fn level_of(mass: f64, radius: f64) -> f64 {
    mass / (std::f64::consts::PI * radius * radius)
}

/// A frame's particles as a spoke search sees its neighbours: the frame's tracked points
/// (px), first, then its detections that are not theirs.
struct FrameNeighbours {
    points: Vec<[f64; 2]>,
}

impl FrameNeighbours {
    /// The tracked points (px) and the detections `found` that are not theirs (farther than
    /// half the radius `radius`, px, from every one).
    fn new(tracked: &[[f64; 2]], found: &[Detection], radius: f64) -> FrameNeighbours {
        let own = PointGrid::new(tracked);
        let mut points = tracked.to_vec();
        points.extend(found.iter().map(|d| [d.x, d.y]).filter(|q| {
            let mut mine = false;
            own.within(q, 0.5 * radius, |_, _| mine = true);
            !mine
        }));
        FrameNeighbours { points }
    }

    /// `f` on the view of `signal` (of `size`, width and height) about `p` (px), its
    /// neighbours those particles (`grid` over them) that a ring search for radius `radius`
    /// (px) reaches, those nearer than half the radius (`p` itself, or its own detection)
    /// left out.
    fn view<R>(
        &self,
        grid: &PointGrid<'_>,
        signal: &[f32],
        size: (usize, usize),
        p: [f64; 2],
        radius: f64,
        f: impl FnOnce(&About<'_>) -> R,
    ) -> R {
        let reach = 2.0 * (locate_window(radius) + 3.0 + 0.25 * radius);
        let mut others = Vec::new();
        grid.within(&p, reach, |j, d2| {
            if d2 > 0.25 * radius * radius {
                others.push(self.points[j]);
            }
        });
        f(&About {
            signal,
            width: size.0,
            height: size.1,
            c: p,
            others: &others,
        })
    }
}

/// Locates again, with their lines cut out (see the module documentation), the detected
/// points of the particles of `table` (not in `hollow`, located by their rims) that have lines
/// leaving them in a quarter of the sample frames looked at; `located` holds each frame's
/// detections (the neighbours whose pixels the search leaves out). A particle's cut positions
/// are kept only where they lead away from its lines ([`leads_away`]): a particle that is not
/// symmetric about its centre where the cuts cross it (pendulum-scale's bob, a square whose
/// string was found, moved by 0.3-0.6 px either way from frame to frame) keeps its
/// centroids.
pub(super) fn mask_spokes(
    table: &mut TrackTable,
    hollow: &BTreeSet<String>,
    located: &[FrameDetections],
    class: &ClassFrames<'_>,
) -> Result<SpokesMasked, TrackError> {
    let ClassFrames {
        frames,
        background,
        radius,
        workers,
    } = *class;
    let noise = background.noise_sigma;
    let found: BTreeMap<usize, &[Detection]> = located
        .iter()
        .map(|f| (f.frame, f.detections.as_slice()))
        .collect();
    let found_in = |k: usize| found.get(&k).copied().unwrap_or(&[]);
    // Each frame's detected points (index into the table), in the frames `keep` keeps.
    let detected_by_frame = |keep: &dyn Fn(&TrackPoint) -> bool| {
        let mut by_frame: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for (i, p) in table.points.iter().enumerate() {
            if p.flag == PointFlag::Detected && keep(p) {
                by_frame.entry(p.frame).or_default().push(i);
            }
        }
        by_frame
    };
    let at = |i: usize| {
        let p = &table.points[i];
        [p.x, p.y, p.mass]
    };
    let chosen = frames.spread_samples(SPOKE_FRAMES);
    let in_chosen = detected_by_frame(&|p| chosen.binary_search(&p.frame).is_ok());
    let search = SpokeSearch::new(radius, locate_window(radius));
    let looked: Vec<Vec<Look>> = in_chosen
        .par_iter()
        .map(|(&k, points)| {
            frames.with_signal(k, background, workers, |signal, width, height| {
                let xy: Vec<[f64; 2]> = points.iter().map(|&i| [at(i)[0], at(i)[1]]).collect();
                let near = FrameNeighbours::new(&xy, found_in(k), radius);
                let grid = PointGrid::new(&near.points);
                points
                    .iter()
                    .filter(|&&i| !hollow.contains(&table.points[i].particle))
                    .map(|&i| {
                        let p = at(i);
                        let level = level_of(p[2], radius);
                        near.view(&grid, signal, (width, height), [p[0], p[1]], radius, |image| {
                            Look {
                                point: i,
                                lines: !search.lines(image, level, noise).is_empty(),
                                mark: mark_pull(image, radius, level, noise).map(|m| m[0].hypot(m[1]) / p[2]),
                            }
                        })
                    })
                    .collect()
            })
        })
        .collect::<Result<_, TrackError>>()?;
    // Frames looked at and frames with lines, by particle.
    let mut seen: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for look in looked.iter().flatten() {
        let e = seen
            .entry(table.points[look.point].particle.as_str())
            .or_default();
        e.0 += 1;
        e.1 += usize::from(look.lines);
    }
    let mut out = SpokesMasked {
        moved: 0,
        warnings: mark_warnings(&looked, table),
    };
    let spoked: BTreeMap<String, (usize, usize)> = seen
        .into_iter()
        .filter(|&(_, (n, with))| with > 1 && 4 * with >= n)
        .map(|(name, counts)| (name.to_string(), counts))
        .collect();
    if spoked.is_empty() {
        return Ok(out);
    }
    let window = locate_window(radius);
    let frames_of_spoked: BTreeSet<usize> = table
        .points
        .iter()
        .filter(|p| spoked.contains_key(&p.particle))
        .map(|p| p.frame)
        .collect();
    let by_frame = detected_by_frame(&|p| frames_of_spoked.contains(&p.frame));
    let frames_with: Vec<(usize, &Vec<usize>)> = by_frame.iter().map(|(&k, points)| (k, points)).collect();
    // Each frame's moved points.
    let moved: Vec<Vec<Moved>> = frames_with
        .par_iter()
        .map(|&(k, points)| {
            frames.with_signal(k, background, workers, |signal, width, height| {
                let tracked: Vec<[f64; 2]> = points.iter().map(|&i| [at(i)[0], at(i)[1]]).collect();
                let near = FrameNeighbours::new(&tracked, found_in(k), radius);
                let grid = PointGrid::new(&near.points);
                // The frame's other detections are located with them, as in the locate pass,
                // so each window is split with the same neighbours.
                let seeds: &[[f64; 2]] = &near.points;
                let lines: Vec<Vec<[f64; 2]>> = points
                    .iter()
                    .map(|&i| {
                        if !spoked.contains_key(&table.points[i].particle) {
                            return Vec::new();
                        }
                        let p = at(i);
                        near.view(&grid, signal, (width, height), [p[0], p[1]], radius, |image| {
                            search.lines(image, level_of(p[2], radius), noise)
                        })
                    })
                    .collect();
                let cuts: Vec<Vec<([f64; 2], f64)>> = lines.iter().map(|l| spoke_cuts(l, radius)).collect();
                if cuts.iter().all(Vec::is_empty) {
                    return Vec::new();
                }
                let cut = refine_centroids_with_cuts(
                    signal,
                    width,
                    height,
                    seeds,
                    &[],
                    window,
                    noise,
                    &cuts,
                    &mut LocateScratch::default(),
                );
                points
                    .iter()
                    .zip(&lines)
                    .zip(cut)
                    .zip(seeds)
                    .filter(|(((_, l), _), _)| !l.is_empty())
                    .filter_map(|(((&i, l), d), s)| {
                        let d = d?;
                        // The lines' pull: the sum of their directions.
                        let pull = l.iter().fold([0.0, 0.0], |a, u| [a[0] + u[0], a[1] + u[1]]);
                        // A cut window that runs off by half a radius has lost its particle.
                        ((d.x - s[0]).hypot(d.y - s[1]) < 0.5 * radius).then(|| Moved {
                            point: i,
                            at: [d.x, d.y],
                            error: d.fixed_point_error().hypot(cut_sampling_error(radius, l.len())),
                            pull,
                        })
                    })
                    .collect()
            })
        })
        .collect::<Result<_, TrackError>>()?;
    // Judged particle by particle: the cut positions kept where they lead away from the lines.
    let mut by_particle: BTreeMap<&str, Vec<Moved>> = BTreeMap::new();
    for m in moved.into_iter().flatten() {
        by_particle
            .entry(table.points[m.point].particle.as_str())
            .or_default()
            .push(m);
    }
    let mut kept: Vec<Moved> = Vec::new();
    let mut named: Vec<String> = Vec::new();
    let mut refused: Vec<String> = Vec::new();
    for (name, moves) in by_particle {
        let (n, with) = spoked[name];
        if leads_away(&moves, table) {
            named.push(format!("{name} ({with} of {n})"));
            kept.extend(moves);
        } else {
            let mut sizes: Vec<f64> = moves
                .iter()
                .map(|m| {
                    let p = &table.points[m.point];
                    (m.at[0] - p.x).hypot(m.at[1] - p.y)
                })
                .collect();
            refused.push(name.to_string());
            if refused.len() > NAMED {
                continue;
            }
            out.warnings.push(format!(
                "{name}: lines leave it (a drawn spring, a string, a rod: in {with} of {n} sample frames looked at) and may \
                 pull its positions towards them; cut out of its centroid window with the side opposite them, they moved \
                 it {:.3} px (median) as often towards them as away, so its positions are the plain centroids and may be \
                 off by as much",
                median(&mut sizes)
            ));
        }
    }
    for m in &kept {
        let p = &mut table.points[m.point];
        (p.x, p.y, p.ep) = (m.at[0], m.at[1], p.ep.max(m.error));
    }
    out.moved = kept.len();
    if refused.len() > NAMED {
        out.warnings.push(format!(
            "{} more particles with lines leaving them keep their plain centroids, as above: {}",
            refused.len() - NAMED,
            short_list(&refused[NAMED..])
        ));
    }
    if !named.is_empty() {
        out.warnings.push(format!(
            "lines leave particle(s) {} (a drawn spring, a string, a rod: in that many of the sample frames looked at); \
             {} of their points located with each line and the side opposite it cut out of the centroid window",
            short_list(&named),
            out.moved
        ));
    }
    Ok(out)
}

/// Standard deviations (of the count of a fair coin's heads) by which the moves that lead
/// away from a track's lines must outnumber half its moves (see [`leads_away`]).
const AWAY_SIGMAS: f64 = 3.0;

/// Whether the cuts moved a track's points away from their lines' pull (the sum of the lines'
/// directions) consistently: the moves with a component away from the pull must number at
/// least `n / 2 + AWAY_SIGMAS sqrt(n) / 2` of the `n` moves (all of them for up to 9). Lines
/// that pulled each point move every point away (drawn springs, 21-40 frames: all but 0-2);
/// cuts that move a particle by their own sampling move it either way, as a coin falls
/// (pendulum-scale's bob: 26 of 52).
fn leads_away(moves: &[Moved], table: &TrackTable) -> bool {
    let away = moves
        .iter()
        .filter(|m| {
            let p = &table.points[m.point];
            (m.at[0] - p.x) * m.pull[0] + (m.at[1] - p.y) * m.pull[1] < 0.0
        })
        .count();
    let n = moves.len() as f64;
    away as f64 >= n.min(0.5 * n + 0.5 * AWAY_SIGMAS * n.sqrt())
}

/// `names` joined, the first [`NAMED`] of them named.
fn short_list(names: &[String]) -> String {
    let mut list: Vec<&str> = names.iter().take(NAMED).map(String::as_str).collect();
    let more = names.len().saturating_sub(NAMED);
    let rest = format!("and {more} more");
    if more > 0 {
        list.push(&rest);
    }
    list.join(", ")
}
