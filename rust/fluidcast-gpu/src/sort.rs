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

/// Values the device's scans and sort are checked on when the device is opened: several
/// blocks and a partial one, pseudo-random.
const CHECKED: u32 = 5 * 256 + 77;

impl Gpu {
    /// Runs a scan and a sort of [`CHECKED`] pseudo-random values on the device and compares
    /// them with the host's: false where they differ (prefix_subgroups.wgsl assumes full
    /// subgroups, which a driver need not give).
    pub(crate) fn check_prefix_sums(&self) -> Result<bool, GpuError> {
        let mix = |i: u32| i.wrapping_mul(2_654_435_761).rotate_right(7);
        let values: Vec<u32> = (0..CHECKED).map(|i| mix(i) % 1000).collect();
        let keys: Vec<u32> = (0..CHECKED).map(|i| mix(i + CHECKED) & 0xFFFF).collect();
        let order: Vec<u32> = (0..CHECKED).collect();
        let data = self.upload("prefix check values", &values);
        let (k, v) = (
            self.upload("prefix check keys", &keys),
            self.upload("prefix check order", &order),
        );
        let mut enc = self.encoder();
        let sorted = {
            let mut pass = enc.begin_compute_pass(&Default::default());
            self.scan(&mut pass, &data, CHECKED, 0)?;
            self.sort(&mut pass, &k, &v, CHECKED, 16)?
        };
        self.submit(enc);
        let bytes = 4 * u64::from(CHECKED);
        let got = self.fetch(&[(&data, bytes), (&sorted.0, bytes), (&sorted.1, bytes)])?;
        let (scanned, keys_out, order_out) = (
            crate::cast::<u32>(&got[0]),
            crate::cast::<u32>(&got[1]),
            crate::cast::<u32>(&got[2]),
        );
        let mut want_scan = Vec::with_capacity(values.len());
        let mut sum = 0u32;
        for &x in &values {
            want_scan.push(sum);
            sum += x;
        }
        let mut want_order = order;
        want_order.sort_by_key(|&i| keys[i as usize]);
        let want_keys: Vec<u32> = want_order.iter().map(|&i| keys[i as usize]).collect();
        Ok(scanned == want_scan && keys_out == want_keys && order_out == want_order)
    }
}
