//! `render`'s iso-surface options: which field, which levels, how they are lit.

use std::sync::Arc;

use anyhow::{bail, Context, Result};
use fluidcast_backend::{IsoField, Surfaces};
use fluidcast_sph::{ParticleSource, Particles, Quantity};
use fluidcast_view::{Light, Lighting};

#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "Surfaces")]
pub struct SurfaceArgs {
    /// Draw iso-surfaces at these values of --iso-field (comma-separated), e.g. `--iso 0.5`
    /// for the free surface. Found exactly along each ray on the CPU by the reference ray
    /// caster (the default --mode with --iso) or between slices by --mode perspective-grid;
    /// with --mode adaptive or --backend gpu the adaptive renderer draws the volume in front
    /// of them (a note says so).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          value_parser = crate::checked::real("--iso"))]
    pub iso: Vec<f64>,
    /// The field whose levels --iso draws: `colour` (Σ V W with V = m/ρ: about 1 inside the
    /// fluid and 0 outside, so 0.5 is the free surface), `density` (Σ m W), or a point array
    /// (NAME, NAME:mag, NAME:K; its CSPH reconstruction).
    #[arg(long, default_value = "colour")]
    pub iso_field: String,
    /// Opacity of the surfaces, in (0, 1] (1 hides everything behind the first one).
    #[arg(long, default_value_t = 1.0, value_parser = crate::checked::real("--iso-opacity"))]
    pub iso_opacity: f64,
    /// A solid surface colour r,g,b (0..1). Default: the colour map's colour of the rendered
    /// array (--array, else the density) at each surface point.
    #[arg(long)]
    pub iso_color: Option<String>,
    /// Also render the volume (emission–absorption of --array through --tf) with the
    /// surfaces, composited in depth order: what lies in front shows over a surface, and
    /// behind a translucent one.
    #[arg(long)]
    pub volume: bool,
    /// Shaded volume rendering: light every volume sample (--ambient, --diffuse, --specular,
    /// --specular-power, --light) with the rendered field's analytic gradient as its normal,
    /// two-sided as VTK's volume shading. Rendered by the reference ray caster (the default
    /// --mode with it); slower than the plain volume (a gradient per visible sample).
    #[arg(long)]
    pub shade_volume: bool,
    /// Light the surfaces (Blinn–Phong with --ambient/--diffuse/--specular); `off`: flat
    /// colour.
    #[arg(long, default_value = "on")]
    pub shading: String,
    /// A directional light from world direction X,Y,Z (toward the light, like a vtkLight's
    /// position minus its focal point). Default: a headlight at the camera.
    #[arg(long, allow_hyphen_values = true)]
    pub light: Option<String>,
    /// Ambient coefficient (vtkVolumeProperty's default).
    #[arg(long, default_value_t = 0.1, allow_hyphen_values = true)]
    pub ambient: f64,
    /// Diffuse coefficient.
    #[arg(long, default_value_t = 0.7, allow_hyphen_values = true)]
    pub diffuse: f64,
    /// Specular coefficient.
    #[arg(long, default_value_t = 0.2, allow_hyphen_values = true)]
    pub specular: f64,
    /// Specular power (shininess).
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    pub specular_power: f64,
}

/// What --iso-field names.
#[derive(Debug, Clone, PartialEq)]
pub enum IsoSource {
    Colour,
    Density,
    /// The rendered array itself.
    Rendered,
    /// Another point array, read per frame.
    Other(Quantity),
}

fn triple(s: &str, what: &str) -> Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{what} '{s}': expected three numbers x,y,z"))?;
    match v[..] {
        [a, b, c] => Ok([a, b, c]),
        _ => bail!("{what} '{s}': expected three numbers x,y,z"),
    }
}

impl SurfaceArgs {
    /// The lighting the options describe (for surfaces with --shading on, and the volume
    /// with --shade-volume).
    fn lighting(&self) -> Result<Lighting> {
        let lighting = Lighting {
            ambient: self.ambient,
            diffuse: self.diffuse,
            specular: self.specular,
            specular_power: self.specular_power,
            light: match &self.light {
                Some(l) => Light::Directional(triple(l, "--light")?),
                None => Light::Headlight,
            },
        };
        lighting
            .validate()
            .context("--ambient/--diffuse/--specular/--light")?;
        Ok(lighting)
    }

    /// The volume's lighting with --shade-volume.
    pub fn volume_lighting(&self) -> Result<Option<Lighting>> {
        self.shade_volume.then(|| self.lighting()).transpose()
    }

    /// Whether surfaces were asked for.
    pub fn on(&self) -> bool {
        !self.iso.is_empty()
    }

    /// The field --iso-field names, given the rendered `--array`.
    pub fn source(&self, array: Option<&str>) -> Result<IsoSource> {
        Ok(match self.iso_field.to_ascii_lowercase().as_str() {
            "colour" | "color" => IsoSource::Colour,
            "density" => IsoSource::Density,
            _ if Some(self.iso_field.as_str()) == array => IsoSource::Rendered,
            _ => IsoSource::Other(self.iso_field.parse().map_err(anyhow::Error::msg)?),
        })
    }

    /// The values of the iso field's array in `ds` when it is another array than the
    /// rendered one (`array`), per kept particle.
    pub fn other_values(
        &self,
        array: Option<&str>,
        ds: &impl ParticleSource,
    ) -> Result<Option<Arc<[f32]>>> {
        match self.source(array)? {
            IsoSource::Other(q) if self.on() => Ok(Some(Particles::values_of(ds, &q)?.into())),
            _ => Ok(None),
        }
    }

    /// The surfaces to draw (`None` without --iso), with `other` the values of the iso
    /// field's array when it is another than the rendered one ([`SurfaceArgs::other_values`]);
    /// every option checked.
    pub fn surfaces(
        &self,
        array: Option<&str>,
        other: Option<Arc<[f32]>>,
    ) -> Result<Option<Arc<Surfaces>>> {
        if !self.on() {
            return Ok(None);
        }
        let field = match self.source(array)? {
            IsoSource::Colour => IsoField::Colour,
            IsoSource::Density => IsoField::Density,
            IsoSource::Rendered => IsoField::Attribute(None),
            IsoSource::Other(_) => IsoField::Attribute(other),
        };
        let lighting = match self.shading.to_ascii_lowercase().as_str() {
            "on" => self.lighting()?,
            "off" => Lighting {
                ambient: 1.0,
                diffuse: 0.0,
                specular: 0.0,
                ..Default::default()
            },
            s => bail!("--shading '{s}': expected on or off"),
        };
        let surfaces = Surfaces {
            field,
            values: self.iso.clone(),
            opacity: self.iso_opacity,
            colour: self
                .iso_color
                .as_deref()
                .map(|c| triple(c, "--iso-color"))
                .transpose()?,
            lighting,
            volume: self.volume,
        };
        // Checked here, before any file is read, for the options' own errors.
        let n = match &surfaces.field {
            IsoField::Attribute(Some(v)) => v.len(),
            _ => 0,
        };
        surfaces.validate(n).context("--iso options")?;
        Ok(Some(Arc::new(surfaces)))
    }
}
