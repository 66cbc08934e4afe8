use std::path::{Path, PathBuf};

use fluidcast_io::{DataArray, Dataset};
use rayon::prelude::*;

use crate::grid::bounds;
use crate::NeighbourGrid;

/// Which part of a (possibly vector) point array is the rendered quantity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    /// The single component of a scalar array, or the magnitude of a vector array (ParaView's
    /// default for vectors).
    Auto,
    /// Euclidean norm of the tuple (`NAME:mag`).
    Magnitude,
    /// One component (`NAME:0`, `NAME:1`, …).
    Index(usize),
}

/// The rendered quantity: a point array and a component selection, written `NAME`,
/// `NAME:mag` or `NAME:K`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Quantity {
    pub array: String,
    pub component: Component,
}

impl std::str::FromStr for Quantity {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        // Array names may contain ':'; only a recognised suffix is a selector.
        if let Some((name, sel)) = s.rsplit_once(':') {
            let sel_l = sel.to_ascii_lowercase();
            if sel_l == "mag" || sel_l == "magnitude" {
                return Ok(Quantity {
                    array: name.into(),
                    component: Component::Magnitude,
                });
            }
            if let Ok(k) = sel.parse::<usize>() {
                return Ok(Quantity {
                    array: name.into(),
                    component: Component::Index(k),
                });
            }
        }
        if s.is_empty() {
            return Err("empty array name".into());
        }
        Ok(Quantity {
            array: s.into(),
            component: Component::Auto,
        })
    }
}

impl std::fmt::Display for Quantity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.component {
            Component::Auto => write!(f, "{}", self.array),
            Component::Magnitude => write!(f, "{}:mag", self.array),
            Component::Index(k) => write!(f, "{}:{k}", self.array),
        }
    }
}

/// Where each particle's support radius H (world units) comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum RadiusSource {
    /// `H_j = scale · array_j` (e.g. `--radius-array h --radius-scale 2` for a smoothing length).
    Array { name: String, scale: f64 },
    /// The same H for all particles.
    Constant(f64),
    /// The file's field data `support_radius` (SPlisHSPlasH writes it), else the radius
    /// suggested from the mean particle spacing ([`suggest_support_radius`]).
    Auto,
}

/// Where each particle's volume V = m/ρ (world units³) comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum VolumeSource {
    /// `V_j = mass_j / density_j`.
    MassDensity { mass: String, density: String },
    /// `V_j = array_j`.
    Array(String),
    /// All particles get `spacing³` (spacing = mean nearest-neighbour distance): a uniform
    /// volume cancels in the Shepard-normalised field.
    Uniform,
    /// `mass`/`m` and `density`/`rho` arrays if both exist, else `volume`, else uniform.
    Auto,
}

/// How to turn a [`Dataset`] into [`Particles`].
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleSpec {
    /// `None`: render the particle density / occupancy only (value 1 everywhere).
    pub quantity: Option<Quantity>,
    pub radius: RadiusSource,
    pub volume: VolumeSource,
    /// Mass array for the density field (`Σ m W`); `None`: auto (`mass`/`m`, else V·ρ).
    pub mass: Option<String>,
}

/// The arrays [`VolumeSource::Auto`] and an automatic mass look for, in order.
const MASS_NAMES: [&str; 2] = ["mass", "m"];
const DENSITY_NAMES: [&str; 2] = ["density", "rho"];
const VOLUME_NAMES: [&str; 2] = ["volume", "V"];

impl ParticleSpec {
    /// The point arrays [`Particles::from_dataset`] may read under this spec: a read that
    /// decodes only these ([`fluidcast_io::Arrays`]) builds the same particles.
    pub fn arrays(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        if let Some(q) = &self.quantity {
            names.push(q.array.clone());
        }
        if let RadiusSource::Array { name, .. } = &self.radius {
            names.push(name.clone());
        }
        match &self.volume {
            VolumeSource::MassDensity { mass, density } => {
                names.extend([mass.clone(), density.clone()])
            }
            VolumeSource::Array(name) => names.push(name.clone()),
            VolumeSource::Uniform => {}
            VolumeSource::Auto => names.extend(VOLUME_NAMES.map(String::from)),
        }
        match &self.mass {
            Some(name) => names.push(name.clone()),
            None => names.extend(
                MASS_NAMES
                    .iter()
                    .chain(&DENSITY_NAMES)
                    .map(|n| n.to_string()),
            ),
        }
        names.sort();
        names.dedup();
        names
    }
}

impl Default for ParticleSpec {
    fn default() -> Self {
        ParticleSpec {
            quantity: None,
            radius: RadiusSource::Auto,
            volume: VolumeSource::Auto,
            mass: None,
        }
    }
}

/// A problem turning a data set into particles; names the file.
#[derive(Debug, thiserror::Error)]
pub enum ParticleError {
    #[error("{file}: no point array '{name}' (available: {available})")]
    MissingArray {
        file: PathBuf,
        name: String,
        available: String,
    },
    #[error("{file}: array '{name}' has {ncomp} components, component {index} does not exist")]
    BadComponent {
        file: PathBuf,
        name: String,
        ncomp: usize,
        index: usize,
    },
    #[error("{file}: the data set has no points")]
    NoPoints { file: PathBuf },
    #[error("{file}: all {count} points have NaN or infinite coordinates")]
    NoFinitePoints { file: PathBuf, count: usize },
    #[error("{file}: support radius of particle {index} is {value} (must be finite and > 0)")]
    BadRadius {
        file: PathBuf,
        index: usize,
        value: f64,
    },
    #[error("{file}: volume of particle {index} is {value} (must be finite and > 0)")]
    BadVolume {
        file: PathBuf,
        index: usize,
        value: f64,
    },
    #[error("{file}: {message}")]
    Other { file: PathBuf, message: String },
}

/// Particles ready for reconstruction and rendering: structure of arrays, world space,
/// single precision (the layout the CPU and GPU renderers share).
#[derive(Debug, Clone, Default)]
pub struct Particles {
    /// Positions in world space.
    pub positions: Vec<[f32; 3]>,
    /// Support radius H_j (world units); the kernel vanishes beyond it.
    pub radii: Vec<f32>,
    /// Volume V_j = m_j/ρ_j (world units³).
    pub volumes: Vec<f32>,
    /// Mass m_j (for the density field).
    pub masses: Vec<f32>,
    /// The rendered quantity A_j (1 when no array was chosen).
    pub values: Vec<f32>,
    /// Particles dropped because a coordinate was NaN or infinite.
    pub skipped_nonfinite: usize,
    /// Human-readable notes on choices made automatically (radius, volume), for the CLI.
    pub notes: Vec<String>,
}

fn available(ds: &Dataset) -> String {
    let v: Vec<String> = ds
        .point_data
        .iter()
        .map(|a| {
            if a.num_components > 1 {
                format!("{} ({} comp.)", a.name, a.num_components)
            } else {
                a.name.clone()
            }
        })
        .chain(ds.undecoded.iter().cloned())
        .collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

fn array<'a>(ds: &'a Dataset, name: &str) -> Result<&'a DataArray, ParticleError> {
    ds.point_array(name)
        .ok_or_else(|| ParticleError::MissingArray {
            file: ds.path.clone(),
            name: name.into(),
            available: available(ds),
        })
}

fn first_of<'a>(ds: &'a Dataset, names: &[&str]) -> Option<&'a DataArray> {
    names
        .iter()
        .find_map(|n| ds.point_array(n).filter(|a| a.num_components == 1))
}

/// Extracts the selected component of `q` as one value per point.
pub fn quantity_values(ds: &Dataset, q: &Quantity) -> Result<Vec<f64>, ParticleError> {
    let at = quantity_at(ds, q)?;
    Ok((0..ds.points.len()).map(at).collect())
}

/// A far outlier lies beyond this many inter-quartile widths from the central half of
/// the particles (spray flies a few body lengths; a corrupt coordinate, 10^10 and more).
pub const OUTLIER_FACTOR: f64 = 1e4;

/// Most points [`far_outliers`] takes its quartiles from.
const QUARTILE_SAMPLE: usize = 1 << 20;

/// Which finite points lie far outside the rest: more than [`OUTLIER_FACTOR`] times the
/// largest inter-quartile width (over x, y, z) outside the box of the quartiles. Empty when
/// there are none, fewer than 8 points, or more than half of them coincide.
pub fn far_outliers(points: &[[f64; 3]]) -> Vec<usize> {
    // Quartiles of up to 2^20 points (a stride sample beyond): with a margin of 10^4
    // quartile widths they need not be exact, and millions of particles need no copy.
    let stride = points.len().div_ceil(QUARTILE_SAMPLE).max(1);
    let finite: Vec<&[f64; 3]> = points
        .iter()
        .step_by(stride)
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .collect();
    if finite.len() < 8 {
        return Vec::new();
    }
    let quartiles = |k: usize| {
        let mut v: Vec<f64> = finite.iter().map(|p| p[k]).collect();
        let n = v.len();
        let q1 = *v.select_nth_unstable_by(n / 4, f64::total_cmp).1;
        let q3 = *v.select_nth_unstable_by(3 * n / 4, f64::total_cmp).1;
        (q1, q3)
    };
    let q = [quartiles(0), quartiles(1), quartiles(2)];
    let iqr = q.iter().map(|(a, b)| b - a).fold(0.0, f64::max);
    if iqr.is_nan() || iqr <= 0.0 {
        return Vec::new();
    }
    let margin = OUTLIER_FACTOR * iqr;
    (0..points.len())
        .filter(|&i| {
            let p = points[i];
            p.iter().all(|v| v.is_finite())
                && (0..3).any(|k| p[k] < q[k].0 - margin || p[k] > q[k].1 + margin)
        })
        .collect()
}

/// Mean nearest-neighbour distance of (up to 4096 of) the finite points, world units; far
/// outliers ([`far_outliers`]) do not count.
pub fn mean_spacing(points: &[[f64; 3]]) -> Option<f64> {
    spacing_without(points, &far_outliers(points))
}

/// [`mean_spacing`] of the finite points not listed in `far` (sorted indices).
fn spacing_without(points: &[[f64; 3]], far: &[usize]) -> Option<f64> {
    let pts: Vec<[f32; 3]> = points
        .iter()
        .enumerate()
        .filter(|(i, p)| p.iter().all(|v| v.is_finite()) && far.binary_search(i).is_err())
        .map(|(_, p)| [p[0] as f32, p[1] as f32, p[2] as f32])
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let (lo, hi) = bounds(&pts);
    let ext: Vec<f32> = (0..3).map(|k| (hi[k] - lo[k]).max(0.0)).collect();
    let diag = (ext[0] * ext[0] + ext[1] * ext[1] + ext[2] * ext[2]).sqrt();
    if diag == 0.0 {
        return None;
    }
    // Start with a cell size from the bounding box and grow until neighbours are found.
    let vol: f32 = ext.iter().map(|e| e.max(diag * 1e-3)).product();
    let mut cell = (vol / pts.len() as f32).cbrt() * 2.0;
    let stride = (pts.len() / 4096).max(1);
    for _ in 0..20 {
        let grid = NeighbourGrid::new(&pts, cell);
        let mut sum = 0.0f64;
        let mut n = 0usize;
        for i in (0..pts.len()).step_by(stride) {
            let mut best = f32::INFINITY;
            grid.for_each_near(pts[i], cell, |j, d2| {
                if j != i as u32 && d2 > 0.0 && d2 < best {
                    best = d2;
                }
            });
            if best.is_finite() {
                sum += (best as f64).sqrt();
                n += 1;
            }
        }
        if n * 2 >= pts.len().div_ceil(stride) {
            return Some(sum / n as f64);
        }
        cell *= 2.0;
    }
    None
}

/// Suggested support radius H when neither the user nor the file gives one: twice the mean
/// nearest-neighbour spacing (SPlisHSPlasH uses H = 4r = 2·spacing; PySPH's Wendland with
/// h = 1.3·dx gives H = 2.6·dx), so that a sample sees ~30 neighbours.
pub fn suggest_support_radius(points: &[[f64; 3]]) -> Option<f64> {
    mean_spacing(points).map(|s| 2.0 * s)
}

/// Refuses a particle quantity that single precision, in which the renderers compute,
/// turns into infinity, or (for radii and volumes, which are divided by) into zero or a
/// subnormal: a volume of 1e39, a radius of 1e-40.
/// `divided_by`: the renderers divide by the quantity, so it must stay a normal number.
fn single_precision(
    file: &Path,
    index: usize,
    divided_by: bool,
    vals: &[(&str, f64)],
) -> Result<(), ParticleError> {
    for &(what, v) in vals {
        let f = v as f32;
        let bad = (v.is_finite() && f.is_infinite()) || (divided_by && v != 0.0 && !f.is_normal());
        if bad {
            return Err(ParticleError::Other {
                file: file.to_path_buf(),
                message: format!(
                    "{what} of particle {index} is {v:e}, outside single precision (the \
                     renderers' arithmetic, about 1e-38 to 3e38): rescale the data"
                ),
            });
        }
    }
    Ok(())
}

/// One value per point index, computed when asked: the particles are built from the data
/// set's arrays without a second full-length copy of each in double precision.
type PerParticle<'a> = Box<dyn Fn(usize) -> f64 + 'a>;

/// `scale · a[i]` of a one-component array.
fn per_value(a: &DataArray, scale: f64) -> PerParticle<'_> {
    Box::new(move |i| a.values[i] * scale)
}

/// The selected component of `q` at each point (see [`quantity_values`]).
fn quantity_at<'a>(ds: &'a Dataset, q: &Quantity) -> Result<PerParticle<'a>, ParticleError> {
    let a = array(ds, &q.array)?;
    let nc = a.num_components;
    let v = &a.values;
    Ok(match q.component {
        Component::Auto if nc == 1 => per_value(a, 1.0),
        Component::Auto | Component::Magnitude => Box::new(move |i| {
            v[i * nc..(i + 1) * nc]
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
                .sqrt()
        }),
        Component::Index(k) if k < nc => Box::new(move |i| v[i * nc + k]),
        Component::Index(k) => {
            return Err(ParticleError::BadComponent {
                file: ds.path.clone(),
                name: q.array.clone(),
                ncomp: nc,
                index: k,
            })
        }
    })
}

/// Each particle's support radius under `spec`, with a note where it was chosen for the
/// user; `kept` finite points and `spacing` (the mean nearest-neighbour distance) for the
/// message and the suggestion when nothing gives a radius.
fn radius_at<'a>(
    ds: &'a Dataset,
    spec: &ParticleSpec,
    kept: usize,
    spacing: &dyn Fn() -> Option<f64>,
    notes: &mut Vec<String>,
) -> Result<PerParticle<'a>, ParticleError> {
    let h = match &spec.radius {
        RadiusSource::Array { name, scale } => {
            let a = array(ds, name)?;
            if a.num_components != 1 {
                return Err(ParticleError::Other {
                    file: ds.path.clone(),
                    message: format!("radius array '{name}' must have 1 component"),
                });
            }
            return Ok(per_value(a, *scale));
        }
        RadiusSource::Constant(h) => *h,
        RadiusSource::Auto => match ds.field_scalar("support_radius") {
            Some(h) => {
                notes.push(format!(
                    "support radius {h} from the file's field data 'support_radius'"
                ));
                h
            }
            None => {
                let h = spacing()
                    .map(|s| 2.0 * s)
                    .ok_or_else(|| no_spacing(ds, kept))?;
                notes.push(format!(
                    "no support radius given: using {h:.6} (2 x mean particle spacing); set --support-radius or --radius-array"
                ));
                h
            }
        },
    };
    Ok(Box::new(move |_| h))
}

fn no_spacing(ds: &Dataset, kept: usize) -> ParticleError {
    ParticleError::Other {
        file: ds.path.clone(),
        message: format!(
            "cannot suggest a support radius: {kept} finite points with no measurable \
             spacing between neighbours{}: give --support-radius",
            ds.bounds()
                .map(|(lo, hi)| format!(
                    ", spread over {:.3e} world units",
                    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
                ))
                .unwrap_or_default()
        ),
    }
}

/// Each particle's volume under `spec`, with a note where it was chosen automatically.
fn volume_at<'a>(
    ds: &'a Dataset,
    spec: &ParticleSpec,
    spacing: &dyn Fn() -> Option<f64>,
    notes: &mut Vec<String>,
) -> Result<PerParticle<'a>, ParticleError> {
    let mass_density = |m: &'a DataArray, d: &'a DataArray| -> PerParticle<'a> {
        Box::new(move |i| m.values[i] / d.values[i])
    };
    let uniform = |s: Option<f64>| -> PerParticle<'a> {
        let s = s.unwrap_or(1.0);
        Box::new(move |_| s * s * s)
    };
    Ok(match &spec.volume {
        VolumeSource::MassDensity { mass, density } => {
            mass_density(array(ds, mass)?, array(ds, density)?)
        }
        VolumeSource::Array(name) => per_value(array(ds, name)?, 1.0),
        VolumeSource::Uniform => uniform(spacing()),
        VolumeSource::Auto => match (
            first_of(ds, &MASS_NAMES),
            first_of(ds, &DENSITY_NAMES),
            first_of(ds, &VOLUME_NAMES),
        ) {
            (Some(m), Some(d), _) => {
                notes.push(format!("particle volume = {} / {}", m.name, d.name));
                mass_density(m, d)
            }
            (_, _, Some(v)) => {
                notes.push(format!("particle volume from array '{}'", v.name));
                per_value(v, 1.0)
            }
            _ => {
                notes.push("uniform particle volume (no mass/density or volume arrays)".into());
                uniform(spacing())
            }
        },
    })
}

fn far_outlier_warning(x: [f64; 3], i: usize, count: usize, kept: usize) -> String {
    format!(
        "warning: {count} of {kept} particles lie far outside the rest (e.g. particle {i} at \
         ({:.3e}, {:.3e}, {:.3e})); they are rendered, and an automatic camera frames \
         them too: remove them, or set the camera",
        x[0], x[1], x[2]
    )
}

impl Particles {
    /// Builds particles from a data set. Points with a NaN/infinite coordinate are skipped and
    /// counted in `skipped_nonfinite`; bad radii or volumes of kept particles are errors.
    pub fn from_dataset(ds: &Dataset, spec: &ParticleSpec) -> Result<Particles, ParticleError> {
        let file = ds.path.clone();
        let n = ds.points.len();
        if n == 0 {
            return Err(ParticleError::NoPoints { file });
        }
        let finite = |i: usize| ds.points[i].iter().all(|v| v.is_finite());
        let kept = (0..n).into_par_iter().filter(|&i| finite(i)).count();
        if kept == 0 {
            return Err(ParticleError::NoFinitePoints { file, count: n });
        }
        let mut notes = Vec::new();
        let values: PerParticle = match &spec.quantity {
            Some(q) => quantity_at(ds, q)?,
            None => Box::new(|_| 1.0),
        };
        // Outliers and the particle spacing are computed once, for the radius, the volume and
        // the warning alike.
        let far = far_outliers(&ds.points);
        let spacing_cell = std::cell::OnceCell::new();
        let spacing = || *spacing_cell.get_or_init(|| spacing_without(&ds.points, &far));
        let radii = radius_at(ds, spec, kept, &spacing, &mut notes)?;
        let volumes = volume_at(ds, spec, &spacing, &mut notes)?;
        let masses: PerParticle = match spec.mass.as_deref() {
            Some(name) => per_value(array(ds, name)?, 1.0),
            None => match (first_of(ds, &MASS_NAMES), first_of(ds, &DENSITY_NAMES)) {
                (Some(m), _) => per_value(m, 1.0),
                (None, Some(d)) => {
                    let v = volume_at(ds, spec, &spacing, &mut Vec::new())?;
                    Box::new(move |i| v(i) * d.values[i])
                }
                _ => volume_at(ds, spec, &spacing, &mut Vec::new())?,
            },
        };
        if let Some(&i) = far.first() {
            notes.push(far_outlier_warning(ds.points[i], i, far.len(), kept));
        }
        let mut p = Particles {
            notes,
            skipped_nonfinite: n - kept,
            positions: Vec::with_capacity(kept),
            radii: Vec::with_capacity(kept),
            volumes: Vec::with_capacity(kept),
            masses: Vec::with_capacity(kept),
            values: Vec::with_capacity(kept),
        };
        for i in (0..n).filter(|&i| finite(i)) {
            let (h, v, m, a) = (radii(i), volumes(i), masses(i), values(i));
            if !(h.is_finite() && h > 0.0) {
                return Err(ParticleError::BadRadius {
                    file,
                    index: i,
                    value: h,
                });
            }
            if !(v.is_finite() && v > 0.0) {
                return Err(ParticleError::BadVolume {
                    file,
                    index: i,
                    value: v,
                });
            }
            single_precision(&file, i, true, &[("volume", v), ("support radius", h)])?;
            single_precision(&file, i, false, &[("mass", m), ("value", a)])?;
            let x = ds.points[i];
            p.positions.push([x[0] as f32, x[1] as f32, x[2] as f32]);
            p.radii.push(h as f32);
            p.volumes.push(v as f32);
            p.masses.push(m as f32);
            p.values.push(a as f32);
        }
        Ok(p)
    }

    /// The values of quantity `q` of `ds` at the particles [`Particles::from_dataset`] keeps
    /// (the points with finite coordinates), in their order: a second attribute beside the
    /// rendered one (e.g. the field of an iso-surface), checked as the rendered one is.
    pub fn values_of(ds: &Dataset, q: &Quantity) -> Result<Vec<f32>, ParticleError> {
        let values = quantity_values(ds, q)?;
        let mut out = Vec::new();
        for (i, x) in ds.points.iter().enumerate() {
            if x.iter().all(|v| v.is_finite()) {
                single_precision(&ds.path, i, false, &[("value", values[i])])?;
                out.push(values[i] as f32);
            }
        }
        Ok(out)
    }

    /// The particles `keep` (indices, in the order given), without the notes.
    pub fn select(&self, keep: &[usize]) -> Particles {
        Particles {
            positions: keep.iter().map(|&j| self.positions[j]).collect(),
            radii: keep.iter().map(|&j| self.radii[j]).collect(),
            volumes: keep.iter().map(|&j| self.volumes[j]).collect(),
            masses: keep.iter().map(|&j| self.masses[j]).collect(),
            values: keep.iter().map(|&j| self.values[j]).collect(),
            skipped_nonfinite: 0,
            notes: Vec::new(),
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no particles.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Largest support radius.
    pub fn max_radius(&self) -> f32 {
        self.radii.iter().copied().fold(0.0, f32::max)
    }

    /// Bounds of the particles' supports (positions ± H), world space.
    pub fn support_bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for (p, h) in self.positions.iter().zip(&self.radii) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k] - h);
                hi[k] = hi[k].max(p[k] + h);
            }
        }
        (lo, hi)
    }

    /// Range of the rendered values (finite ones), `(0, 1)` if none.
    pub fn value_range(&self) -> (f32, f32) {
        let mut r = (f32::INFINITY, f32::NEG_INFINITY);
        for v in self.values.iter().filter(|v| v.is_finite()) {
            r = (r.0.min(*v), r.1.max(*v));
        }
        if r.0 > r.1 {
            (0.0, 1.0)
        } else {
            r
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize) -> Vec<[f64; 3]> {
        (0..n * n * n)
            .map(|i| {
                [
                    (i % n) as f64 * 0.1,
                    (i / n % n) as f64 * 0.1,
                    (i / n / n) as f64 * 0.1,
                ]
            })
            .collect()
    }

    #[test]
    fn far_outliers_are_found_and_spray_is_not() {
        let mut pts = lattice(4);
        assert!(far_outliers(&pts).is_empty());
        // Spray: droplets a few body lengths away are data, not outliers.
        pts.push([0.0, 3.0, 0.0]);
        pts.push([-2.0, 0.0, 5.0]);
        assert!(far_outliers(&pts).is_empty());
        pts.push([0.0, -1e14, 0.0]);
        pts.push([f64::NAN, 0.0, 0.0]);
        assert_eq!(far_outliers(&pts), vec![66]);
        // The spacing estimate ignores the outlier (0.1, not 10^13).
        let s = mean_spacing(&pts).unwrap();
        assert!((s - 0.1).abs() < 0.02, "{s}");
        // Planar data (zero spread in z) is judged by its widest axis.
        let flat: Vec<[f64; 3]> = lattice(4).iter().map(|p| [p[0], p[1], 0.0]).collect();
        assert!(far_outliers(&flat).is_empty());
    }

    #[test]
    fn single_precision_limits() {
        let f = Path::new("f.vtu");
        assert!(
            single_precision(f, 0, true, &[("volume", 1e-30), ("support radius", 1e30)]).is_ok()
        );
        assert!(single_precision(f, 0, true, &[("volume", 1e39)]).is_err());
        assert!(single_precision(f, 3, true, &[("support radius", 1e-40)])
            .unwrap_err()
            .to_string()
            .contains("support radius of particle 3 is 1e-40"));
        assert!(single_precision(f, 0, false, &[("value", 1e39)]).is_err());
        // Small values and masses may round to zero; they are not divided by.
        assert!(single_precision(f, 0, false, &[("value", 1e-50), ("mass", 1e-50)]).is_ok());
    }
}
