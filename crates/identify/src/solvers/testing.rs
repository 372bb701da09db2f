//! Toy problems for the solver tests: bond-like parameter couples with a known optimum and a
//! local decomposition, plus a wrapper that checks every evaluated point.

use crate::{
    BondGenes, BondRef, CostFunction, Layout, LocalCostFunction, Observer, Parameter, ParameterKind,
};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// How a bond's couple of values enters the toy cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Shape {
    /// Sum of squared relative errors (absolute for cosines).
    Quadratic,
    /// A Rosenbrock valley per couple, `10 (s - l^2)^2 + (1 - l)^2` in relative coordinates
    /// (`l = L / L*` or `M - M* + 1`, `s = S / S*`): a curved ridge, minimum at (1, 1).
    Rosenbrock,
}

/// A toy identification problem: `springs` spring couples `(L, S)` and `torsions` torsion
/// couples `(M, T)`, laid out as a chain; region `r` depends on bonds `r - 1, r, r + 1`.
pub(crate) struct Toy {
    pub layout: Layout,
    pub truth: Vec<f64>,
    pub shape: Shape,
    regions: Vec<Vec<usize>>,
    region_bonds: Vec<Vec<usize>>,
}

impl Toy {
    pub(crate) fn new(springs: usize, torsions: usize, shape: Shape) -> Toy {
        let mut layout = Layout::default();
        let mut truth = Vec::new();
        for k in 0..springs + torsions {
            let is_spring = k < springs;
            // Deterministic, varied truths; stiffness scales off by up to a factor 3 from the truth,
            // as a data-derived scale would be.
            let (value, stiffness) = if is_spring {
                (30.0 + 7.0 * (k % 5) as f64, 50.0 * (1.0 + (k % 4) as f64))
            } else {
                (-0.6 + 0.3 * (k % 5) as f64, 400.0 * (1.0 + (k % 3) as f64))
            };
            let stiffness_scale = stiffness * [0.4, 1.0, 2.5][k % 3];
            let observed: Vec<f64> = (0..60)
                .map(|t| {
                    let wobble = (0.37 * t as f64 + k as f64).sin();
                    if is_spring {
                        value * (1.0 + 0.15 * wobble)
                    } else {
                        (value + 0.1 * wobble).clamp(-1.0, 1.0)
                    }
                })
                .collect();
            let first = layout.parameters.len();
            let (bond, kinds, bounds, scales) = if is_spring {
                let mean = observed.iter().sum::<f64>() / observed.len() as f64;
                (
                    BondRef::Spring(k),
                    [ParameterKind::RestLength, ParameterKind::SpringStiffness],
                    [[0.5, 1000.0], [0.0, 1e7]],
                    [mean, stiffness_scale],
                )
            } else {
                (
                    BondRef::Torsion(k - springs),
                    [ParameterKind::RestCos, ParameterKind::TorsionStiffness],
                    [[-1.0, 1.0], [0.0, 1e8]],
                    [1.0, stiffness_scale],
                )
            };
            for j in 0..2 {
                layout.parameters.push(Parameter {
                    bond,
                    kind: kinds[j],
                    bounds: bounds[j],
                    scale: scales[j],
                });
            }
            truth.extend([value, stiffness]);
            layout.bonds.push(BondGenes {
                bond,
                params: vec![first, first + 1],
                particles: if is_spring {
                    vec![k, k + 1]
                } else {
                    vec![k, k + 1, k + 2]
                },
                observed,
            });
        }
        let bonds = layout.bonds.len();
        let region_bonds: Vec<Vec<usize>> = (0..bonds)
            .map(|r| (r.saturating_sub(1)..(r + 2).min(bonds)).collect())
            .collect();
        let regions = region_bonds
            .iter()
            .map(|bs| bs.iter().flat_map(|&b| layout.bonds[b].params.clone()).collect())
            .collect();
        Toy {
            layout,
            truth,
            shape,
            regions,
            region_bonds,
        }
    }

    fn bond_cost(&self, b: usize, x: &[f64]) -> f64 {
        let [i, j] = [self.layout.bonds[b].params[0], self.layout.bonds[b].params[1]];
        let is_cos = self.layout.parameters[i].kind == ParameterKind::RestCos;
        let l = if is_cos {
            x[i] - self.truth[i] + 1.0
        } else {
            x[i] / self.truth[i]
        };
        let s = x[j] / self.truth[j];
        match self.shape {
            Shape::Quadratic => (l - 1.0).powi(2) + (s - 1.0).powi(2),
            Shape::Rosenbrock => 10.0 * (s - l * l).powi(2) + (1.0 - l).powi(2),
        }
    }

    /// Largest error over the parameters: relative for lengths and stiffnesses, absolute for
    /// cosines.
    pub(crate) fn max_error(&self, x: &[f64]) -> f64 {
        self.layout
            .parameters
            .iter()
            .zip(x.iter().zip(&self.truth))
            .map(|(info, (v, t))| match info.kind {
                ParameterKind::RestCos => (v - t).abs(),
                _ => ((v - t) / t).abs(),
            })
            .fold(0.0, f64::max)
    }
}

impl CostFunction for Toy {
    fn dimension(&self) -> usize {
        self.layout.dimension()
    }

    fn cost(&self, params: &[f64]) -> f64 {
        let mut out = vec![0.0; self.region_count()];
        self.local_costs(params, &mut out);
        out.iter().sum()
    }
}

impl LocalCostFunction for Toy {
    fn region_count(&self) -> usize {
        self.regions.len()
    }

    fn region_parameters(&self, r: usize) -> &[usize] {
        &self.regions[r]
    }

    fn local_costs(&self, params: &[f64], out: &mut [f64]) {
        for (o, bonds) in out.iter_mut().zip(&self.region_bonds) {
            *o = bonds.iter().map(|&b| self.bond_cost(b, params)).sum();
        }
    }
}

/// Wraps a problem, counting evaluations and recording whether any evaluated point left the
/// layout's bounds.
pub(crate) struct Checked<'a> {
    pub inner: &'a Toy,
    pub evaluations: AtomicUsize,
    pub out_of_bounds: AtomicBool,
}

impl<'a> Checked<'a> {
    pub(crate) fn new(inner: &'a Toy) -> Self {
        Checked {
            inner,
            evaluations: AtomicUsize::new(0),
            out_of_bounds: AtomicBool::new(false),
        }
    }

    fn check(&self, params: &[f64]) {
        self.evaluations.fetch_add(1, Ordering::Relaxed);
        let outside = params
            .iter()
            .zip(&self.inner.layout.parameters)
            .any(|(v, info)| !(info.bounds[0]..=info.bounds[1]).contains(v));
        if outside {
            self.out_of_bounds.store(true, Ordering::Relaxed);
        }
    }
}

impl CostFunction for Checked<'_> {
    fn dimension(&self) -> usize {
        self.inner.dimension()
    }

    fn cost(&self, params: &[f64]) -> f64 {
        self.check(params);
        self.inner.cost(params)
    }
}

impl LocalCostFunction for Checked<'_> {
    fn region_count(&self) -> usize {
        self.inner.region_count()
    }

    fn region_parameters(&self, r: usize) -> &[usize] {
        self.inner.region_parameters(r)
    }

    fn local_costs(&self, params: &[f64], out: &mut [f64]) {
        self.check(params);
        self.inner.local_costs(params, out);
    }
}

/// An observer that keeps every reported best cost.
#[derive(Default)]
pub(crate) struct Recorder(pub Mutex<Vec<(usize, f64)>>);

impl Observer for Recorder {
    fn observe(&self, iteration: usize, best_cost: f64) {
        if let Ok(mut v) = self.0.lock() {
            v.push((iteration, best_cost));
        }
    }
}

/// Bit patterns of a vector, for bitwise comparisons.
pub(crate) fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// A cost that is the same everywhere (nothing to improve).
pub(crate) struct Flat(pub usize);

impl CostFunction for Flat {
    fn dimension(&self) -> usize {
        self.0
    }

    fn cost(&self, _params: &[f64]) -> f64 {
        1.0
    }
}
