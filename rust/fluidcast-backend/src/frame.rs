//! [`Renderer::render`]: one frame of a [`Scene`] as a [`RenderPlan`] asks, whatever the mode,
//! field, tiles, level of detail or device.

use fluidcast_image::Image;
use fluidcast_render::{
    render_adaptive, render_in_tiles, render_object_space, render_over_surfaces,
    render_perspective_grid, render_reference, tile_margin, tile_particles_within, RenderParams,
    RenderStats,
};
use fluidcast_sph::Particles;

use crate::plan::{Mode, RenderPlan, Tiles};
use crate::scene::LodReport;
use crate::{march, BackendError, Renderer, Scene};

/// One rendered frame and what a front-end tells its user about it.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// Premultiplied linear RGBA and depth per pixel.
    pub image: Image,
    /// Timings (milliseconds per stage) and counts.
    pub stats: RenderStats,
    /// Where it rendered: "CPU (N threads)" or "GPU: adapter".
    pub device: String,
    /// The mode the volume was sampled in (`None`: the stochastic march drew it).
    pub mode: Option<Mode>,
    /// What the library chose or fell back to, for the user ("rendering with the reference
    /// ray caster …", `auto`'s fallback to the CPU, the level of detail's line).
    pub notes: Vec<String>,
    /// What level of detail did, when asked for.
    pub lod: Option<LodReport>,
    /// Bytes of the marched field (weights, attributes and BVH), when marched.
    pub march_bytes: Option<usize>,
    /// Bytes of the marched field's BVH alone, when marched.
    pub march_bvh_bytes: Option<usize>,
}

/// Times [`Renderer::render`] halves the particles of its screen tiles for a view that does
/// not fit the GPU's buffers before it gives up.
const GPU_TILE_TRIES: usize = 6;

/// The most particles a screen tile of `n` particles at `width × height` may hold under
/// `tiles`; `None`: one render. With a budget only, `None` also when one render fits it.
pub fn tile_particles(
    n: usize,
    (width, height): (u32, u32),
    tiles: &Tiles,
) -> Result<Option<usize>, BackendError> {
    let n = n.max(1);
    let by_count = tiles.count.map(|t| n.div_ceil(t.max(1) as usize));
    let Some(budget) = tiles.budget_bytes else {
        return Ok(by_count);
    };
    let by_memory = tile_particles_within(n, width, height, budget)?.unwrap_or(n);
    Ok(Some(by_count.map_or(by_memory, |c| c.min(by_memory))).filter(|&m| m < n))
}

impl Renderer {
    /// Renders one frame of `scene` as `plan` asks: the stochastic march when `plan.march`
    /// is set, else the volume in the plan's mode ([`RenderPlan::mode_for`]), on this
    /// renderer's device for the adaptive mode and the RBF field, through the level-of-detail
    /// cut and in screen tiles when asked. What the scene keeps (surface flags, hierarchy and
    /// cut, the marched field, accumulated passes) is reused by later frames.
    pub fn render(&self, scene: &mut Scene, plan: &RenderPlan) -> Result<Rendered, BackendError> {
        plan.check()?;
        let mut notes: Vec<String> = self.note().map(str::to_string).into_iter().collect();
        if let Some(m) = &plan.march {
            let f = march::render(scene, &plan.params, m, self.gpu())?;
            let device = if f.on_gpu {
                self.device()
            } else {
                Renderer::cpu().device()
            };
            return Ok(Rendered {
                image: f.image,
                stats: f.stats,
                device,
                mode: None,
                notes,
                lod: None,
                march_bytes: Some(f.field_bytes),
                march_bvh_bytes: Some(f.bvh_bytes),
            });
        }
        let (mode, note) = plan.mode_for(self.requested);
        notes.extend(crate::device_note(note, self.gpu().is_some()).map(str::to_string));
        let full_rate;
        let (skip, known_work) = skip_adaptivity(scene, plan, mode)?;
        let plan = match skip {
            Some(why) => {
                notes.push(why);
                full_rate = {
                    let mut p = plan.clone();
                    p.params.adaptive.tolerance = None;
                    p
                };
                &full_rate
            }
            None => plan,
        };
        let flags = mode == Mode::Adaptive && plan.params.adaptive.uses_surface_cells();
        let t_prep = std::time::Instant::now();
        let lod = prepare(scene, plan, flags, &mut notes)?;
        // What this render made of the scene first (level-of-detail hierarchy and cut, surface
        // flags; about 0 when the scene held them), in milliseconds: stage `scene`.
        let prep_ms = t_prep.elapsed().as_secs_f64() * 1e3;
        let scene = &*scene;
        let cut = scene.cut.as_ref().filter(|_| lod.is_some());
        let (particles, surface) = match cut.and_then(|c| c.particles.as_ref().map(|p| (p, c))) {
            Some((p, c)) => (p, c.surface_flags()),
            None => (scene.particles(), scene.surface_flags()),
        };
        let limit = plan.work_limit.unwrap_or(crate::work::DEFAULT_WORK_LIMIT);
        // skip_adaptivity estimated the work of these particles (no level of detail) already.
        let work = match known_work {
            Some(w) => w,
            None => crate::work::estimate(particles, &scene.camera, &plan.params)?,
        };
        crate::work::refuse_above(work, particles, limit)?;
        let tiles = tile_particles(particles.len(), plan.size(), &plan.tiles)?;
        let surface = surface.filter(|_| flags);
        let (image, mut stats) =
            self.render_mode(scene, particles, surface, plan, (mode, tiles))?;
        stats.stages.insert(0, ("scene", prep_ms));
        let device = match mode {
            Mode::Adaptive => self.device(),
            _ => Renderer::cpu().device(),
        };
        Ok(Rendered {
            image,
            stats,
            device,
            mode: Some(mode),
            notes,
            lod,
            march_bytes: None,
            march_bvh_bytes: None,
        })
    }

    /// The volume of `particles` in `mode`, in screen tiles of at most `tiles` particles.
    fn render_mode(
        &self,
        scene: &Scene,
        particles: &Particles,
        surface: Option<&[bool]>,
        plan: &RenderPlan,
        (mode, tiles): (Mode, Option<usize>),
    ) -> Result<(Image, RenderStats), BackendError> {
        let draw = |p: &Particles, s: Option<&[bool]>, prm: &RenderParams| {
            self.render_untiled(scene, p, s, prm, mode)
        };
        match tiles {
            // The perspective grid's pixels read neighbouring columns: a tile also needs
            // the particles around it.
            Some(max) => {
                let margin = match mode {
                    Mode::PerspectiveGrid { cell } => tile_margin(cell),
                    _ => 0,
                };
                let (camera, params) = (&scene.camera, &plan.params);
                render_in_tiles(particles, surface, camera, params, (max, margin), draw)
            }
            None => match draw(particles, surface, &plan.params) {
                Err(BackendError::Gpu(e)) if plan.params.surfaces.is_none() => {
                    let Some(over) = e.buffer_overflow() else {
                        return Err(e.into());
                    };
                    self.gpu_tiles(scene, particles, surface, &plan.params, over)
                }
                r => r,
            },
        }
    }

    /// A view whose pairs or cells (`over`: needed, limit) do not fit the GPU's buffers,
    /// rendered in screen tiles with proportionally fewer particles each (half as many
    /// again while a tile still does not fit, at most [`GPU_TILE_TRIES`] times).
    fn gpu_tiles(
        &self,
        scene: &Scene,
        particles: &Particles,
        surface: Option<&[bool]>,
        params: &RenderParams,
        (needed, limit): (u64, u64),
    ) -> Result<(Image, RenderStats), BackendError> {
        let draw = |p: &Particles, s: Option<&[bool]>, prm: &RenderParams| {
            self.render_untiled(scene, p, s, prm, Mode::Adaptive)
        };
        let n = particles.len() as u64;
        let mut max = (n * limit / needed.max(1) / 2).max(1) as usize;
        let mut tries = 1;
        loop {
            match render_in_tiles(particles, surface, &scene.camera, params, (max, 0), draw) {
                Err(BackendError::Gpu(e))
                    if e.buffer_overflow().is_some() && max > 1 && tries < GPU_TILE_TRIES =>
                {
                    (max, tries) = (max.div_ceil(2), tries + 1);
                }
                r => return r,
            }
        }
    }

    /// One render of `particles` (the scene's, a cut's or a tile's) in `mode`.
    fn render_untiled(
        &self,
        scene: &Scene,
        particles: &Particles,
        surface: Option<&[bool]>,
        params: &RenderParams,
        mode: Mode,
    ) -> Result<(Image, RenderStats), BackendError> {
        let (camera, tf) = (&scene.camera, &scene.tf);
        Ok(match mode {
            Mode::Reference => render_reference(particles, camera, tf, params)?,
            Mode::ObjectSpace => render_object_space(particles, camera, tf, params)?,
            Mode::PerspectiveGrid { cell } => {
                render_perspective_grid(particles, camera, tf, params, cell)?
            }
            Mode::Adaptive if params.surfaces.is_some() => {
                let what = match self.gpu() {
                    Some(_) => "the GPU backend",
                    None => "the adaptive grid renderer",
                };
                let surfaces = |p: &RenderParams| match self.gpu() {
                    Some(g) => Ok(g.render_surfaces(particles, camera, tf, p)?),
                    None => Ok(render_reference(particles, camera, tf, p)?),
                };
                let volume = |p: &RenderParams| self.render_volume(particles, surface, scene, p);
                render_over_surfaces::<BackendError>(params, what, surfaces, volume)?
            }
            Mode::Adaptive => self.render_volume(particles, surface, scene, params)?,
        })
    }

    /// The adaptive volume alone, on this renderer's device.
    fn render_volume(
        &self,
        particles: &Particles,
        surface: Option<&[bool]>,
        scene: &Scene,
        params: &RenderParams,
    ) -> Result<(Image, RenderStats), BackendError> {
        let (camera, tf) = (&scene.camera, &scene.tf);
        match self.gpu() {
            Some(g) => {
                let r = g.render_adaptive(particles, surface, camera, tf, params)?;
                Ok((r.image, r.stats))
            }
            None => {
                let r = render_adaptive(particles, surface, camera, tf, params)?;
                Ok((r.image, r.stats))
            }
        }
    }

    /// The colour-map range a density RBF field (`plan.march`) of `scene` takes when none
    /// is given: 0 up to the largest field value at a sample of particle centres. The field
    /// it builds is the one the next render of `plan` marches.
    pub fn rbf_density_range(
        &self,
        scene: &mut Scene,
        plan: &RenderPlan,
    ) -> Result<(f64, f64), BackendError> {
        let m = plan
            .march
            .as_ref()
            .ok_or_else(|| BackendError::Plan("the density range is the RBF field's".into()))?;
        march::density_range(scene, &plan.params, m)
    }
}

/// Why the adaptive plan of `plan` is skipped for full rate on this view, if it is: its own
/// work would cost more than it can be counted on saving ([`crate::work::adaptivity_can_pay`]);
/// and that cast's [`crate::work::estimate`] when it was made. Not with level of detail (its
/// particles are known only after the cut), nor without the probe (`--no-probe`: analyse
/// every bundle, whatever it costs).
fn skip_adaptivity(
    scene: &Scene,
    plan: &RenderPlan,
    mode: Mode,
) -> Result<(Option<String>, Option<f64>), BackendError> {
    let a = &plan.params.adaptive;
    if mode != Mode::Adaptive || a.tolerance.is_none() || !a.probe || plan.lod.is_some() {
        return Ok((None, None));
    }
    let particles = scene.particles();
    let work = crate::work::estimate(particles, &scene.camera, &plan.params)?;
    if crate::work::adaptivity_can_pay(work, particles.len()) {
        return Ok((None, Some(work)));
    }
    let why = format!(
        "adaptive sampling skipped for this view: its full-rate cast is about {:.0} kernel \
         evaluations a particle, too few for the plan to save more than its own work costs \
         (supports a few pixels wide); rendered at full rate",
        work / particles.len().max(1) as f64
    );
    Ok((Some(why), Some(work)))
}

/// Makes what the render of `plan` needs of `scene`: the level-of-detail cut (with a note
/// when it merged particles) and, with `flags`, the surface flags of what is drawn.
fn prepare(
    scene: &mut Scene,
    plan: &RenderPlan,
    flags: bool,
    notes: &mut Vec<String>,
) -> Result<Option<LodReport>, BackendError> {
    let Some(t) = plan.lod else {
        if flags {
            scene.with_surface();
        }
        return Ok(None);
    };
    let cut = scene.cut_for(plan.size(), t)?;
    let merged = cut.particles.is_some();
    if flags {
        cut.surface();
    }
    let report = cut.report.clone();
    if flags && !merged {
        scene.with_surface();
    }
    if merged {
        notes.push(report.line());
    }
    Ok(Some(report))
}
