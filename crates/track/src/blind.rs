//! Pixels where a particle cannot show, and how their signal is filled in.
//!
//! A solid particle of colour `F` over a background pixel `B` shows the signal
//! `u · (F − B)`: where the scene's own structure (a white grid line behind or in front of a
//! white bob, text, a scale) is already as far from the usual background level as the particle,
//! the particle shows little or nothing there, and its signal has a hole along the structure.
//! A grid line through a pendulum's bob cut it in two blobs, and the track followed the larger
//! half, 2-3 px off the bob's centre (7 px where the cut was near the middle).
//!
//! A pixel is *blind* when the per-pixel background there stands out from the usual level, along
//! the particles' colour direction, by more than half the particles' own contrast. Each frame, a
//! blind pixel's signal is replaced by the mean of the nearest pixels that are not blind on two
//! opposite sides of it (above and below, or left and right), within the particle radius: a thin
//! structure crossing a particle is bridged by the particle on both sides, and away from
//! particles it is filled with background. Blind regions wider than a particle are left as they
//! are (a particle there is hidden, and nothing in the frame says where it is).

/// Blind pixels of a frame and, for each, the pixels its signal is filled from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BlindPixels {
    /// Blind pixels that can be filled (row-major indices).
    pixels: Vec<u32>,
    /// `sources[starts[k]..starts[k + 1]]` are the pixels `pixels[k]` is filled from.
    starts: Vec<u32>,
    sources: Vec<u32>,
    /// Blind pixels in all, filled or not.
    blind_count: usize,
}

impl BlindPixels {
    /// The blind pixels of a `width` x `height` frame, where `structure[p]` (the background's
    /// offset from its usual level along the particles' colour direction, grey levels) exceeds
    /// half of `contrast` (the particles' signal, grey levels). Each is filled from the pairs
    /// of pixels that are not blind and lie opposite each other through it on the nearest
    /// square ring around it (chessboard distance up to `reach` px) that holds such a pair;
    /// pixels with none are left out.
    pub fn find(structure: &[f32], width: usize, height: usize, contrast: f32, reach: usize) -> BlindPixels {
        let limit = 0.5 * contrast;
        let blind: Vec<bool> = structure.iter().map(|&s| s > limit).collect();
        let blind_count = blind.iter().filter(|&&b| b).count();
        let mut out = BlindPixels {
            starts: vec![0],
            blind_count,
            ..BlindPixels::default()
        };
        if blind_count == 0 || contrast <= 0.0 {
            return out;
        }
        let depth = chessboard_depth(&blind, width, height);
        let reach = reach as isize;
        for (p, _) in blind.iter().enumerate().filter(|(_, &b)| b) {
            if depth[p] as isize > reach {
                continue;
            }
            let (x, y) = ((p % width) as isize, (p / width) as isize);
            let clear = |dx: isize, dy: isize| -> bool {
                let (qx, qy) = (x + dx, y + dy);
                qx >= 0
                    && qy >= 0
                    && (qx as usize) < width
                    && (qy as usize) < height
                    && !blind[qy as usize * width + qx as usize]
            };
            // The ring at chessboard distance k, as offsets: each with its reflection through p.
            for k in depth[p] as isize..=reach {
                let before = out.sources.len();
                let ring = (-k..=k)
                    .flat_map(|t| [(t, -k), (t, k)])
                    .chain((1 - k..k).flat_map(|t| [(-k, t), (k, t)]));
                for (dx, dy) in ring {
                    if clear(dx, dy) && clear(-dx, -dy) {
                        out.sources
                            .push(((y + dy) as usize * width + (x + dx) as usize) as u32);
                    }
                }
                if out.sources.len() > before {
                    out.pixels.push(p as u32);
                    out.starts.push(out.sources.len() as u32);
                    break;
                }
            }
        }
        out
    }

    /// Blind pixels found, filled or not.
    pub fn count(&self) -> usize {
        self.blind_count
    }

    /// Returns true if and only if no pixel is filled.
    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    /// Fills each blind pixel of `signal` (grey levels, row-major) with the mean of its sources.
    pub fn fill(&self, signal: &mut [f32]) {
        for (k, &p) in self.pixels.iter().enumerate() {
            let sources = &self.sources[self.starts[k] as usize..self.starts[k + 1] as usize];
            let sum: f32 = sources.iter().map(|&q| signal[q as usize]).sum();
            signal[p as usize] = sum / sources.len() as f32;
        }
    }
}

/// Each pixel's chessboard distance to the nearest pixel that is not `blind` (0 for those), px;
/// `u32::MAX` when every pixel is blind. Two passes of the 8-neighbour distance transform.
fn chessboard_depth(blind: &[bool], width: usize, height: usize) -> Vec<u32> {
    let far = u32::MAX / 2;
    let mut d: Vec<u32> = blind.iter().map(|&b| if b { far } else { 0 }).collect();
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let mut v = d[i];
            if x > 0 {
                v = v.min(d[i - 1] + 1);
            }
            if y > 0 {
                v = v.min(d[i - width] + 1);
                if x > 0 {
                    v = v.min(d[i - width - 1] + 1);
                }
                if x + 1 < width {
                    v = v.min(d[i - width + 1] + 1);
                }
            }
            d[i] = v;
        }
    }
    for y in (0..height).rev() {
        for x in (0..width).rev() {
            let i = y * width + x;
            let mut v = d[i];
            if x + 1 < width {
                v = v.min(d[i + 1] + 1);
            }
            if y + 1 < height {
                v = v.min(d[i + width] + 1);
                if x + 1 < width {
                    v = v.min(d[i + width + 1] + 1);
                }
                if x > 0 {
                    v = v.min(d[i + width - 1] + 1);
                }
            }
            d[i] = v;
        }
    }
    d.iter().map(|&v| if v >= far { u32::MAX } else { v }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_through_a_disc_is_bridged_and_elsewhere_filled_with_background() {
        // A bright line two rows thick at y = 10-11 across a 30 x 24 frame; a disc of signal
        // 100 (radius 5) centred on the line, hidden along it.
        let (w, h) = (30, 24);
        let mut structure = vec![0f32; w * h];
        for x in 0..w {
            structure[10 * w + x] = 150.0;
            structure[11 * w + x] = 150.0;
        }
        let mut signal = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let r = (x as f32 - 15.0).hypot(y as f32 - 10.5);
                if r <= 5.0 && !(10..=11).contains(&y) {
                    signal[y * w + x] = 100.0;
                }
            }
        }
        let blind = BlindPixels::find(&structure, w, h, 100.0, 5);
        assert_eq!(blind.count(), 2 * w);
        blind.fill(&mut signal);
        // Under the disc's middle, the line now reads as the disc; far from it, as background.
        for x in 13..=17 {
            assert!(signal[10 * w + x] > 60.0, "x {x}: {}", signal[10 * w + x]);
        }
        assert!(signal[10 * w + 2].abs() < 1e-6);
        // The filled disc's centroid is its centre (the line's rows filled symmetrically).
        let (mut m, mut my) = (0.0, 0.0);
        for y in 0..h {
            for x in 0..w {
                m += signal[y * w + x];
                my += signal[y * w + x] * y as f32;
            }
        }
        assert!((my / m - 10.5).abs() < 0.05, "centroid row {}", my / m);
    }

    #[test]
    fn structure_below_half_the_contrast_or_wider_than_the_reach_is_left_alone() {
        let (w, h) = (20, 20);
        let faint = vec![40f32; w * h];
        assert_eq!(BlindPixels::find(&faint, w, h, 100.0, 4).count(), 0);
        // A band 12 rows high: its middle rows have no clear pixel within 4 px on both sides.
        let mut band = vec![0f32; w * h];
        band[4 * w..16 * w].iter_mut().for_each(|s| *s = 200.0);
        let blind = BlindPixels::find(&band, w, h, 100.0, 4);
        assert_eq!(blind.count(), 12 * w);
        let mut signal = vec![7f32; w * h];
        blind.fill(&mut signal);
        assert!(signal.iter().all(|&s| (s - 7.0).abs() < 1e-6));
        assert!(blind.is_empty());
    }

    #[test]
    fn chessboard_depth_is_the_distance_to_the_nearest_clear_pixel() {
        let (w, h) = (9, 7);
        let mut blind = vec![true; w * h];
        blind[3 * w + 2] = false;
        let d = chessboard_depth(&blind, w, h);
        for y in 0..h {
            for x in 0..w {
                let want = (x as i64 - 2).unsigned_abs().max((y as i64 - 3).unsigned_abs()) as u32;
                assert_eq!(d[y * w + x], want, "({x}, {y})");
            }
        }
        assert!(chessboard_depth(&[true; 4], 2, 2).iter().all(|&v| v == u32::MAX));
    }
}
