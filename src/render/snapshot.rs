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
    let scene = Scene {
        particles: Some((&group, info.n_liquid.min(nl), ns)),
        objects: &info.objects,
        origin: info.origin,
        dx_solid,
        dx_liquid,
    };
    let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("snapshot") });
    renderer.draw(&mut enc, &target.view, super::offscreen::OFFSCREEN_FORMAT, size, camera, &scene)?;
    ctx.queue.submit([enc.finish()]);
    renderer.submitted();
    Ok(target.read(&ctx.device, &ctx.queue)?)
}
