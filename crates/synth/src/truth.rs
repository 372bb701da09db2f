//! The truth of a drawn recording.

use std::path::Path;

use crate::error::SynthError;

/// Where each particle is, frame by frame, in physfit's conventions (px, x right, y down,
/// pixel centres at integer coordinates).
#[derive(Clone, Debug, PartialEq)]
pub struct Truth {
    /// Particle names, `p0`, `p1`, ...
    pub names: Vec<String>,
    /// `positions[k][i]`: the centre of particle `i` in frame `k` (the disc's, ring's or
    /// sphere's centre; the Gaussian's peak), px.
    pub positions: Vec<Vec<[f64; 2]>>,
    /// `centroids[k][i]`: the intensity centroid of particle `i`, noise-free and lit (with
    /// the illumination gradient and vignetting), in frame `k`, px. It differs from the centre
    /// for a sphere (the light is off-axis) and under uneven light.
    pub centroids: Vec<Vec<[f64; 2]>>,
    /// `even_centroids[k][i]`: the intensity centroid of particle `i` in frame `k` as it
    /// would be under even light (no gradient or vignetting), px: where a tracker that takes
    /// the light out of the image finds it. It differs from the centre for a sphere (its own
    /// light is off-axis) and a lopsided texture.
    pub even_centroids: Vec<Vec<[f64; 2]>>,
}

impl Truth {
    /// The truth table as CSV: a `frame,particle,x,y` header and one row per particle per
    /// frame.
    pub fn to_csv(&self) -> String {
        let mut out = String::from("frame,particle,x,y\n");
        for (k, frame) in self.positions.iter().enumerate() {
            for (name, p) in self.names.iter().zip(frame) {
                out.push_str(&format!("{k},{name},{},{}\n", p[0], p[1]));
            }
        }
        out
    }

    /// Writes [`Truth::to_csv`] to `path`.
    pub fn write_csv(&self, path: &Path) -> Result<(), SynthError> {
        std::fs::write(path, self.to_csv()).map_err(|source| SynthError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Root mean square, over every particle and frame, of the intensity centroid's offset
    /// from the centre on each axis, px, the larger of the lit centroid's and the one under
    /// even light: what a tracker that follows the intensity centroid (of the image as lit,
    /// or with the light taken out) is off by however little noise there is.
    pub fn centroid_offset_rms(&self) -> [f64; 2] {
        let rms = |centroids: &[Vec<[f64; 2]>]| {
            let mut sum = [0.0; 2];
            let mut n = 0usize;
            for (frame, cs) in self.positions.iter().zip(centroids) {
                for (p, c) in frame.iter().zip(cs) {
                    sum[0] += (c[0] - p[0]).powi(2);
                    sum[1] += (c[1] - p[1]).powi(2);
                    n += 1;
                }
            }
            sum.map(|s| (s / n.max(1) as f64).sqrt())
        };
        let (lit, even) = (rms(&self.centroids), rms(&self.even_centroids));
        [lit[0].max(even[0]), lit[1].max(even[1])]
    }
}
