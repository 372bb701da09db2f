//! Each candidate's blob, grown by a span flood fill.

/// The blobs of one frame's candidates, grown by flood fill, with reusable buffers.
#[derive(Default, Debug)]
pub(super) struct Regions {
    /// Region of each pixel (`u32::MAX`: none).
    pub(super) owner: Vec<u32>,
    /// Pixels given a region this frame (reset by the next [`Regions::reset`]).
    claimed: Vec<u32>,
    /// Span fill work list: claimed runs (first column, last column, row), whose
    /// neighbouring rows are still to be searched.
    pub(super) spans: Vec<(u32, u32, u32)>,
    /// Pixel fill work list: pixels as (column, row), so that none is divided by the width.
    stack: Vec<(u32, u32)>,
    /// Pixel count per region.
    pub(super) area: Vec<usize>,
    /// Whether each region touches the image border.
    pub(super) border: Vec<bool>,
}

impl Regions {
    /// Forgets every region, for a frame of `pixels` pixels.
    pub(super) fn reset(&mut self, pixels: usize) {
        if self.owner.len() == pixels {
            for &p in &self.claimed {
                self.owner[p as usize] = u32::MAX;
            }
        } else {
            self.owner.clear();
            self.owner.resize(pixels, u32::MAX);
        }
        self.claimed.clear();
        self.area.clear();
        self.border.clear();
    }

    pub(super) fn region_at(&self, pixel: usize) -> Option<usize> {
        let r = *self.owner.get(pixel)?;
        (r != u32::MAX).then_some(r as usize)
    }

    /// Whether pixel `q` is free for `fill` to take: unclaimed and at least its level.
    fn open(&self, fill: &Fill<'_>, q: usize) -> bool {
        self.owner[q] == u32::MAX && fill.image[q] >= fill.level
    }

    /// Gives pixel `q` to region `id`.
    fn claim(&mut self, q: usize, id: u32) {
        self.owner[q] = id;
        self.claimed.push(q as u32);
    }

    /// Grows a new region from `seed` over the 8-connected pixels open to `fill`, stopping
    /// after its cap; returns the region's index.
    ///
    /// Span by span: a row's run of such pixels is claimed whole, then the rows above and
    /// below are searched under it (one pixel wider each side, for the diagonals) for runs
    /// to claim next. Each pixel is tested about three times, not nine as when each claimed
    /// pixel tests its eight neighbours. A region that reaches the cap (a large object) is
    /// grown again pixel by pixel ([`Regions::grow_pixels`]): which of its pixels a capped
    /// region holds depends on the order of the fill, and the other candidates inside the
    /// object share it or grow their own accordingly.
    pub(super) fn grow(&mut self, fill: &Fill<'_>, seed: usize) -> usize {
        let first_claim = self.claimed.len();
        if let Some(id) = self.grow_spans(fill, seed) {
            return id;
        }
        for &p in &self.claimed[first_claim..] {
            self.owner[p as usize] = u32::MAX;
        }
        self.claimed.truncate(first_claim);
        self.grow_pixels(fill, seed)
    }

    /// [`Regions::grow`] span by span, or `None` (its pixels left claimed) when the region
    /// reaches the cap.
    fn grow_spans(&mut self, fill: &Fill<'_>, seed: usize) -> Option<usize> {
        let (width, height) = (fill.width, fill.height);
        let id = self.area.len() as u32;
        let (sx, sy) = (seed % width, seed / width);
        // The seed is the region's first pixel whatever its value; its row's run extends
        // from it both ways.
        self.claim(seed, id);
        let (a, b) = self.claim_run(fill, sy, sx, id);
        let mut area = b - a + 1;
        let mut border = false;
        self.spans.clear();
        self.spans.push((a as u32, b as u32, sy as u32));
        // Every claimed run is pushed, so the cap is checked after each growth.
        while let Some((x0, x1, y)) = self.spans.pop() {
            if area >= fill.cap {
                return None;
            }
            let (x0, x1, y) = (x0 as usize, x1 as usize, y as usize);
            border |= x0 == 0 || y == 0 || x1 + 1 == width || y + 1 == height;
            for yy in [y.wrapping_sub(1), y + 1].into_iter().filter(|&yy| yy < height) {
                let mut x = x0.saturating_sub(1);
                while x <= (x1 + 1).min(width - 1) {
                    let q = yy * width + x;
                    if !self.open(fill, q) {
                        x += 1;
                        continue;
                    }
                    self.claim(q, id);
                    let (a, b) = self.claim_run(fill, yy, x, id);
                    area += b - a + 1;
                    self.spans.push((a as u32, b as u32, yy as u32));
                    x = b + 2;
                }
            }
        }
        self.area.push(area);
        self.border.push(border);
        Some(id as usize)
    }

    /// [`Regions::grow`] pixel by pixel: each claimed pixel claims its 8-neighbours open to
    /// `fill`, until the region holds its cap.
    pub(super) fn grow_pixels(&mut self, fill: &Fill<'_>, seed: usize) -> usize {
        let (width, height) = (fill.width, fill.height);
        let id = self.area.len() as u32;
        let mut area = 0;
        let mut border = false;
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push(((seed % width) as u32, (seed / width) as u32));
        self.claim(seed, id);
        while let Some((x, y)) = stack.pop() {
            let (x, y) = (x as usize, y as usize);
            area += 1;
            border |= x == 0 || y == 0 || x + 1 == width || y + 1 == height;
            if area + stack.len() >= fill.cap {
                continue;
            }
            for yy in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                for xx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                    let q = yy * width + xx;
                    if self.open(fill, q) {
                        self.claim(q, id);
                        stack.push((xx as u32, yy as u32));
                    }
                }
            }
        }
        self.stack = stack;
        self.area.push(area);
        self.border.push(border);
        id as usize
    }

    /// Extends the claimed pixel `x` of row `y` left and right over the pixels open to
    /// `fill`, claiming them for region `id`; returns the run's ends (inclusive).
    fn claim_run(&mut self, fill: &Fill<'_>, y: usize, x: usize, id: u32) -> (usize, usize) {
        let row = y * fill.width;
        let (mut x0, mut x1) = (x, x);
        while x0 > 0 && self.open(fill, row + x0 - 1) {
            x0 -= 1;
            self.claim(row + x0, id);
        }
        while x1 + 1 < fill.width && self.open(fill, row + x1 + 1) {
            x1 += 1;
            self.claim(row + x1, id);
        }
        (x0, x1)
    }
}

/// What a blob's flood fill spreads over: the pixels of `image` (`width` x `height`, the
/// small box mean, grey levels) at least `level`, until the region holds `cap` pixels.
pub(super) struct Fill<'a> {
    pub(super) image: &'a [f32],
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) level: f32,
    pub(super) cap: usize,
}
