//! `--lod`: what the level of detail did, for `--stats`.

use fluidcast_backend::LodReport;
use serde_json::json;

/// The level of detail's report as `--stats` writes it.
pub fn json(r: &LodReport) -> serde_json::Value {
    json!({
        "tolerance_px": r.tolerance,
        "full_detail_particles": r.full_detail,
        "rendered_particles": r.rendered,
        "per_level": r.per_level,
        "levels": r.levels,
        "build_ms": r.build_ms,
        "cut_ms": r.cut_ms,
        "hierarchy_bytes": r.hierarchy_bytes,
    })
}
