//! One particle's appearance: its profile in its own coordinates, and the integral of that
//! profile over each pixel's area.
//!
//! A pixel's value is the mean of the profile over the pixel's square, taken on an `n x n`
//! grid of sub-samples ([`samples_per_axis`]). Hard edges (the rim of a disc, ring, textured
//! ball or sphere) are not sampled as in/out: each sub-sample takes the fraction of its own
//! square that lies inside the edge's tangent line ([`square_coverage`]: exact for a
//! straight edge in any direction, odd about the edge, so a symmetric particle keeps its
//! centroid). At radius 1.5 px and 8 x 8 sub-samples the pixel values are within 1.5e-3 of
//! the exact area integral (a unit test checks it against an integral with exact chords),
//! which moves a centroid by well under 0.01 px.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::style::Profile;

/// Sub-samples per pixel axis at `radius` px: 8 below 6 px, 4 above (textures are at least
/// 0.12 radius wide, so 0.7 px or more).
pub fn samples_per_axis(radius: f64) -> usize {
    if radius < 6.0 {
        8
    } else {
        4
    }
}

/// A particle's appearance, in its own coordinates (px from its centre; it translates without
/// rotating, so a texture moves with it).
#[derive(Clone, Debug)]
pub struct ParticleLook {
    /// Radius, px (the half-maximum radius of a Gaussian spot).
    pub radius: f64,
    kind: LookKind,
}

#[derive(Clone, Debug)]
enum LookKind {
    Disc,
    Gaussian,
    /// Inner radius of the rim, px.
    Ring(f64),
    /// A `size x size` grid of relative brightness changes over `[-R, R]^2`.
    Textured {
        grid: Vec<f64>,
        size: usize,
    },
    /// Unit vector towards the light and the half vector between it and the viewer.
    Sphere {
        light: [f64; 3],
        half: [f64; 3],
    },
}

/// Grid points per axis of a texture.
const TEXTURE_GRID: usize = 48;
/// Bumps summed into a texture.
const TEXTURE_BUMPS: usize = 20;
/// A Gaussian spot is drawn out to this many radii (its value there is 2e-4 of the peak).
const GAUSSIAN_REACH: f64 = 3.5;

impl ParticleLook {
    /// The look of a particle of `radius` px with `profile`; `seed` draws its texture.
    pub fn new(profile: &Profile, radius: f64, seed: u64) -> ParticleLook {
        let kind = match *profile {
            Profile::Disc => LookKind::Disc,
            Profile::Gaussian => LookKind::Gaussian,
            Profile::Ring { width } => LookKind::Ring(radius * (1.0 - width)),
            Profile::Textured { contrast } => LookKind::Textured {
                grid: texture(contrast, seed),
                size: TEXTURE_GRID,
            },
            Profile::Sphere { light } => {
                let h = [light[0], light[1], light[2] + 1.0];
                let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                LookKind::Sphere {
                    light,
                    half: [h[0] / n, h[1] / n, h[2] / n],
                }
            }
        };
        ParticleLook { radius, kind }
    }

    /// Distance from the centre beyond which the profile is zero, px.
    pub fn reach(&self) -> f64 {
        match self.kind {
            LookKind::Gaussian => GAUSSIAN_REACH * self.radius,
            _ => self.radius,
        }
    }

    /// The profile at offset `(dx, dy)` px from the centre, averaged over a sub-sample square
    /// of side `h` px at its hard edges; 0 outside, about 1 inside (a texture or a highlight
    /// reaches 1.4 at most).
    pub fn value(&self, dx: f64, dy: f64, h: f64) -> f64 {
        let r = self.radius;
        let rho2 = dx * dx + dy * dy;
        if let LookKind::Gaussian = self.kind {
            let reach = GAUSSIAN_REACH * r;
            return if rho2 > reach * reach {
                0.0
            } else {
                (-std::f64::consts::LN_2 * rho2 / (r * r)).exp()
            };
        }
        let rho = rho2.sqrt();
        // The edge's normal is radial; its direction sets the sub-sample's coverage ramp.
        let (c, s) = if rho > 0.0 {
            (dx / rho, dy / rho)
        } else {
            (1.0, 0.0)
        };
        let edge = square_coverage(r - rho, c, s, h);
        if edge <= 0.0 {
            return 0.0;
        }
        match &self.kind {
            LookKind::Disc | LookKind::Gaussian => edge,
            LookKind::Ring(inner) => {
                let inside = square_coverage(rho - inner, c, s, h);
                (edge + inside - 1.0).max(0.0)
            }
            LookKind::Textured { grid, size } => edge * (1.0 + bilinear(grid, *size, dx / r, dy / r)),
            LookKind::Sphere { light, half } => {
                // The normal of the visible hemisphere; at the rim (the ramp reaches half a
                // sub-sample outside the radius) it lies in the image plane.
                let (nx, ny) = (dx / r, dy / r);
                let nz = (1.0 - (nx * nx + ny * ny)).max(0.0).sqrt();
                let diffuse = (nx * light[0] + ny * light[1] + nz * light[2]).max(0.0);
                let spec = (nx * half[0] + ny * half[1] + nz * half[2]).max(0.0).powi(30);
                edge * (0.2 + 0.65 * diffuse + 0.3 * spec)
            }
        }
    }
}

/// The fraction of a square of side `h` inside a straight edge whose unit normal is
/// `(c, s)` and which passes at signed distance `d` from the square's centre (positive:
/// the centre is inside). The square's extent along the normal is the sum of two uniform
/// variables of widths `h |c|` and `h |s|`, so the fraction is their distribution function at
/// `d`: quadratic in the corners, linear between them.
pub fn square_coverage(d: f64, c: f64, s: f64, h: f64) -> f64 {
    let (a, b) = {
        let (p, q) = ((h * c).abs(), (h * s).abs());
        (p.max(q), p.min(q))
    };
    let half = 0.5 * (a + b);
    if d >= half {
        return 1.0;
    }
    if d <= -half {
        return 0.0;
    }
    let lower = |t: f64| {
        // P(X <= t) for t <= 0.
        if b < 1e-12 * a || t >= -0.5 * (a - b) {
            0.5 + t / a
        } else {
            (t + half).powi(2) / (2.0 * a * b)
        }
    };
    if d <= 0.0 {
        lower(d)
    } else {
        1.0 - lower(-d)
    }
}

/// A texture: a sum of random Gaussian bumps (widths 0.12-0.25 radius, either sign) scaled to
/// `±contrast`, less its mean and its first moments over the disc, so the textured ball's
/// intensity centroid stays its centre (a textured particle with a lopsided pattern has its
/// centroid off its centre by up to a tenth of a bump width; the truth is the centre).
fn texture(contrast: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7e47_0e5d);
    let bumps: Vec<([f64; 2], f64, f64)> = (0..TEXTURE_BUMPS)
        .map(|_| {
            let (a, rho) = (std::f64::consts::TAU * rng.gen::<f64>(), rng.gen::<f64>().sqrt());
            let w = rng.gen_range(0.12..0.25);
            let sign = if rng.gen::<bool>() { 1.0 } else { -1.0 };
            ([rho * a.cos(), rho * a.sin()], w, sign)
        })
        .collect();
    let n = TEXTURE_GRID;
    let coord = |i: usize| -1.0 + 2.0 * i as f64 / (n - 1) as f64;
    let mut grid = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (coord(i), coord(j));
            grid[j * n + i] = bumps
                .iter()
                .map(|(c, w, s)| {
                    let d2 = (u - c[0]).powi(2) + (v - c[1]).powi(2);
                    s * (-d2 / (2.0 * w * w)).exp()
                })
                .sum();
        }
    }
    let inside: Vec<usize> = (0..n * n)
        .filter(|k| coord(k % n).powi(2) + coord(k / n).powi(2) <= 1.0)
        .collect();
    let peak = inside.iter().map(|&k| grid[k].abs()).fold(1e-12, f64::max);
    for g in &mut grid {
        *g *= contrast / peak;
    }
    // Zero mean and first moments of the interpolated texture over the unit disc, by polar
    // quadrature (midpoints, 160 rings by 480 angles): interpolation reproduces the linear
    // correction exactly, so one pass removes them to the quadrature's precision (a moment
    // of 1e-4 R would move a 60 px ball's centroid by 0.006 px).
    let (rings, angles) = (160, 480);
    let (mut m0, mut mx, mut my, mut area, mut ixx) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..rings {
        let rho = (i as f64 + 0.5) / rings as f64;
        for j in 0..angles {
            let a = std::f64::consts::TAU * (j as f64 + 0.5) / angles as f64;
            let (u, v) = (rho * a.cos(), rho * a.sin());
            let t = bilinear(&grid, n, u, v);
            m0 += t * rho;
            mx += t * u * rho;
            my += t * v * rho;
            area += rho;
            ixx += u * u * rho;
        }
    }
    let (c0, a, b) = (m0 / area, mx / ixx, my / ixx);
    for (k, g) in grid.iter_mut().enumerate() {
        *g -= c0 + a * coord(k % n) + b * coord(k / n);
    }
    grid
}

/// Bilinear interpolation of an `n x n` grid over `[-1, 1]^2` at `(u, v)` (clamped to it).
fn bilinear(grid: &[f64], n: usize, u: f64, v: f64) -> f64 {
    let s = (n - 1) as f64;
    let fx = ((u + 1.0) * 0.5 * s).clamp(0.0, s);
    let fy = ((v + 1.0) * 0.5 * s).clamp(0.0, s);
    let (i, j) = ((fx as usize).min(n - 2), (fy as usize).min(n - 2));
    let (tx, ty) = (fx - i as f64, fy - j as f64);
    let g = |i: usize, j: usize| grid[j * n + i];
    (1.0 - ty) * ((1.0 - tx) * g(i, j) + tx * g(i + 1, j))
        + ty * ((1.0 - tx) * g(i, j + 1) + tx * g(i + 1, j + 1))
}

/// Adds the pixel integral of `look` centred at `centre` (px) to the `width x height` plane
/// `plane` (nothing is drawn when `plane` is empty). Returns the sums `[Σ w s, Σ x w s,
/// Σ y w s, Σ s, Σ x s, Σ y s]` over the sub-samples (times the sub-sample area) with
/// `w = weight(x, y)` (the illumination), from which the intensity centroids of the lit
/// particle and of the particle under even light follow.
pub fn add_particle(
    plane: &mut [f64],
    width: usize,
    height: usize,
    look: &ParticleLook,
    centre: [f64; 2],
    weight: &dyn Fn(f64, f64) -> f64,
) -> [f64; 6] {
    let n = samples_per_axis(look.radius);
    let h = 1.0 / n as f64;
    let reach = look.reach() + h;
    let x0 = ((centre[0] - reach).floor().max(0.0)) as usize;
    let y0 = ((centre[1] - reach).floor().max(0.0)) as usize;
    let x1 = ((centre[0] + reach).ceil().max(0.0) as usize).min(width.saturating_sub(1));
    let y1 = ((centre[1] + reach).ceil().max(0.0) as usize).min(height.saturating_sub(1));
    let area = h * h;
    let mut sums = [0.0; 6];
    if width == 0 || height == 0 {
        return sums;
    }
    for py in y0..=y1 {
        for px in x0..=x1 {
            let mut acc = 0.0;
            for j in 0..n {
                let y = py as f64 - 0.5 + (j as f64 + 0.5) * h;
                for i in 0..n {
                    let x = px as f64 - 0.5 + (i as f64 + 0.5) * h;
                    let s = look.value(x - centre[0], y - centre[1], h);
                    if s != 0.0 {
                        let ws = s * weight(x, y) * area;
                        acc += s * area;
                        sums[0] += ws;
                        sums[1] += x * ws;
                        sums[2] += y * ws;
                        sums[3] += s * area;
                        sums[4] += x * s * area;
                        sums[5] += y * s * area;
                    }
                }
            }
            if let Some(p) = plane.get_mut(py * width + px) {
                *p += acc;
            }
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact area of the disc of `radius` about `c` inside pixel `(px, py)`: exact chords
    /// in y, 4000 midpoints in x.
    fn exact_pixel(c: [f64; 2], radius: f64, px: usize, py: usize) -> f64 {
        let n = 4000;
        let (x0, y0) = (px as f64 - 0.5, py as f64 - 0.5);
        (0..n)
            .map(|i| {
                let x = x0 + (i as f64 + 0.5) / n as f64;
                let d = x - c[0];
                if d.abs() >= radius {
                    return 0.0;
                }
                let half = (radius * radius - d * d).sqrt();
                ((c[1] + half).min(y0 + 1.0) - (c[1] - half).max(y0)).max(0.0)
            })
            .sum::<f64>()
            / n as f64
    }

    fn centroid(plane: &[f64], width: usize) -> [f64; 2] {
        let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for (k, v) in plane.iter().enumerate() {
            s += v;
            sx += v * (k % width) as f64;
            sy += v * (k / width) as f64;
        }
        [sx / s, sy / s]
    }

    #[test]
    fn small_disc_pixels_match_the_exact_area_integral() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for radius in [1.5, 2.2, 3.5] {
            let look = ParticleLook::new(&Profile::Disc, radius, 0);
            for _ in 0..10 {
                let c = [rng.gen_range(8.0..9.0), rng.gen_range(8.0..9.0)];
                let mut plane = vec![0.0; 18 * 18];
                add_particle(&mut plane, 18, 18, &look, c, &|_, _| 1.0);
                for (k, v) in plane.iter().enumerate() {
                    let exact = exact_pixel(c, radius, k % 18, k / 18);
                    assert!(
                        (v - exact).abs() < 1.5e-3,
                        "radius {radius} at {c:?}, pixel {k}: {v} against {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn symmetric_particles_have_their_centre_as_intensity_centroid() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let cases = [
            (Profile::Gaussian, 1.5),
            (Profile::Gaussian, 4.0),
            (Profile::Disc, 24.0),
            (Profile::Ring { width: 0.3 }, 24.0),
            (Profile::Textured { contrast: 0.4 }, 24.0),
        ];
        // A hard-edged particle of a few pixels has a pixel-integrated centroid of its own,
        // up to 0.01 px off its centre at 1.5 px (the pixel grid aliases its edge), so they are
        // tried at 24 px, where that is below 1e-3 px.
        for (profile, radius) in cases {
            let side = 64;
            for seed in 0..6 {
                let look = ParticleLook::new(&profile, radius, seed);
                let c = [rng.gen_range(31.0..32.0), rng.gen_range(31.0..32.0)];
                let mut plane = vec![0.0; side * side];
                let sums = add_particle(&mut plane, side, side, &look, c, &|_, _| 1.0);
                let m = centroid(&plane, side);
                let err = (m[0] - c[0]).abs().max((m[1] - c[1]).abs());
                assert!(
                    err < 1e-3,
                    "{profile:?} r {radius} at {c:?}: centroid {m:?}, off {err}"
                );
                // The centroid the truth reports (from the sub-samples) agrees.
                let t = [sums[1] / sums[0], sums[2] / sums[0]];
                assert!((t[0] - c[0]).abs().max((t[1] - c[1]).abs()) < 1e-3, "{t:?}");
            }
        }
    }

    #[test]
    fn sphere_centroid_leans_towards_the_light_by_a_fifth_of_radius_times_tilt() {
        let [.., Profile::Sphere { light }] = Profile::all() else {
            unreachable!()
        };
        let look = ParticleLook::new(&Profile::Sphere { light }, 20.0, 0);
        let s = add_particle(&mut [], 64, 64, &look, [32.0, 32.0], &|_, _| 1.0);
        let off = [s[1] / s[0] - 32.0, s[2] / s[0] - 32.0];
        // Towards the light, about 0.2 R sin(tilt) (0.7 px at 10 degrees and 20 px).
        assert!(off[0] * light[0] > 0.0 && off[1] * light[1] > 0.0, "{off:?}");
        let len = off[0].hypot(off[1]);
        let tilt = light[2].acos();
        assert!((0.1..0.3).contains(&(len / (20.0 * tilt.sin()))), "{len}");
    }
}
