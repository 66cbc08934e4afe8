use std::path::PathBuf;

use anyhow::Result;
use fluidcast_io::Input;
use fluidcast_sph::suggest_support_radius;
use serde_json::json;

/// Prints the adapters, best first, and where `--backend auto` renders.
fn adapters() -> Result<()> {
    let list = crate::render::without_wayland_noise(fluidcast_backend::list_adapters);
    if list.is_empty() {
        out!("no GPU adapters");
    }
    for (k, a) in list.iter().enumerate() {
        out!("adapter {k}: {a}");
    }
    let auto = crate::render::without_wayland_noise(|| {
        fluidcast_backend::Renderer::open(fluidcast_backend::Backend::Auto, None)
    })?;
    out!("--backend auto renders on: {}", auto.device());
    Ok(())
}

#[derive(clap::Args)]
pub struct InfoArgs {
    /// A .vtu, .vtp, .pvtu, .pvtp, .vtk file or a .pvd series (its first frame is described).
    #[arg(required_unless_present = "adapters")]
    input: Option<PathBuf>,
    /// List the GPU adapters fluidcast finds, best first, and what --backend auto picks.
    #[arg(long)]
    adapters: bool,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

pub fn run(a: InfoArgs) -> Result<()> {
    let Some(path) = a.input.as_ref().filter(|_| !a.adapters) else {
        return adapters();
    };
    let input = Input::open(path)?;
    let frames = input.frames();
    let ds = input.read_frame(&frames[0], &fluidcast_io::Arrays::All)?;
    let nonfinite = ds
        .points
        .iter()
        .filter(|p| !p.iter().all(|v| v.is_finite()))
        .count();
    let suggested = if ds.field_scalar("support_radius").is_none() {
        suggest_support_radius(&ds.points)
    } else {
        None
    };
    if a.json {
        out!("{}", info_json(&ds, frames.len(), nonfinite, suggested));
        return Ok(());
    }
    if let Input::Series(c) = &input {
        out!(
            "series {}: {} frames ({} data sets), t = {} .. {}",
            c.path.display(),
            frames.len(),
            c.entries.len(),
            c.entries.first().map_or(0.0, |e| e.timestep),
            c.entries.last().map_or(0.0, |e| e.timestep)
        );
        out!("first frame:");
    }
    print_geometry(&ds, nonfinite)?;
    print_arrays(&ds)?;
    match (ds.field_scalar("support_radius"), radius_array(&ds), suggested) {
        (Some(h), _, _) => out!("support radius: {h} (field data 'support_radius')"),
        (None, Some(name), _) => out!(
            "per-particle smoothing length '{name}': pass --radius-array {name} --radius-scale 2 \
             (support H = 2h)"
        ),
        (None, None, Some(h)) => out!("suggested support radius: {h:.6} (2 x mean nearest-neighbour spacing; pass --support-radius)"),
        (None, None, None) => out!("no support radius can be suggested (no measurable spacing between neighbouring points)"),
    }
    Ok(())
}

/// The point array holding a smoothing length, if the data set has one.
fn radius_array(ds: &fluidcast_io::Dataset) -> Option<&str> {
    let names = ds
        .point_data
        .iter()
        .map(|a| (a.name.as_str(), a.num_components));
    fluidcast_sph::suggest_radius_array(names)
}

/// `fluidcast info --json`: the first frame's data set as one object.
fn info_json(
    ds: &fluidcast_io::Dataset,
    frames: usize,
    nonfinite: usize,
    suggested: Option<f64>,
) -> serde_json::Value {
    let arrays: Vec<_> = ds
        .point_data
        .iter()
        .map(|x| {
            let mag = if x.num_components > 1 { x.magnitude_range() } else { None };
            json!({"name": x.name, "type": x.scalar_type.vtk_name(), "components": x.num_components,
                   "range": x.range().map(|r| [r.0, r.1]), "magnitude_range": mag.map(|r| [r.0, r.1])})
        })
        .collect();
    let fields: Vec<_> = ds
        .field_data
        .iter()
        .map(|x| json!({"name": x.name, "type": x.scalar_type.vtk_name(), "components": x.num_components, "values": x.values.iter().take(16).collect::<Vec<_>>()}))
        .collect();
    let bounds = ds.bounds().map(|(lo, hi)| json!({"min": lo, "max": hi}));
    let other: serde_json::Map<String, serde_json::Value> = ds
        .cells
        .other
        .iter()
        .map(|(k, n)| (k.clone(), json!(n)))
        .collect();
    let cells =
        json!({"count": ds.cells.count, "not_vertices": other, "cell_data": ds.cells.cell_arrays});
    json!({"file": ds.path, "frames": frames, "points": ds.points.len(), "nonfinite_points": nonfinite,
           "bounds": bounds, "point_data": arrays, "field_data": fields, "cells": cells,
           "suggested_support_radius": suggested,
           "suggested_radius_array": radius_array(ds).map(|n| json!({"name": n, "radius_scale": 2}))})
}

/// The file, its kind, points, cells and bounds, a line each.
fn print_geometry(ds: &fluidcast_io::Dataset, nonfinite: usize) -> Result<()> {
    out!("file:   {}", ds.path.display());
    out!("kind:   {:?}", ds.kind);
    out!(
        "points: {}{}",
        ds.points.len(),
        if nonfinite > 0 {
            format!(" ({nonfinite} with NaN/Inf coordinates)")
        } else {
            String::new()
        }
    );
    if let Some(dropped) = ds.cells.dropped() {
        out!(
            "cells:  {} ({dropped}; fluidcast renders the points only)",
            ds.cells.count
        );
    }
    if let Some((lo, hi)) = ds.bounds() {
        out!(
            "bounds: x [{:.6}, {:.6}]  y [{:.6}, {:.6}]  z [{:.6}, {:.6}] (world units)",
            lo[0],
            hi[0],
            lo[1],
            hi[1],
            lo[2],
            hi[2]
        );
    }
    Ok(())
}

/// The point arrays (type, components, range) and the field data (first values).
fn print_arrays(ds: &fluidcast_io::Dataset) -> Result<()> {
    out!("point data:");
    for x in &ds.point_data {
        let r = x
            .range()
            .map(|r| format!("[{:.6}, {:.6}]", r.0, r.1))
            .unwrap_or("(empty)".into());
        let m = if x.num_components > 1 {
            x.magnitude_range()
                .map(|r| format!("  |v| in [{:.6}, {:.6}]", r.0, r.1))
                .unwrap_or_default()
        } else {
            String::new()
        };
        out!(
            "  {:<24} {:<8} x{}  range {r}{m}",
            x.name,
            x.scalar_type.vtk_name(),
            x.num_components
        );
    }
    if !ds.field_data.is_empty() {
        out!("field data:");
        for x in &ds.field_data {
            let vals: Vec<String> = x.values.iter().take(6).map(|v| format!("{v}")).collect();
            out!(
                "  {:<24} {:<8} {}{}",
                x.name,
                x.scalar_type.vtk_name(),
                vals.join(" "),
                if x.values.len() > 6 { " …" } else { "" }
            );
        }
    }
    Ok(())
}
