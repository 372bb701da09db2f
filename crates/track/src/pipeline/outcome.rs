//! What tracking returns: the table, its statistics and warnings.

use crate::{Ambiguity, BackgroundModel, FrameDetections, TrackTable};

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
    /// The particle and frame of each point not written because the particle was cut by
    /// the image border (its centre within the radius in use of the edge: the centroid of
    /// the part in view leans inward), by particle then frame; a warning names them too.
    pub cut_by_border: Vec<(String, usize)>,
    /// The particle and frame of each point of a ring (a hollow particle) whose rim was not
    /// found in that frame, by particle then frame: placed from the motion of its rim's
    /// centre in the frames around it (flagged interpolated, `ep` unknown), or, with too few
    /// such frames, left at its centroid, which can lie the rim's width or more off the
    /// ring's centre; a warning names them too.
    pub rim_not_found: Vec<(String, usize)>,
    /// The particle and frame of each detected point that lies off the path its neighbours
    /// agree on (a single-frame excursion: a noise peak, a fragment or another image taken
    /// for a frame), by particle then frame; a warning names them too.
    pub excursions: Vec<(String, usize)>,
    /// The light read off the background and taken out of the particles' images, as its
    /// brightest over its dimmest level (docs/tracking.md section 2, "Light"); `None` where
    /// none was (a background with structure of its own, lit evenly, near black, or a light
    /// the tracks showed falls on the background alone).
    pub light_taken_out: Option<f64>,
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
        )?;
        if let Some(range) = self.light_taken_out {
            write!(
                f,
                ", uneven light taken out of the particles' images (brightest {:.0} % above dimmest)",
                100.0 * (range - 1.0)
            )?;
        }
        Ok(())
    }
}

/// The result of [`track_folder`](crate::track_folder).
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
