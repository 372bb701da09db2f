//! [`track_folder`]: the whole tracking stage, from a recording (a folder of frames, a video,
//! a TIFF stack: a [`FrameSource`]) to a track table.
//!
//! Every threshold is measured from the frames themselves: the background model and pixel
//! noise from a sample of frames ([`crate::estimate_background`]), the particle radius from
//! the radius of gyration of the blobs found (unless given), and the expected blob area
//! from the components at that radius. Frames are decoded, filtered and located in
//! parallel; linking is sequential.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use physfit_tracks::stats::median;
use rayon::prelude::*;

use crate::background::STRUCTURED_LIMIT;
use crate::checks::{check_tracks, skirts, Skirt};
use crate::scale::{self, ScaleBlob};
use crate::shared_blobs::{relocate_shared, Relocated, SharedBlobs, Starts};
use crate::{
    band_noise, estimate_background, find_blobs_forming, find_blobs_with_scratch, link_detections,
    refine_centroids_with_scratch, Ambiguity, AmbiguityKind, Background, BackgroundChoice, BackgroundModel,
    Blob, BlobSet, BlobSize, DecodedFrame, DetectParameters, Detection, Frame, FrameDecoder, FrameDetections,
    FrameSource, FrameView, LinkOptions, LinkOutcome, LocateScratch, PointFlag, SampleExposure, Scratch,
    TrackError, TrackPoint, TrackTable,
};

/// Frames sampled (evenly over the window) to estimate the background and noise.
const BACKGROUND_SAMPLES: usize = 25;
/// Frames sampled to estimate the particle radius.
const RADIUS_SAMPLES: usize = 5;
/// Blobs the size estimates want: of the [`RADIUS_SAMPLES`] frames, only as many are searched
/// as should hold this many (the medians are then known to a twentieth of the blobs' own
/// spread), so a crowded recording measures one frame, not five.
const SIZE_BLOBS: usize = 400;
/// Radius, px, the estimation starts from when the scale-space scan finds no particle.
const START_RADIUS: f64 = 3.0;
/// Most rounds of the radius estimate (each re-detects and re-measures with the last
/// estimate; a small start converges upwards in about ten rounds).
const RADIUS_ROUNDS: usize = 16;

/// How to track a folder of frames. `TrackOptions::default()` derives everything from the data.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackOptions {
    /// First and last frame tracked, inclusive (indices in natural name order); all when `None`.
    pub window: Option<(usize, usize)>,
    /// Named particles and their positions (px) in the first tracked frame: tracks take these
    /// names and only these particles are followed. `None` tracks every blob.
    pub named_start: Option<Vec<(String, [f64; 2])>>,
    /// Particle radius, px; estimated from the frames when `None`.
    pub radius: Option<f64>,
    /// Worker threads; rayon's default (one per core) when `None`.
    pub threads: Option<usize>,
    /// Background model; chosen automatically by default.
    pub background: BackgroundChoice,
    /// Frames a particle may go unseen and still be bridged (named) or kept (unnamed).
    pub memory: usize,
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            window: None,
            named_start: None,
            radius: None,
            threads: None,
            background: BackgroundChoice::Auto,
            memory: 5,
        }
    }
}

/// What tracking measured and had to do.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackStats {
    /// Frames tracked.
    pub frame_count: usize,
    /// First and last tracked frame (inclusive).
    pub frames: (usize, usize),
    /// Tracks written.
    pub track_count: usize,
    /// Points written.
    pub point_count: usize,
    /// Detections located, over all frames.
    pub detection_count: usize,
    /// Points bridged from motion prediction (`flag = interpolated`).
    pub interpolated_count: usize,
    /// Points split from merged blobs (`flag = split`).
    pub split_count: usize,
    /// Points of particles that shared a blob placed again from the image after linking
    /// (named tracks: each group's particles fitted jointly with the measured
    /// single-particle image).
    pub refitted_count: usize,
    /// Points handed to another track of their crossing by the motion after linking.
    pub reordered_count: usize,
    /// Every ambiguity bridged, in frame order.
    pub ambiguities: Vec<Ambiguity>,
    /// Measured pixel noise, grey levels.
    pub noise_sigma: f64,
    /// Particle radius used, px: the smallest of [`TrackStats::radii`].
    pub radius: f64,
    /// Radius of each size of particle told apart, px, smallest first: one entry unless
    /// named particles of sizes far apart (see [`crate::track_folder`]) were tracked each at
    /// its own size.
    pub radii: Vec<f64>,
    /// True if and only if the radius was estimated from the frames.
    pub radius_estimated: bool,
    /// Background model chosen.
    pub background: BackgroundModel,
    /// True if and only if particles are darker than the background.
    pub dark_on_light: bool,
    /// Median estimated position error `ep` of detected points, px.
    pub median_ep: f64,
}

impl TrackStats {
    /// Distance within which a track point counts as matching a true centre when scoring, px:
    /// the particle radius (a point farther than that is on another particle's disc or none).
    pub fn match_radius(&self) -> f64 {
        self.radius
    }
}

impl std::fmt::Display for TrackStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "tracked frames {}..{} ({} frames): {} tracks, {} points ({} interpolated, {} split)",
            self.frames.0,
            self.frames.1,
            self.frame_count,
            self.track_count,
            self.point_count,
            self.interpolated_count,
            self.split_count
        )?;
        write!(
            f,
            "background {} ({}), pixel noise {:.2} grey levels, radius {:.2}{} px ({}), median position error {:.4} px",
            match self.background {
                BackgroundModel::Constant => "constant",
                BackgroundModel::PerPixel => "per-pixel median",
            },
            if self.dark_on_light { "dark on light" } else { "bright on dark" },
            self.noise_sigma,
            self.radius,
            if self.radii.len() > 1 {
                let others: Vec<String> = self.radii[1..].iter().map(|r| format!("{r:.2}")).collect();
                format!(" and {}", others.join(", "))
            } else {
                String::new()
            },
            if self.radius_estimated { "estimated" } else { "given" },
            self.median_ep
        )
    }
}

/// The result of [`track_folder`].
#[derive(Clone, Debug, PartialEq)]
pub struct TrackOutcome {
    /// The trajectories.
    pub table: TrackTable,
    /// What the user should know (empty frames, lost particles, ambiguities bridged).
    pub warnings: Vec<String>,
    /// Measured figures.
    pub stats: TrackStats,
    /// Every frame's located detections before linking (what `--detections` writes).
    pub detections: Vec<FrameDetections>,
}

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
    let mut background = estimate_background(&views(&sample_frames), options.background);
    // With named particles, their frame-A blobs are the particles: the sizes are measured on
    // them alone, so that texture or clutter, however plentiful, cannot set the scale.
    let starts: Option<Vec<[f64; 2]>> = options
        .named_start
        .as_ref()
        .map(|named| named.iter().map(|(_, p)| *p).collect());
    let starts = starts.as_deref();
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
                let flat = estimate_background(&samples, BackgroundChoice::Constant);
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
            background = estimate_background(&samples, BackgroundChoice::Constant);
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
    let mut pass = stage.locate_and_link(&background, &classes, progress)?;
    // Named particles that move less than their size over the samples leave part of
    // themselves in the per-pixel median where the first blobs missed them; the tracks say
    // where every particle was in every sample, so the median is taken again without them.
    for _ in 0..EXCLUSION_ROUNDS {
        let Some(cleaner) = starts.and_then(|_| {
            background_without_tracks(
                &background,
                &views(&sample_frames),
                &sample_of,
                &numbers,
                &pass,
                largest_radius(&classes),
                2.0 * largest_radius(&classes) + 1.0,
                blind_search,
            )
        }) else {
            break;
        };
        let second = stage.locate_and_link(&cleaner, &classes, progress)?;
        // A clean background leaves each particle's integrated signal steady along its
        // track; the particle itself in the median makes it swell and fade.
        if !second.concerns.is_empty() || mass_spread(&second.table) >= mass_spread(&pass.table) {
            break;
        }
        pass = second;
        background = cleaner;
    }
    let background = background;
    let Pass {
        located: by_class,
        table,
        ambiguities,
        warnings: mut pass_warnings,
        relocated,
        concerns,
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
        .flat_map(|f| f.detections.iter().map(|d| d.ep))
        .filter(|e| e.is_finite())
        .collect();
    if !concerns.is_empty() {
        if options.named_start.is_some() {
            let radii: Vec<String> = classes.iter().map(|c| format!("{:.2}", c.sizes.radius)).collect();
            let mut concerns: Vec<String> = concerns.into_iter().map(|c| c.0).collect();
            concerns.push(format!(
                "no tracks written: if the particles are larger or smaller than {} px in radius, give it with \
                 --radius; if they are held or hidden in the first frames (a hand), start after that with --window",
                radii.join(" or ")
            ));
            return Err(TrackError::NotFollowed { concerns });
        }
        warnings.extend(concerns.into_iter().map(|c| c.0));
    }
    warnings.extend(
        ambiguities
            .iter()
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

/// What one pass of locating and linking found.
struct Pass {
    /// Every frame's detections, by size class then frame.
    located: Vec<Vec<FrameDetections>>,
    table: TrackTable,
    ambiguities: Vec<Ambiguity>,
    warnings: Vec<String>,
    relocated: Relocated,
    /// Each track's concern, with the radius of its class, px.
    concerns: Vec<(String, f64)>,
}

/// The inputs every pass of locating and linking shares.
struct Stage<'a> {
    frames: &'a WindowFrames<'a>,
    workers: &'a Workers,
    options: &'a TrackOptions,
    /// Frame width and height, px.
    size: (usize, usize),
    /// First and last frame of the window.
    first: usize,
    last: usize,
}

impl Stage<'_> {
    /// Locates every frame against `background` (in parallel, once for each size class) and
    /// links each class's detections, then places again the points of named particles that
    /// shared a blob and checks the tracks.
    fn locate_and_link(
        &self,
        background: &Background,
        classes: &[SizeClass],
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Pass, TrackError> {
        let Stage {
            frames,
            workers,
            options,
            size,
            first,
            last,
        } = *self;
        let done = std::sync::atomic::AtomicUsize::new(0);
        let total = frames.numbers.len();
        let located: Result<Vec<Vec<FrameDetections>>, TrackError> = frames
            .numbers
            .par_iter()
            .enumerate()
            .map(|(i, k)| {
                workers.with(|w| {
                    let frame = frames.get(i, &mut w.decoder, &mut w.frame)?;
                    let each = classes
                        .iter()
                        .map(|c| FrameDetections {
                            frame: *k,
                            detections: w.finder.locate(
                                background,
                                frame,
                                &c.sizes.params,
                                c.window(),
                                Parts::Join,
                            ),
                        })
                        .collect();
                    let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                    progress(n, total);
                    Ok(each)
                })
            })
            .collect();
        // By size class, then frame.
        let mut by_class: Vec<Vec<FrameDetections>> = vec![Vec::with_capacity(total); classes.len()];
        for each in located? {
            for (class, f) in by_class.iter_mut().zip(each) {
                class.push(f);
            }
        }
        let mut warnings = Vec::new();
        let mut table = TrackTable::default();
        let mut ambiguities = Vec::new();
        let mut relocated = Relocated::default();
        let mut concerns = Vec::new();
        for (class, located) in classes.iter().zip(&by_class) {
            let named = options.named_start.as_deref().map(|n| class.starts(n));
            let linked = link_detections(
                located,
                &LinkOptions {
                    named_start: named.clone(),
                    radius: class.sizes.radius,
                    width: size.0,
                    height: size.1,
                    memory: options.memory,
                },
            );
            let LinkOutcome {
                table: mut class_table,
                ambiguities: mut class_ambiguities,
                warnings: link_warnings,
            } = linked;
            // With the particle count known, the points of particles that shared a blob are placed
            // again from the image, jointly, and the motion judges once more which is which (see
            // `crate::shared`).
            if let Some(named) = named.as_deref() {
                // Decoded with a worker's buffers, as in the locate pass (a fresh decoder per frame
                // paged its buffers in again).
                let signal_of = |k: usize| -> Result<Vec<f32>, TrackError> {
                    workers.with(|w| {
                        let frame = frames.get(k - first, &mut w.decoder, &mut w.frame)?;
                        let mut signal = Vec::new();
                        background.signal_into(frame, &mut signal);
                        background.remove_gain(frame, &mut signal);
                        Ok(signal)
                    })
                };
                let r = relocate_shared(
                    &mut class_table.points,
                    &mut class_ambiguities,
                    &Starts {
                        positions: named,
                        frame: first,
                    },
                    &SharedBlobs {
                        signal_of: &signal_of,
                        width: size.0,
                        height: size.1,
                        radius: class.sizes.radius,
                        window: class.window(),
                    },
                )?;
                relocated.moved += r.moved;
                relocated.renamed += r.renamed;
            }
            warnings.extend(link_warnings);
            // Without a structure, a track of one point inside the recording (not at its first or
            // last frame) is a noise peak that passed the detector, not a particle: a particle is
            // seen in the frames around it (trackpy's users drop such stubs by hand).
            if options.named_start.is_none() {
                let stubs = one_frame_tracks(&class_table, (first, last));
                if !stubs.is_empty() {
                    class_table.points.retain(|p| !stubs.contains(&p.particle));
                    warnings.push(format!(
                        "{} track(s) of a single point inside the recording dropped as noise peaks",
                        stubs.len()
                    ));
                }
            }
            // Tracks that contradict themselves: named particles not followed are an error (their
            // tracks would be wrong); unnamed ones are warned of.
            let skirts = sample_skirts(&class_table, frames, background, class.sizes.radius, workers)?;
            concerns.extend(
                check_tracks(&class_table, class.sizes.radius, &skirts)
                    .iter()
                    .map(|c| (c.to_string(), class.sizes.radius)),
            );
            table.points.extend(class_table.points);
            ambiguities.extend(class_ambiguities);
        }
        if let (true, Some(named)) = (classes.len() > 1, options.named_start.as_deref()) {
            // Frame, then the structure's order, as one class's tracks are.
            let order: BTreeMap<&str, usize> =
                named.iter().enumerate().map(|(i, n)| (n.0.as_str(), i)).collect();
            let rank = |p: &TrackPoint| order.get(p.particle.as_str()).copied().unwrap_or(usize::MAX);
            table
                .points
                .sort_by(|a, b| a.frame.cmp(&b.frame).then_with(|| rank(a).cmp(&rank(b))));
            ambiguities.sort_by_key(|a| (a.first_frame, a.last_frame));
        }
        Ok(Pass {
            located: by_class,
            table,
            ambiguities,
            warnings,
            relocated,
            concerns,
        })
    }
}

/// The frames of the tracked window: the samples already decoded, the others read from the
/// source on demand.
struct WindowFrames<'a> {
    source: &'a FrameSource,
    /// Each frame's number in the source.
    numbers: &'a [usize],
    /// Each frame's place among `samples`, if it is one.
    sample_of: &'a [Option<usize>],
    samples: &'a [DecodedFrame],
    /// The file whose size every frame must have, and that size (width, height, px).
    reference: &'a Path,
    size: (usize, usize),
}

impl WindowFrames<'_> {
    /// Frame `i` of the window: the sample already decoded, or the frame decoded into `buf`
    /// (with `decoder`'s buffers) and checked against the reference size.
    fn get<'b>(
        &'b self,
        i: usize,
        decoder: &'b mut FrameDecoder,
        buf: &'b mut Frame,
    ) -> Result<FrameView<'b>, TrackError> {
        if let Some(j) = self.sample_of[i] {
            return Ok(self.samples[j].view());
        }
        let k = self.numbers[i];
        let view = self.source.load_view(k, decoder, buf)?;
        if view.size() != self.size {
            check_size(&self.source.frame_name(k), view, self.reference, self.size)?;
        }
        Ok(view)
    }
}

/// One worker thread's buffers, reused from frame to frame: the decoder's and the decoded
/// frame's, and the [`Finder`]'s.
#[derive(Default)]
struct Worker {
    decoder: FrameDecoder,
    frame: Frame,
    finder: Finder,
}

/// One thread's buffers for finding and locating a frame's particles: the signal image, the
/// filters' and blob regions' buffers (a frame-sized region map among them) and the
/// centroids'.
#[derive(Default)]
struct Finder {
    /// A frame converted to the background's channel count (a grey file among colour ones).
    converted: Frame,
    /// The last frame's signal, gain-corrected.
    signal: Vec<f32>,
    detect: Scratch,
    locate: LocateScratch,
}

impl Finder {
    /// The blobs of `frame` found with `params` (its signal left in `self.signal`).
    fn blobs(&mut self, background: &Background, frame: FrameView<'_>, params: &DetectParameters) -> BlobSet {
        self.find(background, frame, params, false)
    }

    /// [`Finder::blobs`], the signal then gain-corrected when `levelled`. Blobs are found in
    /// the plain signal (the band-pass ignores a flat change of brightness, and a gain is not
    /// uniform enough over a real frame to correct the component labelling with); centroids
    /// are measured in the gain-corrected one, since a centroid window integrates any offset
    /// left in it. The signal is formed row by row as the detector's filters reach it.
    fn find(
        &mut self,
        background: &Background,
        frame: FrameView<'_>,
        params: &DetectParameters,
        levelled: bool,
    ) -> BlobSet {
        let frame = background.matching(frame, &mut self.converted);
        let (width, height) = frame.size();
        self.signal.resize(width * height, 0.0);
        let blobs = if background.blind.is_empty() {
            find_blobs_forming(
                &mut self.signal,
                width,
                height,
                params,
                &mut self.detect,
                |pixels, out| background.signal_range(frame, pixels, out),
            )
        } else {
            // Blind pixels are filled from their neighbours, so the signal is formed whole first.
            background.signal_into(frame, &mut self.signal);
            find_blobs_with_scratch(&self.signal, width, height, params, &mut self.detect)
        };
        if levelled {
            background.remove_gain(frame, &mut self.signal);
        }
        blobs
    }

    /// The gain-corrected signal of `frame` alone, without finding its blobs (left in
    /// `self.signal`, as [`Finder::find`] leaves it).
    fn levelled_signal(&mut self, background: &Background, frame: FrameView<'_>) {
        background.signal_into(frame, &mut self.signal);
        background.remove_gain(frame, &mut self.signal);
    }

    /// The particles of `frame`: its [`Finder::blobs`], each located by the centroid in a
    /// window of radius `window` (px) of the gain-corrected signal, estimates that end within
    /// a radius of each other joined as `parts` says.
    fn locate(
        &mut self,
        background: &Background,
        frame: FrameView<'_>,
        params: &DetectParameters,
        window: f64,
        parts: Parts,
    ) -> Vec<Detection> {
        let blobs = self.find(background, frame, params, true).blobs;
        let seeds: Vec<[f64; 2]> = blobs.iter().map(|b| [b.x as f64, b.y as f64]).collect();
        let areas: Vec<f64> = blobs.iter().map(|b| b.area).collect();
        let (width, height) = frame.size();
        let noise = background.noise_sigma;
        let mut locate = |seeds: &[[f64; 2]], areas: &[f64]| {
            refine_centroids_with_scratch(
                &self.signal,
                width,
                height,
                seeds,
                areas,
                window,
                noise,
                &mut self.locate,
            )
        };
        let mut found = locate(&seeds, &areas);
        if parts == Parts::Keep {
            return found;
        }
        // Joined estimates move, and may then end within a radius of another: joined again,
        // a few rounds at most (each round leaves fewer estimates). One round left a ring of
        // 9 px 0.62 / 0.98 px RMS off (test `rings_beside_neighbours_are_not_split_between_them`,
        // seed 3002; 0.09 / 0.15 with more). Each round locates every estimate of the frame
        // again: on pendulum-scale, with its dial and text, the rounds add 8 % to the
        // instructions (one round 7 %).
        for _ in 0..JOIN_ROUNDS {
            let Some((seeds, areas)) = join_close(&found, params.radius) else {
                break;
            };
            found = locate(&seeds, &areas);
        }
        found
    }
}

/// What [`Finder::locate`] does with centroid estimates that end closer than a radius to
/// each other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Parts {
    /// Joined and located again as one ([`join_close`]): the frames of the recording.
    Join,
    /// Kept apart: the size estimate's rounds ([`estimate_radius`]). Joined there, the rim
    /// halves of a thin ring measure as one ring and the size comes out right (8.12 px for
    /// the sweep's rings of radius 6.45 px, style 1002, against 3.48 from the halves); but
    /// at that size the band-pass also answers between two rings' near rims, a centroid
    /// started there takes part of a ring and ends beyond a radius of the ring's own, and
    /// the style came out with 13 of its 140 points lost and 0.75 px RMS, tracks written.
    /// At 3.48 px the skirt check refuses it, the honest outcome until those answers are
    /// told apart.
    Keep,
}

/// Most rounds of joining estimates that converged within a radius of each other.
const JOIN_ROUNDS: usize = 4;

/// Seeds (and blob areas) for locating `found` again with the estimates that converged
/// closer than `radius` to each other joined into one, seeded at their mass-weighted mean;
/// `None` when no two did. The detector keeps no two maxima closer than a radius (one
/// particle's band-pass answer); two that end that close took one particle's light between
/// them. A thin ring whose neighbour's rim lies near its own answers the band-pass between
/// the two near rims too, and the centroid started there takes half the ring while the one
/// started at its centre takes the other half: each half's centroid lies `2 r / pi` from
/// the centre (3.7 px for a ring of radius 6.45 px, 3.9 px from the truth in the sweep's
/// style 1002).
fn join_close(found: &[Detection], radius: f64) -> Option<(Vec<[f64; 2]>, Vec<f64>)> {
    let n = found.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| found[a].x.total_cmp(&found[b].x));
    let mut sets = crate::disjoint_sets::DisjointSets::new(n);
    let mut any = false;
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if found[j].x - found[i].x >= radius {
                break;
            }
            if (found[j].x - found[i].x).hypot(found[j].y - found[i].y) < radius {
                sets.union(i, j);
                any = true;
            }
        }
    }
    if !any {
        return None;
    }
    // Every located estimate has a positive mass ([`refine_centroids_with_scratch`] drops
    // the others): each group's seed is its mass-weighted mean, its blob area the sum.
    let mut groups: BTreeMap<usize, ([f64; 3], f64)> = BTreeMap::new();
    for (i, d) in found.iter().enumerate() {
        let g = groups.entry(sets.root(i)).or_insert(([0.0; 3], 0.0));
        g.0[0] += d.mass * d.x;
        g.0[1] += d.mass * d.y;
        g.0[2] += d.mass;
        g.1 += d.area;
    }
    let (seeds, areas) = groups
        .into_values()
        .map(|(sum, area)| ([sum[0] / sum[2], sum[1] / sum[2]], area))
        .unzip();
    Some((seeds, areas))
}

/// Idle workers, handed out to each frame's job and taken back after: their frame-sized
/// buffers are allocated once per thread for the whole recording, not once per stage or per
/// rayon job (a fresh megabyte is page-faulted in again, as costly as filtering a frame).
#[derive(Default)]
struct Workers(std::sync::Mutex<Vec<Worker>>);

impl Workers {
    /// `f` run with an idle worker (a new one when none is idle).
    fn with<R>(&self, f: impl FnOnce(&mut Worker) -> R) -> R {
        let mut w = self.idle().pop().unwrap_or_default();
        let out = f(&mut w);
        self.idle().push(w);
        out
    }

    fn idle(&self) -> std::sync::MutexGuard<'_, Vec<Worker>> {
        // A job that panicked took its worker with it; the list itself is intact.
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Centroid window radius for particles of radius `radius` (at half the peak signal), px:
/// the disc, its anti-aliased edge (half a pixel) and the half-pixel ramp of the window
/// weight, so the window holds all of an isolated disc's signal and as little background
/// noise as possible. Every background pixel in the window adds noise to the centroid in
/// proportion to its distance from the centre, so the centroid's error grows as the square
/// of the window radius: at `radius + 1` it is about 0.0022 px per grey level of pixel noise
/// for the discs (radius 4, amplitude 200), against 0.0031 at `1.25 radius + 1`.
/// Blur widens the measured radius, and with it the window.
fn locate_window(radius: f64) -> f64 {
    radius + 1.0
}

/// Loads up to `count` frames of `source` spread evenly over `numbers` (frame numbers), with
/// the `workers`' decoders; returns their indices into `numbers` and the decoded frames.
fn load_sample(
    source: &FrameSource,
    numbers: &[usize],
    count: usize,
    workers: &Workers,
) -> Result<(Vec<usize>, Vec<DecodedFrame>), TrackError> {
    let n = numbers.len();
    let picks: Vec<usize> = if n <= count {
        (0..n).collect()
    } else {
        let mut v: Vec<usize> = (0..count).map(|i| i * (n - 1) / (count - 1)).collect();
        v.dedup();
        v
    };
    // The decoders' buffers are reused from frame to frame (a fresh decoder per rayon job
    // paged its buffers in again for every few frames).
    let frames = picks
        .par_iter()
        .map(|&i| workers.with(|w| source.load_decoded(numbers[i], &mut w.decoder)))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((picks, frames))
}

/// The sample frames as the estimates read them (8-bit grey files as their bytes).
fn views(frames: &[DecodedFrame]) -> Vec<FrameView<'_>> {
    frames.iter().map(DecodedFrame::view).collect()
}

fn check_size<'a>(
    path: &Path,
    frame: impl Into<FrameView<'a>>,
    reference: &Path,
    size: (usize, usize),
) -> Result<(), TrackError> {
    let (found_width, found_height) = frame.into().size();
    if (found_width, found_height) == size {
        return Ok(());
    }
    Err(TrackError::FrameSize {
        path: path.to_path_buf(),
        first: reference
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        width: size.0,
        height: size.1,
        found_width,
        found_height,
    })
}

/// The blobs of the first of three consecutive `frames` that move steadily: each has a blob
/// in the next frame more than half a pixel away (a speck of static texture stays put), and
/// the frame after holds a blob within a pixel, or a tenth of the step, of where constant
/// velocity puts it (a speck flickering in and out of the band-pass does not chain over
/// three frames). Blobs are found at `radius` (px) with no size rejection and located by
/// their centroids: their peaks' whole pixels judged a slowly rolling ball static at one
/// radius and moving at the next. Positions in the first frame, px; empty when nothing
/// moves.
fn moving_blobs(
    background: &Background,
    frames: [FrameView<'_>; 3],
    radius: f64,
    finder: &mut Finder,
) -> Vec<[f64; 2]> {
    let [a, b, c] = frames.map(|frame| -> Vec<[f64; 2]> {
        locate_unfiltered(background, frame, radius, finder)
            .iter()
            .map(|d| [d.x, d.y])
            .collect()
    });
    let later = [b, c];
    let tree = |pts: &[[f64; 2]]| (!pts.is_empty()).then(|| ImmutableKdTree::<f64, 2>::new_from_slice(pts));
    let (Some(tb), Some(tc)) = (tree(&later[0]), tree(&later[1])) else {
        return Vec::new();
    };
    a.into_iter()
        .filter(|p| {
            let nb = tb.nearest_one::<SquaredEuclidean>(p);
            let b = later[0][nb.item as usize];
            let step = nb.distance.sqrt();
            if step <= 0.5 {
                return false;
            }
            let predicted = [2.0 * b[0] - p[0], 2.0 * b[1] - p[1]];
            let nc = tc.nearest_one::<SquaredEuclidean>(&predicted);
            nc.distance.sqrt() <= (0.1 * step).max(1.0)
        })
        .collect()
}

/// The particle size the detector works with, measured on the sample frames.
struct Sizes {
    /// Particle radius, px.
    radius: f64,
    /// Whether `radius` was measured (not given).
    radius_estimated: bool,
    /// Detection parameters at that radius, with the expected blob sizes.
    params: DetectParameters,
}

impl Sizes {
    /// Radius (unless `given`) and expected blob sizes, from the first [`RADIUS_SAMPLES`]
    /// sample frames against `background`; measured on the blobs nearest `starts` when
    /// named particles are given.
    fn measure(
        background: &Background,
        samples: &[FrameView<'_>],
        given: Option<f64>,
        starts: Option<&[[f64; 2]]>,
        scale: Option<f64>,
        workers: &Workers,
    ) -> Sizes {
        let estimation = Estimation {
            background,
            workers,
            frames: &samples[..samples.len().min(RADIUS_SAMPLES)],
        };
        let (radius, radius_estimated) = match given {
            Some(r) => (r, false),
            None => (estimate_radius(&estimation, starts, scale), true),
        };
        let expected = expected_size(&estimation, radius, starts);
        Sizes {
            radius,
            radius_estimated,
            params: DetectParameters {
                radius,
                noise_sigma: background.noise_sigma,
                expected,
            },
        }
    }
}

/// Ratio of two size classes' measured radii below which they are one size after all (the
/// scale space split them; the measured radii are within a blurred edge of each other).
const SAME_SIZE: f64 = 1.3;

/// Particles of one size and the detector's sizes for them. Named particles whose scales
/// lie far apart (a ball 2.5 times its neighbour's size) are each found, located and linked
/// at their own size: at one radius the larger is found as parts, or the smaller drowns in
/// the noise of a window fit for the larger.
struct SizeClass {
    /// The named particles of this size (indices into the named starts, in order); `None`:
    /// every particle (one size, named or not).
    members: Option<Vec<usize>>,
    sizes: Sizes,
}

impl SizeClass {
    /// The size classes of a recording: one, unless named particles' scales in the first
    /// estimation frame fall into groups far apart ([`scale::size_groups`]), each then measured
    /// on its own particles; classes whose measured radii come out within [`SAME_SIZE`] of
    /// each other are measured again as one. A `given` radius makes one class.
    ///
    /// `scan` is [`first_frame_scan`] against `background`, when already made.
    fn measure_all(
        background: &Background,
        samples: &[FrameView<'_>],
        given: Option<f64>,
        starts: Option<&[[f64; 2]]>,
        scan: Option<&[ScaleBlob]>,
        workers: &Workers,
    ) -> Vec<SizeClass> {
        let one = |scale: Option<f64>| {
            vec![SizeClass {
                members: None,
                sizes: Sizes::measure(background, samples, given, starts, scale, workers),
            }]
        };
        let Some(starts) = starts.filter(|_| given.is_none()) else {
            return one(None);
        };
        let scales = match scan {
            Some(all) => scale_of_each(all, starts),
            None => scale_of_each(&first_frame_scan(background, samples, workers), starts),
        };
        let groups = scale::size_groups(&scales);
        let group_scale = |g: &[usize]| -> Option<f64> {
            let mut r: Vec<f64> = g.iter().filter_map(|&i| scales[i]).collect();
            (!r.is_empty()).then(|| median(&mut r))
        };
        if groups.len() < 2 {
            return one(group_scale(&groups[0]));
        }
        let mut classes: Vec<SizeClass> = groups
            .iter()
            .map(|g| {
                let own: Vec<[f64; 2]> = g.iter().map(|&i| starts[i]).collect();
                SizeClass {
                    members: Some(g.clone()),
                    sizes: Sizes::measure(background, samples, None, Some(&own), group_scale(g), workers),
                }
            })
            .collect();
        classes.sort_by(|a, b| a.sizes.radius.total_cmp(&b.sizes.radius));
        let apart = classes
            .windows(2)
            .all(|w| w[1].sizes.radius > SAME_SIZE * w[0].sizes.radius);
        if apart {
            classes
        } else {
            one(None)
        }
    }

    /// This class's entries of `all` (one per named particle, in order).
    fn starts<T: Clone>(&self, all: &[T]) -> Vec<T> {
        match &self.members {
            None => all.to_vec(),
            Some(m) => m.iter().map(|&i| all[i].clone()).collect(),
        }
    }

    /// Centroid window radius for this class, px ([`locate_window`]).
    fn window(&self) -> f64 {
        locate_window(self.sizes.radius)
    }
}

/// Most rounds of excluding named particles from the per-pixel median and measuring them
/// again.
const EXCLUSION_ROUNDS: usize = 4;
/// Relative change of the largest radius at which those rounds stop.
const SETTLED_SIZE: f64 = 0.05;

/// A named particle whose scale-space answer against a flat level is this many times its
/// answer against the per-pixel median hovers in that median.
const HOVER_RATIO: f64 = 1.5;

/// The starts of the named particles that hover in the per-pixel median: the strongest
/// scale-space answer holding the start ([`scale::holding`]) in the first sample's scan
/// against a flat level (`flat_scan`, see [`first_frame_scan`]) is more than [`HOVER_RATIO`]
/// times its answer in the scan against the median (`median_scan`), or the median shows
/// nothing there. A particle that moves shows
/// whole against both; one that stays put is half or wholly in the median and shows only its
/// leading and trailing edges against it.
fn hovering_starts(median_scan: &[ScaleBlob], flat_scan: &[ScaleBlob], starts: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let (against_median, against_flat) = (
        scale::holding(median_scan, starts),
        scale::holding(flat_scan, starts),
    );
    starts
        .iter()
        .zip(against_median.iter().zip(&against_flat))
        .filter(|(_, (m, f))| match (m, f) {
            (_, None) => false,
            (None, Some(_)) => true,
            (Some(m), Some(f)) => f.peak > HOVER_RATIO * m.peak,
        })
        .map(|(s, _)| *s)
        .collect()
}

/// The largest radius of `classes`, px.
/// The per-pixel `background` taken again with every track of `pass` left out of each
/// sample (within `reach` px of its point there, each sample on the background's exposure)
/// and the pixels no sample shows clear filled from around them; `None` when it would not
/// matter: a background not per-pixel, a pass with concerns, or no tracked point in a sample
/// whose centroid (over `radius` px) the change would move by half its own standard error.
#[allow(clippy::too_many_arguments)]
fn background_without_tracks(
    background: &Background,
    samples: &[FrameView<'_>],
    sample_of: &[Option<usize>],
    numbers: &[usize],
    pass: &Pass,
    radius: f64,
    reach: f64,
    blind_search: Option<(f32, usize)>,
) -> Option<Background> {
    if background.model != BackgroundModel::PerPixel
        || !pass.concerns.is_empty()
        || pass.table.points.is_empty()
    {
        return None;
    }
    let index: std::collections::HashMap<usize, usize> = numbers
        .iter()
        .zip(sample_of)
        .filter_map(|(k, j)| j.map(|j| (*k, j)))
        .collect();
    let mut at: Vec<Vec<[f64; 2]>> = vec![Vec::new(); samples.len()];
    let mut points: Vec<(usize, &TrackPoint)> = Vec::new();
    for p in &pass.table.points {
        if let Some(&j) = index.get(&p.frame) {
            at[j].push([p.x, p.y]);
            points.push((j, p));
        }
    }
    let everywhere: Vec<[f64; 2]> = at.iter().flatten().copied().collect();
    let mut cleaner = background.clone();
    cleaner.exclude_particles(samples, &at, &everywhere, reach, SampleExposure::Matched);
    // Structure as bright as the particles may have been a particle in the median.
    if let Some((contrast, blind_reach)) = blind_search {
        cleaner.find_blind(contrast, blind_reach);
    }
    // What the change does to each point's mass and centroid, read off the two backgrounds
    // without locating again: it matters when some centroid moves by half its standard
    // error and the masses come out steadier by a tenth at least ([`STEADIER`]).
    let mut predicted = pass.table.clone();
    let mut moves = false;
    for (point, (_, p)) in predicted
        .points
        .iter_mut()
        .filter(|q| index.contains_key(&q.frame))
        .zip(&points)
    {
        let (mass, moment) = signal_change(background, &cleaner, [p.x, p.y], radius);
        moves |= p.mass.is_finite() && p.mass > 0.0 && moment / p.mass > 0.5 * p.ep.max(1e-3);
        point.mass += mass;
    }
    let matters = moves && mass_spread(&predicted) < (1.0 - STEADIER) * mass_spread(&pass.table);
    matters.then_some(cleaner)
}

/// How much steadier the masses must come out of a background taken without the tracks for
/// every frame to be located again: on the real bouncing ball they came out 0.3 % steadier,
/// the points moved 0.05 px at most, and the second pass cost 42 % more time; where the
/// particle is in the median they come out 30 % to 99 % steadier (sweep styles 1003,
/// 1030, 1038).
const STEADIER: f64 = 0.1;

/// The mean over `table`'s tracks of the relative spread (standard deviation over mean) of
/// their masses; 0 without any.
fn mass_spread(table: &TrackTable) -> f64 {
    let spreads: Vec<f64> = table
        .by_particle()
        .values()
        .filter_map(|points| {
            let masses: Vec<f64> = points.iter().map(|p| p.mass).filter(|m| m.is_finite()).collect();
            let n = masses.len() as f64;
            let mean = masses.iter().sum::<f64>() / n;
            let var = masses.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / n;
            (masses.len() >= 2 && mean.abs() > 0.0).then(|| var.sqrt() / mean.abs())
        })
        .collect();
    spreads.iter().sum::<f64>() / spreads.len().max(1) as f64
}

/// The change of a particle's signal from background `before` to `after`, over the disc of
/// `radius` px about `centre` (px) along the particles' colour direction: its sum (the change
/// of the particle's mass, grey levels · px²) and the length of its first moment about
/// `centre` (grey levels · px³; divided by the mass, how far the change moves the
/// centroid, px).
fn signal_change(before: &Background, after: &Background, centre: [f64; 2], radius: f64) -> (f64, f64) {
    let (w, h, c) = (before.width, before.height, before.channels);
    let (x0, x1) = (
        (centre[0] - radius).floor().max(0.0) as usize,
        ((centre[0] + radius).ceil().max(0.0) as usize).min(w.saturating_sub(1)),
    );
    let (y0, y1) = (
        (centre[1] - radius).floor().max(0.0) as usize,
        ((centre[1] + radius).ceil().max(0.0) as usize).min(h.saturating_sub(1)),
    );
    let (mut sum, mut moment) = (0.0, [0.0f64; 2]);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (dx, dy) = (x as f64 - centre[0], y as f64 - centre[1]);
            if dx * dx + dy * dy > radius * radius {
                continue;
            }
            let i = (y * w + x) * c;
            let change: f64 = (0..c)
                .map(|ch| f64::from(before.direction[ch] * (before.image[i + ch] - after.image[i + ch])))
                .sum();
            sum += change;
            moment[0] += change * dx;
            moment[1] += change * dy;
        }
    }
    (sum, moment[0].hypot(moment[1]))
}

fn largest_radius(classes: &[SizeClass]) -> f64 {
    classes.iter().map(|c| c.sizes.radius).fold(0.0, f64::max)
}

/// The frames the particle sizes are estimated on.
struct Estimation<'a> {
    background: &'a Background,
    workers: &'a Workers,
    frames: &'a [FrameView<'a>],
}

impl Estimation<'_> {
    /// `measure` (one frame and a worker's finder: its measures) over the first frame and
    /// as many more as should bring the measures to [`SIZE_BLOBS`] at the first frame's
    /// count (the others in parallel), concatenated in frame order; empty without frames.
    fn over_frames<T: Send>(&self, measure: impl Fn(FrameView<'_>, &mut Finder) -> Vec<T> + Sync) -> Vec<T> {
        if self.frames.is_empty() {
            return Vec::new();
        }
        let mut all = self.workers.with(|w| measure(self.frames[0], &mut w.finder));
        let wanted = SIZE_BLOBS.div_ceil(all.len().max(1)).min(self.frames.len());
        let more: Vec<Vec<T>> = (1..wanted)
            .into_par_iter()
            .map(|j| self.workers.with(|w| measure(self.frames[j], &mut w.finder)))
            .collect();
        all.extend(more.into_iter().flatten());
        all
    }
}

/// Estimates the particle radius, px, from the blobs of a few frames: a uniform disc of
/// radius `R` has radius of gyration `R / sqrt(2)`, so `R = sqrt(2)` times the median
/// measured gyration radius (measured in the gain-corrected signal: an exposure change
/// would otherwise make every size grow with its window). Rounds (detect and locate with
/// the current estimate, re-measure) until it changes by less than 0.01 px make the answer
/// independent of the starting value.
///
/// With `starts` (the named particles' positions in the first estimation frame), only the
/// blob nearest each start in that frame is measured; otherwise every blob of the frames
/// [`Estimation::over_frames`] searches.
/// On real video the blobs are mostly texture specks and clutter, and their median is not
/// the particles' size; the structure's start positions say which blobs are particles.
fn estimate_radius(estimation: &Estimation, starts: Option<&[[f64; 2]]>, scale: Option<f64>) -> f64 {
    let background = estimation.background;
    let mut radius = scale
        .or_else(|| scale_start(estimation, starts))
        .unwrap_or(START_RADIUS);
    for _ in 0..RADIUS_ROUNDS {
        let sizes_of = |found: Vec<Detection>| -> Vec<f64> {
            found
                .iter()
                .filter(|d| !d.clipped && d.size.is_finite())
                .map(|d| d.size)
                .collect()
        };
        let mut sizes: Vec<f64> = match starts {
            Some(starts) if !estimation.frames.is_empty() => {
                let found = estimation
                    .workers
                    .with(|w| locate_unfiltered(background, estimation.frames[0], radius, &mut w.finder));
                sizes_of(
                    nearest_each(&found, starts, |d| [d.x, d.y])
                        .into_iter()
                        .copied()
                        .collect(),
                )
            }
            _ => estimation
                .over_frames(|frame, finder| sizes_of(locate_unfiltered(background, frame, radius, finder))),
        };
        if sizes.is_empty() {
            break;
        }
        let next = (median(&mut sizes) * std::f64::consts::SQRT_2).clamp(1.0, 200.0);
        if (next - radius).abs() < 0.01 {
            radius = next;
            break;
        }
        radius = next;
    }
    radius
}

/// Where the radius estimate starts, px: the scale of the particles of the first estimation
/// frame, found in scale space (see [`crate::scale`]): with `starts`, the median over the
/// particle nearest each start; otherwise the typical scale of every particle found
/// ([`scale::typical_radius`]). `None` when no particle is found at any scale.
fn scale_start(estimation: &Estimation, starts: Option<&[[f64; 2]]>) -> Option<f64> {
    match starts {
        Some(starts) => {
            let all = scale_blobs(estimation, false)?;
            let mut radii: Vec<f64> = scale_of_each(&all, starts).into_iter().flatten().collect();
            (!radii.is_empty()).then(|| median(&mut radii))
        }
        None => scale::typical_radius(&scale::strongest(scale_blobs(estimation, true)?)),
    }
}

/// Every scale-space answer in the first of the estimation frames of `samples` against
/// `background` ([`scale_blobs`], the whole ladder); empty without frames.
fn first_frame_scan(background: &Background, samples: &[FrameView<'_>], workers: &Workers) -> Vec<ScaleBlob> {
    let estimation = Estimation {
        background,
        workers,
        frames: &samples[..samples.len().min(RADIUS_SAMPLES)],
    };
    scale_blobs(&estimation, false).unwrap_or_default()
}

/// The scale of each named particle, px, from the answers `all` of one frame: of the
/// strongest answer holding its start ([`scale::holding`]), or else of the particle's
/// strongest answer ([`scale::strongest`]) nearest the start (`None` where nothing answered
/// at any scale).
fn scale_of_each(all: &[ScaleBlob], starts: &[[f64; 2]]) -> Vec<Option<f64>> {
    let held = scale::holding(all, starts);
    let kept = scale::strongest(all.to_vec());
    starts
        .iter()
        .zip(held)
        .map(|(&s, held)| {
            held.or_else(|| {
                nearest_each(&kept, std::slice::from_ref(&s), |b| [b.x, b.y])
                    .first()
                    .map(|b| **b)
            })
            .map(|b| b.radius)
        })
        .collect()
}

/// Every answer over the ladder of scales in the first estimation frame (each radius's
/// blobs); the climb stops beyond every particle's scale when `stop_early`. `None` without
/// frames.
fn scale_blobs(estimation: &Estimation, stop_early: bool) -> Option<Vec<ScaleBlob>> {
    let background = estimation.background;
    let frame = *estimation.frames.first()?;
    let (width, height) = frame.size();
    let at = |radius: f64| -> Vec<ScaleBlob> {
        let blobs = estimation.workers.with(|w| {
            w.finder
                .blobs(background, frame, &unfiltered(background, radius))
                .blobs
        });
        blobs
            .iter()
            .map(|b| ScaleBlob {
                x: b.x as f64,
                y: b.y as f64,
                peak: f64::from(b.peak),
                radius,
                snr: f64::from(b.peak) / band_noise(radius, background.noise_sigma.max(1e-6)),
            })
            .collect()
    };
    // Two radii at a time (one a thread); without named particles the climb stops where
    // nothing answers as strongly as the strongest blobs do below.
    let mut found: Vec<ScaleBlob> = Vec::new();
    for pair in scale::ladder(width, height).chunks(2) {
        let level: Vec<Vec<ScaleBlob>> = pair.par_iter().map(|&r| at(r)).collect();
        let level: Vec<ScaleBlob> = level.into_iter().flatten().collect();
        let stop = stop_early && scale::beyond_every_scale(&found, &level);
        found.extend(level);
        if stop {
            break;
        }
    }
    Some(found)
}

/// The tracks of `table` with a single point, in a frame strictly inside `frames` (first and
/// last, inclusive).
fn one_frame_tracks(table: &TrackTable, frames: (usize, usize)) -> BTreeSet<String> {
    table
        .by_particle()
        .into_iter()
        .filter(|(_, points)| points.len() == 1 && points[0].frame > frames.0 && points[0].frame < frames.1)
        .map(|(id, _)| id.to_string())
        .collect()
}

/// Sample frames the skirts are measured in, at most.
const SKIRT_FRAMES: usize = 8;

/// The skirts ([`skirts`]) of the detected points of `table` in up to
/// [`SKIRT_FRAMES`] of the sample frames of the window, by particle: frame and skirt each.
fn sample_skirts(
    table: &TrackTable,
    frames: &WindowFrames<'_>,
    background: &Background,
    radius: f64,
    workers: &Workers,
) -> Result<BTreeMap<String, Vec<(usize, Skirt)>>, TrackError> {
    let first = frames.numbers.first().copied().unwrap_or(0);
    // At most SKIRT_FRAMES of the sample frames, evenly spread: a median over them is plenty,
    // and each costs a pass over its points' rings.
    let samples: Vec<usize> = (0..frames.numbers.len())
        .filter(|&i| frames.sample_of[i].is_some())
        .collect();
    let every = samples.len().div_ceil(SKIRT_FRAMES).max(1);
    let chosen: Vec<usize> = samples.iter().step_by(every).map(|&i| i + first).collect();
    let mut by_frame: BTreeMap<usize, Vec<&TrackPoint>> = BTreeMap::new();
    for p in &table.points {
        if p.flag == PointFlag::Detected && chosen.binary_search(&p.frame).is_ok() {
            by_frame.entry(p.frame).or_default().push(p);
        }
    }
    let measured: Vec<Vec<(String, usize, Skirt)>> = by_frame
        .into_par_iter()
        .map(|(k, points)| {
            workers.with(|w| {
                let frame = frames.get(k - first, &mut w.decoder, &mut w.frame)?;
                let (width, height) = frame.size();
                w.finder.levelled_signal(background, frame);
                let at: Vec<[f64; 2]> = points.iter().map(|p| [p.x, p.y]).collect();
                let s = skirts(&w.finder.signal, width, height, &at, radius);
                Ok(points
                    .iter()
                    .zip(s)
                    .filter_map(|(p, s)| s.map(|s| (p.particle.clone(), k, s)))
                    .collect())
            })
        })
        .collect::<Result<_, TrackError>>()?;
    let mut out: BTreeMap<String, Vec<(usize, Skirt)>> = BTreeMap::new();
    for (particle, k, s) in measured.into_iter().flatten() {
        out.entry(particle).or_default().push((k, s));
    }
    Ok(out)
}

/// The particles' signal, grey levels: the median over the particles of `frame` (those
/// nearest `starts` when given) of the largest signal within a radius of each; `None` when no
/// particle is found.
fn particle_contrast(
    background: &Background,
    frame: FrameView<'_>,
    sizes: &Sizes,
    starts: Option<&[[f64; 2]]>,
    workers: &Workers,
) -> Option<f32> {
    let (width, height) = frame.size();
    let mut peaks: Vec<f64> = workers.with(|w| {
        let found = w.finder.locate(
            background,
            frame,
            &sizes.params,
            locate_window(sizes.radius),
            Parts::Join,
        );
        let particles: Vec<&Detection> = match starts {
            Some(starts) => nearest_each(&found, starts, |d| [d.x, d.y]),
            None => found.iter().collect(),
        };
        let r = sizes.radius;
        particles
            .iter()
            .map(|d| {
                let (x0, x1) = (
                    (d.x - r).floor().max(0.0) as usize,
                    ((d.x + r).ceil() as usize).min(width - 1),
                );
                let (y0, y1) = (
                    (d.y - r).floor().max(0.0) as usize,
                    ((d.y + r).ceil() as usize).min(height - 1),
                );
                (y0..=y1)
                    .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
                    .filter(|&(x, y)| (x as f64 - d.x).hypot(y as f64 - d.y) <= r)
                    .map(|(x, y)| f64::from(w.finder.signal[y * width + x]))
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .filter(|v| v.is_finite())
            .collect()
    });
    (!peaks.is_empty()).then(|| median(&mut peaks) as f32)
}

/// Every blob of one estimation frame at `radius`, with no size rejection, located in the
/// gain-corrected signal.
fn locate_unfiltered(
    background: &Background,
    frame: FrameView<'_>,
    radius: f64,
    finder: &mut Finder,
) -> Vec<Detection> {
    finder.locate(
        background,
        frame,
        &unfiltered(background, radius),
        locate_window(radius),
        Parts::Keep,
    )
}

/// Detection at `radius` with no size rejection.
fn unfiltered(background: &Background, radius: f64) -> DetectParameters {
    DetectParameters {
        radius,
        noise_sigma: background.noise_sigma,
        expected: None,
    }
}

/// For each start position, the item nearest to it (none when `items` is empty); an item
/// nearest to two starts is counted once per start.
fn nearest_each<'a, T>(items: &'a [T], starts: &[[f64; 2]], at: impl Fn(&T) -> [f64; 2]) -> Vec<&'a T> {
    starts
        .iter()
        .filter_map(|s| {
            items.iter().min_by(|a, b| {
                let da = at(a);
                let db = at(b);
                let da = (da[0] - s[0]).hypot(da[1] - s[1]);
                let db = (db[0] - s[0]).hypot(db[1] - s[1]);
                da.total_cmp(&db)
            })
        })
        .collect()
}

/// One particle's blob measures at `radius` (medians of [`Blob::area`] and
/// [`Blob::extent`], as blobs are found, in the plain signal); `None` when no blob is found
/// (size rejection is then off). With `starts`, of the blobs nearest the named particles'
/// start positions in the first frame; otherwise of every blob of the frames
/// [`Estimation::over_frames`] searches (see
/// [`estimate_radius`] for why).
fn expected_size(estimation: &Estimation, radius: f64, starts: Option<&[[f64; 2]]>) -> Option<BlobSize> {
    let background = estimation.background;
    let params = unfiltered(background, radius);
    let blobs: Vec<Blob> = match starts {
        Some(starts) if !estimation.frames.is_empty() => {
            let blobs = estimation
                .workers
                .with(|w| w.finder.blobs(background, estimation.frames[0], &params).blobs);
            nearest_each(&blobs, starts, |b| [b.x as f64, b.y as f64])
                .into_iter()
                .copied()
                .collect()
        }
        _ => estimation.over_frames(|frame, finder| finder.blobs(background, frame, &params).blobs),
    };
    let inside: Vec<&Blob> = blobs.iter().filter(|b| !b.at_border).collect();
    if inside.is_empty() {
        return None;
    }
    let mut areas: Vec<f64> = inside.iter().map(|b| b.area).collect();
    let mut extents: Vec<f64> = inside.iter().map(|b| b.extent).collect();
    Some(BlobSize {
        area: median(&mut areas),
        extent: median(&mut extents),
    })
}

fn frame_list(frames: &[usize]) -> String {
    let shown: Vec<String> = frames.iter().take(10).map(|f| f.to_string()).collect();
    if frames.len() > 10 {
        format!("{} and {} more", shown.join(", "), frames.len() - 10)
    } else {
        shown.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn detection(x: f64, y: f64, mass: f64) -> Detection {
        Detection {
            x,
            y,
            mass,
            size: 1.0,
            ep: 0.01,
            area: 10.0,
            clipped: false,
        }
    }

    #[test]
    fn estimates_within_a_radius_are_joined_at_their_mass_weighted_mean() {
        // Two halves of one ring (3.7 px either side of its centre at x = 20) and a particle
        // a diameter away: the halves are joined, the particle keeps its own seed.
        let found = [
            detection(16.3, 30.0, 100.0),
            detection(23.7, 30.0, 300.0),
            detection(36.0, 30.0, 200.0),
        ];
        let (seeds, areas) = join_close(&found, 8.0).expect("joined");
        assert_eq!(seeds.len(), 2);
        let joined = seeds.iter().position(|s| s[0] < 30.0).expect("the joined seed");
        assert!((seeds[joined][0] - 21.85).abs() < 1e-9 && (seeds[joined][1] - 30.0).abs() < 1e-9);
        assert!((areas[joined] - 20.0).abs() < 1e-9);
        assert!(seeds.iter().any(|s| (s[0] - 36.0).abs() < 1e-9));
        // Estimates a radius or more apart are left alone.
        assert!(join_close(&found[1..], 8.0).is_none());
    }
}
