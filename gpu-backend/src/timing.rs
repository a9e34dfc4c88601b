//! GPU timestamps per stage: [`StageTimer`] owns a timestamp query set with two
//! queries per stage (start of its first pass, end of its last pass), hands each
//! stage its pair, resolves them after the frame and reads back milliseconds.
//! Without timestamp queries ([`GpuContext::timestamps`] false) it hands out
//! nothing and reads back `None`: the caller times stages with the wall clock.

use crate::{GpuContext, GpuError};

/// Bytes of one resolved query ([`wgpu::QUERY_SIZE`]).
const QUERY_BYTES: u64 = wgpu::QUERY_SIZE as u64;

struct Queries {
    set: wgpu::QuerySet,
    /// `QUERY_RESOLVE | COPY_SRC`: where the query set resolves.
    resolve: wgpu::Buffer,
    /// `MAP_READ | COPY_DST`: the CPU-readable copy.
    readback: wgpu::Buffer,
}

/// Timestamp queries for `stages` stages: stage `i` writes queries `2i` (start)
/// and `2i + 1` (end).
pub struct StageTimer {
    stages: u32,
    queries: Option<Queries>,
}

impl StageTimer {
    /// A timer for `stages` stages; inactive (every method answers `None`) when the
    /// device has no timestamp queries or `stages` is 0. At most
    /// `wgpu::QUERY_SET_MAX_QUERIES / 2` (2048) stages.
    pub fn new(ctx: &GpuContext, stages: u32) -> Result<StageTimer, GpuError> {
        if 2 * stages as u64 > wgpu::QUERY_SET_MAX_QUERIES as u64 {
            return Err(GpuError::Limits(format!(
                "{stages} timed stages need more than {} timestamp queries",
                wgpu::QUERY_SET_MAX_QUERIES
            )));
        }
        if !ctx.timestamps || stages == 0 {
            return Ok(StageTimer { stages, queries: None });
        }
        let count = 2 * stages;
        let size = count as u64 * QUERY_BYTES;
        let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("stage timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count,
        });
        let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("stage timestamps resolve"),
            size,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("stage timestamps readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(StageTimer { stages, queries: Some(Queries { set, resolve, readback }) })
    }

    /// Number of stages this timer was made for.
    pub fn stages(&self) -> u32 {
        self.stages
    }

    /// True if GPU timestamps are recorded.
    pub fn is_active(&self) -> bool {
        self.queries.is_some()
    }

    /// The `timing` argument of stage `stage`'s `encode`: the query set and the
    /// index of its start query (`2 * stage`; its end is the next one). `None` when
    /// inactive or `stage` is out of range.
    pub fn stage(&self, stage: u32) -> Option<(&wgpu::QuerySet, u32)> {
        match &self.queries {
            Some(q) if stage < self.stages => Some((&q.set, 2 * stage)),
            _ => None,
        }
    }

    /// Record, after the frame's passes, the resolution of every query and its copy
    /// into the readback buffer. Nothing when inactive.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(q) = &self.queries {
            let count = 2 * self.stages;
            encoder.resolve_query_set(&q.set, 0..count, &q.resolve, 0);
            encoder.copy_buffer_to_buffer(&q.resolve, 0, &q.readback, 0, count as u64 * QUERY_BYTES);
        }
    }

    /// Milliseconds per stage of the last submitted frame whose encoder went
    /// through [`Self::resolve`] (waits for the GPU); `None` when inactive. Every
    /// stage must have written its two queries in that frame (a stage that did not
    /// run reads whatever its queries last held); an end before its start reads 0.
    pub fn read_ms(&self, ctx: &GpuContext) -> Result<Option<Vec<f64>>, GpuError> {
        let Some(q) = &self.queries else { return Ok(None) };
        let slice = q.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        ctx.device
            .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
        let ticks: Vec<u64> = {
            let view = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            bytemuck::pod_collect_to_vec::<u8, u64>(&view[..])
        };
        q.readback.unmap();
        // Nanoseconds per tick.
        let period = ctx.queue.get_timestamp_period() as f64;
        Ok(Some(ticks.chunks_exact(2).map(|t| t[1].saturating_sub(t[0]) as f64 * period * 1e-6).collect()))
    }
}

/// A compute pass labelled `label`, with the stage's timestamps when `timing` is
/// `Some((set, i))` ([`StageTimer::stage`]): query `i` at its start, `i + 1` at its end.
pub fn begin_timed_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    timing: Option<(&wgpu::QuerySet, u32)>,
) -> wgpu::ComputePass<'e> {
    encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: timing.map(|(query_set, i)| wgpu::ComputePassTimestampWrites {
            query_set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        }),
    })
}
