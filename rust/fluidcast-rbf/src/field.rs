//! The attribute-aware RBF field (Morrical et al. 2023, Sec. 3.1, Eq. 1–5).

use rayon::prelude::*;

use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::TransferFunction;

use crate::bvh::{holds, ClusterBvh};
use crate::RbfError;

/// The truncated Gaussian's support in standard deviations (the paper's "three standard
/// deviations": σ = r/3).
pub const SIGMAS: f64 = 3.0;

/// Particles per cluster by default: the paper's memory study finds 8–16 particles per leaf
/// cut the tree's memory 8–16× for little change in render time.
pub const DEFAULT_LEAF_SIZE: usize = 8;

/// One particle's RBF at distance `d` from its centre (world units): `w·exp(−½(3d/r)²)` within
/// radius `r`, 0 beyond (Eq. 1–2).
#[inline]
pub fn rbf(d: f64, r: f64, w: f64) -> f64 {
    if d <= r && r > 0.0 {
        let u = SIGMAS * d / r;
        w * (-0.5 * u * u).exp()
    } else {
        0.0
    }
}

/// What colours the field (Sec. 3.1.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Colouring {
    /// Post-classification: the attributes blend, `Θ = Σ φ_i s_i / Φ`, and Θ is colour
    /// mapped (continuous attributes such as velocity blend gradually).
    #[default]
    Post,
    /// Pre-classification: each particle's attribute is colour mapped first, `Θ = Σ φ_i
    /// colour(s_i) / Φ` (categorical attributes keep their classes' colours, mixing only
    /// where particles of different classes overlap).
    Pre,
    /// No attribute: every particle has weight 1 and the density Φ itself is colour mapped.
    Density,
}

impl Colouring {
    /// Every colouring, in the order of their codes on the GPU (`RBF_*` in WGSL).
    pub const ALL: [Colouring; 3] = [Colouring::Post, Colouring::Pre, Colouring::Density];

    /// The name the CLI and the mapper take (post, pre, density).
    pub fn name(self) -> &'static str {
        match self {
            Colouring::Post => "post",
            Colouring::Pre => "pre",
            Colouring::Density => "density",
        }
    }
}

/// A piecewise-linear map from an attribute's position on the colour map's range (0..1,
/// clamped) to a factor: the paper's radius map.
#[derive(Debug, Clone, PartialEq)]
pub struct AttributeMap {
    /// (position in [0, 1], factor >= 0), sorted by position.
    points: Vec<(f64, f64)>,
}

impl AttributeMap {
    /// The same factor everywhere.
    pub fn constant(v: f64) -> AttributeMap {
        AttributeMap {
            points: vec![(0.0, v), (1.0, v)],
        }
    }

    /// A map through the given (position, factor) points; positions in [0, 1], factors
    /// finite and >= 0.
    pub fn new(mut points: Vec<(f64, f64)>) -> Result<AttributeMap, RbfError> {
        let bad = |p: &(f64, f64)| !((0.0..=1.0).contains(&p.0) && p.1.is_finite() && p.1 >= 0.0);
        if points.is_empty() || points.iter().any(bad) {
            return Err(RbfError::Map(format!("{points:?}")));
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(AttributeMap { points })
    }

    /// Parses `t,f,t,f,…` (pairs of position and factor).
    pub fn parse(s: &str) -> Result<AttributeMap, RbfError> {
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| RbfError::Map(s.to_string()))?;
        if !v.len().is_multiple_of(2) {
            return Err(RbfError::Map(s.to_string()));
        }
        AttributeMap::new(v.chunks_exact(2).map(|c| (c[0], c[1])).collect())
    }

    /// The factor at position `t` (clamped to the first and last points).
    pub fn eval(&self, t: f64) -> f64 {
        let p = &self.points;
        let k = p.partition_point(|q| q.0 < t);
        // Between a (left of t) and b (at or right of t), so b.0 > a.0.
        match (k.checked_sub(1).and_then(|i| p.get(i)), p.get(k)) {
            (Some(a), Some(b)) => a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0),
            (_, Some(b)) => b.1,
            (Some(a), None) => a.1,
            (None, None) => 0.0,
        }
    }
}

/// The radial function each particle contributes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Profile {
    /// The paper's truncated Gaussian, `w·exp(−½(3d/r)²)` ([`rbf`]).
    #[default]
    Gaussian,
    /// An SPH field ([`RbfField::from_sph`]): `w·W(d, r)` with the SPH kernel, `r` the
    /// support radius, so that the sums are the SPH renderers' (Σ V A W and Σ V W, or Σ m W)
    /// and a field sampled this way is theirs; the transfer function classifies the field's
    /// value ([`FieldKind`]) as they do.
    Sph(Kernel, FieldKind),
}

impl Profile {
    /// A particle's contribution at distance `d` from its centre (radius `r`, weight `w`).
    #[inline]
    pub fn eval(self, d: f64, r: f64, w: f64) -> f64 {
        match self {
            Profile::Gaussian => rbf(d, r, w),
            Profile::Sph(k, _) => w * k.eval(d, r),
        }
    }
}

/// How particles become an RBF field.
#[derive(Debug, Clone)]
pub struct RbfOptions {
    /// The radius (world units) of a particle whose radius-map factor is 1; `None`: each
    /// particle's own support radius.
    pub radius: Option<f64>,
    /// Per-particle radius factor from the attribute (the paper's radius map); 0 hides a
    /// particle.
    pub radius_map: AttributeMap,
    /// How attributes colour the field.
    pub colouring: Colouring,
    /// Particles per BVH leaf (1..=64).
    pub leaf_size: usize,
}

impl Default for RbfOptions {
    fn default() -> Self {
        RbfOptions {
            radius: None,
            radius_map: AttributeMap::constant(1.0),
            colouring: Colouring::Post,
            leaf_size: DEFAULT_LEAF_SIZE,
        }
    }
}

/// The two sums of one field evaluation (Eq. 3 and the numerator of Eq. 5).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RbfSample {
    /// The density `Φ(x) = Σ φ_i(x)`.
    pub density: f64,
    /// `Σ φ_i(x) θ_i`: with post-classification the attribute in channel 0, with
    /// pre-classification the linear RGB colour.
    pub weighted: [f64; 3],
    /// Particles whose sphere holds the point.
    pub neighbours: u32,
}

impl RbfSample {
    /// The attribute field `Θ(x)` (Eq. 5); `None` where no particle has weight.
    pub fn attribute(&self) -> Option<[f64; 3]> {
        (self.density > 0.0).then(|| self.weighted.map(|w| w / self.density))
    }
}

/// Particles as an attribute-aware RBF field, with the BVH that finds those in range.
///
/// Per particle (slot order): the weight `w(s)` from the density map, the transfer
/// function's opacity at the attribute (an opacity curve edited in ParaView is the density
/// map), and `θ̂`, the attribute (post-classification) or its colour (pre). World units
/// throughout.
#[derive(Debug, Clone)]
pub struct RbfField {
    bvh: ClusterBvh,
    weights: Vec<f32>,
    thetas: Vec<[f32; 3]>,
    colouring: Colouring,
    profile: Profile,
    /// Per caller index: the radius at factor 1 and the attribute's map position.
    base_radii: Vec<f32>,
    positions: Vec<f32>,
}

impl RbfField {
    /// The field of `particles` (their `values` are the attribute; ignored for
    /// [`Colouring::Density`]), with `tf`'s opacity as the density map and its colours for
    /// pre-classification.
    pub fn build(
        particles: &Particles,
        tf: &TransferFunction,
        opts: &RbfOptions,
    ) -> Result<RbfField, RbfError> {
        let base_radii: Vec<f32> = match opts.radius {
            Some(r) if r.is_finite() && r > 0.0 => vec![r as f32; particles.len()],
            Some(r) => return Err(RbfError::GlobalRadius(r)),
            None => particles.radii.clone(),
        };
        let density = opts.colouring == Colouring::Density;
        let positions: Vec<f32> = if density {
            vec![0.0; particles.len()]
        } else {
            particles
                .values
                .par_iter()
                .map(|&s| tf.normalised(f64::from(s)).map_or(f32::NAN, |t| t as f32))
                .collect()
        };
        if let Some(index) = positions.iter().position(|t| t.is_nan()) {
            return Err(RbfError::Attribute { index });
        }
        let radii = radii_of(&base_radii, &positions, &opts.radius_map, density);
        let bvh = ClusterBvh::build(&particles.positions, &radii, opts.leaf_size)?;
        let (weights, thetas) = bvh
            .order()
            .par_iter()
            .map(|&i| {
                let i = i as usize;
                if density {
                    return (1.0, [0.0; 3]);
                }
                let t = f64::from(positions[i]);
                let (rgb, opacity) = tf.eval_normalised(t);
                let theta = match opts.colouring {
                    Colouring::Pre => rgb.map(|c| c as f32),
                    _ => [particles.values[i], 0.0, 0.0],
                };
                (opacity as f32, theta)
            })
            .unzip();
        Ok(RbfField {
            bvh,
            weights,
            thetas,
            colouring: opts.colouring,
            profile: Profile::Gaussian,
            base_radii,
            positions,
        })
    }

    /// The SPH field `field` of `particles` with `kernel`, as particles the BVH finds in
    /// range: weight V and value A (Σ V A W, Σ V W), or mass (Σ m W) for a density field,
    /// out to each support radius. What the stochastic renderer marches for an SPH field
    /// (lit with shadows), with the BVH over the supports.
    pub fn from_sph(
        particles: &Particles,
        kernel: Kernel,
        field: FieldKind,
        leaf_size: usize,
    ) -> Result<RbfField, RbfError> {
        if let Some(index) = particles.values.iter().position(|v| v.is_nan()) {
            return Err(RbfError::Attribute { index });
        }
        let bvh = ClusterBvh::build(&particles.positions, &particles.radii, leaf_size)?;
        let (weights, thetas) = bvh
            .order()
            .par_iter()
            .map(|&i| {
                let i = i as usize;
                match field {
                    FieldKind::Density => (particles.masses[i], [0.0; 3]),
                    _ => (particles.volumes[i], [particles.values[i], 0.0, 0.0]),
                }
            })
            .unzip();
        Ok(RbfField {
            bvh,
            weights,
            thetas,
            colouring: Colouring::Post,
            profile: Profile::Sph(kernel, field),
            base_radii: particles.radii.clone(),
            positions: vec![0.0; particles.len()],
        })
    }

    /// The radial function of every particle.
    pub fn profile(&self) -> Profile {
        self.profile
    }

    /// A new radius map: the radii change and the tree is refit, not rebuilt.
    pub fn set_radius_map(&mut self, map: &AttributeMap) -> Result<(), RbfError> {
        let density = self.colouring == Colouring::Density;
        let radii = radii_of(&self.base_radii, &self.positions, map, density);
        self.bvh.refit(&radii)
    }

    /// The field's tree of particle clusters.
    pub fn bvh(&self) -> &ClusterBvh {
        &self.bvh
    }

    /// How the field's attributes are coloured.
    pub fn colouring(&self) -> Colouring {
        self.colouring
    }

    /// Weight `w` and `θ̂` of the particle in `slot`.
    #[inline]
    pub fn weight_theta(&self, slot: u32) -> (f32, [f32; 3]) {
        (self.weights[slot as usize], self.thetas[slot as usize])
    }

    /// The median radius of the visible particles (world units; 0 when none is visible).
    pub fn median_radius(&self) -> f64 {
        let mut r: Vec<f32> = (0..self.bvh.len() as u32)
            .map(|s| self.bvh.sphere(s)[3])
            .filter(|&r| r > 0.0)
            .collect();
        if r.is_empty() {
            return 0.0;
        }
        let k = r.len() / 2;
        let (_, m, _) = r.select_nth_unstable_by(k, f32::total_cmp);
        f64::from(*m)
    }

    /// Bytes held: the BVH and the per-particle weights, attributes and radii.
    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes() + self.bvh.len() * (4 + 12 + 4 + 4)
    }

    /// The field's sums at world point `x`, over the particles the BVH finds in range.
    pub fn sample(&self, x: [f64; 3]) -> RbfSample {
        let mut s = RbfSample::default();
        self.bvh
            .for_each_within(x, |slot| self.add(&mut s, slot, x));
        s
    }

    /// Adds the particle in `slot` to the sums at `x` (whose distance from it the caller has
    /// found within range).
    #[inline]
    pub fn add(&self, s: &mut RbfSample, slot: u32, x: [f64; 3]) {
        let c = self.bvh.sphere(slot);
        let d2: f64 = (0..3).map(|a| (x[a] - f64::from(c[a])).powi(2)).sum();
        let (w, theta) = self.weight_theta(slot);
        let phi = self.profile.eval(d2.sqrt(), f64::from(c[3]), f64::from(w));
        s.density += phi;
        for (w, th) in s.weighted.iter_mut().zip(theta) {
            *w += phi * f64::from(th);
        }
        s.neighbours += u32::from(holds(c, x));
    }
}

/// Per particle: the radius at factor 1 times the radius map at its attribute (1 for a
/// density field).
fn radii_of(base: &[f32], positions: &[f32], map: &AttributeMap, density: bool) -> Vec<f32> {
    base.par_iter()
        .zip(positions.par_iter())
        .map(|(&r, &t)| {
            let f = if density { 1.0 } else { map.eval(f64::from(t)) };
            (f64::from(r) * f) as f32
        })
        .collect()
}
