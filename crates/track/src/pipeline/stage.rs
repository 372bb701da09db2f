//! One size class's pass over the frames: located and linked at its own radius.

use super::border::{drop_cut_by_border, forget_dropped_bridges};
use super::finder::{Parts, Surround, Workers};
use super::guided::{search_missed, Seen};
use super::options::TrackOptions;
use super::profiles::fit_profiles;
use super::rims::{centre_on_rims, hollow_particles};
use super::size_class::SizeClass;
use super::skirts::{sample_clipping, sample_skirts};
use super::spikes::bridge_spikes;
use super::spokes::mask_spokes;
use super::start_offsets::start_offsets;
use super::track_frames::one_frame_tracks;
use super::window_frames::{ClassFrames, WindowFrames};
use crate::checks::{check_tracks, lost_inside, saturated_edges, shared_images, Concern, TrackConcern};
use crate::excursion::excursion_warnings;
use crate::shared_blobs::{relocate_shared, Relocated, SharedBlobs, Starts};
use crate::{
    backward_disagreements, link_detections, Ambiguity, Background, FrameDetections, LinkOptions,
    LinkOutcome, TrackError, TrackPoint, TrackTable,
};
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap};

/// What one pass of locating and linking found.
pub(super) struct Pass {
    /// Every frame's detections, by size class then frame.
    pub(super) located: Vec<Vec<FrameDetections>>,
    pub(super) table: TrackTable,
    pub(super) ambiguities: Vec<Ambiguity>,
    pub(super) warnings: Vec<String>,
    pub(super) relocated: Relocated,
    /// Each track's concern.
    pub(super) concerns: Vec<PassConcern>,
    /// The particle and frame of each point not written because the particle was cut by the
    /// image border (see `border`).
    pub(super) cut_by_border: BTreeSet<(String, usize)>,
    /// The particle and frame of each written point of a ring whose rim was not found there
    /// (see `rims`).
    pub(super) rim_not_found: BTreeSet<(String, usize)>,
    /// The particle and frame of each point off the path its neighbours agree on (see
    /// `excursion`).
    pub(super) excursions: BTreeSet<(String, usize)>,
}

/// A track's concern, worded for the user.
pub(super) struct PassConcern {
    /// The concern as the error or warning states it.
    pub(super) text: String,
    /// Whether it is that the particle's signal reaches beyond the radius in use
    /// ([`Concern::Larger`]), which a particle left in a per-pixel median raises too.
    pub(super) skirt: bool,
}

impl PassConcern {
    fn of(c: &TrackConcern) -> PassConcern {
        PassConcern {
            text: c.to_string(),
            skirt: matches!(c.concern, Concern::Larger { .. }),
        }
    }
}

/// The inputs every pass of locating and linking shares.
pub(super) struct Stage<'a> {
    pub(super) frames: &'a WindowFrames<'a>,
    pub(super) workers: &'a Workers,
    pub(super) options: &'a TrackOptions,
    /// Frame width and height, px.
    pub(super) size: (usize, usize),
    /// First and last frame of the window.
    pub(super) first: usize,
    pub(super) last: usize,
}

impl Stage<'_> {
    /// Locates every frame against `background` (in parallel, once for each size class; the
    /// local background around each particle as `surround` says) and
    /// links each class's detections, then places again the points of named particles that
    /// shared a blob and checks the tracks.
    pub(super) fn locate_and_link(
        &self,
        background: &Background,
        classes: &[SizeClass],
        surround: Surround,
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
                                (surround == Surround::Plane).then(|| c.plane_reach()),
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
        let mut cut_by_border = BTreeSet::new();
        let mut rim_not_found = BTreeSet::new();
        let mut excursions = BTreeSet::new();
        // Each class's radius and its tracks' particles.
        let mut class_tracks: Vec<(f64, Vec<String>)> = Vec::with_capacity(classes.len());
        for (class, located) in classes.iter().zip(&by_class) {
            let named = options.named_start.as_deref().map(|n| class.starts(n));
            let link = LinkOptions {
                named_start: named.clone(),
                radius: class.sizes.radius,
                width: size.0,
                height: size.1,
                memory: options.memory,
            };
            let linked = link_detections(located, &link);
            // Named identities the recording leaves open: linked backward in time, the
            // particles join other blobs (see `crate::link::backward_disagreements`).
            if named.is_some() {
                warnings.extend(
                    backward_disagreements(located, &link, &linked.table)
                        .iter()
                        .map(ToString::to_string),
                );
            }
            let LinkOutcome {
                table: mut class_table,
                ambiguities: mut class_ambiguities,
                warnings: link_warnings,
            } = linked;
            // With the particle count known, the points of particles that shared a blob are placed
            // again from the image, jointly, and the motion judges once more which is which (see
            // `crate::shared_blobs`).
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
                let image = SharedBlobs {
                    signal_of: &signal_of,
                    width: size.0,
                    height: size.1,
                    radius: class.sizes.radius,
                    window: class.window(),
                };
                let r = relocate_shared(
                    &mut class_table.points,
                    &mut class_ambiguities,
                    &Starts {
                        positions: named,
                        frame: first,
                    },
                    &image,
                )?;
                relocated.moved += r.moved;
                relocated.renamed += r.renamed;
                // Particles the detector missed, searched for where their tracks put them.
                let found = search_missed(
                    &mut class_table,
                    &mut class_ambiguities,
                    named,
                    &Seen {
                        located,
                        placed: &r.placed,
                    },
                    (first, last),
                    &image,
                    background.noise_sigma,
                )?;
                warnings.extend(found);
                warnings.extend(bridge_spikes(&mut class_table, class.sizes.radius));
                warnings.extend(start_offsets(&class_table, named, first, class.sizes.radius));
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
            let reading = ClassFrames {
                frames,
                background,
                radius: class.sizes.radius,
                workers,
            };
            let located_frames: &[FrameDetections] = located;
            let located = sample_skirts(&class_table, &reading)?;
            // Rings are located by their rim's centre (see `rims`), and their skirts measured
            // again about it.
            let hollow = hollow_particles(&located);
            // Particles with lines leaving them, located with the lines cut out (see `spokes`).
            let spoked = mask_spokes(&mut class_table, &hollow, located_frames, &reading)?;
            warnings.extend(spoked.warnings);
            let rims = centre_on_rims(&mut class_table, &hollow, &reading)?;
            warnings.extend(rims.warnings);
            // Noisy particles are located by their own profile where that pays (see `profiles`).
            let fitted = fit_profiles(&mut class_table, &hollow, &reading)?;
            let remeasured;
            let skirts = if spoked.moved + rims.moved + fitted.moved > 0 {
                remeasured = sample_skirts(&class_table, &reading)?;
                &remeasured
            } else {
                &located
            };
            let clipping = sample_clipping(&class_table, frames, class.sizes.radius);
            warnings.extend(saturated_edges(&clipping, class.sizes.radius));
            let strays = excursion_warnings(&class_table);
            warnings.extend(strays.warnings);
            excursions.extend(strays.points);
            // Unnamed tracks end once lost (a particle found again starts a new one): only named
            // tracks can be lost and found again.
            let lost = match named {
                Some(_) => lost_inside(&class_table, class.sizes.radius, size, last),
                None => Vec::new(),
            };
            concerns.extend(
                check_tracks(&class_table, class.sizes.radius, skirts, &located, located_frames)
                    .iter()
                    .chain(&lost)
                    .map(PassConcern::of),
            );
            // Points of particles cut by the image border are not written (see `border`); they
            // served as neighbours and in the checks above.
            let (border, dropped) = drop_cut_by_border(&mut class_table, class.sizes.radius, size);
            warnings.extend(border);
            forget_dropped_bridges(&mut class_ambiguities, &dropped);
            rim_not_found.extend(rims.not_found.into_iter().filter(|p| !dropped.contains(p)));
            cut_by_border.extend(dropped);
            class_tracks.push((class.sizes.radius, class_table.particle_ids()));
            table.points.extend(class_table.points);
            ambiguities.extend(class_ambiguities);
        }
        if classes.len() > 1 {
            // Classes are linked apart: a track of one may have taken another's image.
            let (shared, overlaps) = shared_images(&table, &class_tracks);
            concerns.extend(shared.iter().map(PassConcern::of));
            warnings.extend(overlaps);
        }
        if let (true, Some(named)) = (classes.len() > 1, options.named_start.as_deref()) {
            // Frame, then the structure's order, as one class's tracks are.
            sort_in_structure_order(&mut table.points, named);
            ambiguities.sort_by_key(|a| (a.first_frame, a.last_frame));
        }
        Ok(Pass {
            located: by_class,
            table,
            ambiguities,
            warnings,
            relocated,
            concerns,
            cut_by_border,
            rim_not_found,
            excursions,
        })
    }
}

/// Sorts `points` by frame, then by their particle's place in the structure (`named`; names
/// it does not hold last): the order a class's linked tracks come in.
pub(super) fn sort_in_structure_order(points: &mut [TrackPoint], named: &[(String, [f64; 2])]) {
    let order: HashMap<&str, usize> = named.iter().enumerate().map(|(i, n)| (n.0.as_str(), i)).collect();
    let rank = |p: &TrackPoint| order.get(p.particle.as_str()).copied().unwrap_or(usize::MAX);
    points.sort_by(|a, b| a.frame.cmp(&b.frame).then_with(|| rank(a).cmp(&rank(b))));
}
