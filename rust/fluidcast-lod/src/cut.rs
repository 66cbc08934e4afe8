//! The per-view cut through the hierarchy (Fraedrich et al. 2010, Sec. 4.2): top-down, a node
//! is taken once its level's cells are no larger than the tolerance in pixels at the node's
//! nearest depth; otherwise its children are visited.

use crate::{LodError, LodHierarchy};
use fluidcast_sph::Particles;
use fluidcast_view::ViewFrame;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// The particles one view renders, and how many were taken from each level.
#[derive(Debug, Clone)]
pub struct LodCut {
    /// The chosen nodes as particles, in the hierarchy's (Morton) order: when nothing was
    /// merged ([`LodCut::is_full_detail`]), [`LodHierarchy::full_detail`] itself.
    pub particles: Particles,
    /// Particles taken from each level (index 0: full detail), counted at the level whose
    /// merge made them (a node carried up unchanged counts where it was made).
    pub per_level: Vec<usize>,
}

impl LodCut {
    /// Every particle at full detail: the cut is [`LodHierarchy::full_detail`], particle for
    /// particle, so what was computed for it (surface flags) applies.
    pub fn is_full_detail(&self) -> bool {
        self.per_level.iter().skip(1).all(|&k| k == 0)
    }
}

impl LodHierarchy {
    /// The cut for `frame` at `tolerance`: the largest cell edge, in pixels at a node's
    /// nearest depth, a level may have where it is taken (0: full detail wherever the view
    /// reaches).
    /// Nodes wholly outside the view frustum are taken at the level where they are met: no
    /// ray reaches them, and they keep their neighbours' surroundings.
    pub fn cut(&self, frame: &ViewFrame, tolerance: f64) -> Result<LodCut, LodError> {
        if !tolerance.is_finite() || tolerance < 0.0 {
            return Err(LodError::BadTolerance(tolerance));
        }
        let top = self.levels.len() - 1;
        let chosen: Vec<Vec<(u8, u32)>> = (0..self.levels[top].len())
            .into_par_iter()
            .with_min_len(64)
            .map(|i| self.descend(frame, tolerance, top, i))
            .collect();
        let mut per_level = vec![0; self.levels.len()];
        let n: usize = chosen.iter().map(Vec::len).sum();
        let mut out = Particles::default();
        out.positions.reserve(n);
        out.radii.reserve(n);
        out.volumes.reserve(n);
        out.masses.reserve(n);
        out.values.reserve(n);
        for &(level, i) in chosen.iter().flatten() {
            let (l, j) = self.levels[usize::from(level)].origin(usize::from(level), i as usize);
            let p = &self.levels[l].particles;
            per_level[l] += 1;
            out.positions.push(p.positions[j]);
            out.radii.push(p.radii[j]);
            out.volumes.push(p.volumes[j]);
            out.masses.push(p.masses[j]);
            out.values.push(p.values[j]);
        }
        Ok(LodCut {
            particles: out,
            per_level,
        })
    }

    /// The nodes under node `i` of `level` that the cut takes, left to right.
    fn descend(&self, frame: &ViewFrame, tolerance: f64, level: usize, i: usize) -> Vec<(u8, u32)> {
        let mut out = Vec::new();
        let mut stack = vec![(level, i)];
        while let Some((l, i)) = stack.pop() {
            let node = &self.levels[l];
            let (from, _) = node.origin(l, i);
            // A full-detail particle carried up: every level below holds the same.
            if from == 0 || self.coarse_enough(frame, tolerance, l, i) {
                out.push((l as u8, i as u32));
                continue;
            }
            let [a, b] = node.children[i];
            stack.extend((a..b).rev().map(|c| (l - 1, c as usize)));
        }
        out
    }

    /// Node `i` of level `l` may stand for its particles: its cells are at most `tolerance`
    /// pixels at its nearest depth, or it is outside the view.
    fn coarse_enough(&self, frame: &ViewFrame, tolerance: f64, l: usize, i: usize) -> bool {
        let n = crate::build::node_data(&self.levels, l, i);
        let x = Vec3::from(n.position).as_dvec3();
        let h = f64::from(n.radius);
        let v = frame.to_view(x);
        if outside_frustum(frame, v, h) {
            return true;
        }
        // The node's support covers its children's: its nearest point is nearest of all.
        let near = v.z - h;
        if frame.parallel.is_none() && near <= 0.0 {
            return false;
        }
        self.cell_size(l) <= tolerance * frame.pixel_size_at(near)
    }
}

/// A sphere at view-space `v` of radius `h` lies wholly outside the view frustum (beyond one
/// of its side planes, or behind the eye).
pub(crate) fn outside_frustum(frame: &ViewFrame, v: DVec3, h: f64) -> bool {
    match frame.parallel {
        Some(s) => v.x.abs() - s * frame.aspect > h || v.y.abs() - s > h,
        None => {
            let beyond = |lateral: f64, slope: f64| {
                (lateral.abs() - v.z * slope) / (1.0 + slope * slope).sqrt() > h
            };
            v.z < -h || beyond(v.x, frame.tan_half * frame.aspect) || beyond(v.y, frame.tan_half)
        }
    }
}
