//! GPU time of each render pass from timestamp queries, where the device has them: every 30th frame is
//! timed, its queries resolved into a buffer and mapped asynchronously, and the figures are picked up a
//! few frames later — the frame never waits for them.

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

/// The passes of `Renderer::draw`, in order.
pub const PASSES: [&str; 6] = ["scene", "blood thickness", "blood depth", "filter h", "filter v", "composite"];
const EVERY: u64 = 30;
const IDLE: u8 = 0;
const PENDING: u8 = 1;
const READY: u8 = 2;

pub struct RenderTimer {
    query_set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    staging: wgpu::Buffer,
    period_ns: f64,
    state: Arc<AtomicU8>,
    frame: u64,
    /// This frame is timed; which passes ran in it.
    active: bool,
    ran: [bool; 6],
    ran_pending: [bool; 6],
    /// GPU milliseconds per pass of the last timed frame.
    pub last_ms: Vec<(&'static str, f64)>,
}

impl RenderTimer {
    /// None when the device has no timestamp queries.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Option<RenderTimer> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let n = 2 * PASSES.len() as u32;
        let size = 8 * u64::from(n);
        Some(RenderTimer {
            query_set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("render.timer"),
                ty: wgpu::QueryType::Timestamp,
                count: n,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("render.timer_resolve"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            staging: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("render.timer_readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            period_ns: f64::from(queue.get_timestamp_period()),
            state: Arc::new(AtomicU8::new(IDLE)),
            frame: 0,
            active: false,
            ran: [false; 6],
            ran_pending: [false; 6],
            last_ms: Vec::new(),
        })
    }

    /// Starts a frame: collects finished figures and decides whether this frame is timed.
    pub fn begin_frame(&mut self) {
        if self.state.load(Ordering::Acquire) == READY {
            if let Ok(view) = self.staging.slice(..).get_mapped_range() {
                let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&view);
                self.last_ms = PASSES
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| self.ran_pending[*k])
                    .map(|(k, name)| {
                        let d = ticks[2 * k + 1].saturating_sub(ticks[2 * k]);
                        (*name, d as f64 * self.period_ns * 1e-6)
                    })
                    .collect();
            }
            self.staging.unmap();
            self.state.store(IDLE, Ordering::Release);
        }
        self.frame += 1;
        self.active = self.frame % EVERY == 1 && self.state.load(Ordering::Acquire) == IDLE;
        self.ran = [false; 6];
    }

    /// Timestamp writes for pass `k` of a timed frame.
    pub fn writes(&mut self, k: usize) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        if !self.active || k >= PASSES.len() {
            return None;
        }
        self.ran[k] = true;
        Some(wgpu::RenderPassTimestampWrites {
            query_set: &self.query_set,
            beginning_of_pass_write_index: Some(2 * k as u32),
            end_of_pass_write_index: Some(2 * k as u32 + 1),
        })
    }

    /// Resolves the queries of a timed frame into the staging buffer (encode after the passes).
    pub fn end_frame(&mut self, enc: &mut wgpu::CommandEncoder) {
        if !self.active {
            return;
        }
        enc.resolve_query_set(&self.query_set, 0..2 * PASSES.len() as u32, &self.resolve, 0);
        enc.copy_buffer_to_buffer(&self.resolve, 0, &self.staging, 0, self.resolve.size());
    }

    /// After the frame's submission: map the staging buffer without waiting.
    pub fn submitted(&mut self) {
        if !self.active {
            return;
        }
        self.active = false;
        self.ran_pending = self.ran;
        self.state.store(PENDING, Ordering::Release);
        let state = self.state.clone();
        self.staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            state.store(if r.is_ok() { READY } else { IDLE }, Ordering::Release);
        });
    }
}
