//! The frames of the tracked window, decoded on demand.

use super::finder::Workers;
use super::samples::check_size;
use crate::{Background, DecodedFrame, Frame, FrameDecoder, FrameSource, FrameView, TrackError};
use std::path::Path;

/// What a pass over one size class's tracked points reads the frames with: the window's
/// frames, the background model their signal is formed against, the class's radius (px)
/// and the idle workers (the skirts, the rims, the profile fits).
#[derive(Clone, Copy)]
pub(super) struct ClassFrames<'a> {
    pub(super) frames: &'a WindowFrames<'a>,
    pub(super) background: &'a Background,
    /// The class's particle radius, px.
    pub(super) radius: f64,
    pub(super) workers: &'a Workers,
}

/// The frames of the tracked window: the samples already decoded, the others read from the
/// source on demand.
pub(super) struct WindowFrames<'a> {
    pub(super) source: &'a FrameSource,
    /// Each frame's number in the source.
    pub(super) numbers: &'a [usize],
    /// Each frame's place among `samples`, if it is one.
    pub(super) sample_of: &'a [Option<usize>],
    pub(super) samples: &'a [DecodedFrame],
    /// The file whose size every frame must have, and that size (width, height, px).
    pub(super) reference: &'a Path,
    pub(super) size: (usize, usize),
}

impl WindowFrames<'_> {
    /// Frame `i` of the window: the sample already decoded, or the frame decoded into `buf`
    /// (with `decoder`'s buffers) and checked against the reference size.
    pub(super) fn get<'b>(
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

    /// The numbers (in the source) of at most `at_most` of the sample frames, already
    /// decoded, evenly spread over them, in order.
    pub(super) fn spread_samples(&self, at_most: usize) -> Vec<usize> {
        let first = self.numbers.first().copied().unwrap_or(0);
        let samples: Vec<usize> = (0..self.numbers.len())
            .filter(|&i| self.sample_of[i].is_some())
            .collect();
        let every = samples.len().div_ceil(at_most).max(1);
        samples.iter().step_by(every).map(|&i| i + first).collect()
    }

    /// `f(signal, width, height)` on the levelled signal of the frame numbered `k` in the
    /// source (row-major, `width * height` px, particles positive, against `background`),
    /// decoded and levelled with an idle worker's buffers.
    pub(super) fn with_signal<R>(
        &self,
        k: usize,
        background: &Background,
        workers: &Workers,
        f: impl FnOnce(&[f32], usize, usize) -> R,
    ) -> Result<R, TrackError> {
        let first = self.numbers.first().copied().unwrap_or(0);
        workers.with(|w| {
            let frame = self.get(k - first, &mut w.decoder, &mut w.frame)?;
            let (width, height) = frame.size();
            w.finder.levelled_signal(background, frame);
            Ok(f(&w.finder.signal, width, height))
        })
    }
}
