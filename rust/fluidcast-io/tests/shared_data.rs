//! Every file in ../shared/data reads, and the encodings of DoubleDamBreak frame 0011 agree.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;
use common::shared;
use fluidcast_io::{read_collection, read_dataset};

#[test]
fn every_shared_file_reads() {
    let Some(root) = shared("") else {
        return;
    };
    let mut n = 0;
    for dir in std::fs::read_dir(root).unwrap() {
        let dir = dir.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        for f in std::fs::read_dir(&dir).unwrap() {
            let f = f.unwrap().path();
            match f.extension().and_then(|e| e.to_str()) {
                Some("vtu" | "vtp") => {
                    let d = read_dataset(&f).unwrap_or_else(|e| panic!("{e}"));
                    assert!(!d.points.is_empty(), "{}", f.display());
                    n += 1;
                }
                Some("pvd") => {
                    let c = read_collection(&f).unwrap();
                    assert!(c.entries.iter().all(|e| e.file.exists()));
                }
                _ => {}
            }
        }
    }
    assert!(n >= 20);
}

#[test]
fn double_dam_break_encodings_identical() {
    let Some(dir) = shared("splash_doubledambreak") else {
        return;
    };
    let base = read_dataset(dir.join("DoubleDamBreak_r0.0125_0011.vtu")).unwrap();
    assert_eq!(base.points.len(), 42282);
    assert_eq!(base.field_scalar("support_radius"), Some(0.05f32 as f64)); // stored as Float32
    for name in [
        "DoubleDamBreak_r0.0125_0011.vtp",
        "DoubleDamBreak_r0.0125_0011_raw.vtu",
        "DoubleDamBreak_r0.0125_0011_raw.vtp",
        "DoubleDamBreak_r0.0125_0011_ascii.vtu",
    ] {
        let d = read_dataset(dir.join(name)).unwrap();
        assert_eq!(d.points, base.points, "{name}");
        for a in &base.point_data {
            assert_eq!(Some(a), d.point_array(&a.name), "{name}: {}", a.name);
        }
    }
}

#[test]
fn pysph_version_0_1_base64() {
    let Some(dir) = shared("pysph_dambreak3d") else {
        return;
    };
    let d = read_dataset(dir.join("dam_break_3d_fluid_01180.vtu")).unwrap();
    assert_eq!(d.points.len(), 23760);
    let h = d.point_array("h").unwrap();
    assert!((h.values[0] - 0.039).abs() < 1e-9);
    let z = read_dataset(dir.join("dam_break_3d_fluid_01180_zlib.vtp")).unwrap();
    assert_eq!(z.points, d.points);
}
