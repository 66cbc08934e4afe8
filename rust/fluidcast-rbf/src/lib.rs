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
    #[error("BVH leaf size {0}: must be 1..={MAX_LEAF_SIZE} particles")]
    LeafSize(usize),
    #[error("{got} {what} for {expected} particles")]
    Length {
        what: &'static str,
        got: usize,
        expected: usize,
    },
    #[error("{0} particles: the RBF field indexes at most 4,294,967,295")]
    TooMany(usize),
    #[error("particle {index}: centre {centre:?} is not finite")]
    Centre { index: usize, centre: [f32; 3] },
    #[error("particle {index}: radius {radius} is not a finite number >= 0")]
    Radius { index: usize, radius: f32 },
    #[error("RBF radius {0}: must be finite and > 0 (world units)")]
    GlobalRadius(f64),
    #[error("particle {index}: its attribute is NaN")]
    Attribute { index: usize },
    #[error(
        "attribute map '{0}': expected pairs of position in [0, 1] and factor >= 0, e.g. 0,1,1,0.5"
    )]
    Map(String),
}
