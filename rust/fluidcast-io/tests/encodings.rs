//! Every encoding VTK writes must give the same particles as the ascii file.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;
use common::fixture;
use fluidcast_io::{read_collection, read_dataset, Dataset, ScalarType};

fn same(a: &Dataset, b: &Dataset) {
    assert_eq!(
        a.points,
        b.points,
        "{} vs {}",
        a.path.display(),
        b.path.display()
    );
    let names = |d: &Dataset| {
        d.point_data
            .iter()
            .map(|x| x.name.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(names(a), names(b), "{}", b.path.display());
    for (x, y) in a.point_data.iter().zip(&b.point_data) {
        assert_eq!(x, y, "array {} of {}", x.name, b.path.display());
    }
    assert_eq!(
        a.field_scalar("TIME"),
        b.field_scalar("TIME"),
        "{}",
        b.path.display()
    );
    assert_eq!(
        a.field_scalar("support_radius"),
        b.field_scalar("support_radius")
    );
}

#[test]
fn all_xml_encodings_agree_with_ascii() {
    for ext in ["vtu", "vtp"] {
        let reference = read_dataset(fixture(&format!("lattice_ascii_none_h64.{ext}"))).unwrap();
        assert_eq!(reference.points.len(), 256);
        assert_eq!(reference.point_data.len(), 6);
        let v = reference.point_array("velocity").unwrap();
        assert_eq!((v.num_components, v.scalar_type), (3, ScalarType::F32));
        assert_eq!(
            reference.point_array("ubig").unwrap().scalar_type,
            ScalarType::U64
        );
        assert_eq!(reference.field_scalar("TIME"), Some(0.25));
        let mut n = 0;
        for entry in std::fs::read_dir(fixture("")).unwrap() {
            let p = entry.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            if name.starts_with("lattice_") && name.ends_with(ext) {
                let d = read_dataset(&p).unwrap_or_else(|e| panic!("{e}"));
                same(&reference, &d);
                n += 1;
            }
        }
        assert!(n >= 20, "only {n} .{ext} fixtures");
    }
}

#[test]
fn legacy_files_agree_with_xml() {
    let reference = read_dataset(fixture("lattice_ascii_none_h64.vtu")).unwrap();
    for name in [
        "lattice_legacy42_ascii.vtk",
        "lattice_legacy42_binary.vtk",
        "lattice_legacy51_ascii.vtk",
        "lattice_legacy51_binary.vtk",
    ] {
        let d = read_dataset(fixture(name)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(d.points.len(), 256, "{name}");
        // Legacy ascii writes floats with limited digits: compare values loosely.
        for (p, q) in d.points.iter().zip(&reference.points) {
            for k in 0..3 {
                assert!((p[k] - q[k]).abs() < 1e-6, "{name}");
            }
        }
        for a in &reference.point_data {
            let b = d
                .point_array(&a.name)
                .unwrap_or_else(|| panic!("{name} lacks {}", a.name));
            assert_eq!(b.num_components, a.num_components, "{name}: {}", a.name);
            for (x, y) in a.values.iter().zip(&b.values) {
                assert!(
                    (x - y).abs() <= 1e-5 * x.abs().max(1.0),
                    "{name}: {} {x} vs {y}",
                    a.name
                );
            }
        }
        assert_eq!(d.field_scalar("support_radius"), Some(0.03), "{name}");
    }
}

#[test]
fn pvd_collection_sorted_by_time() {
    let c = read_collection(fixture("series.pvd")).unwrap();
    assert_eq!(c.entries.len(), 2);
    assert_eq!(c.entries[0].timestep, 0.0);
    assert!(c.entries[0].file.ends_with("lattice_ascii_none_h64.vtu"));
    assert_eq!(c.entries[1].timestep, 0.5);
    for e in &c.entries {
        read_dataset(&e.file).unwrap();
    }
}
