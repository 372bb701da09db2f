//! The tracking stage of a recording, from its frames to the linked and checked track table.

use super::finder::{Surround, Workers};
use super::light_check::{check_light, moves, LightVerdict, STAKE_FLOOR};
use super::options::TrackOptions;
use super::outcome::{TrackOutcome, TrackStats};
use super::plane::planes_move_points;
use super::radius::first_frame_scan;
use super::samples::{check_size, load_sample, moving_blobs, views};
use super::size_class::{largest_radius, light_reach, SizeClass, Sizes};
use super::skirts::particle_contrast;
use super::stage::{Pass, Stage};
use super::tracks_background::{
    background_without_tracks, hovering_starts, mass_spread, SampleGains, EXCLUSION_ROUNDS, SETTLED_SIZE,
};
use super::window_frames::WindowFrames;
use crate::background::STRUCTURED_LIMIT;
use crate::scale::ScaleBlob;
use crate::{
    estimate_background, AmbiguityKind, Background, BackgroundChoice, BackgroundModel, FrameDetections,
    FrameSource, PointFlag, SampleExposure, TrackError, TrackTable,
};
use physfit_tracks::stats::median;
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap};
use std::path::Path;

/// Frames sampled (evenly over the window) to estimate the background and noise.
const BACKGROUND_SAMPLES: usize = 25;

/// Tracks the recording at `path`: a folder of frames (PNG, JPEG or TIFF, natural name
/// order), a video or a TIFF stack (see [`FrameSource::open`]). `progress(done, total)` is
/// called as frames are located.
pub fn track_folder(
    path: &Path,
    options: &TrackOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<TrackOutcome, TrackError> {
    let source = FrameSource::open(path, options.window)?;
    track_source(&source, options, progress)
}

/// Tracks the frames of `source` (see [`track_folder`]).
pub fn track_source(
    source: &FrameSource,
    options: &TrackOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<TrackOutcome, TrackError> {
    match options.threads {
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n.max(1))
                .build()
                .map_err(|e| TrackError::Option(format!("cannot start {n} threads: {e}")))?;
            pool.install(|| track_frames(source, options, progress))
        }
        None => track_frames(source, options, progress),
    }
}

fn track_frames(
    source: &FrameSource,
    options: &TrackOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<TrackOutcome, TrackError> {
    let count = source.len();
    if count == 0 {
        return Err(TrackError::NoFrames {
            dir: source.path().to_path_buf(),
        });
    }
    let (first, last) = options.window.unwrap_or((0, count - 1));
    if first > last || last >= count {
        return Err(TrackError::Window {
            start: first,
            end: last,
            count,
        });
    }
    if let Some(r) = options.radius {
        if !(r.is_finite() && r > 0.0) {
            return Err(TrackError::Option(format!(
                "radius {r} px must be a positive number"
            )));
        }
    }
    if let Some(named) = &options.named_start {
        if let Some((id, p)) = named
            .iter()
            .find(|(_, p)| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(TrackError::Option(format!(
                "start position of \"{id}\" ({}, {}) is not finite",
                p[0], p[1]
            )));
        }
    }
    // The window's frame numbers.
    let numbers: Vec<usize> = (first..=last).collect();

    // Background and noise from an even sample of the window.
    // The sampled frames are kept and reused by the locate pass: each file is decoded once.
    let workers = Workers::default();
    let (picks, mut sample_frames) = load_sample(source, &numbers, BACKGROUND_SAMPLES, &workers)?;
    let size = sample_frames[0].view().size();
    let reference = &source.frame_name(numbers[picks[0]]);
    for (&i, frame) in picks.iter().zip(&sample_frames) {
        check_size(&source.frame_name(numbers[i]), frame.view(), reference, size)?;
    }
    let mut sample_of: Vec<Option<usize>> = vec![None; numbers.len()];
    for (j, &i) in picks.iter().enumerate() {
        sample_of[i] = Some(j);
    }
    // With named particles, their frame-A blobs are the particles: the sizes are measured on
    // them alone, so that texture or clutter, however plentiful, cannot set the scale.
    let starts: Option<Vec<[f64; 2]>> = options
        .named_start
        .as_ref()
        .map(|named| named.iter().map(|(_, p)| *p).collect());
    let starts = starts.as_deref();
    // The first sample is the window's first frame, where the named particles start: they
    // say which way their signal faces (see `Background::face_starts`).
    let estimate = |samples: &[crate::FrameView<'_>], choice: BackgroundChoice| {
        let mut background = estimate_background(samples, choice);
        if let Some(starts) = starts {
            background.face_starts(samples, starts);
        }
        background
    };
    let mut background = estimate(&views(&sample_frames), options.background);
    // The named particles' answers in scale space against this background, scanned once for
    // the sizes and the hovering test below.
    let first_scan: Option<Vec<ScaleBlob>> = (starts.is_some() && options.radius.is_none())
        .then(|| first_frame_scan(&background, &views(&sample_frames), &workers));
    let mut classes = SizeClass::measure_all(
        &background,
        &views(&sample_frames),
        options.radius,
        starts,
        first_scan.as_deref(),
        &workers,
    );
    // Without a structure, the blobs that move steadily, where the sizes were measured on them.
    let mut moving_starts: Option<Vec<[f64; 2]>> = None;
    // The per-pixel median without the particles found in each sample frame (out to twice the
    // radius and a pixel, where a disc or a blurred spot has left less than a grey level).
    if background.model == BackgroundModel::PerPixel {
        let samples = views(&sample_frames);
        // Named particles that barely move are in the per-pixel median: against it they show
        // as crescents. Their sizes are measured against a flat level, where they show whole.
        let hovering: Vec<[f64; 2]> = match starts {
            Some(starts) if options.radius.is_none() => {
                let flat = estimate(&samples, BackgroundChoice::Constant);
                let flat_scan = first_frame_scan(&flat, &samples, &workers);
                let against_median = first_scan.as_deref().unwrap_or_default();
                let hovering = hovering_starts(against_median, &flat_scan, starts);
                if !hovering.is_empty() {
                    classes = SizeClass::measure_all(
                        &flat,
                        &samples,
                        None,
                        Some(starts),
                        Some(&flat_scan),
                        &workers,
                    );
                }
                hovering
            }
            _ => Vec::new(),
        };
        let found_blobs = |background: &Background, classes: &[SizeClass]| -> Vec<Vec<[f64; 2]>> {
            samples
                .par_iter()
                .map(|&frame| {
                    workers.with(|w| {
                        classes
                            .iter()
                            .flat_map(|c| {
                                w.finder
                                    .blobs(background, frame, &c.sizes.params)
                                    .blobs
                                    .iter()
                                    .map(|b| [b.x as f64, b.y as f64])
                                    .collect::<Vec<_>>()
                            })
                            .collect()
                    })
                })
                .collect()
        };
        let mut found = found_blobs(&background, &classes);
        let reach = 2.0 * largest_radius(&classes) + 1.0;
        // Named particles are particles wherever they start, whatever the median says: one
        // that barely moves is in the median like a static object (seven discs of a small
        // rendered frame, 0.7-5 px over the recording, took the per-pixel model and were
        // tracked 1 px off). Structure under a start in every sample is not the scene's.
        let with_starts: Vec<Vec<[f64; 2]>> = found
            .iter()
            .map(|f| [f.as_slice(), starts.unwrap_or_default()].concat())
            .collect();
        if options.background == BackgroundChoice::Auto
            && background.static_structure_fraction(&samples, &with_starts, reach) <= STRUCTURED_LIMIT
        {
            // All the structure of the median lies where particles were: particles that
            // hovered over few samples left themselves in it, and the scene itself is flat.
            background = estimate(&samples, BackgroundChoice::Constant);
            classes = SizeClass::measure_all(&background, &samples, options.radius, starts, None, &workers);
        } else {
            // Hovering particles cover their start in every sample; pixels near a named start
            // that no sample shows clear are the particle's own. Particles half in the median
            // show smaller than they are, so named ones are measured again on the median
            // without them, and excluded again, until their size settles.
            let mut reach = reach;
            for round in 0..EXCLUSION_ROUNDS {
                let with_hovering: Vec<Vec<[f64; 2]>> =
                    found.iter().map(|f| [f.as_slice(), &hovering].concat()).collect();
                background.exclude_particles(
                    &samples,
                    &with_hovering,
                    starts.unwrap_or_default(),
                    reach,
                    light_reach(&classes),
                    SampleExposure::AsRecorded,
                );
                if starts.is_none() || options.radius.is_some() || round + 1 == EXCLUSION_ROUNDS {
                    break;
                }
                let before = largest_radius(&classes);
                classes = SizeClass::measure_all(&background, &samples, None, starts, None, &workers);
                if (largest_radius(&classes) - before).abs() <= SETTLED_SIZE * before {
                    break;
                }
                found = found_blobs(&background, &classes);
                reach = 2.0 * largest_radius(&classes) + 1.0;
            }
            // The views borrow the sample frames, which the frames after the first may join.
            drop(samples);
            if starts.is_none() && options.radius.is_none() {
                // A static scene's texture flickers into blobs as the exposure shifts, and
                // outnumbers the particles: the sizes are measured again on the blobs of
                // frame A that move steadily over the next two frames, as on named ones.
                // Frames A to A + 2; those not among the samples are kept with them, so the
                // locate pass does not decode them again.
                if picks[0] + 2 < numbers.len() {
                    let mut three = [0usize; 3];
                    for (slot, k) in three.iter_mut().zip(picks[0]..) {
                        *slot = match sample_of[k] {
                            Some(j) => j,
                            None => {
                                let frame =
                                    workers.with(|w| source.load_decoded(numbers[k], &mut w.decoder))?;
                                check_size(&source.frame_name(numbers[k]), frame.view(), reference, size)?;
                                sample_frames.push(frame);
                                sample_of[k] = Some(sample_frames.len() - 1);
                                sample_frames.len() - 1
                            }
                        };
                    }
                    let moving = workers.with(|w| {
                        moving_blobs(
                            &background,
                            three.map(|j| sample_frames[j].view()),
                            largest_radius(&classes),
                            &mut w.finder,
                        )
                    });
                    if !moving.is_empty() {
                        classes = vec![SizeClass {
                            members: None,
                            sizes: Sizes::measure(
                                &background,
                                &views(&sample_frames),
                                None,
                                Some(&moving),
                                None,
                                &workers,
                            ),
                        }];
                        moving_starts = Some(moving);
                    }
                }
            }
        }
    }
    // The particles' contrast (grey levels) and the reach (px) the blind pixels were found with.
    let mut blind_search: Option<(f32, usize)> = None;
    // Where the scene's own structure is as bright as the particles they cannot show, and a
    // thin structure across a particle cuts it in two: such pixels are filled in from their
    // neighbours, and the sizes measured again on the particles made whole.
    if background.model == BackgroundModel::PerPixel {
        let size_starts = starts.or(moving_starts.as_deref());
        let samples = views(&sample_frames);
        // The contrast of the size of most particles.
        let most = classes
            .iter()
            .max_by_key(|c| c.members.as_ref().map_or(usize::MAX, Vec::len))
            .expect("one size class at least");
        let most_starts = size_starts.map(|s| most.starts(s));
        if let Some(contrast) = particle_contrast(
            &background,
            samples[0],
            &most.sizes,
            most_starts.as_deref(),
            &workers,
        ) {
            blind_search = Some((contrast, largest_radius(&classes).ceil() as usize));
            background.find_blind(contrast, largest_radius(&classes).ceil() as usize);
            if !background.blind.is_empty() {
                classes = if moving_starts.is_some() {
                    vec![SizeClass {
                        members: None,
                        sizes: Sizes::measure(
                            &background,
                            &samples,
                            options.radius,
                            size_starts,
                            None,
                            &workers,
                        ),
                    }]
                } else {
                    SizeClass::measure_all(&background, &samples, options.radius, starts, None, &workers)
                };
            }
        }
    }
    let radius_estimated = classes[0].sizes.radius_estimated;

    let frames = WindowFrames {
        source,
        numbers: &numbers,
        sample_of: &sample_of,
        samples: &sample_frames,
        reference,
        size,
    };
    let stage = Stage {
        frames: &frames,
        workers: &workers,
        options,
        size,
        first,
        last,
    };
    let mut pass = stage.locate_and_link(&background, &classes, Surround::Ignore, progress)?;
    // Named particles that move less than their size over the samples leave part of
    // themselves in the per-pixel median where the first blobs missed them; the tracks say
    // where every particle was in every sample, so the median is taken again without them.
    if starts.is_some() && background.model == BackgroundModel::PerPixel {
        // The samples' exposure gains, against which the masses are compared.
        let gains = SampleGains::measure(&background, &views(&sample_frames), &sample_of, &numbers);
        for _ in 0..EXCLUSION_ROUNDS {
            let Some(cleaner) = background_without_tracks(
                &background,
                &views(&sample_frames),
                &gains,
                &pass,
                &classes,
                blind_search,
            ) else {
                break;
            };
            // The sizes, unless given, were measured with the particles partly in the median:
            // they are measured again without them (fresh style 6237, a disc of 34.5 px: 25.9
            // px with part of it in the median, 34.2 px without).
            let remeasured = options.radius.is_none().then(|| {
                SizeClass::measure_all(&cleaner, &views(&sample_frames), None, starts, None, &workers)
            });
            let second = stage.locate_and_link(
                &cleaner,
                remeasured.as_deref().unwrap_or(&classes),
                Surround::Ignore,
                progress,
            )?;
            // A clean background leaves each particle's integrated signal steady along its
            // track; the particle itself in the median makes it swell and fade.
            if !second.concerns.is_empty()
                || mass_spread(&second.table, &gains) >= mass_spread(&pass.table, &gains)
            {
                break;
            }
            pass = second;
            background = cleaner;
            if let Some(remeasured) = remeasured {
                classes = remeasured;
            }
        }
    }
    // Light read off the background was taken out of the particles' images: where their
    // brightness along the tracks says it only lights the background, the images are left as
    // they are and the frames located again.
    if let Some(light) = &background.light {
        let gains = SampleGains::measure(&background, &views(&sample_frames), &sample_of, &numbers);
        match check_light(&pass.table, light, size.0, &gains) {
            LightVerdict::AddsToBackground => {
                background.light = None;
                pass = stage.locate_and_link(&background, &classes, Surround::Ignore, progress)?;
            }
            // Particles that cross too little of the light to tell (one that hovers) keep the
            // light taken out, as light that falls on them wants; where the frames located
            // without it put them more than 3 standard errors (and 0.05 px) away, a warning
            // says so.
            LightVerdict::Undecided => {
                let mut unlit = background.clone();
                unlit.light = None;
                let other = stage.locate_and_link(&unlit, &classes, Surround::Ignore, progress)?;
                for (particle, most, ep) in moves(&pass.table, &other.table) {
                    if most > (3.0 * ep).max(STAKE_FLOOR) {
                        pass.warnings.push(format!(
                            "{particle}: the light read off the background (its brightest {:.0} % above its dimmest) was taken out of its image, as light that falls on the particle wants; its brightness along the track cannot tell whether it does (it crosses too little of the light), and if the light falls on the background alone its positions are off by up to {most:.2} px",
                            100.0 * (light.range - 1.0)
                        ));
                    }
                }
            }
            LightVerdict::FallsOnParticles => {}
        }
    }
    let background = background;
    // A background the model could not see (under a large particle that hovers, under
    // uneven light) is left in each centroid window: where taking out the plane around each
    // particle moves a tracked point by half its standard error, the frames are located
    // again with it, unless that raises concerns the first pass did not.
    let surround = planes_move_points(
        &background,
        &views(&sample_frames),
        &sample_of,
        &pass,
        &classes,
        &workers,
    );
    let mut located_again = false;
    if surround.moves {
        let corrected = stage.locate_and_link(&background, &classes, Surround::Plane, progress)?;
        if corrected.concerns.len() <= pass.concerns.len() {
            pass = corrected;
            located_again = true;
        }
    }
    pass.warnings.extend(surround.uneven);
    if !located_again {
        pass.warnings.extend(surround.unmoved);
    }
    let Pass {
        located: by_class,
        table,
        ambiguities,
        warnings: mut pass_warnings,
        relocated,
        concerns,
        cut_by_border,
        rim_not_found,
        excursions,
    } = pass;
    let total = numbers.len();
    let mut warnings = Vec::new();
    let empty: Vec<usize> = (0..total)
        .filter(|&i| by_class.iter().all(|c| c[i].detections.is_empty()))
        .map(|i| by_class[0][i].frame)
        .collect();
    if !empty.is_empty() {
        warnings.push(format!(
            "no particle found in {} frame(s): {}",
            empty.len(),
            frame_list(&empty)
        ));
    }
    warnings.append(&mut pass_warnings);
    let detection_count = by_class.iter().flatten().map(|f| f.detections.len()).sum();
    let mut eps: Vec<f64> = by_class
        .iter()
        .flatten()
        .flat_map(|f| f.detections.iter().map(crate::Detection::fixed_point_error))
        .filter(|e| e.is_finite())
        .collect();
    if !concerns.is_empty() {
        if options.named_start.is_some() {
            let radii: Vec<String> = classes.iter().map(|c| format!("{:.2}", c.sizes.radius)).collect();
            let mut concerns: Vec<String> = concerns.into_iter().map(|c| c.text).collect();
            // The structure gives each particle where it is in the first frame tracked: a window
            // started later than the frame those positions were read in starts the tracks on
            // whatever lies there (the ball toss from frame 3 with its frame-2 position took the
            // hand, radius read 65 px).
            concerns.push(format!(
                "no tracks written: if the particles are larger or smaller than {} px in radius, give it with \
                 --radius; if they are held or hidden in the first frames (a hand), start after that with --window; \
                 the structure's positions must be where the particles are in frame {first}, the first frame tracked",
                radii.join(" or ")
            ));
            return Err(TrackError::NotFollowed { concerns });
        }
        warnings.extend(concerns.into_iter().map(|c| c.text));
    }
    warnings.extend(
        ambiguities
            .iter()
            // Found faint points are warned of per particle by the search (`guided`).
            .filter(|a| a.kind != AmbiguityKind::Faint)
            .filter(|a| a.kind != AmbiguityKind::Merged || options.named_start.is_some())
            .map(|a| a.to_string()),
    );
    let stats = TrackStats {
        frame_count: total,
        frames: (first, last),
        track_count: table.particle_ids().len(),
        point_count: table.points.len(),
        detection_count,
        interpolated_count: table
            .points
            .iter()
            .filter(|p| p.flag == PointFlag::Interpolated)
            .count(),
        split_count: table.points.iter().filter(|p| p.flag == PointFlag::Split).count(),
        refitted_count: relocated.moved,
        reordered_count: relocated.renamed,
        ambiguities,
        noise_sigma: background.noise_sigma,
        radius: classes
            .iter()
            .map(|c| c.sizes.radius)
            .fold(f64::INFINITY, f64::min),
        radii: classes.iter().map(|c| c.sizes.radius).collect(),
        radius_estimated,
        background: background.model,
        dark_on_light: background.is_dark_on_light(),
        median_ep: median(&mut eps),
        cut_by_border: cut_by_border.into_iter().collect(),
        rim_not_found: rim_not_found.into_iter().collect(),
        excursions: excursions.into_iter().collect(),
        light_taken_out: background.light.as_ref().map(|l| l.range),
    };
    Ok(TrackOutcome {
        table,
        warnings,
        stats,
        detections: merge_classes(by_class),
    })
}
/// One frame list of detections from each size class's (all of one length, in frame order):
/// each frame's detections of every class, smallest size first.
fn merge_classes(by_class: Vec<Vec<FrameDetections>>) -> Vec<FrameDetections> {
    let mut classes = by_class.into_iter();
    let mut merged = classes.next().unwrap_or_default();
    for class in classes {
        for (into, f) in merged.iter_mut().zip(class) {
            into.detections.extend(f.detections);
        }
    }
    merged
}
/// The tracks of `table` with a single point, in a frame strictly inside `frames` (first and
/// last, inclusive).
pub(super) fn one_frame_tracks(table: &TrackTable, frames: (usize, usize)) -> BTreeSet<String> {
    // Each track's point count and first frame, by name: its point list (as
    // `TrackTable::by_particle` gives it) is not needed.
    let mut tracks: HashMap<&str, (usize, usize)> = HashMap::new();
    for p in &table.points {
        tracks.entry(p.particle.as_str()).or_insert((0, p.frame)).0 += 1;
    }
    tracks
        .into_iter()
        .filter(|&(_, (count, frame))| count == 1 && frame > frames.0 && frame < frames.1)
        .map(|(id, _)| id.to_string())
        .collect()
}
fn frame_list(frames: &[usize]) -> String {
    let shown: Vec<String> = frames.iter().take(10).map(|f| f.to_string()).collect();
    if frames.len() > 10 {
        format!("{} and {} more", shown.join(", "), frames.len() - 10)
    } else {
        shown.join(", ")
    }
}
