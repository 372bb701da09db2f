//! [`Layout`]: how a structure's unknown bond values map to a flat parameter vector.

use serde::Serialize;

/// Which bond a parameter belongs to, by index in the structure's lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum BondRef {
    /// `scene.springs[k]`.
    Spring(usize),
    /// `scene.torsions[k]`.
    Torsion(usize),
}

/// What a parameter is, physically.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum ParameterKind {
    /// Spring rest length `L`, px.
    RestLength,
    /// Spring stiffness `S`.
    SpringStiffness,
    /// Torsion rest cosine `M`, in [-1, 1].
    RestCos,
    /// Torsion angular stiffness `T`.
    TorsionStiffness,
}

impl ParameterKind {
    /// The scene-file key of this parameter (`length`, `stiffness`, `rest_cos`).
    pub fn key(self) -> &'static str {
        match self {
            ParameterKind::RestLength => "length",
            ParameterKind::SpringStiffness | ParameterKind::TorsionStiffness => "stiffness",
            ParameterKind::RestCos => "rest_cos",
        }
    }
}

/// One entry of the parameter vector.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Parameter {
    /// The bond it belongs to.
    pub bond: BondRef,
    /// What it is.
    pub kind: ParameterKind,
    /// Physically admissible range `[lower, upper]` (stiffnesses non-negative, cosines in
    /// [-1, 1], lengths positive).
    pub bounds: [f64; 2],
    /// A typical magnitude from the data (mutation and finite-difference scale).
    pub scale: f64,
}

/// A bond's unknowns, kept together: the genetic algorithms cross over a bond's couple of
/// values as a unit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BondGenes {
    /// The bond.
    pub bond: BondRef,
    /// Indices of its unknown parameters in the vector (one or two).
    pub params: Vec<usize>,
    /// The particles it touches (2 for a spring, 3 for a torsion).
    pub particles: Vec<usize>,
    /// The bond's observed geometry over the analysed frames: distances (px) for a spring,
    /// cosines for a torsion. Rest-length mutation draws from these.
    pub observed: Vec<f64>,
}

/// The parameter vector of an identification problem.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Layout {
    /// The parameters, in vector order.
    pub parameters: Vec<Parameter>,
    /// The bonds with at least one unknown.
    pub bonds: Vec<BondGenes>,
}

impl Layout {
    /// Length of the parameter vector.
    pub fn dimension(&self) -> usize {
        self.parameters.len()
    }

    /// Clamps `params` into every parameter's bounds.
    pub fn clamp(&self, params: &mut [f64]) {
        for (p, info) in params.iter_mut().zip(&self.parameters) {
            *p = p.clamp(info.bounds[0], info.bounds[1]);
        }
    }
}
