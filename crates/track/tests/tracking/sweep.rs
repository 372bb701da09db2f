//! Randomized style sweep (tracker issue 20, "follow any particle a person can see, at any
//! size"): 40 styles drawn by `physfit-synth` (flat discs, Gaussian spots, rings, textured
//! balls, shaded spheres; radius 1.5-60 px, mixed sizes, either polarity, grey or colour,
//! blur, noise, uneven light, exposure drift, saturation) and 8 drawn through physfit's own
//! renderer (flat discs, radius 1.5-60 px), all from fixed seeds.
//!
//! Every particle must be followed in every frame under its own name (recall 1, no identity
//! switch) with an RMS error per axis within
//!
//! * `0.05 px + 0.01 σ` (σ the pixel noise, grey levels) when the smallest particle is at
//!   least 3 px in radius, or `0.10 px + 0.02 σ` below that: a sharp 1.5 px disc's
//!   pixel-integrated image has its own centroid up to 0.01 px off its centre (the pixel grid
//!   aliases its edge), and its centroid window holds more background per unit of signal;
//! * or twice the style's Cramér-Rao bound (the standard deviation), where that is larger;
//! * plus the RMS offset of the noise-free particle's intensity centroid from its centre
//!   (the truth): a shaded sphere's centroid leans towards the light, and an illumination
//!   gradient or vignetting tilts any particle's (a centroid cannot know the centre of a
//!   lopsided image). The larger of the lit centroid's offset and the one under even light
//!   counts: a tracker that reads the light off the background and takes it out follows the
//!   second (a sphere's own lean, which the gradient's may have cancelled in the first). The table shows that offset and the error against the centroid, so a
//!   track that follows the centroid is told from one that follows something else.
//!
//! Every style is run before anything is asserted, and a table with one row per style is
//! printed, so a failure shows every failing style, not the first.

use std::path::Path;

use physfit_model::{Colour, Recording, RenderSettings, Vec2};
use physfit_render::render_sequence;
use physfit_synth::{Lines, Polarity, Profile, Sequence, Style};
use physfit_track::{
    in_view, rms_offset, score_tracks, track_folder, PointFlag, TrackOptions, TrackPoint, TrackTable,
};

use crate::common::{names_at_head, TempDir};

/// Seeds of the styles drawn by `physfit-synth`.
const SYNTH_SEEDS: std::ops::Range<u64> = 1000..1040;
/// Seeds of the flat-disc styles drawn through `physfit-render`.
const RENDER_SEEDS: std::ops::Range<u64> = 2000..2008;

/// One style's outcome: a row of the table.
struct Row {
    source: &'static str,
    style: Style,
    recall: f64,
    rms: [f64; 2],
    rms_centroid: [f64; 2],
    switches: usize,
    crb: [f64; 2],
    offset: [f64; 2],
    tolerance: [f64; 2],
    tracker_radius: f64,
    failure: Option<String>,
    /// Particles whose own RMS error lies beyond the tolerance on an axis and that no
    /// warning of the tracker names (`"{particle}: ..."`): tracks wrong without a word.
    unwarned: Vec<String>,
    /// True centres in view with no point of their particle within the match radius that
    /// the tracker names neither as cut by the border, nor as off its neighbours' path, nor
    /// in an ambiguity over that frame (not seen and bridged, lost, shared): points missing
    /// without a word.
    unnamed_missing: usize,
    /// The light the tracker took out of the particles' images (its range), if any.
    light: Option<f64>,
    /// The pixel noise the tracker read, grey levels (NaN where it refused).
    noise: f64,
    /// True if and only if the tracker said it cut lines leaving particles out of their
    /// windows (`crate::spokes`).
    lines_cut: bool,
    /// True if and only if the tracker said which particle is which is uncertain somewhere
    /// (`crate::link::backward_disagreements`); the particles it named are then warned of
    /// (`unwarned`).
    identities_doubted: bool,
}

impl Row {
    fn passed(&self) -> bool {
        self.failure.is_none()
    }

    /// Followed within the bound, or refused with an error (never tracks that are wrong).
    fn followed_or_refused(&self) -> bool {
        self.passed()
            || self
                .failure
                .as_deref()
                .is_some_and(|f| f.starts_with("tracking failed"))
    }

    /// Followed, refused, or every particle out of its tolerance named in a warning, every
    /// point found or its absence named, each under its own name (never tracks wrong
    /// without a word).
    fn followed_refused_or_warned(&self) -> bool {
        self.followed_or_refused()
            || (self.unnamed_missing == 0
                && (self.switches == 0 || self.identities_doubted)
                && self.unwarned.is_empty())
    }

    fn line(&self) -> String {
        let s = &self.style;
        let mut extras = Vec::new();
        if s.gradient > 0.0 {
            extras.push(format!("grad {:.2}", s.gradient));
        }
        if s.vignetting > 0.0 {
            extras.push(format!("vign {:.2}", s.vignetting));
        }
        if s.exposure > 0.0 {
            extras.push(format!("exp ±{:.2}", s.exposure));
        }
        if s.saturating {
            extras.push("sat".to_string());
        }
        format!(
            "| {} | {} | {} | {:.2} | {} | {:.1} | {:.2} | {} | {} | {} | {} | {:.3} | {:.4} / {:.4} | {:.4} / {:.4} | {} | {:.4} / {:.4} | {:.4} / {:.4} | {:.4} / {:.4} | {:.2} | {} |",
            self.source,
            s.seed,
            s.profile.name(),
            s.radius,
            if s.mixed { "x2.5" } else { "-" },
            s.noise,
            s.blur,
            match s.polarity {
                Polarity::BrightOnDark => "bright",
                Polarity::DarkOnLight => "dark",
            },
            if s.colour { "rgb" } else { "grey" },
            s.particle_count,
            if extras.is_empty() { "-".to_string() } else { extras.join(", ") },
            self.recall,
            self.rms[0],
            self.rms[1],
            self.rms_centroid[0],
            self.rms_centroid[1],
            self.switches,
            self.crb[0],
            self.crb[1],
            self.offset[0],
            self.offset[1],
            self.tolerance[0],
            self.tolerance[1],
            self.tracker_radius,
            match &self.failure {
                None => "pass".to_string(),
                Some(why) if !self.followed_or_refused() && self.followed_refused_or_warned() => {
                    format!("FAIL: {why} (warned)")
                }
                Some(why) => format!("FAIL: {why}"),
            }
        )
    }
}

const HEADER: &str = "| source | seed | profile | radius | mixed | noise | blur | polarity | colour | n | light, camera | recall | RMS x / y (px) | RMS vs centroid x / y | switches | CRB σ x / y | centroid offset x / y | tolerance x / y | tracker radius | result |\n|---|---:|---|---:|---|---:|---:|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|";

/// The truth as a track table: `points[k]` of every particle (centres or centroids).
fn table(names: &[String], points: &[Vec<[f64; 2]>]) -> TrackTable {
    let mut out = Vec::new();
    for (k, frame) in points.iter().enumerate() {
        for (name, p) in names.iter().zip(frame) {
            out.push(TrackPoint::new(k, name.clone(), p[0], p[1]));
        }
    }
    TrackTable { points: out }
}

/// Tracks the frames in `dir` named after `seq`'s particles and scores them.
fn run(source: &'static str, seq: &Sequence, dir: &Path) -> Row {
    let style = seq.style.clone();
    let truth = table(&seq.truth.names, &seq.truth.positions);
    let centroid_truth = table(&seq.truth.names, &seq.truth.centroids);
    let even_truth = table(&seq.truth.names, &seq.truth.even_centroids);
    // The lean allowed: the larger of the lit centroid's and the one under even light (a
    // tracker may follow either: the image's, or the image with the light taken out).
    let lean = |truth: &TrackTable| {
        let (lit, even) = (rms_offset(truth, &centroid_truth), rms_offset(truth, &even_truth));
        [lit[0].max(even[0]), lit[1].max(even[1])]
    };
    let start: Vec<(String, [f64; 2])> = seq
        .truth
        .names
        .iter()
        .cloned()
        .zip(seq.truth.positions[0].iter().copied())
        .collect();
    let crb = seq.bound().sigma();
    let offset = seq.truth.centroid_offset_rms();
    let tolerance_for = |lean: [f64; 2]| style.tolerance(crb, lean);
    let tolerance = tolerance_for(offset);
    let mut row = Row {
        source,
        style: style.clone(),
        recall: 0.0,
        rms: [f64::NAN; 2],
        rms_centroid: [f64::NAN; 2],
        switches: 0,
        crb,
        offset,
        tolerance,
        tracker_radius: f64::NAN,
        failure: None,
        unwarned: Vec::new(),
        unnamed_missing: 0,
        light: None,
        noise: f64::NAN,
        lines_cut: false,
        identities_doubted: false,
    };
    let options = TrackOptions {
        named_start: Some(start),
        threads: Some(1),
        ..TrackOptions::default()
    };
    // PHYSFIT_SWEEP_KEEP=DIR keeps each style's frames in DIR/SOURCE-SEED for a closer look.
    if let Ok(keep) = std::env::var("PHYSFIT_SWEEP_KEEP") {
        let to = Path::new(&keep).join(format!("{source}-{}", style.seed));
        std::fs::create_dir_all(&to).expect("keep folder");
        for entry in std::fs::read_dir(dir).expect("frames").flatten() {
            std::fs::copy(entry.path(), to.join(entry.file_name())).expect("copy frame");
        }
        truth.write_csv(&to.join("truth.csv")).expect("write truth");
    }
    let outcome = match track_folder(dir, &options, &|_, _| {}) {
        Ok(o) => o,
        Err(e) => {
            row.failure = Some(format!("tracking failed: {e}"));
            return row;
        }
    };
    row.light = outcome.stats.light_taken_out;
    row.noise = outcome.stats.noise_sigma;
    row.lines_cut = outcome.warnings.iter().any(|w| {
        w.starts_with("lines leave")
            && w.contains("cut out of the centroid window")
            && !w.contains("plain centroids")
    });
    row.identities_doubted = outcome.warnings.iter().any(|w| w.contains("uncertain identit"));
    // The tracker writes no point of a particle cut by the border (its centre within the
    // radius in use of the edge: the centroid of the part in view leans inward), and says
    // so; those truth points are not asked for.
    let reach = outcome
        .stats
        .radii
        .iter()
        .copied()
        .fold(outcome.stats.radius, f64::max);
    // The tracker judges its own points, which lean with the centroid: a true centre within
    // that lean of the line may be either side of it.
    let reach = reach + offset[0].hypot(offset[1]);
    let size = (style.width as usize, style.height as usize);
    let truth = in_view(&truth, size, reach);
    // The lean allowed is the RMS over the points scored, as the error is: a particle left
    // out near the border takes its lean with it (style 6644: a sphere of 18 px, leaning
    // 0.36 px, left out beside one of 45 px leaning 0.93 px, which was then held to the
    // pair's RMS of 0.70 px).
    row.offset = lean(&truth);
    row.tolerance = tolerance_for(row.offset);
    let tolerance = row.tolerance;
    // A point farther than the smallest true radius from a true centre is on another
    // particle or none.
    let s = score_tracks(&outcome.table, &truth, style.radius);
    // PHYSFIT_SWEEP_DEBUG prints each particle's mean error and spread.
    if std::env::var("PHYSFIT_SWEEP_DEBUG").is_ok() {
        debug_errors(&style, &outcome, &seq.truth);
    }
    let c = score_tracks(
        &outcome.table,
        &in_view(&centroid_truth, size, reach),
        style.radius,
    );
    row.recall = s.matched_count as f64 / s.truth_count.max(1) as f64;
    row.rms = [s.rms_x, s.rms_y];
    row.rms_centroid = [c.rms_x, c.rms_y];
    row.switches = s.id_switches + s.name_mismatches.unwrap_or(0);
    row.tracker_radius = outcome.stats.radius;
    let mut why = Vec::new();
    if s.matched_count < s.truth_count {
        why.push(format!("{} of {} points", s.matched_count, s.truth_count));
    }
    if row.switches > 0 {
        why.push(format!("{} identity errors", row.switches));
    }
    if !(row.rms[0] <= tolerance[0] && row.rms[1] <= tolerance[1]) {
        why.push("RMS".to_string());
    }
    if !why.is_empty() {
        row.failure = Some(why.join(", "));
    }
    row.unwarned = seq
        .truth
        .names
        .iter()
        .filter(|name| {
            let own = |t: &TrackTable| TrackTable {
                points: t
                    .points
                    .iter()
                    .filter(|p| &p.particle == *name)
                    .cloned()
                    .collect(),
            };
            let s = score_tracks(&own(&outcome.table), &own(&truth), style.radius);
            // Each particle is held to its own lean (a large sphere leans farther than a
            // small one beside it).
            let tolerance = tolerance_for(lean(&own(&truth)));
            // NaN (no point matched) counts as beyond the tolerance.
            let within = s.rms_x <= tolerance[0] && s.rms_y <= tolerance[1];
            // A warning names it at its head: `p2: ...`, or `p2 and p6: ...`.
            let named = outcome.warnings.iter().any(|w| names_at_head(w, name));
            // Or its detected points are within the tolerance and each point it was given
            // from its motion lies in a run of frames a warning names it as not seen in (the
            // CSV flags those points interpolated).
            let detected = TrackTable {
                points: own(&outcome.table)
                    .points
                    .into_iter()
                    .filter(|p| p.flag == PointFlag::Detected)
                    .collect(),
            };
            let d = score_tracks(&detected, &own(&truth), style.radius);
            let bridged_in_named_runs = outcome
                .table
                .points
                .iter()
                .filter(|p| &p.particle == *name && p.flag != PointFlag::Detected)
                .all(|p| {
                    outcome.stats.ambiguities.iter().any(|a| {
                        a.particles.contains(name) && (a.first_frame..=a.last_frame).contains(&p.frame)
                    })
                });
            let bridged_warned = d.rms_x <= tolerance[0] && d.rms_y <= tolerance[1] && bridged_in_named_runs;
            !(within || named || bridged_warned)
        })
        .cloned()
        .collect();
    row.unnamed_missing = truth
        .points
        .iter()
        .filter(|t| {
            let found = outcome.table.points.iter().any(|p| {
                p.frame == t.frame && p.particle == t.particle && (p.x - t.x).hypot(p.y - t.y) <= style.radius
            });
            let listed = |points: &[(String, usize)]| {
                points
                    .iter()
                    .any(|(name, frame)| *name == t.particle && *frame == t.frame)
            };
            let cut = listed(&outcome.stats.cut_by_border)
                || listed(&outcome.stats.rim_not_found)
                || listed(&outcome.stats.excursions);
            let ambiguous = outcome.stats.ambiguities.iter().any(|a| {
                a.particles.contains(&t.particle) && (a.first_frame..=a.last_frame).contains(&t.frame)
            });
            // Which particle a track follows on either side of a frame is in doubt.
            let doubted = outcome
                .warnings
                .iter()
                .any(|w| w.contains("uncertain identit") && names_at_head(w, &t.particle));
            !(found || cut || ambiguous || doubted)
        })
        .count();
    row
}

/// Prints the tracker's figures and each particle's mean and spread of error per axis
/// (`PHYSFIT_SWEEP_DEBUG`): a bias tells a systematic error from noise.
fn debug_errors(style: &Style, outcome: &physfit_track::TrackOutcome, truth: &physfit_synth::Truth) {
    eprintln!("style {}: {}", style.seed, outcome.stats);
    for w in &outcome.warnings {
        eprintln!("  warning: {w}");
    }
    for (i, name) in truth.names.iter().enumerate() {
        let mut e: Vec<[f64; 2]> = Vec::new();
        for p in outcome.table.points.iter().filter(|p| &p.particle == name) {
            if let Some(t) = truth.positions.get(p.frame).map(|f| f[i]) {
                e.push([p.x - t[0], p.y - t[1]]);
                if (p.x - t[0]).hypot(p.y - t[1]) > 0.5 {
                    eprintln!(
                        "    {name} frame {}: error {:+.2} / {:+.2} ({:?})",
                        p.frame,
                        p.x - t[0],
                        p.y - t[1],
                        p.flag
                    );
                }
            }
        }
        let mut eps: Vec<f64> = outcome
            .table
            .points
            .iter()
            .filter(|p| &p.particle == name && p.ep.is_finite())
            .map(|p| p.ep)
            .collect();
        let ep = physfit_tracks::stats::median_upper(&mut eps);
        let n = e.len().max(1) as f64;
        let mean = [0, 1].map(|a| e.iter().map(|v| v[a]).sum::<f64>() / n);
        let sd = [0, 1].map(|a| (e.iter().map(|v| (v[a] - mean[a]).powi(2)).sum::<f64>() / n).sqrt());
        let at = truth.positions[0][i];
        eprintln!(
            "  {name} at ({:.0}, {:.0}): {} points, mean error {:+.3} / {:+.3}, spread {:.3} / {:.3}, median ep {ep:.3}",
            at[0],
            at[1],
            e.len(),
            mean[0],
            mean[1],
            sd[0],
            sd[1]
        );
    }
}

/// A synth style drawn from `seed`, tracked.
fn synth_row(seed: u64) -> Row {
    let mut style = Style::random(seed);
    // PHYSFIT_SWEEP_VARIANT=nogradient,novignetting,noexposure,nonoise draws the style without
    // those, to tell which of them a failure comes from; `additive` lights the background
    // alone; `fast` and `faster` let the particles step up to one or two of the largest
    // radii a frame (6 px at least) for a look beyond the drawn speeds.
    if let Ok(v) = std::env::var("PHYSFIT_SWEEP_VARIANT") {
        for part in v.split(',') {
            match part {
                "nogradient" => style.gradient = 0.0,
                "novignetting" => style.vignetting = 0.0,
                "noexposure" => style.exposure = 0.0,
                "nonoise" => style.noise = 0.0,
                "additive" => style.additive_light = true,
                // Steps up to the largest particle's radius a frame (6 px at least), or
                // twice that: a fast throw or bounce at a low frame rate.
                "fast" => hasten(&mut style, 1.0),
                "faster" => hasten(&mut style, 2.0),
                _ => {}
            }
        }
    }
    let seq = Sequence::new(style);
    let dir = TempDir::new("sweep");
    seq.write_frames(dir.path()).expect("write frames");
    run("synth", &seq, dir.path())
}

/// Lets the particles of `style` step up to `times` the largest radius a frame (6 px at
/// least): a fast throw or bounce at a low frame rate.
fn hasten(style: &mut Style, times: f64) {
    let largest = style.radii().iter().fold(0.0f64, |m, &r| m.max(r));
    style.speed = style.speed.max(times * largest.max(6.0));
}

/// A flat-disc style for `physfit-render`: the style drawn from `seed` with the radius
/// spread log-uniformly over 1.5-60 px across the seeds, one size, no uneven light or
/// exposure drift (the renderer draws neither); rendered by `physfit_render`.
fn render_row(seed: u64, index: usize, count: usize) -> Row {
    let mut style = Style::random(seed);
    let u = (index as f64 + 0.5) / count as f64;
    style.radius = 1.5 * 40f64.powf(u);
    style.profile = Profile::Disc;
    style.mixed = false;
    style.particle_count = style
        .particle_count
        .min(((48.0 / style.radius) as usize).clamp(1, 8));
    style.gradient = 0.0;
    style.vignetting = 0.0;
    style.exposure = 0.0;
    style.saturating = false;
    style.background = style.background.map(|v| v.round());
    style.foreground = style.foreground.map(|v| v.round());
    style.fit_frame(1.1);
    style.noise = style.noise.min(style.visible_noise());
    let colour = |c: [f64; 3]| {
        let c = c.map(|v| v.clamp(0.0, 255.0) as u8);
        if style.colour {
            Colour::Rgb(c)
        } else {
            Colour::Grey(c[0])
        }
    };
    let settings = RenderSettings {
        width: style.width,
        height: style.height,
        radius: style.radius,
        background: colour(style.background),
        foreground: colour(style.foreground),
        noise: style.noise,
        blur: style.blur,
        seed,
    };
    let seq = Sequence::new(style);
    let positions: Vec<Vec2> = seq
        .truth
        .positions
        .iter()
        .flatten()
        .map(|p| Vec2::new(p[0], p[1]))
        .collect();
    let recording = Recording {
        particle_count: seq.style.particle_count,
        velocities: vec![Vec2::zeros(); positions.len()],
        positions,
    };
    let dir = TempDir::new("sweep-render");
    render_sequence(&recording, &settings, dir.path(), &|_| {}).expect("render frames");
    run("render", &seq, dir.path())
}

/// Every style of the sweep, 48 drawn from fixed seeds (the synth styles and
/// `physfit-render`'s discs), must be followed within the bound: recall 1, no identity error,
/// RMS within `max(0.05 + 0.01 sigma, 2 CRB)` plus the centroid's own offset. All 48 are
/// since session 36: 1025 (seven shaded spheres of 2.42 px at noise 23, about at the
/// detector's threshold; four of its tracks bridged in half their frames or lost, refused)
/// is followed since a named particle the detector missed is searched for where its track
/// puts it (`pipeline/guided.rs`). Until then the 47 others were held by a test of their
/// own and 1025 by one that it be refused or followed; the history of each style is in
/// `docs/tracking.md`, section 8.
#[test]
fn sweep_of_random_styles_is_followed_within_the_bound() {
    let start = std::time::Instant::now();
    // PHYSFIT_SWEEP_ONLY=SEED,SEED,... runs those styles alone (a seed beyond the render
    // seeds as a synth style, in or out of the sweep's own).
    let only: Option<Vec<u64>> = std::env::var("PHYSFIT_SWEEP_ONLY")
        .ok()
        .map(|v| v.split(',').filter_map(|s| s.trim().parse().ok()).collect());
    let wanted = |seed: &u64| only.as_ref().is_none_or(|o| o.contains(seed));
    let synth: Vec<u64> = match &only {
        Some(o) => o.iter().copied().filter(|s| !RENDER_SEEDS.contains(s)).collect(),
        None => SYNTH_SEEDS.collect(),
    };
    let mut rows: Vec<Row> = synth.into_iter().map(synth_row).collect();
    let count = (RENDER_SEEDS.end - RENDER_SEEDS.start) as usize;
    rows.extend(
        RENDER_SEEDS
            .enumerate()
            .filter(|(_, seed)| wanted(seed))
            .map(|(i, seed)| render_row(seed, i, count)),
    );
    let failed = rows.iter().filter(|r| !r.passed()).count();
    let mut report = format!("{HEADER}\n");
    for r in &rows {
        report.push_str(&r.line());
        report.push('\n');
    }
    report.push_str(&format!(
        "\n{failed} of {} styles fail ({:.1} s)\n",
        rows.len(),
        start.elapsed().as_secs_f64()
    ));
    println!("{report}");
    assert_eq!(failed, 0, "\n{report}");
}

/// A ring style: the style drawn from `seed` (its light, camera, polarity, colours, blur,
/// count and motion) with rings of rim width `width` (a fraction of the radius) and radius
/// `radius` px, one size, under pixel noise `noise` (lowered where the rings would not be
/// visible, as [`Style::random`] does).
fn ring_row(seed: u64, radius: f64, width: f64, noise: f64) -> Row {
    let mut style = Style::random(seed);
    style.profile = Profile::Ring { width };
    style.radius = radius;
    style.mixed = false;
    style.particle_count = style.particle_count.min(((48.0 / radius) as usize).clamp(1, 8));
    style.fit_frame(1.1);
    style.noise = noise.min(style.visible_noise());
    let seq = Sequence::new(style);
    let dir = TempDir::new("sweep-ring");
    seq.write_frames(dir.path()).expect("write frames");
    run("ring", &seq, dir.path())
}

/// Radii of the ring neighbours, px.
const RING_RADII: [f64; 5] = [4.0, 6.0, 9.0, 14.0, 20.0];

/// The rim width of ring neighbour `(seed, radius index)`, a fraction of the radius
/// (0.2-0.35, spread over the seeds and radii).
fn ring_width(seed: u64, i: usize) -> f64 {
    0.2 + 0.15 * ((seed as usize + i) % 4) as f64 / 3.0
}

/// Rings beyond the sweep's seeds: radius 4-20 px, rim 0.2-0.35 of it, noise 5 and 15,
/// each seed's own light and camera. Prints the table; asserts nothing (an exploration of
/// the class, `--ignored`).
#[test]
#[ignore = "exploration: prints the ring neighbours' table"]
fn ring_neighbours_table() {
    let mut report = format!("{HEADER}\n");
    let mut failed = 0;
    let mut count = 0;
    for seed in 3000..3006u64 {
        for (i, &radius) in RING_RADII.iter().enumerate() {
            for &noise in &[5.0, 15.0] {
                let row = ring_row(seed, radius, ring_width(seed, i), noise);
                failed += usize::from(!row.passed());
                count += 1;
                report.push_str(&row.line());
                report.push('\n');
            }
        }
    }
    println!("{report}\n{failed} of {count} ring styles fail");
}

/// Rings of radius 6 and 9 px beside their neighbours (seeds 3001, 3002 and 3005: no
/// gradient, a gradient of 0.17 with vignetting 0.22, none), noise 5 and 15: each is
/// followed within the bound or refused (never tracks that are wrong), and every ring of
/// 6 px is followed. Before estimates that end within a radius of each other were joined,
/// the band-pass answer between two rings' near rims took half a ring, 2r/pi off its
/// centre: 0.66/0.50 px RMS at 6 px and noise 5 under seed 3002's light (0.05 now), and
/// 1.85/1.91 px at 9 px. (Rings of 14-20 px, and rings under a saturating exposure, still
/// fail: `ring_neighbours_table`.)
#[test]
fn rings_beside_neighbours_are_not_split_between_them() {
    let mut bad = Vec::new();
    for seed in [3001u64, 3002, 3005] {
        for i in [1usize, 2] {
            for noise in [5.0, 15.0] {
                let row = ring_row(seed, RING_RADII[i], ring_width(seed, i), noise);
                // Refused is allowed only for the larger rings.
                if !(row.passed() || (row.followed_or_refused() && i > 1)) {
                    bad.push(row.line());
                }
            }
        }
    }
    assert!(bad.is_empty(), "\n{HEADER}\n{}", bad.join("\n"));
}

/// Rings of 14 and 20 px (a third to a half of the sweep's largest particles) beside their
/// neighbours, noise 5 and 15, each seed's light: every one is followed within the bound,
/// refused with an error, or warned of (never tracked wrong without a word), and at least 16
/// of the 20 are followed. Their size was measured on the named particles' blobs among every
/// blob of the frame, whose centroid windows split each other's: a ring's own rim, answering
/// the band-pass at the ring's scale, drew its centre's window onto the rim, and the size
/// settled on the rim's width (3001 at 14 px: 5.7 px, refused). Measured alone, the rings
/// read 17-26 px and 16 of these 20 are followed (3 before, 17 refused), 4 refused. Seed 3001
/// at 20 px and noise 5, its two rings near a corner not found in 7 of 16 frames (the
/// band-pass answers at the frame's edge too, and the ring's blob, merged with that answer,
/// is too large), is followed through them since a rim of another radius than the ring's is
/// not taken for its own (`pipeline::rims`): a bridged point 4 px off before. Before, rings 3
/// to 6 times the radius the estimate settled on were followed on their rim, and the
/// skirt's elongation refuses those (seed 3004 at 20 px and noise 15: 11.4 / 5.5 px RMS at
/// radius 3.11 px).
#[test]
fn large_rings_are_followed_or_refused() {
    let cases: &[(u64, usize, f64)] = &[
        (3000, 3, 5.0),
        (3001, 3, 5.0),
        (3001, 3, 15.0),
        (3001, 4, 5.0),
        (3001, 4, 15.0),
        (3002, 3, 5.0),
        (3002, 3, 15.0),
        (3002, 4, 5.0),
        (3002, 4, 15.0),
        (3003, 3, 5.0),
        (3003, 3, 15.0),
        (3003, 4, 5.0),
        (3003, 4, 15.0),
        (3004, 3, 5.0),
        (3004, 3, 15.0),
        (3004, 4, 5.0),
        (3004, 4, 15.0),
        (3005, 3, 5.0),
        (3005, 4, 15.0),
        (3003, 1, 15.0),
    ];
    let rows: Vec<Row> = cases
        .iter()
        .map(|&(seed, i, noise)| ring_row(seed, RING_RADII[i], ring_width(seed, i), noise))
        .collect();
    let bad: Vec<String> = rows
        .iter()
        .filter(|row| !row.followed_refused_or_warned())
        .map(|row| row.line())
        .collect();
    assert!(bad.is_empty(), "\n{HEADER}\n{}", bad.join("\n"));
    let followed = rows.iter().filter(|row| row.passed()).count();
    let table: Vec<String> = rows.iter().map(Row::line).collect();
    assert!(
        followed >= 16,
        "{followed} of {} followed\n{HEADER}\n{}",
        rows.len(),
        table.join("\n")
    );
}

/// Two rings of 10 px under noise 15 found as one blob between them in a frame (seed 3009,
/// beyond the ring neighbours' seeds): the rim about that blob's centroid, the near arcs of
/// both rings with the neighbour's pixels left out, read 7.2 px against the ring's 8.75 and
/// put the point 13 px off, detected, without a word (0.84 / 1.47 px RMS). A rim of another
/// radius than the particle's is not its own; the point is placed from its motion.
#[test]
fn a_rim_between_two_rings_is_not_taken_for_either() {
    let row = ring_row(3009, 10.0, 0.25, 15.0);
    assert!(row.passed(), "\n{HEADER}\n{}", row.line());
}

/// Rings located by their rim's centre (`crate::rim`): hollow particles of 4-20 px beside
/// their neighbours, under each seed's gradient, vignetting and exposure drift, are followed
/// within `max(0.05 + 0.01 sigma, 2 CRB)` of their true centres, without the allowance for a
/// centroid's lean with the light that the sweep's tolerance adds: the rim's position does
/// not lean. Their intensity centroids did (seed 3000 at 20 px, gradient 0.19: 0.07 / 0.33 px
/// RMS, at 14 px and blur 2.4 px 0.05 / 0.19; seed 3004 at 14 px: 0.11 / 0.11 px; now 0.015 /
/// 0.024, 0.014 / 0.035 and 0.012 / 0.014). The linker's bridges over frames a ring was not
/// detected in are placed again from its rim-centred neighbours, and its rim searched for
/// there (seed 3005 at 14 px and noise 12: 1.77 / 0.87 px RMS with a warning, a bridge 5.7
/// px off; at 20 px and noise 5, a bridge over the last frame 22.8 px off, without one). And
/// rings whose centroids scattered about their
/// rim (seed 3003 at 4 and 6 px and noise 5, a saturating exposure drift: 1.28 / 0.27 and
/// 1.68 / 1.26 px RMS written without a word) are refused.
#[test]
fn rings_are_followed_to_their_rims_centre() {
    let cases: &[(u64, usize, f64)] = &[
        (3000, 2, 5.0),
        (3000, 3, 5.0),
        (3000, 4, 5.0),
        (3000, 4, 15.0),
        (3001, 2, 5.0),
        (3002, 0, 5.0),
        (3002, 1, 5.0),
        (3002, 1, 15.0),
        (3002, 2, 5.0),
        (3002, 4, 5.0),
        (3004, 1, 5.0),
        (3004, 2, 5.0),
        (3004, 2, 15.0),
        (3004, 3, 5.0),
        (3004, 3, 15.0),
        (3005, 2, 5.0),
        (3005, 3, 15.0),
        (3005, 4, 5.0),
    ];
    let mut bad = Vec::new();
    for &(seed, i, noise) in cases {
        let row = ring_row(seed, RING_RADII[i], ring_width(seed, i), noise);
        let base = 0.05 + 0.01 * row.style.noise;
        let within = (0..2).all(|a| row.rms[a] <= base.max(2.0 * row.crb[a]));
        if !(within && row.recall >= 1.0 && row.switches == 0) {
            bad.push(format!("{} (without the lean: {base:.3} px)", row.line()));
        }
    }
    for i in [0, 1] {
        let refused = ring_row(3003, RING_RADII[i], ring_width(3003, i), 5.0);
        if !refused.followed_or_refused() {
            bad.push(refused.line());
        }
    }
    assert!(bad.is_empty(), "\n{HEADER}\n{}", bad.join("\n"));
}

/// A cell of `physfit bench track --sweep` ([`Style::bench_cell`]) of shaded spheres of
/// radius `radius` px under pixel noise `noise`, on `seed`'s motion, tracked.
fn sphere_row(seed: u64, radius: f64, noise: f64) -> Row {
    let sphere = Profile::named("sphere").expect("a shaded sphere profile");
    let seq = Sequence::new(Style::bench_cell(sphere, radius, noise, seed));
    let dir = TempDir::new("sweep-sphere");
    seq.write_frames(dir.path()).expect("write frames");
    run("sphere", &seq, dir.path())
}

/// Shaded spheres (lit from the diagonal, their light gathered towards one side) of 12-48 px
/// are measured out to their silhouette and followed to their intensity centroid, which leans
/// towards the light by a fifth of the radius times the light's tilt: within the sweep's
/// tolerance, and the radius in use from 1.5 px below the true radius (the window, a pixel
/// wider, then cuts at most the dim rim of the limb) to a pixel beyond it plus the lean.
/// The radius of gyration reads such a sphere at 0.8 of its radius, and where the window
/// that small met the border it was not widened to the particle: bench cell seed 7028 at
/// 24 px was followed 1.31 px off (its centroid's lean 0.78), seed 2 at 32 and 48 px 1.55 and
/// 2.71 px off (1.03 and 1.55).
#[test]
fn shaded_spheres_are_measured_to_their_silhouette_and_followed_to_their_centroid() {
    let cases: &[(u64, f64, f64)] = &[
        (1, 12.0, 0.0),
        (2, 12.0, 10.0),
        (7028, 24.0, 0.0),
        (1, 24.0, 10.0),
        (2, 32.0, 0.0),
        (1, 32.0, 10.0),
        (2, 48.0, 0.0),
        (1, 48.0, 10.0),
    ];
    let mut bad = Vec::new();
    for &(seed, radius, noise) in cases {
        let row = sphere_row(seed, radius, noise);
        let lean = row.offset[0].hypot(row.offset[1]);
        let sized = row.tracker_radius >= radius - 1.5 && row.tracker_radius <= radius + lean + 1.0;
        if !(row.passed() && sized) {
            bad.push(format!(
                "{} (radius in use {:.2} px, wanted {:.2}-{:.2})",
                row.line(),
                row.tracker_radius,
                radius - 1.5,
                radius + lean + 1.0
            ));
        }
    }
    assert!(bad.is_empty(), "\n{HEADER}\n{}", bad.join("\n"));
}

/// The style drawn from `seed` with its particles drawn as `profile`, tracked.
fn profile_row(seed: u64, profile: Profile) -> Row {
    let mut style = Style::random(seed);
    style.profile = profile;
    style.fit_frame(1.1);
    let seq = Sequence::new(style);
    let dir = TempDir::new("sweep-neighbours");
    seq.write_frames(dir.path()).expect("write frames");
    run("neighbour", &seq, dir.path())
}

/// Asserts that `row` passed, printing its line of the table.
fn assert_passed(row: &Row) {
    assert!(row.passed(), "\n{HEADER}\n{}", row.line());
}

/// Asserts that `row` was followed, refused, or warned of (see
/// [`Row::followed_refused_or_warned`]), printing its line of the table.
fn assert_not_silent(row: &Row) {
    assert!(row.followed_refused_or_warned(), "\n{HEADER}\n{}", row.line());
}

/// Seven dark dots of 1.6 px on a 60 x 56 frame under a gradient (0.09) and a changing
/// exposure (±0.11), no noise (style 6001, beyond the sweep's seeds): against the constant
/// level, half the frame stood above the noise mask, and the dots there shared that region as
/// their extent (385 px² each). The dots elsewhere (31 px²) were rejected as too small in a
/// third of the frames: recall 0.83, 58 identity errors, no error. One particle's extent is now
/// measured on blobs whose component is their own (17 px²).
#[test]
fn dots_under_uneven_light_are_measured_by_their_own_extent() {
    assert_passed(&synth_row(6001));
}

/// Two dark rings of 7.5 and 19 px under a gradient, no noise (style 6045, beyond the sweep's
/// seeds): each size class is linked on its own, and the large ring's track (at 14.4 px, on
/// its rim) took the small ring's image from frame 2 on, both tracks written on one point for
/// 20 frames without a word. Followed or refused, never that.
#[test]
fn two_classes_tracks_on_one_image_are_refused() {
    let row = synth_row(6045);
    assert!(row.followed_or_refused(), "\n{HEADER}\n{}", row.line());
}

/// Four dark Gaussian spots of 4.5 px, no noise, under an exposure drift of ±0.13 that
/// saturates the light background (style 6101, beyond the sweep's seeds): in the last frames
/// every spot's mass fell by 13 % and then 9 % a frame, beyond each track's own spread, and
/// all four were refused as lost in view. A change every particle of the frame shares is the
/// camera's, and appearances are now compared net of it (followed at 0.005 px).
#[test]
fn a_change_of_exposure_every_particle_shares_loses_none() {
    assert_passed(&synth_row(6101));
}

/// Six dark spheres of 6 px on a light background under vignetting (0.20) and an exposure
/// drift (±0.12) that saturates half the frame in some frames (style 6137, beyond the sweep's
/// seeds): the frame's gain was read from every pixel, the clipped ones pulling it down, and
/// the background taken as `g b` beyond the clip level, so the light round the particles in
/// the clipped part read as lighter than the model: a dark ring round each, and the
/// recording refused. The gain is now read from the pixels that did not clip, and the
/// background is taken as `min(g b, 255)`.
#[test]
fn a_background_saturating_with_the_exposure_is_read_where_it_clipped() {
    assert_passed(&synth_row(6137));
}

/// A bright disc of 34.5 px under noise 10 and vignetting 0.16, moving 40 px over 16 frames
/// near the lower border (style 6237, beyond the sweep's seeds): it stays on its own pixels in
/// most samples, so part of it is in the per-pixel median, and it measured 25.9 px. Taken out
/// of the median along its track, the samples where its points near the border were not
/// written (11, 13 and 14) counted clear and made the median there of the disc itself, and
/// the disc was followed 12 px off its centre without a word. Those samples now hold it where
/// its track puts it, and its size is measured again on the cleaned median (34.2 px): within
/// 1.1 times the tolerance, the uneven background left around it named.
#[test]
fn a_disc_half_in_the_median_near_the_border_is_measured_whole() {
    let row = synth_row(6237);
    let within = row.rms.iter().zip(&row.tolerance).all(|(r, t)| *r <= 1.1 * t);
    assert!(
        row.followed_refused_or_warned() && row.recall >= 1.0 && within,
        "\n{HEADER}\n{}",
        row.line()
    );
}

/// Three bright Gaussian spots of 4.5 px (half-maximum radius), two of them 20 px apart, no
/// noise, under an exposure drift (style 6381, beyond the sweep's seeds): the window alone
/// found each to 0.003 px, but the pass that takes out the plane round each particle, in a
/// window reaching as far as its light (12.4 px), took the neighbour's skirt in with it and
/// moved the two 0.15 px towards each other (0.097 px RMS in y against a tolerance of 0.05),
/// without a word. An estimate with a neighbour nearer than twice its reach now stays.
#[test]
fn gaussian_spots_are_not_pulled_by_a_neighbours_skirt() {
    assert_passed(&synth_row(6381));
}

/// Two dark Gaussian spots of 3.9 px hovering under vignetting 0.05 and an exposure drifting
/// by ±8 %, no noise (style 6248, beyond the sweep's seeds), and six bright spots of 3.2 px
/// under a gradient, vignetting and a drift of ±9 % (6298): the spots stay partly in the
/// per-pixel median, and taking it again without their tracks made their plain masses less
/// steady (the masses follow the exposure), so it was not taken: 0.68 / 0.61 px against a
/// tolerance of 0.056, and 0.088 against 0.063, without a word. Their masses on each frame's
/// exposure come out three times steadier, and the spots are followed (0.016 / 0.021 and
/// 0.015 / 0.008 px). Since the light is taken out of their images (docs/tracking.md section
/// 2, "Light"), 6248 is followed to 0.0075 / 0.0067 px, and 6298's masses are steady to a
/// few parts in a thousand: its last frame's exposure step (3.2 %) is the frame's level only
/// because the border specks' links weigh by their noise (0.12 / 0.10 px RMS, the six points
/// bridged, with them weighing alike; 0.006 / 0.006 px since).
#[test]
fn hovering_spots_under_an_exposure_drift_are_followed() {
    for seed in [6248, 6298] {
        assert_passed(&synth_row(seed));
    }
}

/// Two dark shaded spheres of 12.5 and 31 px, blurred by 2.3 px, under noise 24 (style 6629,
/// beyond the sweep's seeds): the large sphere's edge falls a few grey levels a ring, about
/// the noise of one ring's fall, and a larger fall near its centre, within the noise, was
/// taken for the steepest: no edge was found, its radius stayed at 23.3 px, and its track
/// flipped between two points 2.7 px apart (3.2 px RMS in x against a tolerance of 1.9)
/// without a word. Falls over two rings, the steepest of those above the noise: 34.4 px,
/// followed within the tolerance.
#[test]
fn a_large_noisy_sphere_is_measured_to_its_silhouette() {
    assert_passed(&synth_row(6629));
}

/// Two dark Gaussian spots of 16.6 px under vignetting and an exposure drift of ±0.12 that
/// saturates the light round them in frames 10 and 11 only, 6-10 % of each ring (style 6171,
/// beyond the sweep's seeds): their edges there are cut off where the light is brightest, and
/// their points 0.5 px off, 1.3 times the tolerance. The skirts are measured in frames 0, 3,
/// 6, 9, 12 and 15, and the saturation warning read them alone: nothing was said. The light
/// round each point is now read in every sample frame, and both spots are named.
#[test]
fn light_saturating_between_the_skirts_frames_is_named() {
    assert_not_silent(&synth_row(6171));
}

/// Single rings of 16-56 px, blurred by up to 2.5 px, under noise up to 28.5 and each
/// style's light (fresh styles beyond the sweep's seeds): a centroid window short of a ring's
/// rim is drawn onto the rim, and the window there holds an arc of it, so each round of the
/// radius estimate read a smaller arc: radii of 7.4-22.7 px were read for rings of 16.8-56 px
/// (6063, a ring of 32.7 px: 14.1 px). Each was refused, its skirt, its motion or its
/// detections contradicting the radius. A named particle hollow about its
/// start is now measured by its rim's radius where the window does not reach it, and each is
/// followed. (6063, under noise 28.5 on a light background vignetted to the clip level, is
/// refused again since its frames' gain is read through their clipped values: its skirt
/// holds 53 % of its centre's level, likely the noise clipped at 255, whose mean lies below
/// the model's, which the gain read low before offset in part. Left.)
#[test]
fn rings_whose_window_fell_short_of_their_rim_are_followed() {
    let bad: Vec<String> = [6021, 6116, 6302, 6390, 6488, 6585, 6616]
        .into_iter()
        .map(synth_row)
        .filter(|row| !row.passed())
        .map(|row| row.line())
        .collect();
    assert!(bad.is_empty(), "\n{HEADER}\n{}", bad.join("\n"));
}

/// Noise-free rings (fresh styles 6045, rings of 7.5 and 18.8 px, and 6551, rings of 18 px):
/// their points' errors read under 0.005 px, and a large ring's centroid offsets from its
/// rim's centre, which the pixel sampling moves too, scattered 8.6 and 12.6 times as much as
/// those allow: refused as not following the ring. Each offset's error is now 0.02 px at
/// least (`checks::RIM_OFFSET_FLOOR`), and both are followed within their tolerance.
#[test]
fn noise_free_rings_are_not_refused_for_their_pixel_sampling() {
    assert_passed(&synth_row(6045));
    assert_passed(&synth_row(6551));
}

/// Rings of 1.8 px under noise 16.9 (style 6496, beyond the sweep's seeds): in one frame a
/// ring's rim was not found, and its point, placed from the motion of its rim's centre in
/// the frames around, lies 1.9 px off, beyond the ring's radius. A warning named the frame in
/// its text only, so a program reading the outcome saw a point missing without a word; the
/// point is now listed in `TrackStats::rim_not_found` too.
#[test]
fn a_ring_point_whose_rim_was_not_found_is_listed() {
    assert_not_silent(&synth_row(6496));
}

/// Gaussian spots of 12 px (half-maximum radius), dark, blurred by 2.5 px, under vignetting
/// 0.20 and no noise (style 4006 drawn as spots): the tracked spots are taken out of the
/// per-pixel median as far as their skirts stand above the noise, not `2R + 1`, and are
/// followed within the sweep's tolerance (0.35 / 0.49 px RMS with errors of 0.002 px
/// before, against 0.13 / 0.09).
#[test]
fn gaussian_spots_leave_no_skirt_in_the_median() {
    let gauss = Profile::named("gauss").expect("a Gaussian profile");
    assert_passed(&profile_row(4006, gauss));
}

/// One profile beyond the sweep's seeds: each seed's own style (size, mixed sizes, polarity,
/// colour, blur, noise, light, camera) drawn with the profile `PHYSFIT_NEIGHBOURS_PROFILE`
/// names (`sphere` unless set; `disc`, `gauss`, `ring`, `texture`). Prints the table and how
/// many fail, and how many of those silently (beyond the tolerance, unnamed in a warning);
/// asserts nothing (an exploration of a class, `--ignored`). On 2026-11-27, followed (and
/// written off tolerance without a word): discs 22 (1), Gaussian spots 16 (3), rings 9 (1),
/// textured balls 23 (1), spheres 19 (1).
#[test]
#[ignore = "exploration: prints one profile's neighbours' table"]
fn profile_neighbours_table() {
    let name = std::env::var("PHYSFIT_NEIGHBOURS_PROFILE").unwrap_or_else(|_| "sphere".to_string());
    let profile = Profile::named(&name).expect("a profile's name");
    let mut report = format!("{HEADER}\n");
    let (mut failed, mut silent, mut count) = (0, 0, 0);
    for seed in 4000..4024u64 {
        let row = profile_row(seed, profile);
        failed += usize::from(!row.passed());
        silent += usize::from(!row.followed_refused_or_warned());
        count += 1;
        report.push_str(&row.line());
        report.push('\n');
    }
    println!("{report}\n{failed} of {count} {name} styles fail, {silent} of them without a word");
}

/// Styles no test holds: the synth styles of the seeds `PHYSFIT_FRESH_SEEDS` names (`A..B`,
/// default `6000..6048`), each its own random size, profile, polarity, colour, blur, noise,
/// light and camera. Prints the table and the counts of followed, refused, warned and
/// silently wrong styles; asserts nothing (an estimate of how the tracker does on recordings
/// nobody tuned it on, `--ignored`).
#[test]
#[ignore = "exploration: prints the table of styles beyond the sweep's seeds"]
fn fresh_styles_table() {
    let seeds = std::env::var("PHYSFIT_FRESH_SEEDS").unwrap_or_else(|_| "6000..6048".to_string());
    let (a, b) = seeds.split_once("..").expect("PHYSFIT_FRESH_SEEDS as A..B");
    let (a, b): (u64, u64) = (a.parse().expect("a seed"), b.parse().expect("a seed"));
    let mut report = format!("{HEADER}\n");
    let (mut followed, mut refused, mut warned, mut silent) = (0, 0, 0, 0);
    for seed in a..b {
        let row = synth_row(seed);
        if row.passed() {
            followed += 1;
        } else if row.followed_or_refused() {
            refused += 1;
        } else if row.followed_refused_or_warned() {
            warned += 1;
        } else {
            silent += 1;
        }
        report.push_str(&row.line());
        report.push('\n');
    }
    println!(
        "{report}\nseeds {a}..{b}: {followed} followed, {refused} refused, {warned} warned, {silent} wrong without a word"
    );
}

/// Particles that pass close and fast while one turns (fast-motion styles 6064: rings of
/// 3.2 px stepping 7 px a frame, one stopping dead 11 px from another; 6119: spheres of 1.6
/// px at noise 26, 10 px apart as one turned back) were handed each other's blobs and
/// followed under each other's names without a word. Linked backward in time, the tracks
/// take other blobs there, and the particles are named as uncertain.
#[test]
fn particles_exchanged_as_they_pass_fast_are_named_uncertain() {
    for seed in [6064, 6119] {
        let mut style = Style::random(seed);
        hasten(&mut style, 1.0);
        let seq = Sequence::new(style);
        let dir = TempDir::new("sweep-fast");
        seq.write_frames(dir.path()).expect("write frames");
        let row = run("synth", &seq, dir.path());
        assert!(row.identities_doubted, "style {seed}: {}", row.line());
        assert!(row.followed_refused_or_warned(), "style {seed}: {}", row.line());
    }
}

/// A textured ball of 39.5 px under noise 30, a gradient of 0.19 and vignetting of 0.18
/// (fresh style 6646), tracked against a constant background: the plane around it would move
/// it 1.1-2.5 px in 5 of the 6 samples read, its ring even in 3 of them and curved by the
/// vignetting in 2, so neither count made a majority; it was written 2.9 / 2.7 px off without
/// a word. It is now named in a warning that gives the frames and the move.
#[test]
fn a_ball_the_local_plane_would_move_in_most_samples_is_named() {
    assert_not_silent(&synth_row(6646));
}

/// Shaded spheres of 18 and 45 px (fresh style 6644, no noise) whose small one lies at the
/// border, where it is not scored: the large one, followed to 0.02 px of its intensity
/// centroid, was held to the pair's RMS lean (0.70 px) instead of its own (0.93 px). The
/// tolerance now takes the lean over the points scored, as the error is.
#[test]
fn the_lean_allowed_is_taken_over_the_points_scored() {
    assert_passed(&synth_row(6644));
}

/// Styles under uneven light drawn from `seeds`, each a random style made a Gaussian spot or
/// a flat disc (alternately) of radius 6-50 px (log-uniform), one size, under a gradient of
/// 0.1-0.2 and a vignetting of 0.1-0.25, dark on a light background (one that shows the
/// light), pixel noise at most 8 grey levels (the bias is what is measured), a steady
/// exposure and no saturation; `additive` lights the background alone. (An exposure
/// drifting by ±13 % as well, style 7104 drawn so, scattered a spot of 38 px by 0.3 px from
/// frame to frame, and is left; so are dark backgrounds, see docs/tracking.md section 2.)
fn uneven_light_rows(seeds: std::ops::Range<u64>, additive: bool) -> Vec<Row> {
    use rand::{Rng, SeedableRng};
    seeds
        .map(|seed| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x11_6874);
            let mut style = Style::random(seed);
            style.profile = if seed % 2 == 0 {
                Profile::Gaussian
            } else {
                Profile::Disc
            };
            style.radius = (6f64.ln() + (50f64.ln() - 6f64.ln()) * rng.gen::<f64>()).exp();
            style.mixed = false;
            style.gradient = rng.gen_range(0.1..0.2);
            style.vignetting = rng.gen_range(0.1..0.25);
            style.saturating = false;
            style.exposure = 0.0;
            if style.polarity == Polarity::BrightOnDark {
                std::mem::swap(&mut style.background, &mut style.foreground);
                style.polarity = Polarity::DarkOnLight;
            }
            style.additive_light = additive;
            style.fit_frame(1.1);
            style.noise = style.noise.min(style.visible_noise()).min(8.0);
            let seq = Sequence::new(style);
            let dir = TempDir::new("sweep-light");
            seq.write_frames(dir.path()).expect("write frames");
            run("light", &seq, dir.path())
        })
        .collect()
}

/// Styles whose particles are joined by drawn lines, from `seeds` (a mass-spring model's
/// springs as a physics engine's view draws them, from each particle to the next, beneath
/// them): each a random style made flat discs of radius 3-30 px (log-uniform), one size, 2-5
/// particles, blurred by at most 1 px, the lines 1 px to 0.4 radius wide (log-uniform) at
/// 0.3-1 of the particles' contrast; the light, noise, colour and camera as drawn, no
/// saturation. (Gaussian spots drawn so are left: a line shows through a spot's skirt
/// inside its window, where no cut reaches; docs/tracking.md section 8.)
fn drawn_lines_rows(seeds: std::ops::Range<u64>) -> Vec<Row> {
    use rand::{Rng, SeedableRng};
    seeds
        .map(|seed| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x005b_0ce5);
            let mut style = Style::random(seed);
            style.profile = Profile::Disc;
            style.radius = (3f64.ln() + (30f64.ln() - 3f64.ln()) * rng.gen::<f64>()).exp();
            style.mixed = false;
            style.particle_count = rng.gen_range(2..=5);
            style.blur = style.blur.min(1.0);
            style.saturating = false;
            let widest = (0.4 * style.radius).max(1.0);
            style.lines = Some(Lines {
                width: (widest.ln() * rng.gen::<f64>()).exp(),
                level: rng.gen_range(0.3..1.0),
            });
            style.fit_frame(1.1);
            style.noise = style.noise.min(style.visible_noise());
            let seq = Sequence::new(style);
            let dir = TempDir::new("sweep-lines");
            seq.write_frames(dir.path()).expect("write frames");
            run("lines", &seq, dir.path())
        })
        .collect()
}

/// Discs joined by drawn lines: a line crossing the centroid window's rim pulled discs of
/// 6 px, joined by lines 2 px wide as bright as they, 0.14-0.16 px towards it where the noise
/// allowed 0.006 px, without a word. The lines are now found about each particle and cut out
/// of its window with the side opposite them (`crate::spokes`), or the particle is named in a
/// warning where the cuts did not lead away from its lines (a tangle of lines crossing it).
/// Of 16 random styles, two in three at least are followed within the sweep's bound
/// (measured 13; 9 before the cuts) and in three in four the lines were found and cut
/// (measured 14), with full recall and no identity error in every one. Left (docs/tracking.md
/// section 8): discs of 3.6 px, whose cut window holds a blurred line's edge (7204, 7205),
/// and a disc in a tangle of lines (7215).
#[test]
fn particles_joined_by_drawn_lines_are_followed_to_their_centres() {
    let rows = drawn_lines_rows(7200..7216);
    let mut report = format!("{HEADER}\n");
    for row in &rows {
        report.push_str(&row.line());
        report.push_str(if row.lines_cut { " lines cut\n" } else { "\n" });
    }
    println!("{report}");
    let whole = rows.iter().all(|r| r.recall >= 1.0 && r.switches == 0);
    assert!(whole, "a particle lost or mistaken:\n{report}");
    let followed = rows.iter().filter(|r| r.passed()).count();
    let cut = rows.iter().filter(|r| r.lines_cut).count();
    assert!(
        3 * followed >= 2 * rows.len() && 4 * cut >= 3 * rows.len(),
        "{followed} of {} followed, lines cut in {cut}:\n{report}",
        rows.len()
    );
}

/// Spots and discs under an illumination gradient and vignetting that light them as they
/// light the background are followed to their centres, not to their lit centroids: each
/// axis within the sweep's bound without the lean plus a quarter of the lean (before the
/// light was read off the background, fresh style 6081, a spot of 45 px, was followed
/// 0.95 / 0.48 px off its centre, leaning 1.26 / 0.13 px).
#[test]
fn particles_under_uneven_light_are_followed_to_their_centres() {
    let rows = uneven_light_rows(7100..7108, false);
    let mut report = format!("{HEADER}\n");
    let mut wrong = Vec::new();
    for row in &rows {
        report.push_str(&row.line());
        report.push('\n');
        let bound = row.style.tolerance(row.crb, [0.0; 2]);
        let within = (0..2).all(|a| row.rms[a] <= bound[a] + 0.25 * row.offset[a]);
        if !(row.passed() && within) {
            wrong.push(row.style.seed);
        }
    }
    // The class is tested only if the light leans the particles' centroids.
    let leaning = rows
        .iter()
        .filter(|r| r.offset[0].hypot(r.offset[1]) > 0.1)
        .count();
    assert!(
        leaning >= 4,
        "only {leaning} styles lean by over 0.1 px:\n{report}"
    );
    assert!(
        wrong.is_empty(),
        "styles {wrong:?} not followed to their centres:\n{report}"
    );
}

/// The same styles under light that falls on the background alone (a haze, a lamp on the
/// backdrop): where the particles cross enough of the light, their brightness along the
/// tracks, unchanged by it, tells that it is not to be taken out of their images (styles
/// 7101, 7105-7107); where they cannot tell (a single spot that hovers, 7102 and 7104, 0.5
/// and 0.3 px off with it taken out; small discs under noise 8, 7103) it stays, and a
/// warning names each particle it moved by more than its noise. (Whether the particles are
/// then followed within the bound is the tracker's under an uneven background: style 7107's
/// disc of 18 px, 4 px from the border, is 0.19 px off there, left.)
#[test]
fn light_on_the_background_alone_is_dropped_or_named() {
    let rows = uneven_light_rows(7100..7108, true);
    let report: String = rows
        .iter()
        .map(|r| format!("{} light taken out: {:?}\n", r.line(), r.light))
        .collect();
    for row in &rows {
        assert!(
            row.light.is_none() || row.followed_refused_or_warned(),
            "style {}: the light taken out without a word:\n{HEADER}\n{report}",
            row.style.seed
        );
    }
    // Every style's background shows the light; where the tracks tell, it is dropped.
    let dropped = rows.iter().filter(|r| r.light.is_none()).count();
    assert!(
        dropped >= 3,
        "the light dropped in {dropped} of 8 styles:\n{HEADER}\n{report}"
    );
}

/// The seeds of the first `count` synth styles from seed `from` on that `keep` holds.
fn first_styles(from: u64, count: usize, keep: impl Fn(&Style) -> bool) -> Vec<u64> {
    (from..)
        .filter(|&s| keep(&Style::random(s)))
        .take(count)
        .collect()
}

/// The largest difference between a style's particle and background colours over the
/// channels, grey levels.
fn contrast(style: &Style) -> f64 {
    (0..3)
        .map(|c| (style.foreground[c] - style.background[c]).abs())
        .fold(0.0, f64::max)
}

/// Tracks the synth styles `seeds` and asserts that none is written wrong without a word
/// and that at least `least` are followed within the bound, printing the table (each row
/// with the noise the tracker read).
fn assert_class_followed(seeds: &[u64], least: usize) {
    let rows: Vec<Row> = seeds.iter().map(|&s| synth_row(s)).collect();
    let report: String = rows
        .iter()
        .map(|r| format!("{} noise read {:.2}\n", r.line(), r.noise))
        .collect();
    println!("{HEADER}\n{report}");
    let silent: Vec<u64> = rows
        .iter()
        .filter(|r| !r.followed_refused_or_warned())
        .map(|r| r.style.seed)
        .collect();
    assert!(
        silent.is_empty(),
        "styles {silent:?} written wrong without a word:\n{HEADER}\n{report}"
    );
    let followed = rows.iter().filter(|r| r.passed()).count();
    assert!(
        followed >= least,
        "{followed} of {} followed:\n{HEADER}\n{report}",
        seeds.len()
    );
}

/// The first 24 styles from seed 7200 on that are dark on a light background under a
/// drifting exposure (±5 % and more; a third of those drawn so clip the light background at
/// 255 for part of the recording), each otherwise as drawn (any profile, size, colour, blur,
/// noise and light): at least 20 are followed within the bound. Before the frames' gain was
/// read through their clipped values (and an RGB frame's on every channel), 17 were, and
/// dark styles under a drifting exposure were refused four times as often as the rest of
/// the fresh styles (65 of 311 against 16 of 601). None is written wrong without a word
/// (7247, discs of 2.7 px blurred by 3 px under noise 14.6, one point of which lies 2.7 px
/// off its neighbours' path in frame 1, was, before single-frame excursions were named).
#[test]
fn dark_particles_under_a_drifting_exposure_are_followed() {
    let seeds = first_styles(7200, 24, |style| {
        style.polarity == Polarity::DarkOnLight && style.exposure >= 0.05
    });
    assert_class_followed(&seeds, 20);
}

/// Fresh style 6653 (a shaded sphere of 39 px under vignetting of 0.24, near a corner of a
/// frame of 283 x 261 px) and its neighbours, the first 12 styles from seed 7400 on whose
/// particles are sized at their edge (a disc, a textured ball or a shaded sphere) and large
/// (25 px and more) under vignetting (0.1 and more), each otherwise as drawn. Such a
/// particle barely moves for its size, so it is in the per-pixel median, and the light read
/// off that median bends with it: 6653 was followed 8 px off without a word while the light
/// under it was kept as first read (twice its radius about its positions left 23 % of the
/// frame to read it on again). None is written wrong without a word, and at least 11 of the
/// 13 are followed within the bound (12; of the 12 neighbours, 11 were on the earlier code
/// too, and one, 7802, a sphere of 42 px under a saturating exposure, is refused).
#[test]
fn large_particles_that_hover_under_vignetting_are_followed() {
    let neighbours = first_styles(7400, 12, |style| {
        matches!(
            style.profile,
            Profile::Disc | Profile::Textured { .. } | Profile::Sphere { .. }
        ) && style.radius >= 25.0
            && style.vignetting >= 0.1
    });
    let seeds: Vec<u64> = std::iter::once(6653).chain(neighbours).collect();
    assert_class_followed(&seeds, 11);
}

/// Fresh styles 6139, 6168 and 6419 (a ring, a disc and a textured ball of 21-29 px, one in
/// each recording) and their neighbours, the first 12 styles from seed 7600 on that hold one
/// particle of 15 px or more, each otherwise as drawn. With one particle there are no links
/// between particles to pool the size's frame-to-frame spread from, and a track judged sizes
/// against the spread's floor of 0.001 px: the three took a speck 126-232 px away in the
/// frame after their start and were refused (as were fresh 6063, 6611, 6746 and 6798). At
/// least 13 of the 15 are followed within the bound (14; of the neighbours, 11 were before
/// too), and none is written wrong without a word.
#[test]
fn single_large_particles_are_followed() {
    let neighbours = first_styles(7600, 12, |style| {
        style.particle_count == 1 && style.radius >= 15.0
    });
    let seeds: Vec<u64> = [6139, 6168, 6419].into_iter().chain(neighbours).collect();
    assert_class_followed(&seeds, 13);
}

/// Fresh style 8350 (a textured ball of 3 px, 30 grey levels dark at noise 11 under
/// vignetting, alone in a frame of 58 × 62 px) and its neighbours, the first 12 styles from
/// seed 8400 on that hold one or two particles of 5 px or less, under 8 or more grey levels
/// of noise, less than 6 noise sigmas from the background, in uneven light (vignetting of
/// 0.05 or a gradient of 0.1 and more), each otherwise as drawn. The light left out of the
/// background outweighed 8350's particle when the signal's sign was read off the pixels, and
/// the bright middle of its frame was followed 16.6 px away without a word; the named starts
/// now say which way the particles face. At least 11 of the 13 are followed within the bound
/// (12; 11 before, 8350 not among them), and none is written wrong without a word.
#[test]
fn faint_particles_in_uneven_light_are_followed() {
    let neighbours = first_styles(8400, 12, |style| {
        style.particle_count <= 2
            && style.radius <= 5.0
            && style.noise >= 8.0
            && contrast(style) < 6.0 * style.noise
            && (style.vignetting >= 0.05 || style.gradient >= 0.1)
    });
    let seeds: Vec<u64> = std::iter::once(8350).chain(neighbours).collect();
    assert_class_followed(&seeds, 11);
}

/// Fresh style 8321 (five discs of 1.5 px blurred by 2.5 px, 15 grey levels over noise 5.5,
/// under vignetting) and its neighbours, the first 12 styles from seed 8400 on that hold four
/// or more particles of one size, 2.5 px or less, blurred by 2 px or more, each otherwise as
/// drawn. Such a faint, broad particle can rise above the noise as two peaks, and its track
/// took one half, 2.5 px off (8321 frame 12; fresh 6435, 6580, 8275 and 8426 alike); a named
/// particle's halves are now joined. At least 11 of the 13 are followed within the bound (11,
/// the other two refused; 9 before, 8321 and 8426 written wrong without a word), and none is
/// written wrong without a word. (Recordings that mix sizes are another class: 8767, the
/// first of them here, loses its small particle beside a large one in 6 of 17 frames.)
#[test]
fn faint_blurred_particles_found_as_halves_are_followed() {
    let neighbours = first_styles(8400, 12, |style| {
        style.particle_count >= 4 && !style.mixed && style.radius <= 2.5 && style.blur >= 2.0
    });
    let seeds: Vec<u64> = std::iter::once(8321).chain(neighbours).collect();
    assert_class_followed(&seeds, 11);
}

/// Sweep style 1025 (seven shaded spheres of 2.42 px, about 51 grey levels above the
/// background at their centres under noise 23) and its neighbours, the first 12 styles from
/// seed 8400 on that hold three or more particles of one size, 4 px or less, less than 4
/// noise sigmas from the background, each otherwise as drawn. Such particles stand about at
/// the detector's threshold, and a named track was bridged in half its frames or lost (1025
/// refused: four of its seven tracks); a named particle the detector missed is now searched
/// for where its track puts it (`pipeline/guided.rs`). At least 10 of the 13 are followed
/// within the bound and none is written wrong without a word: 10 followed,
/// 1 warned, 2 refused (8780, 9276: bridged in all but one of their frames). Before the
/// search, 10 were followed too, 1025 refused: 10744 (rings of 1.76 px at noise 23) was
/// followed, bridged in 27 points; searched, one point is found 1.9 px off (3.3 times its
/// error) where its bridge was 0.35 px off, and is named in a warning.
#[test]
fn faint_small_particles_near_the_threshold_are_followed() {
    let neighbours = first_styles(8400, 12, |style| {
        style.particle_count >= 3
            && !style.mixed
            && style.radius <= 4.0
            && contrast(style) < 4.0 * style.noise
    });
    let seeds: Vec<u64> = std::iter::once(1025).chain(neighbours).collect();
    assert_class_followed(&seeds, 10);
}

/// Particles with an edge whose light falls off inside it (shaded spheres, textured balls)
/// of 10 px or more under an illumination gradient or vignetting: fresh styles 6198 and 6389
/// (spheres of 27 and 21 px beside smaller ones, written 2.7 / 0.8 and 0.4 / 0.7 px off
/// against tolerances of 1.4 / 0.5 and 0.3 / 0.5 without a word), 6447 (textured balls of 22
/// px, 5.8 / 2.4 px off, warned) and the first 12 styles from seed 9800 on of such particles,
/// each otherwise as drawn. Their radius of gyration reads short of their silhouette, which
/// the profile's steepest fall beyond the window finds; a constant background a few grey
/// levels off the local one set the profile's whole tail below zero, and that was read as a
/// dark halo (not one particle's image), the radius left short and the window cut the
/// particle on its bright side. None may be written wrong without a word, and at least 12
/// of the 15 must be followed within the bound.
#[test]
fn large_shaded_particles_under_uneven_light_are_sized_to_their_silhouette() {
    let neighbours = first_styles(9800, 12, |style| {
        let largest = if style.mixed {
            2.5 * style.radius
        } else {
            style.radius
        };
        largest >= 10.0
            && (style.gradient > 0.0 || style.vignetting > 0.0)
            && matches!(style.profile, Profile::Sphere { .. } | Profile::Textured { .. })
    });
    let seeds: Vec<u64> = [6198, 6389, 6447].into_iter().chain(neighbours).collect();
    assert_class_followed(&seeds, 12);
}

/// Rings wider than the radius the tracker sizes them at, found as two or three arcs of
/// their rim: fresh styles 6717 (a clean ring of 33 px, three arcs 40.6 px apart at a radius
/// of 40.4 px), 6038 (53 px) and 6487 (16 px), refused as reaching beyond their radius,
/// 6336 and 6403 (29 and 25 px, 0.5-5.6 px off, warned), and the first 12 styles from seed
/// 10000 on of rings of 12 px or more (or mixed with such), each otherwise as drawn. Arcs
/// within two radii of each other are joined where a closed rim is found about their
/// midpoint, holding both (`pipeline/finder.rs`, `join_close`). None may be written wrong
/// without a word, and at least 14 of the 17 must be followed within the bound.
#[test]
fn wide_rings_found_as_arcs_are_joined() {
    let neighbours = first_styles(10_000, 12, |style| {
        let largest = if style.mixed {
            2.5 * style.radius
        } else {
            style.radius
        };
        largest >= 12.0 && matches!(style.profile, Profile::Ring { .. })
    });
    let seeds: Vec<u64> = [6717, 6038, 6487, 6336, 6403]
        .into_iter()
        .chain(neighbours)
        .collect();
    assert_class_followed(&seeds, 14);
}

/// Noisy small particles, whose centroid's error runs to two to four times the bound: fresh
/// styles 8020 and 8145 (rings of 4.3 and 3.4 px at noise 16 and 21, written 0.26 / 0.20 and
/// 0.41 / 0.31 px off against tolerances of 0.25 and 0.26 without a word) and the first 12
/// styles from seed 9600 on of plain discs, Gaussian spots or rings of 6 px or less, one size,
/// under noise 12 or more, each otherwise as drawn. Their points are now located by a fit of
/// their own mean profile where it pays (`pipeline/profiles.rs`): none may be written wrong
/// without a word, and at least 12 of the 14 must be followed within the bound.
#[test]
fn noisy_small_particles_are_located_near_their_bound() {
    let neighbours = first_styles(9600, 12, |style| {
        !style.mixed
            && style.radius <= 6.0
            && style.noise >= 12.0
            && matches!(
                style.profile,
                Profile::Disc | Profile::Gaussian | Profile::Ring { .. }
            )
    });
    let seeds: Vec<u64> = [8020, 8145].into_iter().chain(neighbours).collect();
    assert_class_followed(&seeds, 12);
}
