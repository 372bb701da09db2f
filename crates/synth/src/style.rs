//! A recording's style: the particles' profile, size, count, colours, the optics and the
//! camera; [`Style::random`] draws one over the whole range from a seed.

use std::fmt;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::blur::blur_plane;
use crate::look::{add_particle, ParticleLook};

/// The intensity profile of a particle, in units of its contrast.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Profile {
    /// A flat disc of the radius (anti-aliased by its area).
    Disc,
    /// A Gaussian spot whose radius is its half-maximum radius, `exp(-ln 2 ρ² / R²)`.
    Gaussian,
    /// A bright rim between `(1 - width) R` and `R`, background inside.
    Ring {
        /// The rim's width as a fraction of the radius (0.2-0.35 when drawn).
        width: f64,
    },
    /// A disc with a fixed random texture that moves with it: brightness `1 + t` with
    /// `|t| <= contrast`, `t` of zero mean and zero first moments over the disc.
    Textured {
        /// The texture's peak relative contrast (0.2-0.4 when drawn).
        contrast: f64,
    },
    /// A Lambertian sphere lit from `light`, with ambient 0.2, diffuse 0.65 and a
    /// Blinn-Phong highlight (0.3, exponent 30) towards the light. Its intensity centroid lies
    /// off its centre towards the light (about 0.2 R sin(tilt)); the truth is the centre.
    Sphere {
        /// Unit vector towards the light (x right, y down, z towards the viewer).
        light: [f64; 3],
    },
}

impl Profile {
    /// A short name: `disc`, `gauss`, `ring`, `texture`, `sphere`.
    pub fn name(&self) -> &'static str {
        match self {
            Profile::Disc => "disc",
            Profile::Gaussian => "gauss",
            Profile::Ring { .. } => "ring",
            Profile::Textured { .. } => "texture",
            Profile::Sphere { .. } => "sphere",
        }
    }

    /// The profile of [`Profile::all`] with this [`Profile::name`], if any.
    pub fn named(name: &str) -> Option<Profile> {
        Profile::all().into_iter().find(|p| p.name() == name)
    }

    /// The five profiles with typical parameters (ring width 0.3, texture contrast 0.3,
    /// light tilted 10 degrees to the upper left).
    pub fn all() -> [Profile; 5] {
        let t = 10f64.to_radians();
        let a = 225f64.to_radians();
        [
            Profile::Disc,
            Profile::Gaussian,
            Profile::Ring { width: 0.3 },
            Profile::Textured { contrast: 0.3 },
            Profile::Sphere {
                light: [t.sin() * a.cos(), t.sin() * a.sin(), t.cos()],
            },
        ]
    }
}

/// Particles brighter or darker than the background.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Polarity {
    /// Bright particles on a dark background.
    BrightOnDark,
    /// Dark particles on a light background.
    DarkOnLight,
}

/// Everything that decides a recording's frames; two equal styles draw the same bytes.
///
/// Units: px, grey levels (0-255 per channel), frames. A frame's pixel value per channel is
/// `gain(k) * light(x, y) * (background + (foreground - background) * P(x, y)) + noise`,
/// rounded and clamped to 0..255, where `P` is the sum of the particles' pixel-integrated
/// profiles blurred by a Gaussian of `blur` px, `light` the illumination gradient times the
/// vignetting and `gain(k) = 1 + exposure sin(2 π k / exposure_period + exposure_phase)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Style {
    /// The seed the style was drawn from; also seeds the motion, textures and noise.
    pub seed: u64,
    /// The particles' profile.
    pub profile: Profile,
    /// The particle radius, px (the smaller one when `mixed`).
    pub radius: f64,
    /// True if and only if every other particle is 2.5 times `radius`.
    pub mixed: bool,
    /// Number of particles (1-8).
    pub particle_count: usize,
    /// Bright on dark or dark on light.
    pub polarity: Polarity,
    /// True if and only if the frames are RGB (colour particle on a coloured background);
    /// grey frames otherwise.
    pub colour: bool,
    /// Background level per channel (R, G, B; all equal when grey), grey levels.
    pub background: [f64; 3],
    /// Particle level per channel at profile value 1, grey levels.
    pub foreground: [f64; 3],
    /// Standard deviation of the Gaussian blur, px (0-3).
    pub blur: f64,
    /// Standard deviation of the Gaussian pixel noise, grey levels (0-30).
    pub noise: f64,
    /// Relative change of the illumination across the frame's width along
    /// `gradient_angle` (0-0.2): `1 + gradient * (p - centre) . dir / width`.
    pub gradient: f64,
    /// Direction of the illumination gradient, radians from +x towards +y.
    pub gradient_angle: f64,
    /// Relative loss of light at the frame's corners, `1 - vignetting (r / r_corner)²` (0-0.25).
    pub vignetting: f64,
    /// True if and only if the gradient and vignetting light the background alone (a haze,
    /// a lamp on the backdrop, a renderer's ramp): a pixel is then
    /// `gain(k) * (light(x, y) * background + (foreground - background) * P(x, y))`, the
    /// particles' contrast the same everywhere. False in every drawn style: light falls on
    /// particles and background alike.
    pub additive_light: bool,
    /// Amplitude of the per-frame gain (0-0.15).
    pub exposure: f64,
    /// Period of the per-frame gain, frames.
    pub exposure_period: f64,
    /// Phase of the per-frame gain, radians.
    pub exposure_phase: f64,
    /// True if and only if a light background drifts in and out of saturation (its lightest
    /// channel times the largest gain passes 255).
    pub saturating: bool,
    /// Largest step of a particle per frame, px.
    pub speed: f64,
    /// Frames in the recording.
    pub frame_count: usize,
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Lines drawn from each particle to the next, beneath them (a mass-spring model's
    /// springs as a physics engine's view draws them); `None` in every drawn style.
    pub lines: Option<Lines>,
}

/// Lines joining consecutive particles (see [`Style::lines`]): each pixel's profile value
/// beneath the particles gains `level` times the fraction of the pixel across the line's
/// width (the overlap of the pixel's span and the line's, measured across the line), so a
/// line is drawn at `level` of the particles' contrast where it is not covered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lines {
    /// Width, px.
    pub width: f64,
    /// Level, as a fraction of the particles' profile value 1.
    pub level: f64,
}

/// A draw in `[lo, hi]` uniform in the logarithm.
fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * rng.gen::<f64>()).exp()
}

impl Style {
    /// The RMS error per axis, px, the tracker is held to on this style (tracker issue 20):
    /// `max(0.05 + 0.01 σ, 2 crb) + lean`, with `0.10 + 0.02 σ` in place of the first term
    /// when the smallest radius is under 3 px (a sharp 1.5 px disc's pixel-integrated image
    /// has its own centroid up to 0.01 px off its centre, and its window holds more
    /// background per unit of signal). σ is the pixel noise (grey levels), `crb` the
    /// Cramér-Rao bound per axis (px, [`crate::Sequence::bound`]) and `lean` the RMS offset
    /// per axis (px) of the particles' intensity centroids from their centres over the
    /// points scored (a centroid cannot know the centre of a lopsided image).
    pub fn tolerance(&self, crb: [f64; 2], lean: [f64; 2]) -> [f64; 2] {
        let base = if self.radius >= 3.0 {
            0.05 + 0.01 * self.noise
        } else {
            0.10 + 0.02 * self.noise
        };
        [0, 1].map(|a| base.max(2.0 * crb[a]) + lean[a])
    }

    /// Draws a style from `seed`, over the whole range: any profile; radius 1.5-60 px
    /// (log-uniform; a quarter of the styles mix two sizes, 1.5-24 px and 2.5 times that);
    /// 1-8 particles (fewer as they grow, so frames stay small); either polarity, grey or
    /// colour (a third); contrast 60-200 grey levels; blur 0-3 px (none in 3 of 10); noise
    /// 0-30 grey levels (none in 1 of 5); an illumination gradient (up to 20 % across the frame),
    /// vignetting (up to 25 % at the corners) and exposure drift (gain ±2-12 % per frame),
    /// each in half the styles; a third of the dark-on-light styles on a background of
    /// 236-248 whose gain drifts by ±10-15 %, in and out of saturation; steps up to 0.5-3 px
    /// or 0.3 radius per frame; 15-22 frames.
    ///
    /// A particle must be visible: the noise is lowered, where needed, to a third of the
    /// smallest particle's blurred peak contrast (a heavily blurred 1.5 px spot has a peak of
    /// a few grey levels, which nobody can see under noise 30).
    pub fn random(seed: u64) -> Style {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let profile = match rng.gen_range(0..5) {
            0 => Profile::Disc,
            1 => Profile::Gaussian,
            2 => Profile::Ring {
                width: rng.gen_range(0.2..0.35),
            },
            3 => Profile::Textured {
                contrast: rng.gen_range(0.2..0.4),
            },
            _ => {
                let tilt = rng.gen_range(5f64..15.0).to_radians();
                let az = rng.gen_range(0.0..std::f64::consts::TAU);
                Profile::Sphere {
                    light: [tilt.sin() * az.cos(), tilt.sin() * az.sin(), tilt.cos()],
                }
            }
        };
        let mixed = rng.gen_bool(0.25);
        let radius = if mixed {
            log_uniform(&mut rng, 1.5, 24.0)
        } else {
            log_uniform(&mut rng, 1.5, 60.0)
        };
        let largest = if mixed { 2.5 * radius } else { radius };
        let most = ((48.0 / largest).floor() as usize).clamp(1, 8);
        let particle_count = if mixed {
            rng.gen_range(2..=most.max(2))
        } else {
            rng.gen_range(1..=most)
        };
        let polarity = if rng.gen_bool(0.5) {
            Polarity::BrightOnDark
        } else {
            Polarity::DarkOnLight
        };
        let colour = rng.gen_bool(1.0 / 3.0);
        let saturating = polarity == Polarity::DarkOnLight && rng.gen_bool(1.0 / 3.0);
        let level = match (polarity, saturating) {
            (Polarity::BrightOnDark, _) => rng.gen_range(5.0f64..70.0),
            (Polarity::DarkOnLight, false) => rng.gen_range(150.0..230.0),
            (Polarity::DarkOnLight, true) => rng.gen_range(236.0..248.0),
        };
        let contrast = rng.gen_range(60.0..200.0);
        let sign = if polarity == Polarity::BrightOnDark {
            1.0
        } else {
            -1.0
        };
        let (background, direction) = if colour {
            let mut tint = [0.0f64; 3];
            tint.iter_mut().for_each(|t| *t = rng.gen_range(0.6..1.4));
            if saturating {
                // The lightest channel is the one that saturates.
                let top = tint.iter().fold(0.0f64, |m, &t| m.max(t));
                tint.iter_mut().for_each(|t| *t /= top);
            }
            // A hue of its own: one channel changes by the whole contrast, the others by
            // -0.4 to 1 of it.
            let mut e = [0.0f64; 3];
            e.iter_mut().for_each(|c| *c = rng.gen_range(-0.4..1.0));
            e[rng.gen_range(0..3)] = 1.0;
            let cap = if saturating { 250.0 } else { 245.0 };
            (tint.map(|t| (level * t).clamp(5.0, cap)), e)
        } else {
            ([level; 3], [1.0; 3])
        };
        // Keep the brightest point of the particle (a texture or a highlight reaches 1.4
        // times the contrast) within 3..252 on every channel, channel by channel.
        let foreground = [0, 1, 2].map(|c| {
            let d = sign * direction[c] * contrast;
            let d = d.clamp(-(background[c] - 3.0) / 1.4, (252.0 - background[c]) / 1.4);
            background[c] + d
        });
        let blur = if rng.gen_bool(0.3) {
            0.0
        } else {
            rng.gen_range(0.3..3.0)
        };
        let noise = if rng.gen_bool(0.2) {
            0.0
        } else {
            rng.gen_range(1.0..30.0)
        };
        let (gradient, gradient_angle) = if rng.gen_bool(0.5) {
            (
                rng.gen_range(0.05..0.2),
                rng.gen_range(0.0..std::f64::consts::TAU),
            )
        } else {
            (0.0, 0.0)
        };
        let vignetting = if rng.gen_bool(0.5) {
            rng.gen_range(0.05..0.25)
        } else {
            0.0
        };
        let (exposure, exposure_period) = if saturating {
            (rng.gen_range(0.1..0.15), rng.gen_range(8.0..20.0))
        } else if rng.gen_bool(0.5) {
            (rng.gen_range(0.02..0.12), rng.gen_range(8.0..30.0))
        } else {
            (0.0, 10.0)
        };
        let exposure_phase = rng.gen_range(0.0..std::f64::consts::TAU);
        let speed = log_uniform(&mut rng, 0.5, (0.3 * largest).max(3.0));
        let frame_count = rng.gen_range(15..=22);
        let mut style = Style {
            seed,
            profile,
            radius,
            mixed,
            particle_count,
            polarity,
            colour,
            background,
            foreground,
            blur,
            noise,
            gradient,
            gradient_angle,
            vignetting,
            additive_light: false,
            exposure,
            exposure_period,
            exposure_phase,
            saturating,
            speed,
            frame_count,
            width: 0,
            height: 0,
            lines: None,
        };
        let aspect = rng.gen_range(1.0..1.3);
        style.fit_frame(aspect);
        style.noise = style.noise.min(style.visible_noise());
        style
    }

    /// Each particle's radius, px: all `radius`, or alternately `radius` and `2.5 radius`
    /// when `mixed`.
    pub fn radii(&self) -> Vec<f64> {
        (0..self.particle_count)
            .map(|i| {
                if self.mixed && i % 2 == 1 {
                    2.5 * self.radius
                } else {
                    self.radius
                }
            })
            .collect()
    }

    /// The radius a particle of `radius` px visibly covers, px: the radius itself, or 1.6
    /// times it for a Gaussian spot (whose value there is 0.17 of its peak).
    pub fn outer_radius(&self, radius: f64) -> f64 {
        match self.profile {
            Profile::Gaussian => 1.6 * radius,
            _ => radius,
        }
    }

    /// How far a particle's centre is kept inside the frame, px: its outer radius, three
    /// blur widths and 2 px.
    pub fn margin(&self, radius: f64) -> f64 {
        self.outer_radius(radius) + 3.0 * self.blur + 2.0
    }

    /// The smallest distance kept between the centres of particles of radii `a` and `b`, px:
    /// 2.2 times the larger outer radius plus 4 px.
    pub fn separation(&self, a: f64, b: f64) -> f64 {
        2.2 * self.outer_radius(a.max(b)) + 4.0
    }

    /// The exposure gain of frame `k`.
    pub fn gain(&self, k: usize) -> f64 {
        1.0 + self.exposure
            * (std::f64::consts::TAU * k as f64 / self.exposure_period + self.exposure_phase).sin()
    }

    /// The illumination times the vignetting at `(x, y)` px (1 at the frame's centre).
    pub fn light(&self, x: f64, y: f64) -> f64 {
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let (dx, dy) = (x - 0.5 * (w - 1.0), y - 0.5 * (h - 1.0));
        let g = 1.0 + self.gradient * (dx * self.gradient_angle.cos() + dy * self.gradient_angle.sin()) / w;
        let corner2 = 0.25 * (w * w + h * h);
        g * (1.0 - self.vignetting * (dx * dx + dy * dy) / corner2)
    }

    /// A cell of `physfit bench track --sweep`: the style drawn from `seed` (its motion and its
    /// profile's own draws) with up to four particles of `profile` and radius `radius` px (as
    /// many as fit 48 px), one size, bright (150 over 30), grey, sharp, under even light and a
    /// steady exposure, pixel noise `noise` grey levels, walking up to 2 px a frame for 20
    /// frames, the frame fitted to them.
    pub fn bench_cell(profile: Profile, radius: f64, noise: f64, seed: u64) -> Style {
        let mut s = Style::random(seed);
        s.profile = profile;
        s.radius = radius;
        s.mixed = false;
        s.particle_count = ((48.0 / radius) as usize).clamp(1, 4);
        s.polarity = Polarity::BrightOnDark;
        s.colour = false;
        s.background = [30.0; 3];
        s.foreground = [180.0; 3];
        s.blur = 0.0;
        s.noise = noise;
        s.gradient = 0.0;
        s.vignetting = 0.0;
        s.exposure = 0.0;
        s.saturating = false;
        s.speed = 2.0;
        s.frame_count = 20;
        s.fit_frame(1.0);
        s
    }

    /// Sets the frame size from the particles' sizes, count, blur and speed: room for the
    /// margins and about 1.5 separations of space per particle; `aspect` (width over height,
    /// at least 1) widens it. Call it after changing the radius, count, blur or speed.
    pub fn fit_frame(&mut self, aspect: f64) {
        let radii = self.radii();
        let largest = radii.iter().fold(0.0f64, |m, &r| m.max(r));
        let cell = self.separation(largest, largest) + 4.0 * self.speed.min(6.0);
        let side = 2.0 * self.margin(largest) + 1.5 * cell * (self.particle_count as f64).sqrt();
        self.height = side.ceil().max(32.0) as u32;
        self.width = (side * aspect).ceil().max(32.0) as u32;
    }

    /// The largest noise under which the smallest particle stays visible: a third of its
    /// blurred peak contrast (the Euclidean norm over channels), grey levels.
    pub fn visible_noise(&self) -> f64 {
        let look = ParticleLook::new(&self.profile, self.radius, self.seed);
        let side = (2.0 * (look.reach() + 4.0 * self.blur + 3.0)).ceil() as usize;
        let mut plane = vec![0.0; side * side];
        let c = 0.5 * side as f64 + 0.23;
        add_particle(&mut plane, side, side, &look, [c, c], &|_, _| 1.0);
        blur_plane(&mut plane, side, side, self.blur);
        let d = self.contrast();
        let peak = plane.iter().fold(0.0f64, |m, &p| m.max(p.abs())) * d;
        peak / 3.0
    }

    /// The particles' contrast, `|foreground - background|` (Euclidean over channels; a grey
    /// contrast counts once), grey levels.
    pub fn contrast(&self) -> f64 {
        let d2: f64 = (0..3)
            .map(|c| (self.foreground[c] - self.background[c]).powi(2))
            .sum();
        if self.colour {
            d2.sqrt()
        } else {
            (d2 / 3.0).sqrt()
        }
    }
}

impl fmt::Display for Style {
    /// One line: seed, profile, radius, count, polarity, colour, blur, noise, light, camera.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "seed {} {} r {:.2}{} n {} {} {} contrast {:.0} blur {:.2} noise {:.1}",
            self.seed,
            self.profile.name(),
            self.radius,
            if self.mixed { " (mixed x2.5)" } else { "" },
            self.particle_count,
            match self.polarity {
                Polarity::BrightOnDark => "bright",
                Polarity::DarkOnLight => "dark",
            },
            if self.colour { "rgb" } else { "grey" },
            self.contrast(),
            self.blur,
            self.noise
        )?;
        if self.gradient > 0.0 {
            write!(f, " gradient {:.2}", self.gradient)?;
        }
        if self.vignetting > 0.0 {
            write!(f, " vignetting {:.2}", self.vignetting)?;
        }
        if self.additive_light && (self.gradient > 0.0 || self.vignetting > 0.0) {
            write!(f, " (on the background alone)")?;
        }
        if self.exposure > 0.0 {
            write!(f, " exposure ±{:.2}", self.exposure)?;
        }
        if self.saturating {
            write!(f, " saturating")?;
        }
        if let Some(l) = self.lines {
            write!(f, " lines {:.1} px at {:.2}", l.width, l.level)?;
        }
        write!(
            f,
            " speed {:.2} {}x{}x{}",
            self.speed, self.width, self.height, self.frame_count
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tolerance_is_the_noise_floor_or_twice_the_bound_plus_the_lean() {
        let mut style = Style::random(3);
        style.noise = 10.0;
        style.radius = 4.0;
        let close = |a: [f64; 2], b: [f64; 2]| (0..2).all(|k| (a[k] - b[k]).abs() < 1e-12);
        // 0.05 + 0.1 = 0.15 against 2 x 0.05 and 2 x 0.2.
        assert!(close(style.tolerance([0.05, 0.2], [0.1, 0.0]), [0.25, 0.4]));
        // Below 3 px the floor is 0.10 + 0.2 = 0.3.
        style.radius = 2.0;
        assert!(close(style.tolerance([0.05, 0.2], [0.0, 0.3]), [0.3, 0.7]));
    }

    #[test]
    fn random_styles_cover_the_whole_range() {
        let styles: Vec<Style> = (0..400).map(Style::random).collect();
        for name in ["disc", "gauss", "ring", "texture", "sphere"] {
            assert!(styles.iter().any(|s| s.profile.name() == name), "{name}");
        }
        let (lo, hi) = styles.iter().fold((f64::MAX, 0.0f64), |(lo, hi), s| {
            let r = s.radii();
            (lo.min(r[0]), hi.max(r.iter().fold(0.0f64, |m, &x| m.max(x))))
        });
        assert!(lo < 1.7 && hi > 50.0 && lo >= 1.5 && hi <= 60.0, "{lo} {hi}");
        assert!(styles.iter().any(|s| s.mixed) && styles.iter().any(|s| s.colour));
        assert!(styles.iter().any(|s| s.saturating));
        assert!(styles.iter().any(|s| s.polarity == Polarity::DarkOnLight));
        assert!(styles.iter().any(|s| s.polarity == Polarity::BrightOnDark));
        for s in &styles {
            assert!((1..=8).contains(&s.particle_count), "{s}");
            assert!(s.noise <= 30.0 && s.blur <= 3.0 && s.contrast() > 20.0, "{s}");
            assert!(s.width <= 800 && s.height <= 700, "{s}");
            if s.saturating {
                let top = (0..s.frame_count).map(|k| s.gain(k)).fold(0.0, f64::max);
                assert!(s.background.iter().any(|b| b * top > 255.0), "{s}");
            }
        }
    }
}
