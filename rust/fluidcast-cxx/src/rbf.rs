//! The RBF field (`Settings::field` "rbf") in the bridge: the field built once per data set
//! and transfer function, and progressive accumulation over still renders of one view.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use fluidcast_image::Image;
use fluidcast_rbf::{AttributeMap, Colouring, RbfField, RbfOptions, DEFAULT_LEAF_SIZE};
use fluidcast_render::{render_rbf, RbfRenderParams, RbfShadows, RenderParams, RenderStats};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};

use crate::ffi;

/// The RBF field of the prepared particles, a fingerprint of what it was built with
/// (transfer function and field options but the radius map) and the radius map it holds.
pub struct RbfCache {
    key: u64,
    radius_map: AttributeMap,
    field: RbfField,
}

/// Passes accumulated over still renders of one view: a fingerprint of everything the image
/// depends on, the passes so far and their mean.
pub struct Accumulation {
    key: u64,
    passes: u32,
    image: Image,
}

/// What the bridge keeps for the RBF field between renders (reset with the particles).
#[derive(Default)]
pub struct RbfState {
    cache: Option<RbfCache>,
    accumulated: Option<Accumulation>,
}

/// A fingerprint of values' Debug text and of the depth limits' bits.
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

/// The march's parameters for `s` (passes `first..first + spp`).
fn march(
    s: &ffi::Settings,
    camera: &Camera,
    first: u32,
    spp: u32,
) -> Result<RbfRenderParams, String> {
    let shadows = if s.shadows {
        let light = if s.light.iter().all(|&v| v == 0.0) {
            RbfShadows::default_light(&camera.frame(2, 2).map_err(|e| e.to_string())?)
        } else {
            s.light
        };
        let sh = RbfShadows::new(light, s.shadow_ambient, 1).map_err(|e| e.to_string())?;
        Some(sh)
    } else {
        None
    };
    Ok(RbfRenderParams {
        spp,
        first_pass: first,
        shadows,
        ..Default::default()
    })
}

impl RbfState {
    /// Renders `particles` as an RBF field, or (with shadows) as the SPH field `params`
    /// names: `s.samples_per_pixel` new passes, averaged with
    /// those of the previous renders of the same view up to `s.progressive_passes` (once
    /// there, the accumulated image again, without rendering).
    pub fn render(
        &mut self,
        particles: &Particles,
        (camera, tf): (&Camera, &TransferFunction),
        params: &RenderParams,
        s: &ffi::Settings,
    ) -> Result<(Image, RenderStats), String> {
        if params.surfaces.is_some() {
            return Err(
                "the RBF field draws no iso-surfaces (use the composite blend mode)".into(),
            );
        }
        if !crate::is_rbf(&s.field) {
            // An SPH field lit with shadows: marched over its supports, built once.
            let key = fingerprint(&format!("sph {:?} {:?}", params.kernel, params.field), &[]);
            if self.cache.as_ref().map(|c| c.key) != Some(key) {
                self.accumulated = None;
                let field =
                    RbfField::from_sph(particles, params.kernel, params.field, DEFAULT_LEAF_SIZE)
                        .map_err(|e| e.to_string())?;
                self.cache = Some(RbfCache {
                    key,
                    radius_map: AttributeMap::constant(1.0),
                    field,
                });
            }
            return self.march(key, (camera, tf), params, s);
        }
        let opts = options(s, !s.scalars.is_empty())?;
        let built = RbfOptions {
            radius_map: AttributeMap::constant(1.0),
            ..opts.clone()
        };
        let field_key = fingerprint(&format!("{tf:?}{built:?}"), &[]);
        match &mut self.cache {
            Some(c) if c.key == field_key => {
                if c.radius_map != opts.radius_map {
                    // Only the radii change: refit the tree (Morrical et al., Sec. 3.2.2).
                    self.accumulated = None;
                    c.field
                        .set_radius_map(&opts.radius_map)
                        .map_err(|e| e.to_string())?;
                    c.radius_map = opts.radius_map.clone();
                }
            }
            _ => {
                self.accumulated = None;
                let field = RbfField::build(particles, tf, &opts).map_err(|e| e.to_string())?;
                self.cache = Some(RbfCache {
                    key: field_key,
                    radius_map: opts.radius_map.clone(),
                    field,
                });
            }
        }
        self.march(field_key, (camera, tf), params, s)
    }

    /// Renders the cached field (`field_key`): new passes averaged with those accumulated
    /// for the same view (see [`RbfState::render`]).
    fn march(
        &mut self,
        field_key: u64,
        (camera, tf): (&Camera, &TransferFunction),
        params: &RenderParams,
        s: &ffi::Settings,
    ) -> Result<(Image, RenderStats), String> {
        let Some(cache) = &self.cache else {
            return Err("RBF field missing".into());
        };
        let depths = [&params.depth_limit, &params.depth_near].map(|d| d.as_deref().unwrap_or(&[]));
        let view = format!(
            "{camera:?}{s:?}{}x{}{:?}{}",
            params.width, params.height, params.support_depths, field_key
        );
        let key = fingerprint(&view, &depths);
        let spp = s.samples_per_pixel.max(1);
        let most = s.progressive_passes.max(spp);
        let acc = self.accumulated.take().filter(|a| a.key == key);
        let done = acc.as_ref().map_or(0, |a| a.passes);
        if let Some(a) = acc.as_ref().filter(|a| a.passes >= most) {
            let image = a.image.clone();
            self.accumulated = acc;
            return Ok((image, RenderStats::default()));
        }
        let new = spp.min(most - done);
        let rp = march(s, camera, done, new)?;
        let (mut image, stats) =
            render_rbf(&cache.field, camera, tf, params, &rp).map_err(|e| e.to_string())?;
        if let Some(a) = acc {
            let (wa, wb) = (done as f32, new as f32);
            for (p, q) in image.rgba.iter_mut().zip(&a.image.rgba) {
                for c in 0..4 {
                    p[c] = (q[c] * wa + p[c] * wb) / (wa + wb);
                }
            }
            image.depth = a.image.depth;
        }
        if s.progressive_passes > spp {
            self.accumulated = Some(Accumulation {
                key,
                passes: done + new,
                image: image.clone(),
            });
        }
        Ok((image, stats))
    }
}
