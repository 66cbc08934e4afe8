//! Opaque iso-surfaces over a volume rendered by another renderer (the adaptive one, on the
//! CPU or the GPU): the surfaces are found exactly per ray (by the reference caster on the
//! CPU, by the GPU's surface walk on the GPU), and the
//! volume renderer sees the first surface as opaque geometry (its per-pixel depth limit),
//! which its sampling plan already honours — no cell behind a surface is sampled and the
//! error bound covers only what is composited in front of it. The front volume is then
//! composited over the surface. For opaque surfaces this equals the reference's mixed
//! rendering; translucent surfaces over a volume need the volume behind them too, which only
//! [`crate::render_reference`] composites.

use std::sync::Arc;
use std::time::Instant;

use fluidcast_image::Image;

use crate::surface::{SurfaceError, Surfaces};
use crate::{ms, RenderError, RenderParams, RenderStats};

/// Renders `params.surfaces` with `surfaces` (given `params` with surfaces only: the
/// reference caster on the CPU, or the GPU's) and, when they ask for the volume, the volume
/// with `volume` (given `params` without surfaces and with the surfaces' depths as its depth
/// limit), composited in front of them. `what` names the volume renderer in errors.
pub fn render_over_surfaces<E: From<RenderError>>(
    params: &RenderParams,
    what: &'static str,
    surfaces: impl FnOnce(&RenderParams) -> Result<(Image, RenderStats), E>,
    volume: impl FnOnce(&RenderParams) -> Result<(Image, RenderStats), E>,
) -> Result<(Image, RenderStats), E> {
    let t0 = Instant::now();
    let Some(asked) = params.surfaces.as_deref() else {
        return volume(params);
    };
    if params.volume_lighting.is_some() {
        return Err(RenderError::VolumeLighting(what).into());
    }
    if asked.volume && asked.opacity < 1.0 {
        return Err(RenderError::from(SurfaceError::Translucent(what)).into());
    }
    let only = RenderParams {
        surfaces: Some(Arc::new(Surfaces {
            volume: false,
            ..asked.clone()
        })),
        ..params.clone()
    };
    let (mut image, surface_stats) = surfaces(&only)?;
    let surfaces_ms = ms(t0);
    if !asked.volume {
        return Ok((image, surface_stats));
    }
    let limit: Arc<[f32]> = match &params.depth_limit {
        Some(d) => d.iter().zip(&image.depth).map(|(a, b)| a.min(*b)).collect(),
        None => image.depth.clone().into(),
    };
    let front_params = RenderParams {
        surfaces: None,
        depth_limit: Some(limit),
        ..params.clone()
    };
    let (front, mut stats) = volume(&front_params)?;
    for (s, f) in image.rgba.iter_mut().zip(&front.rgba) {
        *s = [0, 1, 2, 3].map(|c| f[c] + (1.0 - f[3]) * s[c]);
    }
    image.aovs.extend(front.aovs);
    // The front volume's counts and stages, the surfaces' time (and GPU stage) first.
    stats.stages.insert(0, ("surfaces", surfaces_ms));
    if let Some(g) = surface_stats.stages.iter().find(|s| s.0 == "gpu_surfaces") {
        stats.stages.insert(1, *g);
    }
    stats.dispatches += surface_stats.dispatches;
    stats.transfers += surface_stats.transfers;
    if let Some(t) = stats.stages.iter_mut().find(|s| s.0 == "total") {
        t.1 = ms(t0);
    }
    Ok((image, stats))
}
