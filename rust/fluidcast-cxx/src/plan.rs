//! The mapper's settings as the library's [`RenderPlan`]: what VTK and ParaView set becomes
//! the plan the CLI's options become, and [`fluidcast_backend::Renderer::render`] draws it.

use std::sync::Arc;

use fluidcast_backend::{
    AttributeMap, BackendError, Colouring, March, Marched, PlanItem, PlanParams, RbfOptions,
    RbfRenderParams, RbfShadows, RenderParams, RenderPlan, Tiles,
};
use fluidcast_sph::FieldKind;
use fluidcast_view::Camera;

use crate::ffi;

/// Whether `Settings::field` names the RBF field.
pub(crate) fn is_rbf(field: &str) -> bool {
    field.eq_ignore_ascii_case("rbf")
}

/// Refuses a field name no renderer has.
pub(crate) fn check_field(s: &str) -> Result<(), String> {
    if !is_rbf(s) {
        parse_field(s)?;
    }
    Ok(())
}

fn parse_field(s: &str) -> Result<FieldKind, String> {
    match s.to_ascii_lowercase().as_str() {
        "" | "csph" => Ok(FieldKind::Csph),
        "sph" => Ok(FieldKind::Sph),
        "density" => Ok(FieldKind::Density),
        other => Err(format!("unknown field '{other}' (csph, sph, density, rbf)")),
    }
}

/// The plan for settings `s` at `width × height` seen by `camera` (the shadows' default
/// light comes from it), with the caller's depth limit per pixel (empty: none).
pub(crate) fn plan_of(
    s: &ffi::Settings,
    (width, height): (u32, u32),
    depth_limit: &[f32],
    camera: &Camera,
) -> Result<RenderPlan, String> {
    let params = RenderParams {
        width,
        height,
        kernel: s.kernel.parse().map_err(|e: String| e)?,
        field: if is_rbf(&s.field) {
            FieldKind::Csph
        } else {
            parse_field(&s.field)?
        },
        adaptive: PlanParams {
            tolerance: (s.error_tolerance > 0.0).then_some(s.error_tolerance),
            ..Default::default()
        },
        depth_limit: (!depth_limit.is_empty()).then(|| Arc::from(depth_limit)),
        ..Default::default()
    };
    let march = if is_rbf(&s.field) || s.shadows {
        Some(march(s, camera)?)
    } else {
        None
    };
    Ok(RenderPlan {
        params,
        mode: None,
        tiles: Tiles {
            count: None,
            budget_bytes: (s.memory_limit_mib > 0.0)
                .then(|| (s.memory_limit_mib * 1048576.0).min(u64::MAX as f64) as u64),
        },
        lod: (s.lod_tolerance > 0.0).then_some(s.lod_tolerance),
        march,
    })
}

/// The stochastic march `s` asks for: the RBF field, or an SPH field lit with shadows.
fn march(s: &ffi::Settings, camera: &Camera) -> Result<March, String> {
    let field = if is_rbf(&s.field) {
        Marched::Rbf(options(s, !s.scalars.is_empty())?)
    } else {
        Marched::Sph
    };
    let shadows = if s.shadows {
        let light = if s.light.iter().all(|&v| v == 0.0) {
            RbfShadows::default_light(&camera.frame(2, 2).map_err(|e| e.to_string())?)
        } else {
            s.light
        };
        Some(RbfShadows::new(light, s.shadow_ambient, 1).map_err(|e| e.to_string())?)
    } else {
        None
    };
    Ok(March {
        field,
        params: RbfRenderParams {
            spp: s.samples_per_pixel.max(1),
            shadows,
            ..Default::default()
        },
        progressive_passes: s.progressive_passes,
        time_refit: false,
    })
}

/// The field options `s` asks for (`attribute`: a point array is rendered).
fn options(s: &ffi::Settings, attribute: bool) -> Result<RbfOptions, String> {
    let colouring = match (
        attribute,
        s.rbf_classification.to_ascii_lowercase().as_str(),
    ) {
        (false, _) => Colouring::Density,
        (true, "" | "post") => Colouring::Post,
        (true, "pre") => Colouring::Pre,
        (true, c) => return Err(format!("RBF classification '{c}': expected post or pre")),
    };
    let radius_map = match &s.radius_map[..] {
        [] => AttributeMap::constant(1.0),
        m if m.len() % 2 == 0 => {
            AttributeMap::new(m.chunks_exact(2).map(|c| (c[0], c[1])).collect())
                .map_err(|e| e.to_string())?
        }
        m => return Err(format!("RBF radius map: {} values, not pairs", m.len())),
    };
    Ok(RbfOptions {
        radius: (s.rbf_radius > 0.0).then_some(s.rbf_radius),
        radius_map,
        colouring,
        ..Default::default()
    })
}

/// The mapper property (as ParaView names it) behind a refused part of the plan.
pub(crate) fn property(e: &BackendError, s: &ffi::Settings) -> Option<String> {
    Some(match e.item()? {
        PlanItem::Lod => "LODTolerance".to_string(),
        PlanItem::Tiles => format!("MemoryLimit {} MiB", s.memory_limit_mib),
        PlanItem::Surfaces => "iso-surfaces (the iso-surface blend mode)".to_string(),
        PlanItem::Mode => "the field (RBF)".to_string(),
    })
}
