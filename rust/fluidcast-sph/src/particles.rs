use std::path::{Path, PathBuf};

use std::borrow::Cow;

use fluidcast_io::{DataArray, Dataset, LazyDataset, ReadError};
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
/// `NAME:mag` or `NAME:K`, or with ParaView's names `NAME:Magnitude` and `NAME:X|Y|Z`
/// (components 0, 1, 2; any case).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Quantity {
    /// The point array.
    pub array: String,
    /// Which of its components, or the magnitude.
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
            let axis = ["x", "y", "z"].iter().position(|a| *a == sel_l);
            if let Some(k) = axis.or_else(|| sel.parse::<usize>().ok()) {
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
    Array {
        /// The point array.
        name: String,
        /// The factor from its values to H.
        scale: f64,
    },
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
    MassDensity {
        /// The mass array.
        mass: String,
        /// The density array.
        density: String,
    },
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
    /// Where the support radii come from.
    pub radius: RadiusSource,
    /// Where the volumes come from.
    pub volume: VolumeSource,
    /// Mass array for the density field (`Σ m W`); `None`: auto (`mass`/`m`, else V·ρ).
    pub mass: Option<String>,
}

/// The mass arrays [`VolumeSource::Auto`] and an automatic mass look for, in order.
pub const MASS_NAMES: [&str; 2] = ["mass", "m"];
/// The density arrays [`VolumeSource::Auto`] looks for, in order.
pub const DENSITY_NAMES: [&str; 2] = ["density", "rho"];
/// The volume arrays [`VolumeSource::Auto`] looks for, in order.
pub const VOLUME_NAMES: [&str; 2] = ["volume", "V"];

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
    /// A point array asked for that the file does not have.
    #[error("{file}: no point array '{name}' (available: {available})")]
    MissingArray {
        /// The file.
        file: PathBuf,
        /// The array asked for.
        name: String,
        /// The point arrays the file has.
        available: String,
    },
    /// A component index past the array's components.
    #[error("{file}: array '{name}' has {ncomp} components, component {index} does not exist")]
    BadComponent {
        /// The file.
        file: PathBuf,
        /// The array.
        name: String,
        /// Its components.
        ncomp: usize,
        /// The component asked for.
        index: usize,
    },
    /// A data set without points.
    #[error("{file}: the data set has no points")]
    NoPoints {
        /// The file.
        file: PathBuf,
    },
    /// Every point has a NaN or infinite coordinate.
    #[error("{file}: all {count} points have NaN or infinite coordinates")]
    NoFinitePoints {
        /// The file.
        file: PathBuf,
        /// Its points.
        count: usize,
    },
    /// A support radius that is not a finite number > 0.
    #[error("{file}: support radius of particle {index} is {value} (must be finite and > 0)")]
    BadRadius {
        /// The file.
        file: PathBuf,
        /// The particle.
        index: usize,
        /// Its radius.
        value: f64,
    },
    /// A volume that is not a finite number > 0.
    #[error("{file}: volume of particle {index} is {value} ({from}; must be finite and > 0)")]
    BadVolume {
        /// The file.
        file: PathBuf,
        /// The particle.
        index: usize,
        /// Its volume.
        value: f64,
        /// Where the volume came from, with the values at fault (e.g. `mass 0.0156 /
        /// density 0`: a particle whose density the code has not computed yet).
        from: String,
    },
    /// Another problem with the data, in words.
    #[error("{file}: {message}")]
    Other {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Reading an array of a file opened for reading one array at a time.
    #[error(transparent)]
    Read(#[from] ReadError),
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

/// What particles are built from: a data set in memory ([`Dataset`]) or a file read one
/// array at a time ([`LazyDataset`]), so that each array is decoded, turned into the
/// particles' single precision and dropped before the next.
pub trait ParticleSource {
    /// The file, for messages.
    fn path(&self) -> &Path;
    /// Number of points.
    fn num_points(&self) -> usize;
    /// First value of a field-data array (e.g. `support_radius`).
    fn field_scalar(&self, name: &str) -> Option<f64>;
    /// Every point array, decoded or not, as (name, components).
    fn arrays(&self) -> Vec<(String, usize)>;
    /// The points, x, y, z of each in turn.
    fn points(&self) -> Result<Cow<'_, [f64]>, ParticleError>;
    /// Point array `name`; `None` when there is none.
    fn array(&self, name: &str) -> Result<Option<Cow<'_, DataArray>>, ParticleError>;
}

impl ParticleSource for Dataset {
    fn path(&self) -> &Path {
        &self.path
    }
    fn num_points(&self) -> usize {
        self.points.len()
    }
    fn field_scalar(&self, name: &str) -> Option<f64> {
        Dataset::field_scalar(self, name)
    }
    fn arrays(&self) -> Vec<(String, usize)> {
        self.point_arrays()
    }
    fn points(&self) -> Result<Cow<'_, [f64]>, ParticleError> {
        Ok(Cow::Borrowed(bytemuck::cast_slice(&self.points)))
    }
    fn array(&self, name: &str) -> Result<Option<Cow<'_, DataArray>>, ParticleError> {
        Ok(self.point_array(name).map(Cow::Borrowed))
    }
}

impl ParticleSource for LazyDataset {
    fn path(&self) -> &Path {
        LazyDataset::path(self)
    }
    fn num_points(&self) -> usize {
        LazyDataset::num_points(self)
    }
    fn field_scalar(&self, name: &str) -> Option<f64> {
        LazyDataset::field_scalar(self, name)
    }
    fn arrays(&self) -> Vec<(String, usize)> {
        self.point_arrays()
    }
    fn points(&self) -> Result<Cow<'_, [f64]>, ParticleError> {
        Ok(LazyDataset::points(self)?)
    }
    fn array(&self, name: &str) -> Result<Option<Cow<'_, DataArray>>, ParticleError> {
        Ok(self.point_array(name)?)
    }
}

fn available(src: &impl ParticleSource) -> String {
    let v: Vec<String> = src
        .arrays()
        .into_iter()
        .map(|(name, nc)| {
            if nc > 1 {
                format!("{name} ({nc} comp.)")
            } else {
                name
            }
        })
        .collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// Point array `name`, or an error naming the file and what it has.
fn array<'a>(
    src: &'a impl ParticleSource,
    name: &str,
) -> Result<Cow<'a, DataArray>, ParticleError> {
    src.array(name)?.ok_or_else(|| ParticleError::MissingArray {
        file: src.path().to_path_buf(),
        name: name.into(),
        available: available(src),
    })
}

/// The first of `names` that is a one-component point array.
fn first_of(src: &impl ParticleSource, names: &[&str]) -> Option<String> {
    let list = src.arrays();
    names
        .iter()
        .find(|n| list.iter().any(|(m, c)| m == *n && *c == 1))
        .map(|n| n.to_string())
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
/// outliers ([`far_outliers`]) do not count. Coincident points count once: the distance to
/// the nearest *other* position, over the distinct positions ([`crate::Distinct`]), so that
/// copies of a point neither shrink the spacing to 0 nor cost a query each.
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
    let pts = crate::Distinct::of(&pts).points;
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

/// The names SPH codes give a per-particle smoothing length h (PySPH `h`, `smoothing_length`,
/// GADGET's `hsml`, SWIFT's `SmoothingLengths`), compared without case.
pub const SMOOTHING_LENGTH_NAMES: [&str; 4] = ["h", "smoothing_length", "hsml", "smoothinglengths"];

/// A point array among `names` that holds a smoothing length h (one component): what to
/// pass as `--radius-array NAME --radius-scale 2` (support H = 2h, as PySPH's and VTK's
/// cubic spline and Wendland kernels take it).
pub fn suggest_radius_array<'a>(
    names: impl IntoIterator<Item = (&'a str, usize)>,
) -> Option<&'a str> {
    names.into_iter().find_map(|(name, components)| {
        let known = SMOOTHING_LENGTH_NAMES
            .iter()
            .any(|n| n.eq_ignore_ascii_case(name));
        (known && components == 1).then_some(name)
    })
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

/// Refuses value `a` of quantity `q` at particle `i` that the renderers cannot sum: NaN
/// (summed into every sample its support reaches, it makes them all not a number, drawn as
/// nothing) or beyond single precision.
fn check_value(file: &Path, q: &Quantity, i: usize, a: f64) -> Result<(), ParticleError> {
    if a.is_nan() {
        return Err(ParticleError::Other {
            file: file.to_path_buf(),
            message: format!(
                "'{}' of particle {i} is NaN: it would blank out every sample its support \
                 reaches; replace or remove such values",
                q.array
            ),
        });
    }
    single_precision(file, i, false, &[("value", a)])
}

/// One value per point index, computed when asked.
type PerParticle<'a> = Box<dyn Fn(usize) -> f64 + 'a>;

/// `scale · a[i]`.
fn per_value(a: &DataArray, scale: f64) -> PerParticle<'_> {
    Box::new(move |i| a.values[i] * scale)
}

/// The component of `a` that `q` selects, at each point.
fn component_at<'a>(
    a: &'a DataArray,
    q: &Quantity,
    file: &Path,
) -> Result<PerParticle<'a>, ParticleError> {
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
                file: file.to_path_buf(),
                name: q.array.clone(),
                ncomp: nc,
                index: k,
            })
        }
    })
}

/// The points with finite coordinates, in single precision, and what is learnt from all
/// points while they are decoded: which are kept, the far outliers' warning and the mean
/// spacing (when something needs it).
struct Located {
    kept: Vec<bool>,
    count: usize,
    positions: Vec<[f32; 3]>,
    outliers: Option<String>,
    spacing: Option<f64>,
    /// The largest extent of the finite points' box (for a message).
    spread: f64,
}

fn locate(src: &impl ParticleSource, needs_spacing: bool) -> Result<Located, ParticleError> {
    let file = src.path().to_path_buf();
    let flat = src.points()?;
    let pts: &[[f64; 3]] = bytemuck::try_cast_slice(&flat).map_err(|_| ParticleError::Other {
        file: file.clone(),
        message: format!("{} point coordinates do not make whole points", flat.len()),
    })?;
    let n = pts.len();
    if n == 0 {
        return Err(ParticleError::NoPoints { file });
    }
    let kept: Vec<bool> = pts
        .par_iter()
        .map(|p| p.iter().all(|v| v.is_finite()))
        .collect();
    let count = kept.iter().filter(|&&k| k).count();
    if count == 0 {
        return Err(ParticleError::NoFinitePoints { file, count: n });
    }
    let far = far_outliers(pts);
    let outliers = far
        .first()
        .map(|&i| far_outlier_warning(pts[i], i, far.len(), count));
    let spacing = if needs_spacing {
        spacing_without(pts, &far)
    } else {
        None
    };
    let positions: Vec<[f32; 3]> = pts
        .iter()
        .zip(&kept)
        .filter(|(_, &k)| k)
        .map(|(x, _)| [x[0] as f32, x[1] as f32, x[2] as f32])
        .collect();
    let (lo, hi) = bounds(&positions);
    let spread = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    Ok(Located {
        kept,
        count,
        positions,
        outliers,
        spacing,
        spread,
    })
}

/// `at(i)` of every kept point in single precision, each checked by `check(i, value)`.
fn kept_values(
    kept: &[bool],
    count: usize,
    at: impl Fn(usize) -> f64,
    check: impl Fn(usize, f64) -> Result<(), ParticleError>,
) -> Result<Vec<f32>, ParticleError> {
    let mut out = Vec::with_capacity(count);
    for i in (0..kept.len()).filter(|&i| kept[i]) {
        let v = at(i);
        check(i, v)?;
        out.push(v as f32);
    }
    Ok(out)
}

/// How each particle's volume is found.
enum Volume<'a> {
    Ratio(Cow<'a, DataArray>, Cow<'a, DataArray>),
    Array(Cow<'a, DataArray>),
    Uniform(f64),
}

impl Volume<'_> {
    fn at(&self, i: usize) -> f64 {
        match self {
            Volume::Ratio(m, d) => m.values[i] / d.values[i],
            Volume::Array(v) => v.values[i],
            Volume::Uniform(v) => *v,
        }
    }

    /// Where particle `i`'s volume comes from, with the values read (for errors).
    fn describe(&self, i: usize) -> String {
        match self {
            Volume::Ratio(m, d) => {
                format!("{} {} / {} {}", m.name, m.values[i], d.name, d.values[i])
            }
            Volume::Array(v) => format!("array '{}'", v.name),
            Volume::Uniform(_) => "uniform volume".into(),
        }
    }
}

/// What the volume rule of `spec` needs: (mass and density, volume array) present.
fn volume_arrays(src: &impl ParticleSource) -> (Option<(String, String)>, Option<String>) {
    let md = first_of(src, &MASS_NAMES).zip(first_of(src, &DENSITY_NAMES));
    (md, first_of(src, &VOLUME_NAMES))
}

fn needs_spacing(src: &impl ParticleSource, spec: &ParticleSpec) -> bool {
    let radius =
        matches!(spec.radius, RadiusSource::Auto) && src.field_scalar("support_radius").is_none();
    let volume = match &spec.volume {
        VolumeSource::Uniform => true,
        VolumeSource::Auto => matches!(volume_arrays(src), (None, None)),
        _ => false,
    };
    radius || volume
}

/// The volume rule of `spec`, with a note where it was chosen automatically.
fn volume_rule<'a>(
    src: &'a impl ParticleSource,
    spec: &ParticleSpec,
    spacing: Option<f64>,
    notes: &mut Vec<String>,
) -> Result<Volume<'a>, ParticleError> {
    let uniform = || {
        let s = spacing.unwrap_or(1.0);
        Volume::Uniform(s * s * s)
    };
    Ok(match &spec.volume {
        VolumeSource::MassDensity { mass, density } => {
            Volume::Ratio(array(src, mass)?, array(src, density)?)
        }
        VolumeSource::Array(name) => Volume::Array(array(src, name)?),
        VolumeSource::Uniform => uniform(),
        VolumeSource::Auto => match volume_arrays(src) {
            (Some((m, d)), _) => {
                notes.push(format!("particle volume = {m} / {d}"));
                Volume::Ratio(array(src, &m)?, array(src, &d)?)
            }
            (None, Some(v)) => {
                notes.push(format!("particle volume from array '{v}'"));
                Volume::Array(array(src, &v)?)
            }
            (None, None) => {
                notes.push("uniform particle volume (no mass/density or volume arrays)".into());
                uniform()
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
    /// Builds particles from a data set (see [`Particles::from_source`]).
    pub fn from_dataset(ds: &Dataset, spec: &ParticleSpec) -> Result<Particles, ParticleError> {
        Particles::from_source(ds, spec)
    }

    /// Builds particles from `src`, one array at a time: the points, the rendered values,
    /// the radii, the volumes and masses, each decoded (from a [`LazyDataset`]), turned
    /// into single precision and dropped before the next. Points with a NaN/infinite
    /// coordinate are skipped and counted in `skipped_nonfinite`; bad radii or volumes of
    /// kept particles are errors (the first particle of the first array at fault).
    pub fn from_source(
        src: &impl ParticleSource,
        spec: &ParticleSpec,
    ) -> Result<Particles, ParticleError> {
        let file = src.path().to_path_buf();
        let at = locate(src, needs_spacing(src, spec))?;
        let (kept, count) = (&at.kept, at.count);
        let mut notes = Vec::new();
        let values = match &spec.quantity {
            Some(q) => {
                let a = array(src, &q.array)?;
                let v = component_at(&a, q, &file)?;
                kept_values(kept, count, v, |i, a| check_value(&file, q, i, a))?
            }
            None => vec![1.0; count],
        };
        let radii = Self::radii(src, spec, &at, &mut notes)?;
        let volume = volume_rule(src, spec, at.spacing, &mut notes)?;
        let volumes = kept_values(
            kept,
            count,
            |i| volume.at(i),
            |i, v| {
                if !(v.is_finite() && v > 0.0) {
                    return Err(ParticleError::BadVolume {
                        file: file.clone(),
                        index: i,
                        value: v,
                        from: volume.describe(i),
                    });
                }
                single_precision(&file, i, true, &[("volume", v)])
            },
        )?;
        let mass_check = |i, m| single_precision(&file, i, false, &[("mass", m)]);
        let mass = spec.mass.clone().or_else(|| first_of(src, &MASS_NAMES));
        let masses = match (mass, &volume) {
            // The mass array the volumes came from: not decoded again.
            (Some(name), Volume::Ratio(m, _)) if m.name == name => {
                kept_values(kept, count, per_value(m, 1.0), mass_check)?
            }
            (Some(name), _) => {
                drop(volume);
                let m = array(src, &name)?;
                kept_values(kept, count, per_value(&m, 1.0), mass_check)?
            }
            (None, _) => match first_of(src, &DENSITY_NAMES) {
                Some(d) => {
                    let d = array(src, &d)?;
                    kept_values(kept, count, |i| volume.at(i) * d.values[i], mass_check)?
                }
                None => kept_values(kept, count, |i| volume.at(i), mass_check)?,
            },
        };
        notes.extend(at.outliers.clone());
        Ok(Particles {
            notes,
            skipped_nonfinite: kept.len() - count,
            positions: at.positions,
            radii,
            volumes,
            masses,
            values,
        })
    }

    /// Each kept particle's support radius under `spec`, with a note where it was chosen
    /// for the user.
    fn radii(
        src: &impl ParticleSource,
        spec: &ParticleSpec,
        at: &Located,
        notes: &mut Vec<String>,
    ) -> Result<Vec<f32>, ParticleError> {
        let file = src.path().to_path_buf();
        let check = |i: usize, h: f64| {
            if !(h.is_finite() && h > 0.0) {
                return Err(ParticleError::BadRadius {
                    file: file.clone(),
                    index: i,
                    value: h,
                });
            }
            single_precision(&file, i, true, &[("support radius", h)])
        };
        let h = match &spec.radius {
            RadiusSource::Array { name, scale } => {
                let a = array(src, name)?;
                if a.num_components != 1 {
                    return Err(ParticleError::Other {
                        file,
                        message: format!("radius array '{name}' must have 1 component"),
                    });
                }
                return kept_values(&at.kept, at.count, per_value(&a, *scale), check);
            }
            RadiusSource::Constant(h) => *h,
            RadiusSource::Auto => match src.field_scalar("support_radius") {
                Some(h) => {
                    notes.push(format!(
                        "support radius {h} from the file's field data 'support_radius'"
                    ));
                    h
                }
                None => {
                    let h = at
                        .spacing
                        .map(|s| 2.0 * s)
                        .ok_or_else(|| ParticleError::Other {
                            file: file.clone(),
                            message: format!(
                                "cannot suggest a support radius: {} finite points with no \
                             measurable spacing between neighbours, spread over {:.3e} world \
                             units: give --support-radius",
                                at.count, at.spread
                            ),
                        })?;
                    notes.push(format!(
                        "no support radius given: using {h:.6} (2 x mean particle spacing); set --support-radius or --radius-array"
                    ));
                    h
                }
            },
        };
        kept_values(&at.kept, at.count, |_| h, check)
    }

    /// The values of quantity `q` of `src` at the particles [`Particles::from_source`]
    /// keeps (the points with finite coordinates), in their order: a second attribute beside
    /// the rendered one (e.g. the field of an iso-surface), checked as the rendered one is.
    pub fn values_of(src: &impl ParticleSource, q: &Quantity) -> Result<Vec<f32>, ParticleError> {
        let kept: Vec<bool> = src
            .points()?
            .chunks_exact(3)
            .map(|p| p.iter().all(|v| v.is_finite()))
            .collect();
        let count = kept.iter().filter(|&&k| k).count();
        let a = array(src, &q.array)?;
        let file = src.path();
        let v = component_at(&a, q, file)?;
        kept_values(&kept, count, v, |i, a| check_value(file, q, i, a))
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
    #[test]
    fn a_smoothing_length_array_is_suggested_by_name_and_shape() {
        assert_eq!(suggest_radius_array([("rho", 1), ("h", 1)]), Some("h"));
        assert_eq!(
            suggest_radius_array([("SmoothingLengths", 1)]),
            Some("SmoothingLengths")
        );
        assert_eq!(suggest_radius_array([("h", 3), ("mass", 1)]), None);
        assert_eq!(suggest_radius_array([("height", 1)]), None);
    }

    #[test]
    fn quantities_take_the_cli_and_paraview_component_names() {
        let q = |s: &str| s.parse::<Quantity>().unwrap();
        let c = |s: &str| q(s).component;
        assert_eq!(c("v:mag"), Component::Magnitude);
        assert_eq!(c("v:Magnitude"), Component::Magnitude);
        assert_eq!(c("v:2"), Component::Index(2));
        assert_eq!(
            [c("v:X"), c("v:y"), c("v:Z")],
            [0, 1, 2].map(Component::Index)
        );
        assert_eq!(c("v"), Component::Auto);
        assert_eq!(q("a:b:Y").array, "a:b");
        assert_eq!(q("v:w").array, "v:w"); // not a selector: part of the name
    }

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
