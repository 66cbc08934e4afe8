//! Attribute-aware RBF particle fields (Morrical et al. 2023, "Attribute-Aware RBFs:
//! Interactive Visualization of Time Series Particle Volumes Using RT Core Range Queries").
//!
//! Where the SPH fields of `fluidcast-sph` need masses, densities and a kernel, this model
//! needs only centres, an attribute and radii, so it serves particles without them
//! (cosmology, molecular dynamics, DEM) and lets the attribute decide what is visible:
//!
//! * each particle is a truncated Gaussian RBF `φ_i(x) = w(s_i)·exp(−½(3d/r_i)²)` for
//!   `d <= r_i` ([`rbf`]), its weight `w` a density map of its attribute `s_i` and its radius
//!   `r_i` a global radius times a radius map of `s_i` ([`AttributeMap`]);
//! * the density field `Φ = Σ φ_i` is the optical density;
//! * the attribute field `Θ = Σ φ_i θ̂_i / Φ` colours it, post-classified (attributes blend,
//!   then the colour map) or pre-classified (colours blend) ([`Colouring`]);
//! * a [`ClusterBvh`] over Hilbert-sorted clusters of particles answers the range queries
//!   (which particles hold a point, which a ray crosses), built per time step and refit when
//!   only radii change.
#![warn(missing_docs)]

mod bvh;
mod field;
mod hilbert;

pub use bvh::{holds, sphere_crossing, Aabb, ClusterBvh, RayHit, MAX_LEAF_SIZE};
pub use field::{
    rbf, AttributeMap, Colouring, Profile, RbfField, RbfOptions, RbfSample, DEFAULT_LEAF_SIZE,
    SIGMAS,
};
pub use hilbert::{hilbert_key, HILBERT_BITS};

/// Why particles cannot become an RBF field.
#[derive(Debug, thiserror::Error)]
pub enum RbfError {
    /// A leaf size out of 1..=64.
    #[error("BVH leaf size {0}: must be 1..={MAX_LEAF_SIZE} particles")]
    LeafSize(usize),
    /// An array of another length than the particles.
    #[error("{got} {what} for {expected} particles")]
    Length {
        /// The array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The particles.
        expected: usize,
    },
    /// More particles than 32-bit slots index.
    #[error("{0} particles: the RBF field indexes at most 4,294,967,295")]
    TooMany(usize),
    /// A particle centre with NaN or infinity.
    #[error("particle {index}: centre {centre:?} is not finite")]
    Centre {
        /// The particle.
        index: usize,
        /// Its centre.
        centre: [f32; 3],
    },
    /// A particle radius that is negative or not finite.
    #[error("particle {index}: radius {radius} is not a finite number >= 0")]
    Radius {
        /// The particle.
        index: usize,
        /// Its radius.
        radius: f32,
    },
    /// A global RBF radius that is not a finite number > 0.
    #[error("RBF radius {0}: must be finite and > 0 (world units)")]
    GlobalRadius(f64),
    /// A particle whose attribute is NaN.
    #[error("particle {index}: its attribute is NaN")]
    Attribute {
        /// The particle.
        index: usize,
    },
    #[error(
        "attribute map '{0}': expected pairs of position in [0, 1] and factor >= 0, e.g. 0,1,1,0.5"
    )]
    /// A radius map that is not pairs of position and factor.
    Map(String),
}
