//! The pairs stage (the GPU's grid.wgsl): each particle's footprint in the view's grid
//! (bundle rectangle and cell depth range), found once, the particle–cell pairs counted per
//! bundle in parallel chunks, and their keys written bundle by bundle.

use rayon::prelude::*;

use crate::{covering_rect, screen_extent, stored_centres, SampleDepths, ViewParticle};
use fluidcast_view::ViewFrame;

/// Chunks of particles the grid counts and fills in parallel: enough for every thread,
/// few enough that their per-bundle counts and slices (20 bytes a bundle each) stay near
/// 80 MiB.
pub(crate) fn chunk_count(particles: usize, bundles: usize) -> usize {
    let want = rayon::current_num_threads() * 4;
    let fit = (4 << 20) / bundles.max(1);
    want.min(fit).clamp(1, particles.max(1))
}

/// What a particle's footprint in a view's grid depends on: the view, its depth samples and
/// their range, bundle size D_xy, D_z and bundles per row.
pub(crate) struct Footprint<'a> {
    pub(crate) frame: &'a ViewFrame,
    pub(crate) depths: &'a SampleDepths,
    pub(crate) range: (f64, f64),
    pub(crate) bundle: u32,
    pub(crate) dz: usize,
    pub(crate) bundles_x: u32,
}

/// A particle's footprint in the grid: the bundle columns `b[0]..=b[1]` and rows
/// `b[2]..=b[3]`, and cells `z[0]..=z[1]` along depth; none (`z[0] > z[1]`) where it reaches
/// no pixel or depth sample. 16 bytes a particle, found once and read by both passes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Foot {
    b: [u16; 4],
    z: [u32; 2],
}

impl Foot {
    const NONE: Foot = Foot {
        b: [0; 4],
        z: [1, 0],
    };

    fn is_some(&self) -> bool {
        self.z[0] <= self.z[1]
    }
}

impl Footprint<'_> {
    /// Particle `p`'s stored pixel rectangle ([`crate::stored_rect`]) and its footprint, from
    /// one projection of its support.
    #[inline]
    pub(crate) fn place(&self, p: &ViewParticle) -> ([u16; 4], Foot) {
        let (near, far) = self.range;
        let extent = screen_extent(self.frame, p, near, far);
        (stored_centres(self.frame, extent), self.foot(p, extent))
    }

    /// The bundle rectangle and cell depth range (inclusive) particle `p` reaches, its
    /// [`screen_extent`] being `extent`.
    #[inline]
    fn foot(&self, p: &ViewParticle, extent: Option<[f64; 4]>) -> Foot {
        let Some(r) = extent.and_then(|e| covering_rect(self.frame, e)) else {
            return Foot::NONE;
        };
        let k = self.depths.indices_within(p.c[2] - p.h(), p.c[2] + p.h());
        if k.is_empty() {
            return Foot::NONE;
        }
        // Bundle indices fit 16 bits: the grid refuses frames wider or taller than that.
        let (d, dz) = (self.bundle, self.dz);
        let b = |v: u32| (v / d) as u16;
        Foot {
            b: [b(r[0]), b(r[1] - 1), b(r[2]), b(r[3] - 1)],
            z: [(k.start / dz) as u32, ((k.end - 1) / dz) as u32],
        }
    }

    /// Calls `pair(bundle, cell z, merge bit)` for every cell of footprint `f`.
    #[inline]
    pub(crate) fn each_pair(&self, f: &Foot, pair: &mut dyn FnMut(usize, u32, bool)) {
        let [x0, x1, y0, y1] = f.b.map(u32::from);
        for y in y0..=y1 {
            for x in x0..=x1 {
                for z in f.z[0]..=f.z[1] {
                    pair((y * self.bundles_x + x) as usize, z, z < f.z[1]);
                }
            }
        }
    }

    /// Per chunk of `chunk_len` particles, its pairs per bundle (of `nb`); and the visible
    /// particles.
    pub(crate) fn count(
        &self,
        feet: &[Foot],
        chunk_len: usize,
        nb: usize,
    ) -> (Vec<Vec<u32>>, usize) {
        let counts: Vec<(Vec<u32>, usize)> = feet
            .par_chunks(chunk_len)
            .map(|fs| {
                let mut c = vec![0u32; nb];
                let mut visible = 0;
                for f in fs.iter().filter(|f| f.is_some()) {
                    visible += 1;
                    self.each_pair(f, &mut |b, _, _| c[b] += 1);
                }
                (c, visible)
            })
            .collect();
        let visible = counts.iter().map(|c| c.1).sum();
        (counts.into_iter().map(|c| c.0).collect(), visible)
    }

    /// The pairs' keys (cell z << 33 | merge bit << 32 | particle), grouped by bundle, each
    /// chunk's keys from its own start in each bundle (`counts`), `total` in all.
    pub(crate) fn keys(
        &self,
        feet: &[Foot],
        chunk_len: usize,
        counts: Vec<Vec<u32>>,
        total: usize,
    ) -> Vec<u64> {
        let nb = counts.first().map_or(0, Vec::len);
        let mut keys = vec![0u64; total];
        // Each chunk's own slice of each bundle's keys.
        let mut own: Vec<Vec<&mut [u64]>> =
            (0..counts.len()).map(|_| Vec::with_capacity(nb)).collect();
        let mut rest = keys.as_mut_slice();
        for b in 0..nb {
            for (c, count) in own.iter_mut().zip(&counts) {
                let (a, r) = rest.split_at_mut(count[b] as usize);
                c.push(a);
                rest = r;
            }
        }
        drop(counts);
        feet.par_chunks(chunk_len)
            .zip(own.into_par_iter())
            .enumerate()
            .for_each(|(ci, (fs, mut slices))| {
                let mut used = vec![0u32; nb];
                for (k, f) in fs.iter().enumerate().filter(|(_, f)| f.is_some()) {
                    let j = (ci * chunk_len + k) as u64;
                    self.each_pair(f, &mut |b, z, bit| {
                        slices[b][used[b] as usize] = ((z as u64) << 33) | ((bit as u64) << 32) | j;
                        used[b] += 1;
                    });
                }
            });
        keys
    }
}

/// Where each bundle's pairs start (`nb + 1` offsets), from the chunks' counts.
pub(crate) fn bundle_offsets(counts: &[Vec<u32>], nb: usize) -> Vec<usize> {
    let mut offsets = vec![0usize; nb + 1];
    for c in counts {
        for (o, &k) in offsets[1..].iter_mut().zip(c) {
            *o += k as usize;
        }
    }
    for b in 0..nb {
        offsets[b + 1] += offsets[b];
    }
    offsets
}
