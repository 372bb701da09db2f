//! [`SplinePath`]: a tracked particle's path between frames, to drive a cut boundary.

use physfit_model::Vec2;

/// A particle's path through its tracked positions at every frame, as a cubic spline (px,
/// time in frames from the first): twice continuously differentiable, with the end slopes of
/// the cubic through the four end points, so that its error is fourth order in the frame
/// interval (inside, about `1e-4 (omega dt)^4` of the amplitude at angular frequency `omega`;
/// in the end intervals about `0.04 (omega dt)^4`).
#[derive(Clone, Debug)]
pub(crate) struct SplinePath {
    points: Vec<Vec2>,
    /// Derivative at each frame, px per frame.
    slopes: Vec<Vec2>,
}

impl SplinePath {
    /// The spline through `points` (one per frame). Fewer than four points: straight pieces.
    pub(crate) fn new(points: Vec<Vec2>) -> SplinePath {
        let n = points.len();
        if n < 4 {
            let slopes = (0..n)
                .map(|i| {
                    let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                    if b > a {
                        (points[b] - points[a]) / (b - a) as f64
                    } else {
                        Vec2::zeros()
                    }
                })
                .collect();
            return SplinePath { points, slopes };
        }
        let p = &points;
        let first = (p[1] * 18.0 - p[0] * 11.0 - p[2] * 9.0 + p[3] * 2.0) / 6.0;
        let last = (p[n - 1] * 11.0 - p[n - 2] * 18.0 + p[n - 3] * 9.0 - p[n - 4] * 2.0) / 6.0;
        // Interior slopes: m[i-1] + 4 m[i] + m[i+1] = 3 (p[i+1] - p[i-1]), by the Thomas algorithm.
        let mut slopes = vec![Vec2::zeros(); n];
        slopes[0] = first;
        slopes[n - 1] = last;
        let mut diag = vec![4.0; n];
        let mut rhs: Vec<Vec2> = (0..n)
            .map(|i| {
                if i == 0 || i == n - 1 {
                    Vec2::zeros()
                } else {
                    (p[i + 1] - p[i - 1]) * 3.0
                }
            })
            .collect();
        rhs[1] -= first;
        rhs[n - 2] -= last;
        for i in 2..n - 1 {
            let w = 1.0 / diag[i - 1];
            diag[i] -= w;
            let prev = rhs[i - 1];
            rhs[i] -= prev * w;
        }
        for i in (1..n - 1).rev() {
            let next = if i + 1 < n - 1 {
                slopes[i + 1]
            } else {
                Vec2::zeros()
            };
            slopes[i] = (rhs[i] - next) / diag[i];
        }
        SplinePath { points, slopes }
    }

    /// Position (px) and velocity (px per frame) at time `t` (frames; clamped to the track).
    pub(crate) fn at(&self, t: f64) -> (Vec2, Vec2) {
        let last = self.points.len() - 1;
        if last == 0 {
            return (self.points[0], Vec2::zeros());
        }
        let t = t.clamp(0.0, last as f64);
        let i = (t.floor() as usize).min(last - 1);
        let u = t - i as f64;
        let (p0, p1, m0, m1) = (
            self.points[i],
            self.points[i + 1],
            self.slopes[i],
            self.slopes[i + 1],
        );
        let (u2, u3) = (u * u, u * u * u);
        let x = p0 * (2.0 * u3 - 3.0 * u2 + 1.0)
            + m0 * (u3 - 2.0 * u2 + u)
            + p1 * (3.0 * u2 - 2.0 * u3)
            + m1 * (u3 - u2);
        let v = p0 * (6.0 * u2 - 6.0 * u)
            + m0 * (3.0 * u2 - 4.0 * u + 1.0)
            + p1 * (6.0 * u - 6.0 * u2)
            + m1 * (3.0 * u2 - 2.0 * u);
        (x, v)
    }
}

/// Pinned particles driven along [`SplinePath`]s, sampled once at every substep of the
/// recording, so that the many simulations of a cost read a table instead of evaluating the
/// splines twice per substep.
#[derive(Clone, Debug)]
pub(crate) struct DrivenBoundary {
    /// The driven particles (indices in the model).
    particles: Vec<usize>,
    /// Position (px) and velocity (px per frame) of each driven particle at each substep:
    /// `samples[i * particles.len() + j]` at time `i / substeps` frames.
    samples: Vec<(Vec2, Vec2)>,
}

impl DrivenBoundary {
    /// Samples `paths` (`(particle, path)`) at `substeps` points per frame over `frames` frames.
    pub(crate) fn new(paths: &[(usize, SplinePath)], frames: usize, substeps: usize) -> DrivenBoundary {
        let substeps = substeps.max(1);
        let steps = frames.saturating_sub(1) * substeps + 1;
        let mut samples = Vec::with_capacity(steps * paths.len());
        for i in 0..steps {
            let t = i as f64 / substeps as f64;
            samples.extend(paths.iter().map(|(_, path)| path.at(t)));
        }
        DrivenBoundary {
            particles: paths.iter().map(|(p, _)| *p).collect(),
            samples,
        }
    }

    /// `(particle, position px, velocity px per frame)` of every driven particle at substep
    /// `i` (counted from the first frame; clamped to the recording).
    pub(crate) fn at(&self, i: usize) -> impl Iterator<Item = (usize, Vec2, Vec2)> + '_ {
        let n = self.particles.len();
        let last = (self.samples.len() / n.max(1)).saturating_sub(1);
        let row = &self.samples[i.min(last) * n..(i.min(last) + 1) * n];
        self.particles.iter().zip(row).map(|(&p, &(x, v))| (p, x, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_a_circle_to_fourth_order_between_frames() {
        // A point on a circle of radius 10 px at 0.1 rad per frame: inside, the error between
        // frames is about 1e-4 (0.1)^4 of the radius; in the end intervals, where the slope
        // comes from a one-sided cubic, about (0.1)^4 / 4 px per frame of slope error, so
        // some 4e-5 px. A quadratic method would be off by about 1e-2 (0.1)^2 10 = 1e-3 px.
        let path = |t: f64| Vec2::new(10.0 * (0.1 * t).cos(), 10.0 * (0.1 * t).sin());
        let spline = SplinePath::new((0..60).map(|k| path(k as f64)).collect());
        let mut worst: f64 = 0.0;
        let mut worst_v: f64 = 0.0;
        for i in 0..590 {
            let t = i as f64 * 0.1 + 0.05;
            let (x, v) = spline.at(t);
            worst = worst.max((x - path(t)).norm());
            let exact_v = Vec2::new(-(0.1 * t).sin(), (0.1 * t).cos());
            worst_v = worst_v.max((v - exact_v).norm());
        }
        assert!(worst < 1e-4, "position error {worst:e} px");
        assert!(worst_v < 5e-4, "velocity error {worst_v:e} px/frame");
        assert_eq!(spline.at(3.0).0, path(3.0));
    }

    #[test]
    fn the_boundary_table_holds_the_spline_at_every_substep() {
        let points: Vec<Vec2> = (0..6).map(|k| Vec2::new(k as f64, (k * k) as f64)).collect();
        let path = SplinePath::new(points);
        let table = DrivenBoundary::new(&[(3, path.clone())], 6, 4);
        for i in [0, 1, 7, 13, 20] {
            let (p, x, v) = table.at(i).next().expect("one driven particle");
            let (xs, vs) = path.at(i as f64 / 4.0);
            assert_eq!((p, x, v), (3, xs, vs), "substep {i}");
        }
        // Beyond the recording: its last sample.
        assert_eq!(table.at(99).next().map(|s| s.1), Some(path.at(5.0).0));
    }
}
