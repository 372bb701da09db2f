//! The background of a recording: its model, how the model is chosen, and the estimate's fields.

use crate::blind::BlindPixels;

/// Which background model a recording uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackgroundModel {
    /// One level per channel for the whole frame.
    Constant,
    /// The per-pixel median over time.
    PerPixel,
}

/// How the background model is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BackgroundChoice {
    /// Constant if the median image is flat apart from compact spots, or its structure
    /// covers no more than twice the part of a frame that moves; else per-pixel.
    #[default]
    Auto,
    /// Always a constant level.
    Constant,
    /// Always the per-pixel median over time.
    PerPixel,
}

/// The estimated background of a recording and how particle signal is measured against it.
#[derive(Clone, Debug, PartialEq)]
pub struct Background {
    /// The model in use.
    pub model: BackgroundModel,
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Samples per pixel (1 or 3).
    pub channels: usize,
    /// Constant background level per channel, grey levels.
    pub level: Vec<f32>,
    /// Per-pixel background (`width * height * channels`, grey levels); the constant level
    /// everywhere for [`BackgroundModel::Constant`].
    pub image: Vec<f32>,
    /// Unit colour direction of particles against the background (one entry per channel);
    /// signal = direction · (pixel − background).
    pub direction: Vec<f32>,
    /// Standard deviation of the signal over background pixels, grey levels (≥ 0.3, the
    /// quantisation noise of 8-bit levels).
    pub noise_sigma: f64,
    /// Fraction of pixels where the per-pixel median differs from the constant level by
    /// more than its noise allows (what the automatic choice looked at).
    pub structured_fraction: f64,
    /// Frames the estimate was made from.
    pub sample_count: usize,
    /// The samples' mean [`Background::frame_gain`]: what a frame's own gain is compared
    /// with (about 1).
    pub reference_gain: f64,
    /// The brightest background value, grey levels: the scale against which a change of
    /// gain is judged significant (see [`Background::remove_gain`]).
    pub brightest: f64,
    /// The largest fraction, over the samples, of a frame's values at the 8-bit clip level
    /// (255): where the exposure drives part of the background into saturation, a gain is
    /// no longer one offset over a flat background (see
    /// [`Background::uniform_gain_offset`]).
    pub saturated_fraction: f64,
    /// Pixel noise measured from differences of consecutive samples, grey levels (sets the
    /// threshold of the colour direction).
    pub temporal_noise: f64,
    /// Mean of the clipped noise added to the background (along `direction`) where most of
    /// the background's noise is clipped at black or white, grey levels; 0 otherwise.
    pub clip_offset: f64,
    /// How far a pixel's per-pixel median must be from the constant level to count as
    /// structure (four standard errors of a median over the samples, at least 3), grey
    /// levels.
    pub structure_threshold: f32,
    /// Pixels where the background is as bright as a particle along its colour direction, so
    /// that a particle cannot show there, and how their signal is filled in (see
    /// [`Background::find_blind`]); none until then.
    pub blind: BlindPixels,
    /// The light over the frame where the per-pixel background is one even surface lit
    /// unevenly: the signal is divided by it (see [`crate::Light`]); `None`
    /// otherwise.
    pub light: Option<super::Light>,
    /// The colour direction the named particles were found to face where it turned the one
    /// the pixels gave (see [`Background::face_starts`]): a direction measured again is
    /// signed to agree with it; `None` otherwise.
    pub facing: Option<Vec<f32>>,
}

/// How [`Background::exclude_particles`] takes the samples' levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleExposure {
    /// As the frames hold them.
    AsRecorded,
    /// Each divided by its gain against the background, so that a median over a few clear
    /// samples does not carry their exposure, unlike its neighbours' over others. Only where
    /// the particles are known in every sample (from tracks): against a median that still
    /// holds particles the gains are off, and matching on them turned two refused styles of
    /// the sweep (1031, 1033) into tracks 1-18 px wrong without a word.
    Matched,
}

/// Least sample frames a background pixel's median is taken over once particles are
/// excluded ([`Background::exclude_particles`]).
pub const CLEAR_SAMPLES: usize = 3;

/// Fraction of structured pixels above which the per-pixel model is chosen.
pub(crate) const STRUCTURED_LIMIT: f64 = 0.02;
