//! The front-ends render through this crate only: neither the CLI nor the C++ bridge
//! depends on a renderer crate directly (their tests may, as oracles).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

/// The crates a front-end must reach only through `fluidcast-backend`.
const BEHIND_THE_API: [&str; 6] = [
    "fluidcast-render",
    "fluidcast-rbf",
    "fluidcast-lod",
    "fluidcast-gpu",
    "fluidcast-grid",
    "fluidcast-plan",
];

/// The dependency names of every `[dependencies]` and `[target.*.dependencies]` table of a
/// Cargo manifest (dev- and build-dependencies left out).
fn dependencies(manifest: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut inside = false;
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            inside = line == "[dependencies]"
                || (line.starts_with("[target.") && line.ends_with(".dependencies]"));
            continue;
        }
        if inside {
            if let Some((name, _)) = line.split_once('=') {
                if !name.trim().starts_with('#') {
                    // `name.workspace = true` and `name = {…}` alike (crate names have no dot).
                    let name = name.trim().trim_matches('"');
                    names.push(name.split('.').next().unwrap_or(name).to_string());
                }
            }
        }
    }
    names
}

#[test]
fn front_ends_depend_on_the_render_api_not_on_the_renderers() {
    for front_end in ["fluidcast-cli", "fluidcast-cxx"] {
        let path = format!("{}/../{front_end}/Cargo.toml", env!("CARGO_MANIFEST_DIR"));
        let manifest = std::fs::read_to_string(&path).expect("the front-end's manifest");
        let deps = dependencies(&manifest);
        assert!(
            deps.iter().any(|d| d == "fluidcast-backend"),
            "{front_end}: {deps:?}"
        );
        for crate_name in BEHIND_THE_API {
            assert!(
                !deps.iter().any(|d| d == crate_name),
                "{front_end} depends on {crate_name} directly: render through fluidcast-backend"
            );
        }
    }
}

/// The parser reads what it must: a dependency in a target table counts, dev-dependencies
/// do not.
#[test]
fn the_manifest_reader_sees_target_tables_and_skips_dev_dependencies() {
    let m = "[package]\nname = \"x\"\n[dependencies]\na = \"1\"\n[target.'cfg(unix)'.dependencies]\nb.workspace = true\n[dev-dependencies]\nc = \"1\"\n";
    assert_eq!(dependencies(m), ["a", "b"]);
}
