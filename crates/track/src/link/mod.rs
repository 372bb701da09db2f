//! Linking: detections of successive frames joined into trajectories.
//!
//! A key design decision made in this module is that identity is never guessed silently.
//! Each frame, every live track predicts where its particle is (constant position, then
//! constant velocity, then constant acceleration once the track's own history shows that
//! model predicts better), with a prediction scale learned from the track's past
//! prediction residuals. Motion is extrapolated (Lagrange polynomial through the latest two
//! or three anchors) from points located from the particle's own blob, preferring those no
//! other tracked particle was near enough to share light with (a soft Voronoi split pulls
//! touching particles' centroids), as long as the newest of them is recent. Candidate
//! detections within a gate of that scale come from a cell grid (`point_grid.rs`), and
//! tracks are assigned to detections by optimal assignment over the whole frame (Hungarian
//! method on each connected group of competing tracks), never greedily.
//!
//! Appearance tells a particle from untracked objects: a track with no other track's
//! prediction within reach compares each candidate's log mass and size with its own recent
//! ones, in units of their measured frame-to-frame spreads ([`crate::TrackAppearance`]).
//! The squared standardised changes add to the cost, and a candidate whose combined change
//! (square root of their sum) exceeds [`APPEARANCE_GATE_SIGMAS`] (twice that in the second
//! chance, whose position gate is also doubled) is another object: the hand that threw the
//! ball, or the ball's reflection in the floor.
//!
//! A blob may hold several particles: its mass, compared with a single particle's, says
//! how many tracks it can take, and a track whose prediction falls inside a blob already
//! taken joins it. The particles of a merged blob are placed at the blob's centroid plus
//! their predicted offsets from the group's mean (flag `split`). A track that finds
//! nothing is bridged with its prediction (flag `interpolated`); once it is found again,
//! the bridged points are replaced by a cubic through the detected points on either side.
//! Each bridged or merged run is reported as an [`Ambiguity`] with its frames and tracks.
//!
//! With named start positions (a structure), exactly those particles are followed for the
//! whole window: unmatched detections never start tracks, and a track is never dropped
//! while it is in the image. Without them, every unmatched detection starts a track named
//! by an integer, and tracks unseen for more than `memory` frames end. Named tracks are
//! checked by linking the same detections backward in time ([`backward_disagreements`]):
//! where the two directions put a particle on different blobs, which is which is uncertain.

mod backward;
mod claimants;
mod fragments;
mod link_detections;
mod linker;
mod options;
mod outcome;
mod reacquire;
mod settle;
mod single_particle;
mod step_bound;
mod track;

pub use backward::{backward_disagreements, Disagreement};
pub use link_detections::link_detections;
pub use options::{FrameDetections, LinkOptions};
pub use outcome::{Ambiguity, AmbiguityKind, LinkOutcome};

/// Gate half-width in units of a track's prediction scale.
const GATE_SIGMAS: f64 = 4.0;
/// Weight of the newest residual in a track's running mean squared prediction error.
const RESIDUAL_RATE: f64 = 0.3;
/// A candidate whose log mass or size differs from the track's latest by more than this
/// many of the measured frame-to-frame spreads is another object (a hand, a reflection).
/// The spreads are robust (median-based) estimates and real features have heavier tails
/// than a normal distribution, hence one more than the position gate.
pub const APPEARANCE_GATE_SIGMAS: f64 = GATE_SIGMAS + 1.0;
/// Frames a track may rely on older uncrowded points for its motion before it falls back
/// on crowded ones (a particle that stays near another for longer moves on its own).
const CLEAN_ANCHOR_AGE: usize = 3;

#[cfg(test)]
pub(crate) mod tests;
