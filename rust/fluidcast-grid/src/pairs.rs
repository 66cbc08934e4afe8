//! The pairs stage (the GPU's grid.wgsl): each particle's footprint in the view's grid
//! (bundle rectangle and cell depth range), the particle–cell pairs counted per bundle in
//! parallel chunks, and their keys written bundle by bundle.

use rayon::prelude::*;

use crate::{screen_rect, SampleDepths, ViewParticle};
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

impl Footprint<'_> {
    /// The bundle rectangle and cell depth range (inclusive) particle `p` reaches, `None`
    /// when it reaches no pixel or depth sample. Computed where needed, twice, rather than
    /// stored: 28 bytes a particle.
    #[inline]
    pub(crate) fn of(&self, p: &ViewParticle) -> Option<[u32; 6]> {
        let (near, far) = self.range;
        let r = screen_rect(self.frame, p, near, far)?;
        let k = self.depths.indices_within(p.c[2] - p.h(), p.c[2] + p.h());
        if k.is_empty() {
            return None;
        }
        let (d, dz) = (self.bundle, self.dz);
        Some([
            r[0] / d,
            (r[1] - 1) / d,
            r[2] / d,
            (r[3] - 1) / d,
            (k.start / dz) as u32,
            ((k.end - 1) / dz) as u32,
        ])
    }

    /// Calls `pair(bundle, cell z, merge bit)` for every cell of footprint `f`.
    #[inline]
    pub(crate) fn each_pair(&self, f: &[u32; 6], pair: &mut dyn FnMut(usize, u32, bool)) {
        for y in f[2]..=f[3] {
            for x in f[0]..=f[1] {
                for z in f[4]..=f[5] {
                    pair((y * self.bundles_x + x) as usize, z, z < f[5]);
                }
            }
        }
    }

    /// Per chunk of `chunk_len` particles, its pairs per bundle (of `nb`); and the visible
    /// particles.
    pub(crate) fn count(
        &self,
        particles: &[ViewParticle],
        chunk_len: usize,
        nb: usize,
    ) -> (Vec<Vec<u32>>, usize) {
        let counts: Vec<(Vec<u32>, usize)> = particles
            .par_chunks(chunk_len)
            .map(|ps| {
                let mut c = vec![0u32; nb];
                let mut visible = 0;
                for f in ps.iter().filter_map(|p| self.of(p)) {
                    visible += 1;
                    self.each_pair(&f, &mut |b, _, _| c[b] += 1);
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
        particles: &[ViewParticle],
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
        particles
            .par_chunks(chunk_len)
            .zip(own.into_par_iter())
            .enumerate()
            .for_each(|(ci, (ps, mut slices))| {
                let mut used = vec![0u32; nb];
                for (k, p) in ps.iter().enumerate() {
                    let Some(f) = self.of(p) else { continue };
                    let j = (ci * chunk_len + k) as u64;
                    self.each_pair(&f, &mut |b, z, bit| {
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
