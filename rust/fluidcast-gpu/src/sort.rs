//! Prefix sums (scan.wgsl) and the stable radix sort of (key, value) pairs (sort.wgsl): the
//! GPU's counterpart of the counting sort in `fluidcast_grid::PerspectiveGrid::build`.

use crate::{Gpu, GpuError, RW};

/// Roles of the partial-sum buffers of a scan, one per level of recursion (256^5 > 2^32).
const SUMS: [&str; 5] = [
    "scan sums 0",
    "scan sums 1",
    "scan sums 2",
    "scan sums 3",
    "scan sums 4",
];

impl Gpu {
    /// Exclusive prefix sum of the first `n` (> 0) u32 of `data`, in place.
    pub(crate) fn scan(
        &self,
        pass: &mut wgpu::ComputePass,
        data: &wgpu::Buffer,
        n: u32,
        level: usize,
    ) -> Result<(), GpuError> {
        let blocks = n.div_ceil(256);
        let role = SUMS
            .get(level)
            .ok_or_else(|| GpuError::Device(format!("a scan of {n} values nests too deep")))?;
        let sums = self.buffer(role, 4 * blocks as u64, RW, None);
        let u = self.small_uniform([n, 0, 0, 0]);
        let binds = [("S", &u), ("data", data), ("sums", &sums)];
        self.dispatch(pass, &self.pipes.scan_blocks, &binds, blocks)?;
        if blocks > 1 {
            self.scan(pass, &sums, blocks, level + 1)?;
            self.dispatch(pass, &self.pipes.add_sums, &binds, blocks)?;
        }
        Ok(())
    }

    /// Stable radix sort (4 bits a pass) of `n` (key, value) pairs by the low `bits` of the
    /// key; returns the buffers holding the result (the inputs or their partners).
    pub(crate) fn sort(
        &self,
        pass: &mut wgpu::ComputePass,
        keys: &wgpu::Buffer,
        vals: &wgpu::Buffer,
        n: u32,
        bits: u32,
    ) -> Result<(wgpu::Buffer, wgpu::Buffer), GpuError> {
        let blocks = n.div_ceil(256);
        let hist = self.buffer("histogram", 64 * blocks as u64, RW, None);
        let mut a = (keys.clone(), vals.clone());
        let mut b = (
            self.buffer("keys (sort)", 4 * n as u64, RW, None),
            self.buffer("values (sort)", 4 * n as u64, RW, None),
        );
        for p in 0..bits.div_ceil(4) {
            let u = self.small_uniform([n, 4 * p, blocks, 0]);
            let binds = [("R", &u), ("keys_in", &a.0), ("hist", &hist)];
            self.dispatch(pass, &self.pipes.histogram, &binds, blocks)?;
            self.scan(pass, &hist, 16 * blocks, 0)?;
            let binds = [
                ("R", &u),
                ("keys_in", &a.0),
                ("vals_in", &a.1),
                ("keys_out", &b.0),
                ("vals_out", &b.1),
                ("hist", &hist),
            ];
            self.dispatch(pass, &self.pipes.scatter, &binds, blocks)?;
            std::mem::swap(&mut a, &mut b);
        }
        Ok(a)
    }
}
