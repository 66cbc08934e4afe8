//! SPH particles, smoothing kernels, neighbour search and field reconstruction.
//!
//! Conventions: every kernel is parametrised by its **support radius** `H` (world units):
//! `W(r, H) = 0` for `r >= H`, and `∫ W dV = 1` over 3D space. Classic smoothing lengths
//! relate as `H = 2h` (cubic spline, Wendland), `H = 3h` (quintic M6) — see [`Kernel`].
#![warn(missing_docs)]

mod field;
mod grid;
mod kernel;
mod particles;

pub use field::{FieldKind, FieldSample};
pub use grid::{Distinct, NeighbourGrid};
pub use kernel::Kernel;
pub use particles::{
    suggest_radius_array, suggest_support_radius, Component, ParticleError, ParticleSource,
    ParticleSpec, Particles, Quantity, RadiusSource, VolumeSource, DENSITY_NAMES, MASS_NAMES,
    SMOOTHING_LENGTH_NAMES, VOLUME_NAMES,
};
