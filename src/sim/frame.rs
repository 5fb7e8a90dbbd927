//! The particle data a renderer draws, as GPU buffers: one set of the viewer's double buffer
//! (DESIGN §Double buffering). The simulation thread fills the back set with [`Simulation::publish`]
//! — on the GPU back-end by buffer-to-buffer copies on the simulation's own device (no readback), on
//! the CPU back-end by one upload — and then publishes it by swapping an index; the render thread
//! draws the front set. Layouts are the GPU solver's own (`common.wgsl`), so the GPU publish is a
//! plain copy and the CPU publish packs its arrays the same way the solver's upload does.
//!
//! [`Simulation::publish`]: crate::sim::Simulation::publish

use super::gpu::gpu_types::StressGpu;

/// Bytes per particle of each buffer (the solver's layouts: `vec4` positions, `vec4` (ρ, nˡ, nˢ, p),
/// `StressGpu` (τ, R), `u32` bond counts and flags).
pub const LIQUID_POS_BYTES: u64 = 16;
pub const SOLID_POS_BYTES: u64 = 16;
pub const SOLID_DENS_BYTES: u64 = 16;
pub const SOLID_STRESS_BYTES: u64 = std::mem::size_of::<StressGpu>() as u64;
pub const U32_BYTES: u64 = 4;

/// One set of render buffers (sized for a scenario's liquid capacity and solid count).
pub struct FrameBuffers {
    pub n_liquid: u32,
    pub n_solid: u32,
    /// xyz: position (simulation coordinates), w: mass.
    pub liquid_pos: wgpu::Buffer,
    pub solid_pos: wgpu::Buffer,
    /// (ρ, nˡ, nˢ, p) of each solid particle.
    pub solid_dens: wgpu::Buffer,
    /// Deviatoric Cauchy stress τ and artificial stress R (`StressGpu`: their upper triangles, 3 vec4).
    pub solid_stress: wgpu::Buffer,
    /// Intact bonds now and at t = 0 (broken = initial − now).
    pub bond_count: wgpu::Buffer,
    pub bond_count0: wgpu::Buffer,
    /// `SolidFlags` bits (kinematic, membrane).
    pub solid_flags: wgpu::Buffer,
}

fn buffer(device: &wgpu::Device, label: &str, n: u32, stride: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        // Bindings cannot be empty: at least one element.
        size: u64::from(n.max(1)) * stride,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl FrameBuffers {
    pub fn new(device: &wgpu::Device, n_liquid: u32, n_solid: u32, label: &str) -> FrameBuffers {
        FrameBuffers {
            n_liquid,
            n_solid,
            liquid_pos: buffer(device, &format!("{label}.liquid_pos"), n_liquid, LIQUID_POS_BYTES),
            solid_pos: buffer(device, &format!("{label}.solid_pos"), n_solid, SOLID_POS_BYTES),
            solid_dens: buffer(device, &format!("{label}.solid_dens"), n_solid, SOLID_DENS_BYTES),
            solid_stress: buffer(device, &format!("{label}.solid_stress"), n_solid, SOLID_STRESS_BYTES),
            bond_count: buffer(device, &format!("{label}.bond_count"), n_solid, U32_BYTES),
            bond_count0: buffer(device, &format!("{label}.bond_count0"), n_solid, U32_BYTES),
            solid_flags: buffer(device, &format!("{label}.solid_flags"), n_solid, U32_BYTES),
        }
    }

    /// Bytes of GPU memory the set holds.
    pub fn bytes(&self) -> u64 {
        u64::from(self.n_liquid) * LIQUID_POS_BYTES
            + u64::from(self.n_solid) * (SOLID_POS_BYTES + SOLID_DENS_BYTES + SOLID_STRESS_BYTES + 3 * U32_BYTES)
    }
}

/// What goes with a published set: the time and the object poses at that time.
#[derive(Clone, Debug, Default)]
pub struct FrameInfo {
    /// Live liquid particles in the set (the buffers hold the capacity).
    pub n_liquid: u32,
    pub t: f64,
    pub steps: u64,
    pub objects: Vec<super::ObjectPose>,
    /// Simulation coordinates = scenario coordinates − origin.
    pub origin: [f64; 3],
}
