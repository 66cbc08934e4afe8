//! Options shared by `render` and `bench`: camera, image size, transfer function, and the
//! renderer and its adaptive sampling.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use fluidcast_backend::{defaults, GridParams, PlanParams, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};

use crate::options::ParticleArgs;

#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "Camera, colour and opacity")]
pub struct ViewArgs {
    /// Camera JSON file (vtkCamera fields: position, focal_point, view_up, view_angle,
    /// parallel_projection, parallel_scale) or `auto` (vtkRenderer::ResetCamera on the data,
    /// looking down -z with y up).
    #[arg(long, default_value = "auto")]
    camera: String,
    /// Rotate the camera about view up (degrees, as vtkCamera::Azimuth), after --camera.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    azimuth: f64,
    /// Rotate the camera up/down about the focal point (degrees, as vtkCamera::Elevation).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    elevation: f64,
    /// Zoom factor (> 1 zooms in, as vtkCamera::Zoom).
    #[arg(long, default_value_t = 1.0)]
    zoom: f64,
    /// Use a parallel projection (for --camera auto).
    #[arg(long)]
    parallel: bool,
    /// Write the camera used (JSON) here.
    #[arg(long)]
    save_camera: Option<PathBuf>,
    /// Image size in pixels, WxH.
    #[arg(long, default_value = "800x600")]
    size: String,
    /// Transfer function (alias --cmap): a built-in preset, in any case (Viridis, Plasma,
    /// Inferno, Magma, Cividis, Turbo, Jet, Cool to Warm, Grayscale, X Ray), or a ParaView
    /// colour-map preset .json file.
    #[arg(long, alias = "cmap", default_value = "Viridis")]
    tf: String,
    /// Data range mapped onto the colour map (alias --clim): lo,hi; or, from the data, `all`
    /// (a series: every rendered frame's values, read before the first frame renders; the
    /// default), `first` (the first frame's, kept for the series) or `frame` (each frame its
    /// own). One file: its own values.
    #[arg(long, alias = "clim", allow_hyphen_values = true)]
    range: Option<String>,
    /// Distance (world units) over which the transfer function's opacity applies, as
    /// ParaView's Scalar Opacity Unit Distance. Default: bounds diagonal / cbrt(particles).
    #[arg(long, allow_hyphen_values = true,
          value_parser = crate::checked::real("--opacity-unit-distance"))]
    opacity_unit_distance: Option<f64>,
    /// Multiply the transfer function's opacities.
    #[arg(long, default_value_t = 1.0)]
    opacity_scale: f64,
    /// Depth samples per pixel footprint (1 = the depth step equals the pixel footprint).
    #[arg(help_heading = "Quality and backend", long, default_value_t = 1.0, value_parser = crate::checked::real("--sampling-scale"))]
    sampling_scale: f64,
}

/// Which renderer draws the image.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The adaptive grid renderer (Hochstetter et al. 2016).
    Adaptive,
    /// The reference renderer (every particle of a tile scattered into every ray).
    Reference,
    /// The perspective grid of Fraedrich et al. 2010: particles resampled into a
    /// view-aligned grid (one column per --grid-cell pixels, logarithmic depth slices), slab
    /// by slab, then ray marched with bilinear interpolation.
    PerspectiveGrid,
}

#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "Quality and backend")]
pub struct SamplingArgs {
    /// Renderer: adaptive (the default), reference (the default with --iso: surfaces exact
    /// along each ray, composited in depth order with the volume) or perspective-grid. With
    /// --mode adaptive, --iso draws the volume in front of the surfaces.
    #[arg(long, value_enum)]
    pub mode: Option<Mode>,
    /// Where the adaptive renderer runs: auto (a hardware GPU if there is one, else the CPU
    /// with a note), cpu, or gpu (every stage in wgpu compute, f32; a software Vulkan such as
    /// Mesa's lavapipe counts too).
    #[arg(long, default_value = "auto")]
    pub backend: fluidcast_backend::Backend,
    /// The GPU adapter to use, by a part of its name (e.g. nvidia, llvmpipe); also from the
    /// FLUIDCAST_ADAPTER environment variable. `fluidcast info --adapters` lists them.
    #[arg(long)]
    pub adapter: Option<String>,
    /// Screen-space error tolerance E_I: the largest change, per colour or alpha channel
    /// (0..1; 0.004 ≈ 1 level of 255), that adaptive sampling may make against full-rate
    /// sampling of the same grid, or `off` (or 0, as ParaView writes it) for full rate everywhere.
    #[arg(long, default_value = "0.004")]
    pub error_tolerance: String,
    /// Relaxation E_relax in [0, 1] (1: ignore the lateral variation inside cells when
    /// estimating errors; 0: strict bound).
    #[arg(long, default_value_t = 1.0, conflicts_with = "strict",
          value_parser = crate::checked::real("--relax"))]
    #[arg(help_heading = "Expert: the sampling plan")]
    pub relax: f64,
    /// Never render cells as super-pixels.
    #[arg(help_heading = "Expert: the sampling plan", long)]
    pub no_superpixels: bool,
    /// Cast every pixel: no image-space interpolation between every second pixel in the
    /// relaxed mode.
    #[arg(help_heading = "Expert: the sampling plan", long)]
    pub no_interpolation: bool,
    /// Analyse every bundle: no check that the plan can save more than its own work costs
    /// (else the view renders at full rate), and no probe of an eighth of the bundles first,
    /// which plans the rest at full rate where adapting would not pay.
    #[arg(help_heading = "Expert: the sampling plan", long)]
    pub no_probe: bool,
    /// Do not force cells with surface particles to full rate.
    #[arg(help_heading = "Expert: the sampling plan", long)]
    pub no_surface_cells: bool,
    /// Ray bundle size D_xy in pixels (1..=64).
    #[arg(help_heading = "Expert: the sampling plan", long, default_value_t = 8, value_parser = crate::checked::whole::<u32>("--bundle"))]
    pub bundle: u32,
    /// Depth samples per cell D_z (a power of two, 1..=64).
    #[arg(long, default_value_t = 16,
          value_parser = crate::checked::whole::<u32>("--depth-samples"))]
    #[arg(help_heading = "Expert: the sampling plan")]
    pub depth_samples: u32,
    /// Strict error bound: no relaxation and no super-pixels, so no pixel differs from the
    /// full-rate rendering by more than E_I.
    #[arg(long)]
    pub strict: bool,
    /// --mode perspective-grid: pixels per grid column along each side (1 = a column per
    /// pixel, the reference's samples; 2 casts a quarter of the columns and interpolates).
    #[arg(help_heading = "Expert: the sampling plan", long, default_value_t = 1, value_parser = crate::checked::whole::<u32>("--grid-cell"))]
    pub grid_cell: u32,
    /// --mode perspective-grid: resample every tile of columns in every slab, also behind
    /// pixels that have stopped (the same image, slower: for measuring occlusion culling).
    #[arg(help_heading = "Expert: the sampling plan", long)]
    pub no_occlusion_culling: bool,
}

/// Parses `off` or a tolerance in [0, 1].
pub fn parse_tolerance(s: &str) -> Result<Option<f64>> {
    if s.eq_ignore_ascii_case("off") || s.eq_ignore_ascii_case("none") {
        return Ok(None);
    }
    let e: f64 = s.trim().parse().with_context(|| {
        format!("--error-tolerance '{s}': expected a number in [0, 1] or 'off'")
    })?;
    fluidcast_backend::Setting::by_flag("--error-tolerance")
        .map(|setting| setting.check(e))
        .transpose()
        .map_err(|err| anyhow::anyhow!("--error-tolerance: {err} (or 'off')"))?;
    Ok(Some(e))
}

impl SamplingArgs {
    /// The mode --mode names (`None`: the library's choice).
    pub fn plan_mode(&self) -> Option<fluidcast_backend::Mode> {
        self.mode.map(|m| match m {
            Mode::Adaptive => fluidcast_backend::Mode::Adaptive,
            Mode::Reference => fluidcast_backend::Mode::Reference,
            Mode::PerspectiveGrid => fluidcast_backend::Mode::PerspectiveGrid {
                cell: self.grid_cell,
            },
        })
    }

    /// Render parameters for an image size and the particle options.
    pub fn params(&self, v: &ViewArgs, p: &ParticleArgs) -> Result<RenderParams> {
        let (width, height) = parse_size(&v.size)?;
        let grid = GridParams {
            bundle: self.bundle,
            depth_samples: self.depth_samples,
        };
        grid.validate().context("--bundle/--depth-samples")?;
        let mut adaptive = PlanParams {
            tolerance: parse_tolerance(&self.error_tolerance)?,
            relax: self.relax,
            superpixels: !self.no_superpixels,
            surface_cells: !self.no_surface_cells,
            interpolate: !self.no_interpolation,
            probe: !self.no_probe,
        };
        if self.strict {
            adaptive = adaptive.strict();
        }
        Ok(RenderParams {
            width,
            height,
            kernel: p.kernel()?,
            field: p.field()?,
            sampling_scale: v.sampling_scale,
            grid,
            adaptive,
            occlusion_culling: !self.no_occlusion_culling,
            ..Default::default()
        })
    }
}

/// How the colour map's range is chosen (`--range`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RangeChoice {
    /// Every rendered frame's values (a series' default).
    All,
    /// The first frame's, kept for the series.
    First,
    /// Each frame its own.
    Frame,
    /// lo, hi as given.
    Fixed(f64, f64),
}

impl ViewArgs {
    /// Whether --range sets the colour map's range as numbers (else the data do).
    pub fn has_range(&self) -> bool {
        matches!(self.range_choice(), Ok(RangeChoice::Fixed(..)))
    }

    /// What --range asks for.
    pub fn range_choice(&self) -> Result<RangeChoice> {
        Ok(match self.range.as_deref().map(str::trim) {
            None | Some("all") => RangeChoice::All,
            Some("first") => RangeChoice::First,
            Some("frame") => RangeChoice::Frame,
            Some(r) => {
                let (lo, hi) =
                    parse_pair(r, "--range").context("--range takes lo,hi, all, first or frame")?;
                RangeChoice::Fixed(lo, hi)
            }
        })
    }

    /// Sets the colour map's range to `range` (a series' range found before its first frame).
    pub fn fix_range(&mut self, (lo, hi): (f64, f64)) {
        self.range = Some(format!("{lo:?},{hi:?}"));
    }

    /// The transfer function as named, with --opacity-scale applied (range and unit distance
    /// come from the data in [`ViewArgs::setup`]).
    pub fn base_tf(&self) -> Result<TransferFunction> {
        let mut tf = load_tf(&self.tf)?;
        if !(self.opacity_scale.is_finite() && self.opacity_scale >= 0.0) {
            bail!(
                "--opacity-scale {}: must be finite and >= 0",
                self.opacity_scale
            );
        }
        tf.scale_opacity(self.opacity_scale);
        Ok(tf)
    }

    /// Camera and transfer function for the data: the camera from --camera (or reset on the
    /// data) with azimuth/elevation/zoom applied, the range from --range or the data, and the
    /// opacity unit distance. Prints a summary line when `verbose`.
    /// The camera: `--camera` (a file, or auto: the particles' supports in view), turned by
    /// `--azimuth`/`--elevation`, zoomed, and written to `--save-camera`.
    fn camera(&self, particles: &Particles) -> Result<Camera> {
        let a = self;
        let mut cam = if a.camera == "auto" {
            defaults::auto_camera(particles, a.parallel)
        } else {
            let text = fluidcast_mem::read_text(Path::new(&a.camera))
                .with_context(|| format!("reading camera file {}", a.camera))?;
            Camera::from_json(&text).with_context(|| a.camera.clone())?
        };
        cam.azimuth(a.azimuth);
        cam.elevation(a.elevation);
        cam.orthogonalize_view_up();
        if !(a.zoom.is_finite() && a.zoom > 0.0) {
            bail!(
                "--zoom {}: must be a finite number > 0 (> 1 zooms in)",
                a.zoom
            );
        }
        let angle = cam.view_angle;
        cam.zoom(a.zoom);
        if !cam.parallel_projection && (cam.view_angle.is_nan() || cam.view_angle >= 180.0) {
            bail!(
                "--zoom {:?}: the view angle would be {:.3e}°, which must stay below 180°; \
                 --zoom must be at least {:.4} here",
                a.zoom,
                cam.view_angle,
                angle / 179.0
            );
        }
        if !cam.parallel_scale.is_finite() {
            bail!("--zoom {}: the parallel scale would not be finite", a.zoom);
        }
        if let Some(p) = &a.save_camera {
            std::fs::write(p, serde_json::to_string_pretty(&cam)?)
                .with_context(|| format!("writing {}", p.display()))?;
        }
        Ok(cam)
    }

    pub fn setup(
        &self,
        particles: &Particles,
        params: &RenderParams,
        base: &TransferFunction,
        verbose: bool,
    ) -> Result<(Camera, TransferFunction)> {
        let a = self;
        let mut tf = base.clone();
        let cam = a.camera(particles)?;
        let (lo, hi) = match a.range_choice()? {
            RangeChoice::Fixed(lo, hi) => (lo, hi),
            _ => defaults::auto_range(particles, params.kernel, params.field),
        };
        tf = tf.with_range(lo, hi)?;
        tf.unit_distance = match a.opacity_unit_distance {
            // Checked while parsing (crate::checked).
            Some(u) => u,
            None => defaults::auto_unit_distance(particles),
        };
        if verbose {
            eprintln!(
                "rendering {} particles at {}x{}, {} kernel, field {:?}, range [{lo:.6}, {hi:.6}], opacity unit distance {:.6}",
                particles.len(),
                params.width,
                params.height,
                params.kernel,
                params.field,
                tf.unit_distance
            );
        }
        Ok((cam, tf))
    }
}

pub fn parse_pair(s: &str, what: &str) -> Result<(f64, f64)> {
    let v: Vec<&str> = s.split(',').collect();
    if v.len() != 2 {
        bail!("{what} '{s}': expected two numbers, lo,hi");
    }
    Ok((
        v[0].trim()
            .parse()
            .with_context(|| format!("{what} '{s}'"))?,
        v[1].trim()
            .parse()
            .with_context(|| format!("{what} '{s}'"))?,
    ))
}

pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let expected =
        || format!("--size '{s}': expected WxH, two whole numbers of pixels, e.g. 800x600");
    let (w, h) = s.split_once(['x', 'X']).with_context(expected)?;
    let side = |t: &str| t.trim().parse::<u64>().ok().with_context(expected);
    let (w, h) = (side(w)?, side(h)?);
    if w == 0
        || h == 0
        || w > fluidcast_backend::MAX_SIDE as u64
        || h > fluidcast_backend::MAX_SIDE as u64
    {
        bail!(
            "--size {w}x{h}: each side must be 1..={} pixels",
            fluidcast_backend::MAX_SIDE
        );
    }
    Ok((w as u32, h as u32))
}

pub fn load_tf(spec: &str) -> Result<TransferFunction> {
    let p = Path::new(spec);
    if p.extension().map(|e| e.eq_ignore_ascii_case("json")) == Some(true) || p.exists() {
        let text = fluidcast_mem::read_text(p)
            .with_context(|| format!("reading transfer function {spec}"))?;
        Ok(TransferFunction::from_paraview_json(&text, spec)?)
    } else {
        Ok(TransferFunction::preset(spec)?)
    }
}
