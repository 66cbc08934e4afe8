//! The stochastic ray march ([`crate::March`]): the field built once per scene and transfer
//! function, refit when only its radius map changes, and passes accumulated over renders of
//! one view.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::time::Instant;

use fluidcast_image::Image;
use fluidcast_rbf::{AttributeMap, Colouring, RbfField, RbfOptions, DEFAULT_LEAF_SIZE};
use fluidcast_render::{render_rbf, RenderParams, RenderStats};
use fluidcast_sph::Particles;
use fluidcast_view::TransferFunction;

use crate::plan::{March, Marched};
use crate::{BackendError, Scene};

/// The marched field, a fingerprint of what it was built with (the transfer function, for
/// attribute colourings, and the options but the radius map) and the radius map it holds.
struct Built {
    key: u64,
    radius_map: AttributeMap,
    field: RbfField,
    /// Milliseconds the build took, until a render reports them (stage `bvh`).
    unreported_build_ms: Option<f64>,
}

/// Passes accumulated over renders of one view: a fingerprint of everything the image
/// depends on, the passes so far and their mean.
struct Accumulation {
    key: u64,
    passes: u32,
    image: Image,
}

/// What a scene keeps for the march between renders.
#[derive(Default)]
pub(crate) struct MarchState {
    built: Option<Built>,
    accumulated: Option<Accumulation>,
}

/// A fingerprint of values' Debug text and of depth limits' bits.
fn fingerprint(text: &str, depths: &[&[f32]]) -> u64 {
    let mut h = DefaultHasher::new();
    text.hash(&mut h);
    for d in depths {
        d.len().hash(&mut h);
        for v in d.iter() {
            v.to_bits().hash(&mut h);
        }
    }
    h.finish()
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl MarchState {
    /// The field `march` asks for over `particles`, built unless the one held matches; a
    /// changed radius map alone refits the tree (Morrical et al., Sec. 3.2.2).
    fn field(
        &mut self,
        particles: &Particles,
        tf: &TransferFunction,
        params: &RenderParams,
        march: &March,
    ) -> Result<&mut Built, BackendError> {
        let (key, opts) = match &march.field {
            Marched::Sph => {
                let text = format!("sph {:?} {:?}", params.kernel, params.field);
                (fingerprint(&text, &[]), None)
            }
            Marched::Rbf(opts) => {
                let built = RbfOptions {
                    radius_map: AttributeMap::constant(1.0),
                    ..opts.clone()
                };
                // A density field weighs every particle alike: the transfer function only
                // colours it.
                let text = match opts.colouring {
                    Colouring::Density => format!("{built:?}"),
                    _ => format!("{tf:?}{built:?}"),
                };
                (fingerprint(&text, &[]), Some(opts))
            }
        };
        if self.built.as_ref().is_some_and(|b| b.key == key) {
            self.refit(opts)?;
        } else {
            self.accumulated = None;
            self.built = None;
            let t = Instant::now();
            let field = match opts {
                None => {
                    RbfField::from_sph(particles, params.kernel, params.field, DEFAULT_LEAF_SIZE)?
                }
                Some(o) => RbfField::build(particles, tf, o)?,
            };
            self.built = Some(Built {
                key,
                radius_map: opts
                    .map_or_else(|| AttributeMap::constant(1.0), |o| o.radius_map.clone()),
                field,
                unreported_build_ms: Some(ms(t)),
            });
        }
        self.built
            .as_mut()
            .ok_or_else(|| BackendError::Plan("RBF field missing".into()))
    }

    /// Refits the held field to `opts`' radius map if it holds another.
    fn refit(&mut self, opts: Option<&RbfOptions>) -> Result<(), BackendError> {
        let (Some(b), Some(o)) = (&mut self.built, opts) else {
            return Ok(());
        };
        if b.radius_map != o.radius_map {
            self.accumulated = None;
            b.field.set_radius_map(&o.radius_map)?;
            b.radius_map = o.radius_map.clone();
        }
        Ok(())
    }
}

/// The colour-map range a density RBF field of `scene` takes without one given: 0 up to the
/// largest Φ at a sample of particle centres (1 where there is none). Builds the field the
/// render then reuses.
pub(crate) fn density_range(
    scene: &mut Scene,
    params: &RenderParams,
    march: &March,
) -> Result<(f64, f64), BackendError> {
    let (particles, tf, _, state) = scene.parts();
    let built = state.field(particles, tf, params, march)?;
    let step = (particles.len() / 2000).max(1);
    let top = particles
        .positions
        .iter()
        .step_by(step)
        .map(|p| built.field.sample(p.map(f64::from)).density)
        .fold(0.0, f64::max);
    Ok((0.0, if top > 0.0 { top } else { 1.0 }))
}

/// One marched frame: its image, statistics (stages `bvh` when the field was built for it,
/// `refit` when timed) and the field's bytes.
pub(crate) struct MarchedFrame {
    pub image: Image,
    pub stats: RenderStats,
    pub field_bytes: usize,
    pub bvh_bytes: usize,
    /// Whether the passes ran on the GPU.
    pub on_gpu: bool,
}

/// Marches `scene` as `march` says: new passes averaged with those accumulated for the same
/// view, up to `march.progressive_passes` (once there, the accumulated image again). The RBF
/// field marches on `gpu` when there is one; an SPH field on the CPU.
pub(crate) fn render(
    scene: &mut Scene,
    params: &RenderParams,
    march: &March,
    gpu: Option<&fluidcast_gpu::Gpu>,
) -> Result<MarchedFrame, BackendError> {
    let (particles, tf, camera, state) = scene.parts();
    let built = state.field(particles, tf, params, march)?;
    let mut stages = Vec::new();
    if let Some(b) = built.unreported_build_ms.take() {
        stages.push(("bvh", b));
    }
    if let (true, Marched::Rbf(o)) = (march.time_refit, &march.field) {
        let t = Instant::now();
        built.field.set_radius_map(&o.radius_map)?;
        stages.push(("refit", ms(t)));
    }
    let depths = [&params.depth_limit, &params.depth_near].map(|d| d.as_deref().unwrap_or(&[]));
    let gpu = gpu.filter(|_| matches!(march.field, Marched::Rbf(_)));
    // The device is part of the view: passes marched on the GPU are not averaged with the
    // CPU's (nor served as the CPU's image once complete) when the backend changes.
    let view = format!(
        "{camera:?}{tf:?}{march:?}{}x{}{:?}{} on {}",
        params.width,
        params.height,
        params.support_depths,
        built.key,
        if gpu.is_some() { "gpu" } else { "cpu" }
    );
    let key = fingerprint(&view, &depths);
    let (field_bytes, bvh_bytes) = (built.field.memory_bytes(), built.field.bvh().memory_bytes());
    let spp = march.params.spp.max(1);
    let most = march.progressive_passes.max(spp);
    let acc = state.accumulated.take().filter(|a| a.key == key);
    let done = acc.as_ref().map_or(0, |a| a.passes);
    if let Some(a) = acc.as_ref().filter(|a| a.passes >= most) {
        let image = a.image.clone();
        state.accumulated = acc;
        let stats = RenderStats::default();
        let on_gpu = gpu.is_some();
        return Ok(MarchedFrame {
            image,
            stats,
            field_bytes,
            bvh_bytes,
            on_gpu,
        });
    }
    let new = spp.min(most - done);
    let mut rp = march.params.clone();
    rp.first_pass = done;
    rp.spp = new;
    let field = &state
        .built
        .as_ref()
        .ok_or_else(|| BackendError::Plan("RBF field missing".into()))?
        .field;
    let (mut image, mut stats) = match gpu {
        Some(g) => g.render_rbf(field, camera, tf, params, &rp)?,
        None => render_rbf(field, camera, tf, params, &rp)?,
    };
    stats.stages.splice(0..0, stages);
    if let Some(a) = acc {
        average(&mut image, &a.image, done, new);
    }
    if march.progressive_passes > spp {
        state.accumulated = Some(Accumulation {
            key,
            passes: done + new,
            image: image.clone(),
        });
    }
    Ok(MarchedFrame {
        image,
        stats,
        field_bytes,
        bvh_bytes,
        on_gpu: gpu.is_some(),
    })
}

/// `image` (of `new` passes) becomes the mean of `earlier`'s `done` passes and its own; the
/// depth is the earlier one's.
fn average(image: &mut Image, earlier: &Image, done: u32, new: u32) {
    let (wa, wb) = (done as f32, new as f32);
    for (p, q) in image.rgba.iter_mut().zip(&earlier.rgba) {
        for c in 0..4 {
            p[c] = (q[c] * wa + p[c] * wb) / (wa + wb);
        }
    }
    image.depth.clone_from(&earlier.depth);
}
