//! Emission–absorption ray casting of SPH particle fields.
//!
//! [`render_reference`] is the reference renderer: the oracle every faster path is tested
//! against. It samples each pixel's ray at the logarithmically spaced view depths of
//! Hochstetter et al. 2016, Eq. 8 (`z_i = n (f/n)^(i/N)`), with `N` from Fraedrich et al.
//! 2010 (`m = ln(f/n)/σ`, σ the angular pixel size) so that the depth step matches the
//! lateral pixel footprint, scaled by the frustum-corner factor λ and a user factor.
//! Samples lie on planes of constant view depth, shared by all rays (the perspective grid's
//! slices). Each sample's field value is the exact kernel sum over all particles whose
//! support contains it.

mod reference;

pub use reference::{
    render_reference, RenderError, RenderParams, RenderStats, SampleDepths, MAX_SIDE,
};
