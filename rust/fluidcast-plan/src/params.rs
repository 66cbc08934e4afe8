//! What a plan is asked for: the field, the error tolerance and the plan's switches
//! ([`PlanParams`]), and why a plan could not be made ([`PlanError`]).

use fluidcast_sph::{FieldKind, Kernel};

/// Largest number of sampling levels (D_z ≤ 64 gives levels 0..=6).
pub(crate) const LEVELS: usize = 7;

/// How the field is sampled: kernel, field kind and the ray caster's early-termination
/// transmittance (which the error budget accounts for).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldParams {
    /// The smoothing kernel.
    pub kernel: Kernel,
    /// The field reconstructed (CSPH, SPH sum, density).
    pub field: FieldKind,
    /// Transmittance below which a ray stops (early termination).
    pub min_transmittance: f64,
}

/// What the user asks of the adaptive sampling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanParams {
    /// Screen-space error tolerance E_I (in colour/alpha units, 0..1), or `None` for no
    /// adaptivity (every cell at full rate).
    pub tolerance: Option<f64>,
    /// E_relax ∈ [0, 1]: 1 removes the lateral (level-0) width from the estimate (Sec. 5.1),
    /// 0 is the strict bound.
    pub relax: f64,
    /// Allow cells to be rendered as super-pixels (Sec. 5.2).
    pub superpixels: bool,
    /// Force cells that reference surface particles to full rate (Sec. 4.2).
    pub surface_cells: bool,
    /// Relaxed mode only: cast every second pixel of every second row first, and interpolate
    /// the pixels between where the image is smooth (image-space refinement, beyond the
    /// paper: `fluidcast_render::interpolate`).
    pub interpolate: bool,
    /// Analyse a sample of the bundles first (beyond the paper; see the crate's
    /// documentation) and plan the others at full rate, without their analysis, where the
    /// sample predicts that adapting saves the ray caster less than the analysis costs.
    pub probe: bool,
}

impl Default for PlanParams {
    fn default() -> Self {
        PlanParams {
            tolerance: Some(0.004),
            relax: 1.0,
            superpixels: true,
            surface_cells: true,
            interpolate: true,
            probe: true,
        }
    }
}

impl PlanParams {
    /// True when surface particles matter: an adaptive, relaxed plan with the surface rule
    /// on. Unrelaxed bounds already include "no particle" wherever a ray may leave the fluid,
    /// so the strict mode needs no surface test.
    pub fn uses_surface_cells(&self) -> bool {
        self.tolerance.is_some() && self.surface_cells && self.relax > 0.0
    }

    /// Checks the ranges: E_I and E_relax in [0, 1].
    pub fn validate(&self) -> Result<(), PlanError> {
        if let Some(e) = self.tolerance {
            if !(0.0..=1.0).contains(&e) {
                return Err(PlanError::Tolerance(e));
            }
        }
        if !(0.0..=1.0).contains(&self.relax) {
            return Err(PlanError::Relax(self.relax));
        }
        Ok(())
    }

    /// The strict mode: no relaxation, no super-pixels and no interpolation, so the bound is
    /// a guarantee.
    pub fn strict(mut self) -> Self {
        self.relax = 0.0;
        self.superpixels = false;
        self.interpolate = false;
        self
    }
}

/// Why a plan could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// An error tolerance outside [0, 1].
    #[error("error tolerance {0} must be in [0, 1]")]
    Tolerance(f64),
    /// A relaxation outside [0, 1].
    #[error("relaxation {0} must be in [0, 1]")]
    Relax(f64),
    /// Surface flags of another particle count (flags, particles).
    #[error("surface flags: {0} given for {1} particles")]
    SurfaceFlags(usize, usize),
    /// Depth stops of another bundle count (stops, bundles).
    #[error("depth stops: {0} given for {1} bundles")]
    Stops(usize, usize),
}
