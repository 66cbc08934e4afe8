//! The mapper's settings as the library's [`RenderPlan`]: what VTK and ParaView set becomes
//! the plan the CLI's options become, and [`fluidcast_backend::Renderer::render`] draws it.

use std::sync::Arc;

use fluidcast_backend::{
    AttributeMap, BackendError, Colouring, GridParams, March, Marched, Mode, Noise, PlanItem,
    PlanParams, RbfOptions, RbfRenderParams, RbfShadows, RenderParams, RenderPlan, Tiles,
};
use fluidcast_sph::FieldKind;
use fluidcast_view::Camera;

use crate::ffi;

/// The RBF field's name, after the SPH fields' (`FieldKind::ALL`) in [`field_names`].
const RBF: &str = "rbf";

/// `Settings::field`'s names in the order of ParaView's `FluidCastField` enumeration: the
/// SPH fields, then the RBF field.
pub(crate) fn field_names() -> Vec<String> {
    FieldKind::ALL
        .iter()
        .map(|f| f.name())
        .chain([RBF])
        .map(str::to_string)
        .collect()
}

/// `Settings::rbf_classification`'s names in the order of ParaView's
/// `FluidCastRBFClassification` enumeration.
pub(crate) const CLASSIFICATION_NAMES: [&str; 2] = ["post", "pre"];

/// Whether `Settings::field` names the RBF field.
pub(crate) fn is_rbf(field: &str) -> bool {
    field.eq_ignore_ascii_case(RBF)
}

/// `Settings::rbf_noise`'s names in the order of ParaView's `FluidCastRBFNoise`.
pub(crate) const NOISE_NAMES: [&str; 2] = ["blue", "white"];

/// The jitter's noise `name` names ("" or "blue": blue noise; "white").
fn noise(name: &str) -> Result<Noise, String> {
    let n = name.trim().to_ascii_lowercase();
    let [blue, white] = NOISE_NAMES;
    match n.as_str() {
        "" => Ok(Noise::Blue),
        n if n == blue => Ok(Noise::Blue),
        n if n == white => Ok(Noise::White),
        other => Err(format!("RBF noise '{other}': expected {blue} or {white}")),
    }
}

/// Refuses a name the mapper's named property `property` does not take (Kernel, Field,
/// Mode, RBFClassification, RBFNoise), by the parsers `configure` uses; "" takes the default.
pub(crate) fn check_name(property: &str, value: &str) -> Result<(), String> {
    let known = |names: Vec<String>| {
        let v = value.trim().to_ascii_lowercase();
        if v.is_empty() || names.contains(&v) {
            Ok(())
        } else {
            Err(format!(
                "{property} '{value}': expected one of {}",
                names.join(", ")
            ))
        }
    };
    match property {
        "Kernel" => value
            .parse::<fluidcast_sph::Kernel>()
            .map(|_| ())
            .map_err(|e| format!("{property} '{value}': {e}")),
        "Field" => check_field(value).map_err(|e| format!("{property}: {e}")),
        "Mode" => Mode::parse(value, 1)
            .map(|_| ())
            .map_err(|e| format!("{property}: {e}")),
        "RBFClassification" => known(CLASSIFICATION_NAMES.map(str::to_string).to_vec()),
        "RBFNoise" => noise(value)
            .map(|_| ())
            .map_err(|e| format!("{property}: {e}")),
        _ => Err(format!("no named setting '{property}'")),
    }
}

/// Every numeric setting of `s` by the library's table, as the mapper's setters checked them
/// (a caller of the bridge other than the mapper gets the same refusals).
pub(crate) fn check_settings(s: &ffi::Settings) -> Result<(), String> {
    let values = [
        ("SupportRadius", s.support_radius),
        ("RadiusScale", s.radius_scale),
        ("ErrorTolerance", s.error_tolerance),
        ("MemoryLimit", s.memory_limit_mib),
        ("WorkLimit", s.work_limit),
        ("LODTolerance", s.lod_tolerance),
        ("RBFRadius", s.rbf_radius),
        ("SamplesPerPixel", f64::from(s.samples_per_pixel)),
        ("ProgressivePasses", f64::from(s.progressive_passes)),
        ("ShadowAmbient", s.shadow_ambient),
        ("GridCell", f64::from(s.grid_cell)),
        ("Tiles", f64::from(s.tiles)),
        ("Relax", s.relax),
        ("BundleSize", f64::from(s.bundle)),
        ("DepthSamples", f64::from(s.depth_samples)),
        ("SamplingScale", s.sampling_scale),
        ("RBFSeed", f64::from(s.rbf_seed)),
        ("RBFLeafSize", f64::from(s.rbf_leaf_size)),
        ("RBFStep", s.rbf_step),
        ("ShadowSamples", f64::from(s.shadow_samples)),
    ];
    for (property, v) in values {
        fluidcast_backend::check_property(property, v).map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Refuses a mode, grid cell, tile count or any other setting the renderers do not take:
/// every numeric setting by the library's table ([`check_settings`], the ranges the mapper's
/// setters already checked), then what the table does not hold.
pub(crate) fn check_sampling(s: &ffi::Settings) -> Result<(), String> {
    check_settings(s)?;
    Mode::parse(&s.mode, s.grid_cell)?;
    // The library's own checks, at configure time rather than at the first render.
    plan_params(s).validate().map_err(|e| e.to_string())?;
    grid_params(s).validate().map_err(|e| e.to_string())?;
    noise(&s.rbf_noise)?;
    Ok(())
}

/// Refuses a field name no renderer has.
pub(crate) fn check_field(s: &str) -> Result<(), String> {
    if !is_rbf(s) {
        parse_field(s)?;
    }
    Ok(())
}

pub(crate) fn parse_field(s: &str) -> Result<FieldKind, String> {
    let s = s.trim().to_ascii_lowercase();
    FieldKind::ALL
        .into_iter()
        .find(|f| f.name() == s || s.is_empty() && *f == FieldKind::default())
        .ok_or_else(|| format!("unknown field '{s}' ({})", field_names().join(", ")))
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
        sampling_scale: s.sampling_scale,
        grid: grid_params(s),
        adaptive: plan_params(s),
        occlusion_culling: s.occlusion_culling,
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
        mode: Mode::parse(&s.mode, s.grid_cell)?,
        tiles: Tiles {
            count: (s.tiles > 0).then_some(s.tiles),
            budget_bytes: (s.memory_limit_mib > 0.0)
                .then(|| (s.memory_limit_mib * 1048576.0).min(u64::MAX as f64) as u64),
        },
        lod: (s.lod_tolerance > 0.0).then_some(s.lod_tolerance),
        march,
        work_limit: (s.work_limit > 0.0).then_some(s.work_limit),
    })
}

/// The adaptive plan's parameters `s` asks for (the strict bound turns relaxation,
/// super-pixels and interpolation off, as the CLI's `--strict`).
fn plan_params(s: &ffi::Settings) -> PlanParams {
    let p = PlanParams {
        tolerance: (s.error_tolerance > 0.0).then_some(s.error_tolerance),
        relax: s.relax,
        probe: s.probe,
        superpixels: s.superpixels,
        surface_cells: s.surface_cells,
        interpolate: s.interpolate,
    };
    if s.strict {
        p.strict()
    } else {
        p
    }
}

/// The grid resolution `s` asks for.
fn grid_params(s: &ffi::Settings) -> GridParams {
    GridParams {
        bundle: s.bundle,
        depth_samples: s.depth_samples,
    }
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
        let samples = s.shadow_samples.max(1);
        Some(RbfShadows::new(light, s.shadow_ambient, samples).map_err(|e| e.to_string())?)
    } else {
        None
    };
    Ok(March {
        field,
        params: RbfRenderParams {
            spp: s.samples_per_pixel.max(1),
            first_pass: 0,
            seed: s.rbf_seed,
            step: (s.rbf_step > 0.0).then_some(s.rbf_step),
            shadows,
            noise: noise(&s.rbf_noise)?,
        },
        progressive_passes: s.progressive_passes,
        time_refit: false,
    })
}

/// The field options `s` asks for (`attribute`: a point array is rendered).
fn options(s: &ffi::Settings, attribute: bool) -> Result<RbfOptions, String> {
    let c = s.rbf_classification.to_ascii_lowercase();
    let [post, pre] = CLASSIFICATION_NAMES;
    let colouring = match (attribute, c.as_str()) {
        (false, _) => Colouring::Density,
        (true, "") => Colouring::Post,
        (true, n) if n == post => Colouring::Post,
        (true, n) if n == pre => Colouring::Pre,
        (true, n) => {
            return Err(format!(
                "RBF classification '{n}': expected {post} or {pre}"
            ))
        }
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
        leaf_size: s.rbf_leaf_size as usize,
    })
}

/// The mapper property (as ParaView names it) behind a refused part of the plan.
pub(crate) fn property(e: &BackendError, s: &ffi::Settings) -> Option<String> {
    Some(match e.item()? {
        PlanItem::Lod => "LODTolerance".to_string(),
        PlanItem::Tiles => format!("MemoryLimit {} MiB", s.memory_limit_mib),
        PlanItem::Surfaces => "iso-surfaces (the iso-surface blend mode)".to_string(),
        PlanItem::Mode => "the field (RBF)".to_string(),
        PlanItem::Work => "WorkLimit".to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The entries (text, value) of the `EnumerationDomain` of ParaView property `name` in the
    /// representation's server-manager XML.
    fn enumeration(xml: &str, name: &str) -> Vec<(String, i64)> {
        let at = xml
            .find(&format!("name=\"{name}\""))
            .unwrap_or_else(|| panic!("no property {name} in the XML"));
        let rest = &xml[at..];
        let end = rest.find("</EnumerationDomain>").expect("an enumeration");
        rest[..end]
            .split("<Entry ")
            .skip(1)
            .map(|e| {
                let attr = |k: &str| {
                    let s = &e[e.find(&format!("{k}=\"")).expect(k) + k.len() + 2..];
                    s[..s.find('"').expect("closing quote")].to_string()
                };
                (
                    attr("text"),
                    attr("value").parse().expect("an integer value"),
                )
            })
            .collect()
    }

    /// ParaView's enumerations (kernel, field, RBF classification, backend) and the Rust lists
    /// the bridge hands the C++ side agree entry by entry: same count, values 0, 1, 2 … in
    /// order, and each label begins with the Rust name (`wendland-c2` as "Wendland C2").
    #[test]
    fn paraview_enumerations_are_the_rust_lists() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../paraview/Representation/fluidcast_representation.xml"
        );
        let xml = std::fs::read_to_string(path).expect("the representation's XML");
        let lists = [
            ("FluidCastKernel", crate::kernel_names()),
            ("FluidCastField", field_names()),
            (
                "FluidCastRBFClassification",
                crate::rbf_classification_names(),
            ),
            ("FluidCastBackend", crate::backend_names()),
            ("FluidCastMode", crate::mode_names()),
            ("FluidCastRBFNoise", crate::rbf_noise_names()),
        ];
        for (property, names) in lists {
            let entries = enumeration(&xml, property);
            assert_eq!(
                entries.len(),
                names.len(),
                "{property}: {entries:?} vs {names:?}"
            );
            for (i, ((text, value), name)) in entries.iter().zip(&names).enumerate() {
                assert_eq!(
                    *value, i as i64,
                    "{property}: entry {text} has value {value}"
                );
                let label = text.to_ascii_lowercase();
                let want = name.replace('-', " ");
                assert!(
                    label.starts_with(&want),
                    "{property} entry {i}: '{text}' in ParaView, '{name}' in Rust"
                );
            }
        }
    }
}
