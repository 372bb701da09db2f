//! Integration tests of physfit-model through its public API: integrators, each physics law
//! against its closed form, and the scene file contract.

mod bumper;
mod common;
mod constraints;
mod drag_per_body;
mod integration_laws;
mod physics_laws;
mod scene_file;
mod surface_friction;
mod wall_friction;
