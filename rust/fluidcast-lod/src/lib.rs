//! Particle level of detail (Fraedrich et al. 2010, Sec. 4.1–4.2): a hierarchy in which the
//! particles of each block of 2³ cells are merged into one larger particle, level by level,
//! and, per view, a cut through it that takes each part of the scene at the coarsest level
//! whose cells are no larger than a stated number of pixels at that depth.
//!
//! Stage: particles → **level of detail** → acceleration structure → … The cut is itself a
//! [`Particles`] set, so every renderer takes it unchanged.
//!
//! What a merge keeps (for the fields of `fluidcast_sph::FieldKind`):
//! - volume `V = Σ V_i` and mass `m = Σ m_i`: the Shepard denominator `Σ V W` and the density
//!   `Σ m W` keep their integrals;
//! - the attribute's volume-weighted mean `A = Σ V_i A_i / V`: `Σ V A` (the integral of the
//!   plain SPH sum) is kept, and a constant attribute stays constant;
//! - position: the volume-weighted centre;
//! - support radius: the smallest that covers every child's support, `max |x_i − x| + H_i`.
//!
//! Paper rules kept: level 0's cells are the simulation's resolution (here the median
//! particle size `V^(1/3)`); at each level only particles smaller than the next level's cell
//! are merged, larger ones (spray of another phase, coarse particles) are copied up
//! unchanged. Left out: the paper's enlargement of a lone small particle to the cell size
//! (it would change `Σ V A`); a lone particle is copied.
//!
//! Beyond the paper: a block at the boundary of the particles (one of its six face
//! neighbours at that level is empty) is not merged, its particles are copied up. A
//! normalised field ends where the last support ends and its value does not fade there, so
//! moving that edge is what a merge shows most. On a 14.5M-particle frame at 1024² this took
//! the error of a 2-pixel cut from RMSE 0.011 to 0.0017 (a larger radius,
//! `(Σ H_i³)^(1/3)`, gave 0.017 without the rule).
#![warn(missing_docs)]

mod build;
mod cut;

pub use build::{LodNode, MAX_LEVELS};
pub use cut::LodCut;

use fluidcast_sph::Particles;

/// Why a hierarchy or a cut could not be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LodError {
    /// No particles.
    #[error("no particles to build a level-of-detail hierarchy from")]
    Empty,
    /// A tolerance that is negative or not finite (pixels).
    #[error("level-of-detail tolerance {0} is not a finite number of pixels >= 0")]
    BadTolerance(f64),
    /// A particle with a non-finite position, volume, radius, mass or value.
    #[error("particle {index}: {what} is not finite ({value}); the hierarchy needs finite positions, volumes, radii, masses and values")]
    NotFinite {
        /// The particle.
        index: usize,
        /// Which of its quantities.
        what: &'static str,
        /// Its value.
        value: f64,
    },
}

/// The particle hierarchy of one data set (one time step); view-independent, so built once
/// and cut for every camera.
#[derive(Debug, Clone)]
pub struct LodHierarchy {
    /// Level 0 is the input particles (sorted along a Morton curve of their cells); each
    /// level above merges the interior blocks of 2³ cells of the one below.
    levels: Vec<Level>,
    /// Each level's cell edge, world units (level 0: the median particle size; doubling per
    /// cell level, and a level that would merge nothing is skipped).
    cells: Vec<f64>,
}

/// One level's nodes. A node is either merged (its particle in `particles`) or carried up
/// unchanged from a level below (its particle is that level's); above level 0 each has
/// children `[start, end)` in the level below.
#[derive(Debug, Clone, Default)]
struct Level {
    /// Level 0: every particle. Above: the merged nodes' particles only.
    particles: Particles,
    children: Vec<[u32; 2]>,
    /// Where each node's particle is (level, index); empty at level 0 (its own).
    origin_level: Vec<u8>,
    origin_index: Vec<u32>,
}

impl Level {
    fn full_detail(particles: Particles) -> Level {
        Level {
            particles,
            ..Level::default()
        }
    }

    /// Number of nodes.
    fn len(&self) -> usize {
        if self.origin_index.is_empty() {
            self.particles.len()
        } else {
            self.origin_index.len()
        }
    }

    /// Where node `i` of this level (`level`) keeps its particle: (level, index).
    fn origin(&self, level: usize, i: usize) -> (usize, usize) {
        if self.origin_index.is_empty() {
            (level, i)
        } else {
            (
                usize::from(self.origin_level[i]),
                self.origin_index[i] as usize,
            )
        }
    }

    /// Puts the nodes in `order` (a permutation).
    fn reorder(&mut self, order: &[usize]) {
        if self.origin_index.is_empty() {
            self.particles = self.particles.select(order);
            return;
        }
        self.children = order.iter().map(|&i| self.children[i]).collect();
        self.origin_level = order.iter().map(|&i| self.origin_level[i]).collect();
        self.origin_index = order.iter().map(|&i| self.origin_index[i]).collect();
    }

    /// Appends a merged node of particle `n` over `children` of the level below; `at` is
    /// this level's index.
    fn push_merged(&mut self, n: LodNode, children: std::ops::Range<usize>, at: usize) {
        let q = &mut self.particles;
        self.origin_level.push(at as u8);
        self.origin_index.push(q.len() as u32);
        q.positions.push(n.position);
        q.radii.push(n.radius);
        q.volumes.push(n.volume);
        q.masses.push(n.mass);
        q.values.push(n.value);
        self.children
            .push([children.start as u32, children.end as u32]);
    }

    /// Appends node `child` of the level below, carried up (its particle stays where it is).
    fn push_carried(&mut self, (level, index): (usize, usize), child: usize) {
        self.origin_level.push(level as u8);
        self.origin_index.push(index as u32);
        self.children.push([child as u32, child as u32 + 1]);
    }
}

impl LodHierarchy {
    /// Number of levels, level 0 (full detail) included.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Nodes at `level`; 0 when there is no such level.
    pub fn level_len(&self, level: usize) -> usize {
        self.levels.get(level).map_or(0, Level::len)
    }

    /// Cell edge of `level` (world units); NaN above the top.
    pub fn cell_size(&self, level: usize) -> f64 {
        self.cells.get(level).copied().unwrap_or(f64::NAN)
    }

    /// Node `i` of `level`'s particle; `None` when there is no such node.
    pub fn node(&self, level: usize, i: usize) -> Option<LodNode> {
        (i < self.level_len(level)).then(|| build::node_data(&self.levels, level, i))
    }

    /// The children of node `i` of `level` in the level below; `None` at level 0 or for a
    /// node that does not exist.
    pub fn children(&self, level: usize, i: usize) -> Option<std::ops::Range<usize>> {
        let [a, b] = *self.levels.get(level)?.children.get(i)?;
        Some(a as usize..b as usize)
    }

    /// The level whose merge made node `i` of `level`'s particle (0: a full-detail particle;
    /// below `level`: carried up unchanged); `None` when there is no such node.
    pub fn made_at(&self, level: usize, i: usize) -> Option<usize> {
        (i < self.level_len(level)).then(|| self.levels[level].origin(level, i).0)
    }

    /// Full detail: the input particles in the hierarchy's order.
    pub fn full_detail(&self) -> &Particles {
        &self.levels[0].particles
    }

    /// Bytes the hierarchy holds (every level's particles and links).
    pub fn memory_bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.particles.len() * 7 * 4 + l.children.len() * 8 + l.origin_index.len() * 5)
            .sum()
    }
}
