//! Options shared by `render` and `probe`: how particles are built from a file.

use anyhow::Result;
use fluidcast_sph::{FieldKind, Kernel, ParticleSpec, Quantity, RadiusSource, VolumeSource};

#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "Particles")]
pub struct ParticleArgs {
    /// Point array to render: NAME, NAME:mag (vector magnitude) or NAME:K (component K).
    /// Without it, the density field of the particles is rendered.
    #[arg(long)]
    pub array: Option<String>,
    /// Smoothing kernel: cubic, quintic, wendland-c2, wendland-c4, poly6, gaussian.
    #[arg(long, default_value = "cubic")]
    pub kernel: String,
    /// Field reconstruction: csph (Shepard-normalised, default), sph (plain sum), density, or
    /// rbf (the attribute-aware RBF field of Morrical et al. 2023: truncated Gaussians whose
    /// weight is the transfer function's opacity at their attribute; see the --rbf-* options,
    /// --radius-map, --classification and --spp).
    #[arg(long)]
    pub field: Option<String>,
    /// One support radius H for all particles (world units; the kernel is 0 beyond H).
    #[arg(long, conflicts_with = "radius_array", allow_hyphen_values = true,
          value_parser = crate::checked::real("--support-radius"))]
    pub support_radius: Option<f64>,
    /// Per-particle radius array; H = value × --radius-scale.
    #[arg(long)]
    pub radius_array: Option<String>,
    /// Factor from --radius-array to the support radius (2 for a smoothing length h with a
    /// cubic or Wendland kernel).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true,
          value_parser = crate::checked::real("--radius-scale"))]
    pub radius_scale: f64,
    /// Mass array (with --density-array: V = m/ρ).
    #[arg(long, requires = "density_array")]
    pub mass_array: Option<String>,
    /// Density array (with --mass-array: V = m/ρ).
    #[arg(long, requires = "mass_array")]
    pub density_array: Option<String>,
    /// Volume array V (instead of mass/density).
    #[arg(long, conflicts_with_all = ["mass_array", "density_array"])]
    pub volume_array: Option<String>,
    /// Treat all particle volumes as equal.
    #[arg(long, conflicts_with_all = ["mass_array", "density_array", "volume_array"])]
    pub uniform_volume: bool,
}

impl ParticleArgs {
    pub fn spec(&self) -> Result<ParticleSpec> {
        let quantity = match &self.array {
            Some(a) => Some(a.parse::<Quantity>().map_err(anyhow::Error::msg)?),
            None => None,
        };
        let radius = match (&self.radius_array, self.support_radius) {
            (Some(n), _) => RadiusSource::Array {
                name: n.clone(),
                scale: self.radius_scale,
            },
            // 0, as in the mapper's SupportRadius: from the data.
            (None, Some(h)) if h > 0.0 => RadiusSource::Constant(h),
            (None, Some(_)) => RadiusSource::Auto,
            (None, None) => RadiusSource::Auto,
        };
        let volume = match (&self.mass_array, &self.density_array, &self.volume_array) {
            (Some(m), Some(d), _) => VolumeSource::MassDensity {
                mass: m.clone(),
                density: d.clone(),
            },
            (_, _, Some(v)) => VolumeSource::Array(v.clone()),
            _ if self.uniform_volume => VolumeSource::Uniform,
            _ => VolumeSource::Auto,
        };
        Ok(ParticleSpec {
            quantity,
            radius,
            volume,
            mass: self.mass_array.clone(),
        })
    }

    pub fn kernel(&self) -> Result<Kernel> {
        self.kernel.parse::<Kernel>().map_err(anyhow::Error::msg)
    }

    /// Whether `--field rbf` asks for the RBF field (drawn by its own ray marcher).
    pub fn rbf(&self) -> bool {
        self.field
            .as_deref()
            .is_some_and(|f| f.eq_ignore_ascii_case("rbf"))
    }

    /// CSPH for an attribute, density when no array is chosen, unless --field says otherwise.
    /// For `--field rbf`, the SPH field whose colour-map range it starts from (the attribute's
    /// range, or a density's).
    pub fn field(&self) -> Result<FieldKind> {
        match &self.field {
            Some(_) if self.rbf() && self.array.is_some() => Ok(FieldKind::Csph),
            Some(_) if self.rbf() => Ok(FieldKind::Density),
            Some(f) => f
                .parse::<FieldKind>()
                .map_err(|e| anyhow::anyhow!("{}", e.replace("or density)", "density or rbf)"))),
            None if self.array.is_none() => Ok(FieldKind::Density),
            None => Ok(FieldKind::Csph),
        }
    }
}
