//! Run-length connected-component labelling of the noise mask, with its union-find.

use super::peaks::above_bits;

/// Connected components (8-connected) of `image > threshold`, stored as row runs, with
/// reusable buffers.
#[derive(Default, Debug)]
pub(super) struct Labels {
    /// Runs `(x_start, x_end_exclusive, label)`, row after row.
    pub(super) runs: Vec<(u32, u32, u32)>,
    /// Index of each row's first run in `runs` (`height + 1` entries).
    row_start: Vec<usize>,
    /// Union-find parents of the provisional labels.
    parent: Vec<u32>,
    /// Compact label of each provisional root.
    compact: Vec<u32>,
    /// Pixel count per label.
    pub(super) area: Vec<usize>,
    /// Whether each label touches the image border.
    pub(super) border: Vec<bool>,
}

impl Labels {
    pub(super) fn label_at(&self, x: usize, y: usize) -> Option<usize> {
        let row = &self.runs[*self.row_start.get(y)?..*self.row_start.get(y + 1)?];
        let k = row.partition_point(|r| r.1 as usize <= x);
        row.get(k).filter(|r| r.0 as usize <= x).map(|r| r.2 as usize)
    }

    /// Starts labelling a frame (its rows follow through [`Labels::push_row`]).
    pub(super) fn begin(&mut self) {
        self.runs.clear();
        self.row_start.clear();
        self.parent.clear();
    }

    /// Adds row `y` (rows come in order from 0): its runs of `line[x] > thresholds[x]`,
    /// joined to the previous row's runs they touch (8-connectivity).
    pub(super) fn push_row(&mut self, y: usize, line: &[f32], thresholds: &[f32]) {
        let width = line.len();
        let prev_start = self.row_start.last().copied().unwrap_or(0);
        let start_here = self.runs.len();
        self.row_start.push(start_here);
        // The row's pixels above the mask as bits, 64 at a time; each run is then found
        // with two bit scans, not pixel by pixel.
        let mut open: Option<usize> = None;
        for x0 in (0..width).step_by(64) {
            let end = (x0 + 64).min(width);
            let bits = above_bits(&line[x0..end], &thresholds[x0..end]);
            let mut x = x0;
            while x < end {
                let rest = bits >> (x - x0);
                match open {
                    None => {
                        if rest == 0 {
                            break;
                        }
                        x += rest.trailing_zeros() as usize;
                        open = Some(x);
                    }
                    Some(s) => {
                        // Bits past the row's end are clear, so a run reaching it stops there.
                        x = (x + (!rest).trailing_zeros() as usize).min(end);
                        if x < end || end == width {
                            let label = self.parent.len() as u32;
                            self.parent.push(label);
                            self.runs.push((s as u32, x as u32, label));
                            open = None;
                        }
                    }
                }
            }
        }
        if y > 0 {
            // Runs of the previous row overlapping [start - 1, end] (8-connectivity).
            let mut k = prev_start;
            for r in start_here..self.runs.len() {
                let run = self.runs[r];
                while k < start_here && self.runs[k].1 < run.0 {
                    k += 1;
                }
                let mut j = k;
                while j < start_here && self.runs[j].0 <= run.1 {
                    let a = find(&mut self.parent, run.2);
                    let b = find(&mut self.parent, self.runs[j].2);
                    if a != b {
                        self.parent[a.max(b) as usize] = a.min(b);
                    }
                    j += 1;
                }
            }
        }
    }

    /// Ends the frame (`width` x `height`, every row pushed): compact labels, with each
    /// one's area and whether it touches the border.
    pub(super) fn finish(&mut self, width: usize, height: usize) {
        self.row_start.push(self.runs.len());
        self.compact.clear();
        self.compact.resize(self.parent.len(), u32::MAX);
        self.area.clear();
        self.border.clear();
        for y in 0..height {
            for r in self.row_start[y]..self.row_start[y + 1] {
                let run = self.runs[r];
                let root = find(&mut self.parent, run.2) as usize;
                if self.compact[root] == u32::MAX {
                    self.compact[root] = self.area.len() as u32;
                    self.area.push(0);
                    self.border.push(false);
                }
                let l = self.compact[root];
                self.runs[r].2 = l;
                self.area[l as usize] += (run.1 - run.0) as usize;
                self.border[l as usize] |= run.0 == 0 || run.1 as usize == width || y == 0 || y + 1 == height;
            }
        }
    }
}

/// The root of `a` in the union-find forest `parent`, halving the path on the way.
fn find(parent: &mut [u32], mut a: u32) -> u32 {
    while parent[a as usize] != a {
        let p = parent[parent[a as usize] as usize];
        parent[a as usize] = p;
        a = p;
    }
    a
}
