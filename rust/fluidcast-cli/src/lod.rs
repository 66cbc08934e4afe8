//! `--lod`: render a per-view cut through the particle hierarchy instead of every particle.

use std::time::Instant;

use anyhow::{Context, Result};
use fluidcast_lod::LodHierarchy;
use fluidcast_sph::Particles;
use fluidcast_view::Camera;
use serde_json::json;

/// What one view's level of detail did, for the render line and `--stats`.
#[derive(Debug, Clone)]
pub struct LodReport {
    /// The tolerance: the largest cell edge taken, in pixels at a node's nearest depth.
    pub tolerance: f64,
    pub full_detail: usize,
    pub rendered: usize,
    /// Nodes taken from each level (0: full detail).
    pub per_level: Vec<usize>,
    pub levels: usize,
    pub build_ms: f64,
    pub cut_ms: f64,
    pub hierarchy_bytes: usize,
}

impl LodReport {
    pub fn line(&self) -> String {
        format!(
            "level of detail {} px: {} of {} particles ({:.1}%; per level {:?}), hierarchy of {} levels built in {:.0} ms, cut in {:.0} ms",
            self.tolerance,
            self.rendered,
            self.full_detail,
            100.0 * self.rendered as f64 / self.full_detail.max(1) as f64,
            self.per_level,
            self.levels,
            self.build_ms,
            self.cut_ms
        )
    }

    pub fn json(&self) -> serde_json::Value {
        json!({
            "tolerance_px": self.tolerance,
            "full_detail_particles": self.full_detail,
            "rendered_particles": self.rendered,
            "per_level": self.per_level,
            "levels": self.levels,
            "build_ms": self.build_ms,
            "cut_ms": self.cut_ms,
            "hierarchy_bytes": self.hierarchy_bytes,
        })
    }
}

/// Builds the hierarchy of `particles` (timed).
pub fn build(particles: Particles) -> Result<(LodHierarchy, f64)> {
    let t = Instant::now();
    let h = LodHierarchy::build(particles).context("--lod: building the particle hierarchy")?;
    Ok((h, t.elapsed().as_secs_f64() * 1e3))
}

/// The cut of `h` for `camera` at `width × height` and `tolerance` pixels.
pub fn cut(
    h: &LodHierarchy,
    camera: &Camera,
    (width, height): (u32, u32),
    tolerance: f64,
    build_ms: f64,
) -> Result<(Particles, LodReport)> {
    let t = Instant::now();
    let frame = camera.frame(width, height)?;
    let c = h.cut(&frame, tolerance).context("--lod")?;
    let report = LodReport {
        tolerance,
        full_detail: h.full_detail().len(),
        rendered: c.particles.len(),
        per_level: c.per_level,
        levels: h.levels(),
        build_ms,
        cut_ms: t.elapsed().as_secs_f64() * 1e3,
        hierarchy_bytes: h.memory_bytes(),
    };
    Ok((c.particles, report))
}
