//! One frame of a running simulation rendered offscreen to an image: `perfuse render`, the viewer's
//! `--screenshot` without a window, documentation figures and the render tests share this path.

use super::camera::OrbitCamera;
use super::offscreen::Offscreen;
use super::renderer::{RenderError, Renderer, Scene};
use crate::scenario::Scenario;
use crate::sim::frame::FrameBuffers;
use crate::sim::gpu::GpuContext;
use crate::sim::{SimError, Simulation};
use glam::Vec3;

/// Why a snapshot failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SnapshotError {
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Gpu(#[from] crate::sim::gpu::GpuError),
}

/// Particle spacings (solid, liquid) of a scenario \[m\], each falling back on the other.
pub fn spacings(s: &Scenario) -> (f32, f32) {
    let n = &s.numerics;
    let solid = n.dx_solid.or(n.dx_liquid).unwrap_or(1e-3) as f32;
    let liquid = n.dx_liquid.or(n.dx_solid).unwrap_or(1e-3) as f32;
    (solid, liquid)
}

/// A camera that frames the scenario's domain (2-D scenarios straight on).
pub fn default_camera(sim: &Simulation) -> OrbitCamera {
    let p = sim.params();
    let flat = p.dim.n() == 2;
    let mut min = p.domain_min;
    let mut max = p.domain_max;
    if flat {
        min.z = 0.0;
        max.z = 0.0;
    }
    // A domain much larger than the material (room for tools, falling parts): frame the material.
    if let Some((lo, hi)) = material_bounds(sim) {
        let dom = (max - min).length();
        if (hi - lo).length() < 0.5 * dom {
            let pad = (hi - lo) * 0.25 + Vec3::splat(1e-3);
            min = lo - pad;
            max = hi + pad;
        }
    }
    OrbitCamera::fit(min, max, flat, up_axis(sim.scenario().gravity))
}

/// The camera's up axis: against gravity, snapped to +y or ±z so the horizon stays level (+y without
/// gravity).
pub fn up_axis(gravity: crate::scenario::V3) -> Vec3 {
    let g = Vec3::new(gravity[0] as f32, gravity[1] as f32, gravity[2] as f32);
    if g.z.abs() > g.y.abs() && g.z != 0.0 { Vec3::Z * -g.z.signum() } else { Vec3::Y }
}

/// Scenario coordinates → simulation coordinates (relative to `origin`).
pub fn to_sim(p: [f64; 3], origin: [f64; 3]) -> Vec3 {
    Vec3::new((p[0] - origin[0]) as f32, (p[1] - origin[1]) as f32, (p[2] - origin[2]) as f32)
}

/// The generated material particles (liquid and solid) of a scenario, in simulation coordinates.
pub fn material_points(s: &Scenario, origin: [f64; 3]) -> Vec<Vec3> {
    let g = crate::scenario::generate(s);
    g.liquid.pos.iter().chain(g.solid.pos.iter()).map(|x| to_sim(*x, origin)).collect()
}

/// Bounding box of `points`.
pub fn bounds(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(lo, hi), x| (lo.min(*x), hi.max(*x))))
}

/// Bounds of the generated particles (simulation coordinates).
fn material_bounds(sim: &Simulation) -> Option<(Vec3, Vec3)> {
    bounds(&material_points(sim.scenario(), sim.params().origin))
}

/// The current state published into its own frame buffers and an offscreen target: what one
/// offscreen draw needs, owned, so the [`Scene`] can borrow it.
struct Prepared {
    _frame: FrameBuffers,
    group: wgpu::BindGroup,
    info: crate::sim::frame::FrameInfo,
    target: Offscreen,
    counts: (u32, u32),
    spacings: (f32, f32),
}

impl Prepared {
    fn new(sim: &Simulation, ctx: &GpuContext, renderer: &Renderer, size: (u32, u32)) -> Result<Self, SnapshotError> {
        let (nl, ns) = sim.frame_counts();
        let frame = FrameBuffers::new(&ctx.device, nl, ns, "snapshot");
        let info = sim.publish(&frame, &ctx.queue)?;
        let group = renderer.bind_frame(&frame);
        let target = Offscreen::new(&ctx.device, size)?;
        Ok(Prepared { _frame: frame, group, info, target, counts: (nl, ns), spacings: spacings(sim.scenario()) })
    }

    fn scene(&self) -> Scene<'_> {
        let (nl, ns) = self.counts;
        Scene {
            particles: Some((&self.group, self.info.n_liquid.min(nl), ns)),
            objects: &self.info.objects,
            origin: self.info.origin,
            dx_solid: self.spacings.0,
            dx_liquid: self.spacings.1,
        }
    }

    /// Encodes and submits one draw of the scene.
    fn draw(
        &self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &OrbitCamera,
        size: (u32, u32),
    ) -> Result<(), SnapshotError> {
        let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("snapshot") });
        let scene = self.scene();
        renderer.draw(&mut enc, &self.target.view, super::offscreen::OFFSCREEN_FORMAT, size, camera, &scene)?;
        ctx.queue.submit([enc.finish()]);
        renderer.submitted();
        Ok(())
    }
}

/// Renders the simulation's current state into an image of `size` on the device of `ctx` (which
/// must be the simulation's device when it runs on the GPU).
pub fn render_image(
    sim: &Simulation,
    ctx: &GpuContext,
    renderer: &mut Renderer,
    camera: &OrbitCamera,
    size: (u32, u32),
) -> Result<image::RgbaImage, SnapshotError> {
    let prepared = Prepared::new(sim, ctx, renderer, size)?;
    prepared.draw(ctx, renderer, camera, size)?;
    Ok(prepared.target.read(&ctx.device, &ctx.queue)?)
}

/// The renderer's cost at one size ([`time_frames`]).
#[derive(Clone, Debug, Default)]
pub struct FrameTiming {
    /// Mean GPU milliseconds of each pass over the frames the timestamp queries timed (empty without them).
    pub passes: Vec<(&'static str, f64)>,
    /// Mean wall-clock milliseconds per frame, submission to completion.
    pub wall_ms: f64,
}

/// GPU cost of drawing the current state `frames` times at `size` (offscreen, the viewer's passes).
/// The renderer's timer times every 30th frame; nothing else is read back.
pub fn time_frames(
    sim: &Simulation,
    ctx: &GpuContext,
    renderer: &mut Renderer,
    camera: &OrbitCamera,
    size: (u32, u32),
    frames: u32,
) -> Result<FrameTiming, SnapshotError> {
    let prepared = Prepared::new(sim, ctx, renderer, size)?;
    let mut sums: Vec<(&'static str, f64)> = Vec::new();
    let mut timed = 0u32;
    let mut last: Vec<(&'static str, f64)> = renderer.pass_ms().to_vec();
    let t0 = std::time::Instant::now();
    for _ in 0..frames {
        prepared.draw(ctx, renderer, camera, size)?;
        ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(crate::sim::gpu::GpuError::from)?;
        let now = renderer.pass_ms();
        if !now.is_empty() && now != last.as_slice() {
            for (name, ms) in now {
                match sums.iter_mut().find(|(n, _)| n == name) {
                    Some(e) => e.1 += ms,
                    None => sums.push((name, *ms)),
                }
            }
            timed += 1;
            last = now.to_vec();
        }
    }
    let wall_ms = t0.elapsed().as_secs_f64() * 1e3 / f64::from(frames.max(1));
    let passes = sums.into_iter().map(|(n, ms)| (n, ms / f64::from(timed.max(1)))).collect();
    Ok(FrameTiming { passes, wall_ms })
}
