//! Particles built one array at a time from a file ([`fluidcast_io::LazyDataset`]) are the
//! particles built from the whole data set, for every spec that reads arrays differently.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
use std::path::PathBuf;

use fluidcast_io::{open_lazy, read_dataset, Arrays};
use fluidcast_sph::{
    Component, ParticleError, ParticleSpec, Particles, Quantity, RadiusSource, VolumeSource,
};

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// `../shared/data/REL` (or under FLUIDCAST_SHARED_DATA, as `fluidcast_testkit::shared_data`,
/// which this crate's tests cannot use: the test kit depends on it), required when
/// FLUIDCAST_REQUIRE_DATA=1.
fn shared(rel: &str) -> Option<PathBuf> {
    let base = std::env::var_os("FLUIDCAST_SHARED_DATA")
        .map_or_else(|| repo("../shared/data"), PathBuf::from);
    let p = base.join(rel);
    if p.exists() {
        return Some(p);
    }
    assert_ne!(
        std::env::var("FLUIDCAST_REQUIRE_DATA").as_deref(),
        Ok("1"),
        "{} missing",
        p.display()
    );
    None
}

fn same(a: &Particles, b: &Particles, what: &str) {
    assert_eq!(a.positions, b.positions, "{what}");
    assert_eq!(a.radii, b.radii, "{what}");
    assert_eq!(a.volumes, b.volumes, "{what}");
    assert_eq!(a.masses, b.masses, "{what}");
    assert_eq!(a.values, b.values, "{what}");
    assert_eq!(a.notes, b.notes, "{what}");
    assert_eq!(a.skipped_nonfinite, b.skipped_nonfinite, "{what}");
}

fn quantity(s: &str) -> Option<Quantity> {
    Some(s.parse().unwrap())
}

#[test]
fn lazily_built_particles_are_those_of_the_whole_data_set() {
    let mut files = vec![
        repo("tests/fixtures/lattice_appended-raw_zlib_h64.vtu"),
        repo("examples/data/sample_column.vtu"),
        // Read whole (not by byte range): the lazy source is a selective read.
        repo("tests/fixtures/lattice_legacy42_binary.vtk"),
    ];
    files.extend(shared(
        "splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu",
    ));
    files.extend(shared("pysph_dambreak3d/dam_break_3d_fluid_01180.vtu"));
    for f in files {
        let whole = read_dataset(&f).unwrap();
        let names: Vec<String> = whole.point_data.iter().map(|a| a.name.clone()).collect();
        let vector = whole
            .point_data
            .iter()
            .find(|a| a.num_components == 3)
            .map(|a| a.name.clone());
        let scalar = whole
            .point_data
            .iter()
            .find(|a| a.num_components == 1)
            .map(|a| a.name.clone())
            .unwrap();
        let mut specs = vec![
            ParticleSpec::default(),
            ParticleSpec {
                quantity: quantity(&scalar),
                volume: VolumeSource::Uniform,
                ..Default::default()
            },
            ParticleSpec {
                quantity: quantity(&scalar),
                radius: RadiusSource::Array {
                    name: scalar.clone(),
                    scale: 1e-3,
                },
                volume: VolumeSource::Array(scalar.clone()),
                mass: Some(scalar.clone()),
            },
            ParticleSpec {
                radius: RadiusSource::Constant(0.05),
                ..Default::default()
            },
        ];
        if let Some(v) = &vector {
            specs.push(ParticleSpec {
                quantity: quantity(v),
                ..Default::default()
            });
            specs.push(ParticleSpec {
                quantity: Some(Quantity {
                    array: v.clone(),
                    component: Component::Index(2),
                }),
                ..Default::default()
            });
        }
        for spec in specs {
            let what = format!("{} {spec:?}", f.display());
            let a = Particles::from_dataset(&whole, &spec);
            let lazy = open_lazy(&f, &Arrays::Named(spec.arrays())).unwrap();
            let b = Particles::from_source(&lazy, &spec);
            match (a, b) {
                (Ok(a), Ok(b)) => same(&a, &b, &what),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{what}"),
                (a, b) => panic!("{what}: {:?} vs {:?}", a.err(), b.err()),
            }
            // A selective whole read builds them too.
            let sel = fluidcast_io::read_dataset_with(&f, &Arrays::Named(spec.arrays())).unwrap();
            if let (Ok(a), Ok(b)) = (
                Particles::from_dataset(&whole, &spec),
                Particles::from_dataset(&sel, &spec),
            ) {
                same(&a, &b, &what);
            }
        }
        // A missing array lists every array of the file, decoded or not, with components.
        let spec = ParticleSpec {
            quantity: quantity("no_such"),
            ..Default::default()
        };
        let lazy = open_lazy(&f, &Arrays::Named(spec.arrays())).unwrap();
        match Particles::from_source(&lazy, &spec) {
            Err(ParticleError::MissingArray { available, .. }) => {
                for n in &names {
                    assert!(available.contains(n.as_str()), "{available}");
                }
                if let Some(v) = &vector {
                    assert!(available.contains(&format!("{v} (3 comp.)")), "{available}");
                }
            }
            other => panic!("{other:?}"),
        }
    }
}
