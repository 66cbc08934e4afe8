//! Compute passes: pipelines whose bindings are looked up by the WGSL global's name (read from
//! the shader by naga when the pipeline is made, so no binding number is written twice),
//! dispatches, and GPU timestamps per stage.

use std::collections::HashMap;
use std::sync::Arc;

use fluidcast_render::RenderStats;
use wgpu::util::DeviceExt;

use crate::{cast, push_stage, Gpu, GpuError, QUERIES};

/// On a software driver, the stride by which consecutive workgroups take bundles
/// (common.wgsl's `scattered_bundle`): Mesa's llvmpipe hands each of its threads one contiguous
/// range of a dispatch's workgroups (lp_cs_tpool.c), so bundles taken in image order leave a
/// thread alone with a dense region while the others idle.
const SCATTER: u32 = 64;

/// Most dispatches of one stage (see [`Gpu::dispatch_until_done`]).
const MAX_DISPATCHES: u32 = 1 << 20;

/// A compute pipeline and the binding numbers of its shader's globals, by name.
pub(crate) struct Pipe {
    pipeline: wgpu::ComputePipeline,
    entry: &'static str,
    slots: Arc<HashMap<String, u32>>,
}

/// A shader module and its globals' bindings (group 0), by name.
pub(crate) struct Shader {
    module: wgpu::ShaderModule,
    slots: Arc<HashMap<String, u32>>,
}

impl Shader {
    /// Compiles `src` and reads its bindings with naga.
    pub(crate) fn new(device: &wgpu::Device, name: &str, src: &str) -> Result<Shader, GpuError> {
        let parsed = naga::front::wgsl::parse_str(src)
            .map_err(|e| GpuError::Device(format!("{name}.wgsl: {}", e.emit_to_string(src))))?;
        let slots = parsed
            .global_variables
            .iter()
            .filter_map(|(_, g)| Some((g.name.clone()?, g.binding.as_ref()?.binding)))
            .collect();
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        Ok(Shader {
            module,
            slots: Arc::new(slots),
        })
    }

    pub(crate) fn pipe(&self, device: &wgpu::Device, entry: &'static str) -> Pipe {
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: None,
            module: &self.module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        Pipe {
            pipeline,
            entry,
            slots: self.slots.clone(),
        }
    }
}

/// Timestamp queries around compute passes, summed by stage name.
pub(crate) struct Timer<'q> {
    pub(crate) queries: Option<&'q wgpu::QuerySet>,
    pub(crate) names: Vec<&'static str>,
}

impl<'q> Timer<'q> {
    pub(crate) fn new(queries: Option<&'q wgpu::QuerySet>) -> Timer<'q> {
        Timer {
            queries,
            names: Vec::new(),
        }
    }

    /// A compute pass timed as `name` (while the query set has room).
    pub(crate) fn pass<'e>(
        &mut self,
        enc: &'e mut wgpu::CommandEncoder,
        name: &'static str,
    ) -> wgpu::ComputePass<'e> {
        let writes = match self.queries {
            Some(q) if 2 * (self.names.len() as u32 + 1) <= QUERIES => {
                let i = 2 * self.names.len() as u32;
                self.names.push(name);
                Some(wgpu::ComputePassTimestampWrites {
                    query_set: q,
                    beginning_of_pass_write_index: Some(i),
                    end_of_pass_write_index: Some(i + 1),
                })
            }
            _ => None,
        };
        enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes: writes,
        })
    }
}

impl Gpu {
    pub(crate) fn encoder(&self) -> wgpu::CommandEncoder {
        self.device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None })
    }

    /// Records one timed compute pass with `f` and submits it.
    pub(crate) fn submit_pass(
        &self,
        timer: &mut Timer,
        name: &'static str,
        f: impl FnOnce(&mut wgpu::ComputePass) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        let mut enc = self.encoder();
        {
            let mut pass = timer.pass(&mut enc, name);
            f(&mut pass)?;
        }
        self.submit(enc);
        Ok(())
    }

    /// Runs `pipe` over `groups` workgroups (folded into two dimensions past 32768), with
    /// the buffers bound to the WGSL globals they are named after (exactly those the entry
    /// point uses).
    pub(crate) fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass,
        pipe: &Pipe,
        binds: &[(&str, &wgpu::Buffer)],
        groups: u32,
    ) -> Result<(), GpuError> {
        if groups == 0 {
            return Ok(());
        }
        let x = groups.min(32768);
        self.dispatch_2d(pass, pipe, binds, (x, groups.div_ceil(x)))
    }

    /// Dispatches `pipe` (with its stage's name for errors) until no invocation stopped at
    /// the loop limit, once where there is none: after each dispatch the first u32 of
    /// `stopped` (the invocations that stopped and are to resume) and of `guard` (set: a
    /// refusal the caller reports) are read back; while some stopped and none refused,
    /// `stopped` is reset, `next(n)` prepares dispatch n + 1 and it runs. Each dispatch takes
    /// every stopped invocation at least one step further (a span, a chunk, a point query),
    /// so the count is bounded by the work; past MAX_DISPATCHES it is refused. Returns the
    /// dispatches.
    pub(crate) fn dispatch_until_done(
        &self,
        timer: &mut Timer,
        (pipe, stage, timed): (&Pipe, &'static str, &'static str),
        binds: &[(&str, &wgpu::Buffer)],
        groups: (u32, u32),
        (stopped, guard): (&wgpu::Buffer, &wgpu::Buffer),
        mut next: impl FnMut(u64),
    ) -> Result<u64, GpuError> {
        for n in 1..=u64::from(MAX_DISPATCHES) {
            self.submit_pass(timer, timed, |pass| {
                self.dispatch_2d(pass, pipe, binds, groups)
            })?;
            if !self.bounded() {
                return Ok(n);
            }
            let parts = [(stopped, 4), (guard, 4)];
            let (left, refused) = self.fetch_with(&parts, |got| {
                (cast::<u32>(got[0])[0], cast::<u32>(got[1])[0])
            })?;
            if left == 0 || refused != 0 {
                return Ok(n);
            }
            self.write(stopped, bytemuck::bytes_of(&0u32));
            next(n);
        }
        Err(self.loop_limit_error(stage))
    }

    pub(crate) fn dispatch_2d(
        &self,
        pass: &mut wgpu::ComputePass,
        pipe: &Pipe,
        binds: &[(&str, &wgpu::Buffer)],
        groups: (u32, u32),
    ) -> Result<(), GpuError> {
        let mut entries = Vec::with_capacity(binds.len());
        for (name, b) in binds {
            let Some(&binding) = pipe.slots.get(*name) else {
                return Err(GpuError::Device(format!(
                    "the shader of '{}' has no binding '{name}'",
                    pipe.entry
                )));
            };
            entries.push(wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            });
        }
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(pipe.entry),
            layout: &pipe.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        pass.set_pipeline(&pipe.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
        Ok(())
    }

    /// For a dispatch over `n` bundles, one workgroup each: the scatter (common.wgsl's
    /// `scattered_bundle`: [`SCATTER`] on a software driver, 1 on hardware) and the workgroups
    /// (folded into two dimensions past 32768).
    pub(crate) fn scattered_groups(&self, n: u32) -> (u32, (u32, u32)) {
        let s = if self.software {
            SCATTER.min(n).max(1)
        } else {
            1
        };
        let total = s * n.div_ceil(s);
        let x = total.clamp(1, 32768);
        (s, (x, total.div_ceil(x)))
    }

    /// A small uniform buffer made for one dispatch (each dispatch of a pass sees its own).
    pub(crate) fn small_uniform(&self, v: [u32; 4]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents: bytemuck::cast_slice(&v),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// Reads the timestamp queries of the frame into `gpu_*` stages (milliseconds), in a
    /// round trip of their own (a frame whose image came back after its last timed pass has
    /// read them with it: [`Gpu::resolve_timers`]).
    pub(crate) fn finish_timers(
        &self,
        timer: &mut Timer,
        stats: &mut RenderStats,
    ) -> Result<(), GpuError> {
        let Some((resolved, bytes)) = self.resolve_timers(timer) else {
            return Ok(());
        };
        let got = self.fetch(&[(&resolved, bytes)])?;
        self.read_timers(timer, &got[0], stats);
        Ok(())
    }

    /// Resolves the timestamp queries of the passes recorded so far into a buffer (submitted),
    /// to be read back with what the frame reads next: the buffer and its bytes; `None`
    /// without queries or passes.
    pub(crate) fn resolve_timers(&self, timer: &Timer) -> Option<(wgpu::Buffer, u64)> {
        let (Some(q), false) = (timer.queries, timer.names.is_empty()) else {
            return None;
        };
        let count = 2 * timer.names.len() as u32;
        let resolve = self.buffer(
            "timestamps",
            8 * QUERIES as u64,
            wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            None,
        );
        let mut enc = self.encoder();
        enc.resolve_query_set(q, 0..count, &resolve, 0);
        self.submit(enc);
        Some((resolve, 8 * u64::from(count)))
    }

    /// The `gpu_*` stages (milliseconds) from the queries [`Gpu::resolve_timers`] resolved
    /// (`bytes`, read back); the timer's queries are then free for the frame's next passes.
    pub(crate) fn read_timers(&self, timer: &mut Timer, bytes: &[u8], stats: &mut RenderStats) {
        let t: Vec<u64> = cast(bytes);
        let period = self.queue.get_timestamp_period() as f64;
        for (k, name) in timer.names.iter().enumerate() {
            let ns = t[2 * k + 1].saturating_sub(t[2 * k]) as f64 * period;
            push_stage(stats, name, ns * 1e-6);
        }
        timer.names.clear();
    }
}
