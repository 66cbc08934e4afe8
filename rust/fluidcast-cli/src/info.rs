use std::path::PathBuf;

use anyhow::Result;
use fluidcast_io::{read_dataset, Input};
use fluidcast_sph::suggest_support_radius;
use serde_json::json;

#[derive(clap::Args)]
pub struct InfoArgs {
    /// A .vtu, .vtp, .vtk file or a .pvd series (its first frame is described).
    input: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

pub fn run(a: InfoArgs) -> Result<()> {
    let input = Input::open(&a.input)?;
    let frames = input.frames();
    let ds = read_dataset(&frames[0].1)?;
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
    if a.json {
        println!(
            "{}",
            json!({"file": ds.path, "frames": frames.len(), "points": ds.points.len(), "nonfinite_points": nonfinite,
                   "bounds": bounds, "point_data": arrays, "field_data": fields, "suggested_support_radius": suggested})
        );
        return Ok(());
    }
    if let Input::Series(c) = &input {
        println!(
            "series {}: {} frames, t = {} .. {}",
            c.path.display(),
            c.entries.len(),
            c.entries[0].timestep,
            c.entries.last().unwrap().timestep
        );
        println!("first frame:");
    }
    println!("file:   {}", ds.path.display());
    println!("kind:   {:?}", ds.kind);
    println!(
        "points: {}{}",
        ds.points.len(),
        if nonfinite > 0 {
            format!(" ({nonfinite} with NaN/Inf coordinates)")
        } else {
            String::new()
        }
    );
    if let Some((lo, hi)) = ds.bounds() {
        println!(
            "bounds: x [{:.6}, {:.6}]  y [{:.6}, {:.6}]  z [{:.6}, {:.6}] (world units)",
            lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
        );
    }
    println!("point data:");
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
        println!(
            "  {:<24} {:<8} x{}  range {r}{m}",
            x.name,
            x.scalar_type.vtk_name(),
            x.num_components
        );
    }
    if !ds.field_data.is_empty() {
        println!("field data:");
        for x in &ds.field_data {
            let vals: Vec<String> = x.values.iter().take(6).map(|v| format!("{v}")).collect();
            println!(
                "  {:<24} {:<8} {}{}",
                x.name,
                x.scalar_type.vtk_name(),
                vals.join(" "),
                if x.values.len() > 6 { " …" } else { "" }
            );
        }
    }
    match (ds.field_scalar("support_radius"), suggested) {
        (Some(h), _) => println!("support radius: {h} (field data 'support_radius')"),
        (None, Some(h)) => println!("suggested support radius: {h:.6} (2 x mean nearest-neighbour spacing; pass --support-radius)"),
        (None, None) => println!("no support radius can be suggested (fewer than 2 distinct points)"),
    }
    Ok(())
}
