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

/// Particle spacings (solid, liquid) of a scenario [m], each falling back on the other.
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
    let g = p.gravity;
    let up = if g.length() > 0.0 { -g.normalize() } else { Vec3::Y };
    // Snap to the nearest axis so the horizon stays level.
    let up = if up.z.abs() > up.y.abs() { Vec3::Z * up.z.signum() } else { Vec3::Y };
    OrbitCamera::fit(min, max, flat, up)
}

/// Bounds of the generated particles (simulation coordinates), from the scenario's generators.
fn material_bounds(sim: &Simulation) -> Option<(Vec3, Vec3)> {
    let g = crate::scenario::generate(sim.scenario());
    let p = sim.params();
    let pts: Vec<Vec3> = g.liquid.pos.iter().chain(g.solid.pos.iter()).map(|x| p.to_sim(*x)).collect();
    let first = *pts.first()?;
    Some(pts.iter().fold((first, first), |(lo, hi), x| (lo.min(*x), hi.max(*x))))
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
    let (nl, ns) = sim.frame_counts();
    let frame = FrameBuffers::new(&ctx.device, nl, ns, "snapshot");
    let info = sim.publish(&frame, &ctx.queue)?;
    let group = renderer.bind_frame(&frame);
    let target = Offscreen::new(&ctx.device, size)?;
    let (dx_solid, dx_liquid) = spacings(sim.scenario());
    let scene =
        Scene { particles: Some((&group, nl, ns)), objects: &info.objects, origin: info.origin, dx_solid, dx_liquid };
    let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("snapshot") });
    renderer.draw(&mut enc, &target.view, super::offscreen::OFFSCREEN_FORMAT, size, camera, &scene)?;
    ctx.queue.submit([enc.finish()]);
    renderer.submitted();
    Ok(target.read(&ctx.device, &ctx.queue)?)
}
