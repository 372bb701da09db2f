//! The rows of a signal image as the filters read them, formed before or on demand.

/// The rows of a signal image as the filters read them: each row once, in order.
pub(super) trait SignalRows {
    /// Row `y` (the image's width of values).
    fn row(&mut self, y: usize) -> &[f32];
}

/// A signal image already formed.
pub(super) struct Formed<'a> {
    pub(super) signal: &'a [f32],
    pub(super) width: usize,
}

impl SignalRows for Formed<'_> {
    fn row(&mut self, y: usize) -> &[f32] {
        &self.signal[y * self.width..(y + 1) * self.width]
    }
}

/// A signal image formed a row at a time, when the filters ask for the row.
pub(super) struct Forming<'a, F> {
    pub(super) signal: &'a mut [f32],
    pub(super) width: usize,
    pub(super) form: F,
}

impl<F: FnMut(std::ops::Range<usize>, &mut [f32])> SignalRows for Forming<'_, F> {
    fn row(&mut self, y: usize) -> &[f32] {
        let pixels = y * self.width..(y + 1) * self.width;
        (self.form)(pixels.clone(), &mut self.signal[pixels.clone()]);
        &self.signal[pixels]
    }
}
