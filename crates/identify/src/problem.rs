//! [`Problem`]: a structure with unknown bond values, its parameter [`Layout`], and the map from
//! a parameter vector to a simulation-ready [`Model`] or a fitted [`Scene`].

use physfit_model::{IntegrationParameters, Model, Particle, ParticleSet, Scene, Spring, Torsion};

use crate::{layout_for, BondRef, IdentifyError, Layout, Observations, ParameterKind};

/// An identification problem: what is known (the structure) and what is fitted (the layout).
#[derive(Clone, Debug)]
pub struct Problem {
    /// The structure: topology, masses and known values; unknown values are `None`.
    pub structure: Scene,
    /// The unknowns, in parameter-vector order.
    pub layout: Layout,
    /// The structure's model with every unknown set to zero (overwritten by [`Problem::write_params`]).
    base: Model,
}

impl Problem {
    /// The problem of fitting `structure`'s unknown values to `observations`, with the layout
    /// from [`layout_for`]. Errors when nothing is unknown or a known value is invalid.
    pub fn new(structure: &Scene, observations: &Observations) -> Result<Problem, IdentifyError> {
        Problem::with_layout(structure, layout_for(structure, observations))
    }

    /// As [`Problem::new`] with a given layout (which must come from this structure).
    pub fn with_layout(structure: &Scene, layout: Layout) -> Result<Problem, IdentifyError> {
        if layout.dimension() == 0 {
            return Err(IdentifyError::NoUnknowns);
        }
        let particles = ParticleSet {
            particles: structure
                .particles
                .iter()
                .map(|p| Particle::new(p.mass, p.fixed))
                .collect(),
        };
        let springs = structure
            .springs
            .iter()
            .map(|s| {
                let mut sp = Spring::new(
                    s.ends[0],
                    s.ends[1],
                    s.rest_length.unwrap_or(0.0),
                    s.stiffness.unwrap_or(0.0),
                );
                sp.damping = s.damping;
                sp
            })
            .collect();
        let torsions = structure
            .torsions
            .iter()
            .map(|t| {
                Torsion::new(
                    t.center,
                    t.ends[0],
                    t.ends[1],
                    t.rest_cos.unwrap_or(0.0),
                    t.stiffness.unwrap_or(0.0),
                )
            })
            .collect();
        let base = Model {
            particles,
            springs,
            torsions,
            physics: structure.physics.clone(),
        };
        Ok(Problem {
            structure: structure.clone(),
            layout,
            base,
        })
    }

    /// Length of the parameter vector.
    pub fn dimension(&self) -> usize {
        self.layout.dimension()
    }

    /// The structure's time stepping (frame interval, substeps, integrator).
    pub fn integration_parameters(&self) -> IntegrationParameters {
        self.structure.integration_parameters()
    }

    /// The model with the structure's known values and `params` for the unknowns.
    pub fn model(&self, params: &[f64]) -> Model {
        let mut m = self.base.clone();
        self.write_params(params, &mut m);
        m
    }

    /// Writes `params` into a model built from this problem's structure (as [`Problem::model`]
    /// returns), leaving known values as they are.
    pub fn write_params(&self, params: &[f64], model: &mut Model) {
        for (value, p) in params.iter().zip(&self.layout.parameters) {
            match (p.bond, p.kind) {
                (BondRef::Spring(k), ParameterKind::RestLength) => model.springs[k].rest_length = *value,
                (BondRef::Spring(k), _) => model.springs[k].stiffness = *value,
                (BondRef::Torsion(k), ParameterKind::RestCos) => model.torsions[k].rest_cos = *value,
                (BondRef::Torsion(k), _) => model.torsions[k].stiffness = *value,
            }
        }
    }

    /// The structure with every unknown filled in from `params`: a scene that simulates and renders.
    pub fn fitted_scene(&self, params: &[f64]) -> Scene {
        let mut s = self.structure.clone();
        for (value, p) in params.iter().zip(&self.layout.parameters) {
            match (p.bond, p.kind) {
                (BondRef::Spring(k), ParameterKind::RestLength) => s.springs[k].rest_length = Some(*value),
                (BondRef::Spring(k), _) => s.springs[k].stiffness = Some(*value),
                (BondRef::Torsion(k), ParameterKind::RestCos) => s.torsions[k].rest_cos = Some(*value),
                (BondRef::Torsion(k), _) => s.torsions[k].stiffness = Some(*value),
            }
        }
        s
    }

    /// The parameter vector of a scene with this structure (a ground truth, a fitted model),
    /// or `None` where the scene lacks one of the values or has different bonds.
    pub fn params_of(&self, scene: &Scene) -> Option<Vec<f64>> {
        self.layout
            .parameters
            .iter()
            .map(|p| match (p.bond, p.kind) {
                (BondRef::Spring(k), ParameterKind::RestLength) => scene.springs.get(k)?.rest_length,
                (BondRef::Spring(k), _) => scene.springs.get(k)?.stiffness,
                (BondRef::Torsion(k), ParameterKind::RestCos) => scene.torsions.get(k)?.rest_cos,
                (BondRef::Torsion(k), _) => scene.torsions.get(k)?.stiffness,
            })
            .collect()
    }

    /// A starting point from the data alone: rest lengths and rest cosines at their observed
    /// means, stiffnesses at their scales (the paper starts rest lengths at the mean distances).
    pub fn initial_guess(&self) -> Vec<f64> {
        let mut x: Vec<f64> = self.layout.parameters.iter().map(|p| p.scale).collect();
        for b in &self.layout.bonds {
            let mean = if b.observed.is_empty() {
                None
            } else {
                Some(b.observed.iter().sum::<f64>() / b.observed.len() as f64)
            };
            for &i in &b.params {
                let kind = self.layout.parameters[i].kind;
                if matches!(kind, ParameterKind::RestLength | ParameterKind::RestCos) {
                    if let Some(m) = mean {
                        x[i] = m;
                    }
                }
            }
        }
        self.layout.clamp(&mut x);
        x
    }

    /// The bond's name as the scene file spells it, e.g. `spring a-b` or `torsion a-c-b`.
    pub fn bond_label(&self, bond: BondRef) -> String {
        match bond {
            BondRef::Spring(k) => self.structure.spring_label(k),
            BondRef::Torsion(k) => self.structure.torsion_label(k),
        }
    }

    /// A parameter's name for messages, e.g. `spring a-b stiffness`.
    pub fn parameter_label(&self, index: usize) -> String {
        let p = &self.layout.parameters[index];
        format!("{} {}", self.bond_label(p.bond), p.kind.key())
    }
}
