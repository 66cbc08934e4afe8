//! `--field rbf` and `--shadows`: the options of the stochastic ray march (the
//! attribute-aware RBF field of Morrical et al. 2023), as the library's plan takes them.

use anyhow::{bail, Context, Result};
use fluidcast_backend::{
    AttributeMap, Colouring, Noise, RbfOptions, RbfRenderParams, RbfShadows, DEFAULT_LEAF_SIZE,
};
use fluidcast_view::Camera;

/// How attributes colour the RBF field.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Classification {
    /// Blend the attribute, then colour map it (continuous attributes).
    Post,
    /// Colour map each particle, then blend the colours (categorical attributes: classes
    /// keep their colours, mixing only where particles of different classes overlap).
    Pre,
}

/// The jitter's noise.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseArg {
    Blue,
    White,
}

/// Options of `--field rbf`.
#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "RBF volumes and shadows")]
pub struct RbfArgs {
    /// --field rbf: the radius (world units) of every particle at radius-map factor 1, where
    /// its truncated Gaussian ends (3 standard deviations). Default: each particle's support
    /// radius (see --support-radius, --radius-array).
    #[arg(long, allow_hyphen_values = true, value_parser = crate::checked::real("--rbf-radius"))]
    pub rbf_radius: Option<f64>,
    /// --field rbf: the radius map, pairs of position on the colour map's range (0..1) and
    /// radius factor, e.g. 0,1,1,0.5; a factor of 0 hides particles. Default: 1 everywhere.
    #[arg(long)]
    pub radius_map: Option<String>,
    /// --field rbf: post (blend the attribute, then colour it) or pre-classification
    /// (colour each particle, then blend). The transfer function's opacity is the density map,
    /// each particle's weight.
    #[arg(long, value_enum, default_value = "post")]
    pub classification: Classification,
    /// --field rbf: jittered passes averaged per pixel (progressive accumulation; noise falls
    /// as 1/√N).
    #[arg(long, default_value_t = 1, value_parser = crate::checked::whole::<u32>("--spp"))]
    pub spp: u32,
    /// --field rbf: the jitter's noise: blue (a 64x64 blue-noise mask over the screen, a
    /// golden-ratio sequence over passes: finer grain, faster convergence) or white
    /// (independent offsets: error falls as 1/√--spp).
    #[arg(long, value_enum, default_value = "blue")]
    pub noise: NoiseArg,
    /// --field rbf: seed of the per-pixel jitter.
    #[arg(long, default_value_t = 0, value_parser = crate::checked::whole::<u32>("--seed"))]
    pub seed: u32,
    /// --field rbf: particles per BVH leaf (the paper's Hilbert clusters; 1..=64).
    #[arg(long, default_value_t = DEFAULT_LEAF_SIZE,
          value_parser = crate::checked::whole::<usize>("--leaf-size"))]
    pub leaf_size: usize,
    /// --field rbf: the step along each ray (world units). Default: half the median
    /// particle's standard deviation (radius/3), over --sampling-scale.
    #[arg(long, allow_hyphen_values = true, value_parser = crate::checked::real("--rbf-step"))]
    pub rbf_step: Option<f64>,
    /// --field rbf, or any SPH field (drawn then by the same stochastic ray marcher, on the
    /// CPU): single scattering with volumetric shadows toward a directional light
    /// (--light X,Y,Z, the world direction toward it; default: from above and behind the
    /// camera, view up plus half the way back to the eye and a quarter to the right). The
    /// transfer function's colours become albedos; each pass shades one point per pixel and
    /// casts --shadow-samples shadow rays from it, so use --spp to converge.
    #[arg(long)]
    pub shadows: bool,
    /// --shadows: shadow rays per pixel and pass.
    #[arg(long, default_value_t = 1, value_parser = crate::checked::whole::<u32>("--shadow-samples"))]
    pub shadow_samples: u32,
    /// --shadows: the light a fully shadowed point still receives, as a share of the full
    /// light (0..1).
    #[arg(long, default_value_t = 0.25, value_parser = crate::checked::real("--shadow-ambient"))]
    pub shadow_ambient: f64,
}

impl RbfArgs {
    /// The field options for particles with (`attribute`) or without an attribute array.
    pub fn options(&self, attribute: bool) -> Result<RbfOptions> {
        let radius_map = match &self.radius_map {
            Some(m) => AttributeMap::parse(m).context("--radius-map")?,
            None => AttributeMap::constant(1.0),
        };
        if !attribute && self.radius_map.is_some() {
            bail!("--radius-map needs an attribute (--array)");
        }
        let colouring = match (attribute, self.classification) {
            (false, _) => Colouring::Density,
            (true, Classification::Post) => Colouring::Post,
            (true, Classification::Pre) => Colouring::Pre,
        };
        Ok(RbfOptions {
            // 0, as the mapper's RBFRadius: the support radius.
            radius: self.rbf_radius.filter(|&r| r > 0.0),
            radius_map,
            colouring,
            leaf_size: self.leaf_size,
        })
    }

    /// The march's parameters; with --shadows the light is `light` (--light, X,Y,Z toward
    /// it) or comes from `camera`.
    pub fn render_params(&self, camera: &Camera, light: Option<&str>) -> Result<RbfRenderParams> {
        let shadows = if self.shadows {
            let light = match light {
                Some(l) => parse_vector(l).context("--light")?,
                None => RbfShadows::default_light(&camera.frame(2, 2)?),
            };
            let s = RbfShadows::new(light, self.shadow_ambient, self.shadow_samples)
                .context("--light/--shadow-ambient/--shadow-samples")?;
            Some(s)
        } else {
            None
        };
        Ok(RbfRenderParams {
            spp: self.spp,
            first_pass: 0,
            seed: self.seed,
            // 0, as the mapper's RBFStep: automatic.
            step: self.rbf_step.filter(|&s| s > 0.0),
            shadows,
            noise: match self.noise {
                NoiseArg::Blue => Noise::Blue,
                NoiseArg::White => Noise::White,
            },
        })
    }
}

/// `X,Y,Z`: three finite numbers.
fn parse_vector(s: &str) -> Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("'{s}': expected X,Y,Z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => bail!("'{s}': expected X,Y,Z, three finite numbers"),
    }
}
