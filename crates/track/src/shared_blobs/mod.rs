//! Particles that share a blob, placed again from the image once the tracks are linked.
//!
//! While particles touch or overlap, linking knows how many share a blob but not where each
//! lies in it: it places them from their motion (split points about the blob's centroid,
//! bridged points on their predicted paths), and a particle whose blob swallowed another's
//! keeps the centroid of both. Those points can sit a pixel or two off, nearer the other
//! particle than their own. Once the recording is linked, each frame's flagged points and
//! the points near them are fitted again, jointly, to the frame's signal: each particle is
//! the recording's own single-particle image (its radial profile, measured on isolated
//! particles), and overlapping images combine either by adding (light-emitting spots) or as
//! layers that each cover what lies below (opaque or rendered discs), whichever fits the
//! pixels better. A centroid cannot do this: with a soft split between two overlapping
//! discs each estimate takes the half of the light on its side, a pixel or more off the
//! particle (about `4R / 3π` when they coincide).
//!
//! Which particle is which stays the linker's (the fit starts from the linked positions and
//! keeps their order), then is judged once more from the motion: inside a group, the
//! positions go to the tracks whose accelerations they keep smallest.

mod overlap_fit;
mod profile;
mod relocate;
mod reorder;

pub(crate) use relocate::{relocate_shared, Relocated, SharedBlobs};
pub(crate) use reorder::Starts;

#[cfg(test)]
mod tests;
