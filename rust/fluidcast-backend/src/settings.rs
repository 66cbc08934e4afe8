//! The numeric settings every front-end takes, and the one check of their values.
//!
//! A setting is a CLI option (`--support-radius`), a property of the VTK mapper and of the
//! ParaView representation (`SupportRadius`, shown as `FluidCastSupportRadius`) and, for
//! some, an argument of the Python package (`support_radius`). Each front-end checks a value
//! here when it is set (the mapper's setters, through the C++ bridge's `check_setting`; the
//! CLI while parsing; Python before it touches the mapper), so that one value is refused
//! alike everywhere, with one message, and a refused value never reaches a render: the
//! mapper keeps its previous value and ParaView's view stays usable.

use std::fmt;

use crate::{MAX_CELL, MAX_LEAF_SIZE};

/// Most screen tiles a frame is split into (`--tiles`, `Tiles`).
pub const MAX_TILES: i64 = 65536;
/// Most samples (rays) per pixel of one pass of the stochastic march.
pub const MAX_SPP: i64 = 65536;
/// Most shadow rays per sample.
pub const MAX_SHADOW_SAMPLES: i64 = 1024;
/// Most progressive passes a still view accumulates.
pub const MAX_PASSES: i64 = 65536;
/// Largest memory limit in MiB (a petabyte: any machine's memory fits under it).
pub const MAX_MEMORY_MIB: f64 = 1.0e9;
/// Largest level-of-detail tolerance in pixels.
pub const MAX_LOD_PIXELS: f64 = 1.0e6;
/// Largest sampling scale, and one over the smallest.
pub const MAX_SAMPLING_SCALE: f64 = 1.0e6;

/// What values a setting takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Domain {
    /// A finite real number in `[lo, hi]`, or `(lo, hi]` when `open_low`.
    Real {
        /// Smallest value (excluded when `open_low`).
        lo: f64,
        /// Largest value.
        hi: f64,
        /// Whether `lo` itself is refused.
        open_low: bool,
    },
    /// A length in world units that single precision holds: within
    /// [`f32::MIN_POSITIVE`, `f32::MAX`], or 0 when `zero` (the setting's automatic value).
    Length {
        /// Whether 0 is taken.
        zero: bool,
    },
    /// A whole number in `[lo, hi]`; a power of two when `pow2`.
    Int {
        /// Smallest value.
        lo: i64,
        /// Largest value.
        hi: i64,
        /// Whether only powers of two are taken.
        pow2: bool,
    },
}

const fn real(lo: f64, hi: f64) -> Domain {
    Domain::Real {
        lo,
        hi,
        open_low: false,
    }
}

const fn positive(hi: f64) -> Domain {
    Domain::Real {
        lo: 0.0,
        hi,
        open_low: true,
    }
}

const fn int(lo: i64, hi: i64) -> Domain {
    Domain::Int {
        lo,
        hi,
        pow2: false,
    }
}

/// The largest finite f32: world lengths go to the renderers in single precision.
const F32_MAX: f64 = f32::MAX as f64;

/// One numeric setting, as every front-end names it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setting {
    /// The mapper's and ParaView representation's property (`SupportRadius`; ParaView
    /// shows it as `FluidCast` + this).
    pub property: &'static str,
    /// The CLI option (`--support-radius`), or empty where the CLI has none.
    pub flag: &'static str,
    /// The Python argument (`support_radius`), or empty where Python has none.
    pub python: &'static str,
    /// The values it takes.
    pub domain: Domain,
    /// Units and the meaning of special values, for messages ("world units; 0: from the
    /// data").
    pub meaning: &'static str,
}

/// Every numeric setting. The mapper's checked setters, the representation and Python look
/// a value up here by property name; the CLI by flag.
pub const SETTINGS: &[Setting] = &[
    Setting {
        property: "SupportRadius",
        flag: "--support-radius",
        python: "support_radius",
        domain: Domain::Length { zero: true },
        meaning: "world units; 0: from the data",
    },
    Setting {
        property: "RadiusScale",
        flag: "--radius-scale",
        python: "radius_scale",
        domain: positive(F32_MAX),
        meaning: "times the radius array",
    },
    Setting {
        property: "ErrorTolerance",
        flag: "--error-tolerance",
        python: "error_tolerance",
        domain: real(0.0, 1.0),
        meaning: "screen-space error E_I; 0: full rate",
    },
    Setting {
        property: "Relax",
        flag: "--relax",
        python: "",
        domain: real(0.0, 1.0),
        meaning: "share of the error bound given up for speed",
    },
    Setting {
        property: "SamplingScale",
        flag: "--sampling-scale",
        python: "",
        domain: real(1.0 / MAX_SAMPLING_SCALE, MAX_SAMPLING_SCALE),
        meaning: "times the default sample spacing",
    },
    Setting {
        property: "MemoryLimit",
        // The CLI's --memory-limit takes bytes with a suffix, and checks them itself.
        flag: "",
        python: "",
        domain: real(0.0, MAX_MEMORY_MIB),
        meaning: "MiB; 0: none",
    },
    Setting {
        property: "WorkLimit",
        flag: "--max-work",
        python: "",
        domain: real(0.0, F32_MAX),
        meaning: "kernel evaluations a frame may be estimated to take; 0: 5e10",
    },
    Setting {
        property: "LODTolerance",
        flag: "--lod",
        python: "",
        domain: real(0.0, MAX_LOD_PIXELS),
        meaning: "pixels; 0: off",
    },
    Setting {
        property: "GridCell",
        flag: "--grid-cell",
        python: "",
        domain: int(1, MAX_CELL as i64),
        meaning: "pixels",
    },
    Setting {
        property: "Tiles",
        flag: "--tiles",
        python: "",
        domain: int(0, MAX_TILES),
        meaning: "0: as the memory limit needs",
    },
    Setting {
        property: "BundleSize",
        flag: "--bundle",
        python: "",
        domain: int(1, 64),
        meaning: "pixels",
    },
    Setting {
        property: "DepthSamples",
        flag: "--depth-samples",
        python: "",
        domain: Domain::Int {
            lo: 1,
            hi: 64,
            pow2: true,
        },
        meaning: "samples per cell",
    },
    Setting {
        property: "SamplesPerPixel",
        flag: "--spp",
        python: "",
        domain: int(1, MAX_SPP),
        meaning: "rays per pixel",
    },
    Setting {
        property: "ProgressivePasses",
        flag: "",
        python: "",
        domain: int(1, MAX_PASSES),
        meaning: "passes a still view accumulates",
    },
    Setting {
        property: "ShadowSamples",
        flag: "--shadow-samples",
        python: "",
        domain: int(1, MAX_SHADOW_SAMPLES),
        meaning: "shadow rays per sample",
    },
    Setting {
        property: "ShadowAmbient",
        flag: "--shadow-ambient",
        python: "",
        domain: real(0.0, 1.0),
        meaning: "light in full shadow",
    },
    Setting {
        property: "RBFRadius",
        flag: "--rbf-radius",
        python: "",
        domain: Domain::Length { zero: true },
        meaning: "world units; 0: the support radius",
    },
    Setting {
        property: "RBFStep",
        flag: "--rbf-step",
        python: "",
        domain: Domain::Length { zero: true },
        meaning: "world units; 0: automatic",
    },
    Setting {
        property: "RBFLeafSize",
        flag: "--leaf-size",
        python: "",
        domain: int(1, MAX_LEAF_SIZE as i64),
        meaning: "particles per BVH leaf",
    },
    Setting {
        property: "RBFSeed",
        flag: "--seed",
        python: "",
        domain: int(0, i32::MAX as i64),
        meaning: "noise seed",
    },
    Setting {
        property: "IsoSurfaceOpacity",
        flag: "--iso-opacity",
        python: "isosurface_opacity",
        domain: real(0.0, 1.0),
        meaning: "opacity of the surfaces",
    },
    Setting {
        property: "IsoValue",
        flag: "--iso",
        python: "isosurfaces",
        domain: real(-F32_MAX, F32_MAX),
        meaning: "a value of the surface field",
    },
    Setting {
        property: "ScalarOpacityUnitDistance",
        flag: "--opacity-unit-distance",
        python: "opacity_unit_distance",
        domain: Domain::Length { zero: false },
        meaning: "world units over which the opacity applies",
    },
];

/// A value a setting does not take.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SettingError {
    /// No setting has that name.
    #[error("no setting '{0}' (settings: {1})")]
    Unknown(String, String),
    /// The value is outside the setting's domain.
    #[error("{rule}, not {}", show(*value))]
    Refused {
        /// The value as given.
        value: f64,
        /// What the setting takes, with its units.
        rule: String,
    },
}

/// A value as users typed it: `1e-40`, not forty zeros.
fn show(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Domain::Real { lo, hi, open_low } => {
                let low = if open_low { "> " } else { ">= " };
                let hi = if hi == F32_MAX || hi == -F32_MAX {
                    "finite".to_string()
                } else {
                    format!("<= {hi}")
                };
                if lo == -F32_MAX {
                    write!(f, "a finite number")
                } else {
                    write!(f, "a number {low}{lo} and {hi}")
                }
            }
            Domain::Length { zero } => {
                let zero = if zero { "0 or " } else { "" };
                write!(
                    f,
                    "{zero}a length from {:e} to {:e}",
                    f32::MIN_POSITIVE,
                    f32::MAX
                )
            }
            Domain::Int { lo, hi, pow2 } => {
                let two = if pow2 {
                    "a power of two "
                } else {
                    "a whole number "
                };
                write!(f, "{two}{lo}..={hi}")
            }
        }
    }
}

impl Domain {
    /// Whether `v` lies in the domain (NaN and infinities never do).
    pub fn takes(&self, v: f64) -> bool {
        match *self {
            Domain::Real { lo, hi, open_low } => {
                v.is_finite() && v <= hi && (v > lo || (!open_low && v == lo))
            }
            Domain::Length { zero } => {
                (zero && v == 0.0) || (f64::from(f32::MIN_POSITIVE)..=F32_MAX).contains(&v)
            }
            Domain::Int { lo, hi, pow2 } => {
                v.is_finite()
                    && v.fract() == 0.0
                    && (lo as f64..=hi as f64).contains(&v)
                    && (!pow2 || (v as i64).count_ones() == 1)
            }
        }
    }
}

impl Setting {
    /// The setting with property name `property` (case-insensitive; ParaView's `FluidCast`
    /// prefix may be given).
    pub fn by_property(property: &str) -> Result<&'static Setting, SettingError> {
        let name = property.strip_prefix("FluidCast").unwrap_or(property);
        SETTINGS
            .iter()
            .find(|s| s.property.eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                let all: Vec<&str> = SETTINGS.iter().map(|s| s.property).collect();
                SettingError::Unknown(property.into(), all.join(", "))
            })
    }

    /// The setting the CLI calls `flag` (`--support-radius`).
    pub fn by_flag(flag: &str) -> Option<&'static Setting> {
        SETTINGS.iter().find(|s| !flag.is_empty() && s.flag == flag)
    }

    /// `Ok` when the setting takes `v`, else what it takes, with its units.
    pub fn check(&self, v: f64) -> Result<f64, SettingError> {
        if self.domain.takes(v) {
            Ok(v)
        } else {
            Err(SettingError::Refused {
                value: v,
                rule: format!("must be {} ({})", self.domain, self.meaning),
            })
        }
    }
}

/// Checks `value` for the setting named `property` (see [`Setting::by_property`]); the
/// message names the property, as the mapper and ParaView report it.
pub fn check_property(property: &str, value: f64) -> Result<(), SettingError> {
    let s = Setting::by_property(property)?;
    s.check(value).map(|_| ()).map_err(|e| match e {
        SettingError::Refused { value, rule } => SettingError::Refused {
            value,
            rule: format!("{} {rule}", s.property),
        },
        other => other,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_setting_refuses_nan_and_infinities() {
        for s in SETTINGS {
            for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                assert!(s.check(v).is_err(), "{} took {v}", s.property);
            }
        }
    }

    #[test]
    fn domains_take_their_ends_and_refuse_beyond() {
        let h = Setting::by_property("FluidCastSupportRadius").unwrap();
        assert!(h.check(0.0).is_ok() && h.check(0.1).is_ok());
        assert!(h.check(-1.0).is_err() && h.check(1e39).is_err() && h.check(1e-40).is_err());
        let scale = Setting::by_property("radiusscale").unwrap();
        assert!(scale.check(0.0).is_err() && scale.check(1e-30).is_ok());
        let e = Setting::by_property("ErrorTolerance").unwrap();
        assert!(e.check(1.0).is_ok() && e.check(1.0 + 1e-9).is_err());
        assert!(e.check(0.0).is_ok() && e.check(-0.5).is_err());
        let d = Setting::by_property("DepthSamples").unwrap();
        assert!(d.check(16.0).is_ok() && d.check(12.0).is_err() && d.check(128.0).is_err());
        let cell = Setting::by_property("GridCell").unwrap();
        assert!(cell.check(2.5).is_err() && cell.check(0.0).is_err());
        assert!(cell.check(MAX_CELL as f64).is_ok());
    }

    #[test]
    fn messages_name_the_property_and_the_rule() {
        let e = check_property("SupportRadius", f64::INFINITY).unwrap_err();
        assert_eq!(
            e.to_string(),
            "SupportRadius must be 0 or a length from 1.1754944e-38 to 3.4028235e38 (world \
             units; 0: from the data), not inf"
        );
        let e = check_property("Nonsense", 1.0).unwrap_err().to_string();
        assert!(e.contains("Nonsense") && e.contains("SupportRadius"), "{e}");
    }

    #[test]
    fn names_are_unique() {
        for (i, a) in SETTINGS.iter().enumerate() {
            for b in &SETTINGS[i + 1..] {
                assert_ne!(a.property.to_lowercase(), b.property.to_lowercase());
                assert!(a.flag.is_empty() || a.flag != b.flag);
                assert!(a.python.is_empty() || a.python != b.python);
            }
        }
    }
}
