//! `sim::gpu` — the wgpu/WGSL back-end: the algorithm of the CPU reference solver `sim::cpu` (thesis
//! chapter 2, SPEC §5), as compute passes, one WGSL file per CPU module of the same name (`grid`,
//! `density`, `solid`, `forces`, `integrate`, `dt`, `fracture`; shared code in `shaders/common.wgsl`).
//!
//! All particle state lives on the GPU; the host encodes the ordered pass lists of [`passes`] and reads
//! back only what it must. Particles stay in id order and every neighbour sum runs in the CPU's
//! canonical order (27 cells in a fixed offset order, ascending index inside a cell), so the two
//! back-ends differ only by f32 rounding of individual operations (transcendental functions, possible
//! FMA contraction). No float atomics: the grid uses integer atomics plus a per-cell sort, Δt a
//! bit-pattern atomicMin/Max, so a run is bit-reproducible on one adapter.
//!
//! Host synchronisation: Δt stays on the GPU (`step.dt`, read by the integrator), but [`GpuSolver::step`]
//! reads the 48-byte `StepState` back twice per step: after Δt (the f64 clock and the analytic boundary
//! motions of `motion_at` are evaluated on the host at tⁿ⁺¹ and uploaded before the second half) and
//! at the end (divergence status, broken bonds). The initial state, the bond table (built once,
//! SPEC §4.6) and the object shapes come from `CpuSolver::new`, so both back-ends start bit-identical.

pub mod bindings;
pub mod buffers;
pub mod device;
pub mod gpu_types;
pub mod passes;
pub mod shaders;

use super::cpu::forces::ObjectGeom;
use super::cpu::{CpuSolver, ObjectPressure};
use super::params::Params;
use super::state::{BoundaryState, PhaseState, SolidExtra, State};
use super::{Command, DtLimit, SimError, StepInfo};
use crate::scenario::{BoundaryObject, GeneratedParticles, motion_at};
use bindings::Slot;
use buffers::SimBuffers;
use bytemuck::Pod;
pub use device::{GpuContext, GpuError};
use glam::{Mat3, Vec3};
use gpu_types::{Counts, GridSet, Mat3Gpu, ObjectGpu, SimParams, StepState, StressGpu};
use passes::{Dispatch, GridOf, PassSpec, Stage};
use std::collections::HashMap;

impl From<GpuError> for SimError {
    fn from(e: GpuError) -> Self {
        SimError::Gpu(e.to_string())
    }
}

struct Pipeline {
    pipeline: wgpu::ComputePipeline,
    /// Bind groups: one for ordinary passes (key `None`), one per set for grid passes.
    groups: Vec<(Option<GridOf>, wgpu::BindGroup)>,
}

/// The GPU solver: same public surface as [`CpuSolver`].
pub struct GpuSolver {
    pub params: Params,
    pub ctx: GpuContext,
    errors: device::ErrorSink,
    buffers: SimBuffers,
    pipelines: HashMap<&'static str, Pipeline>,
    step_staging: wgpu::Buffer,
    counts: Counts,
    cells: u32,
    t: f64,
    steps: u64,
    objects: Vec<BoundaryObject>,
    /// Each object's shape at rest (simulation coordinates), as `CpuSolver::shapes`.
    shapes: Vec<ObjectGeom>,
    pressure_modes: Vec<ObjectPressure>,
    boundary_x0: Vec<Vec3>,
    boundary_object: Vec<u32>,
    gravity: Vec3,
    damping: f32,
    damping_solid_gravity_only: bool,
    solid_flags: Vec<u32>,
    bond_count0: Vec<u32>,
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

fn bytes<T: Pod>(v: &[T]) -> Vec<u8> {
    bytemuck::cast_slice(v).to_vec()
}

fn diverged(step: u64, t: f64, particle: String, reason: String) -> SimError {
    SimError::Diverged { step, t, particle, reason }
}

impl GpuSolver {
    /// Acquires the default adapter (see [`device`]) and builds the solver.
    pub fn new(params: Params, g: &GeneratedParticles) -> Result<GpuSolver, SimError> {
        let ctx = GpuContext::new()?;
        Self::with_context(ctx, params, g)
    }

    /// Builds the solver on an existing device (tests share one adapter).
    pub fn with_context(ctx: GpuContext, params: Params, g: &GeneratedParticles) -> Result<GpuSolver, SimError> {
        let cpu = CpuSolver::new(params.clone(), g)?;
        Self::from_cpu(ctx, &cpu)
    }

    /// Builds the solver with the exact state of `cpu` (initial state, or any later state for
    /// per-pass differential tests).
    pub fn from_cpu(ctx: GpuContext, cpu: &CpuSolver) -> Result<GpuSolver, SimError> {
        let errors = device::ErrorSink::install(&ctx.device);
        let params = cpu.params.clone();
        let st = &cpu.st;
        let counts = Counts {
            liquid: st.liquid.x.len() as u32,
            solid: st.solid.x.len() as u32,
            boundary: st.boundary.x.len() as u32,
            bond_capacity: st.solid.bond_capacity as u32,
            objects: st.objects.len() as u32,
        };
        let cells = params.grid.cell_count() as u32;
        let shapes = object_shapes(&params, &st.objects);
        let mut solver_init = Vec::new();
        Self::state_contents(cpu, &mut solver_init);
        let gravity_liquid = !(st.damping > 0.0 && st.damping_solid_gravity_only);
        let sp = SimParams::new(&params, counts, st.gravity, st.damping, gravity_liquid);
        solver_init.push((Slot::Params, bytes(&[sp])));
        solver_init.push((Slot::Step, bytes(&[StepState::default()])));
        let objects = objects_at(&params, &st.objects, &shapes, &cpu.pressure_modes, st.t);
        solver_init.push((Slot::Objects, bytes(&objects)));
        for (slot, n) in [
            (Slot::LiquidOrder, counts.liquid as usize),
            (Slot::SolidOrder, counts.solid as usize),
            (Slot::BoundaryOrder, counts.boundary as usize),
        ] {
            solver_init.push((slot, vec![0u8; 4 * n]));
        }
        for slot in [Slot::LiquidCellStart, Slot::SolidCellStart, Slot::BoundaryCellStart] {
            solver_init.push((slot, vec![0u8; 4 * (cells as usize + 1)]));
        }
        let gs = |n: u32| GridSet { n, cells, _pad0: 0, _pad1: 0 };
        let (g0, g1, g2) = (bytes(&[gs(counts.liquid)]), bytes(&[gs(counts.solid)]), bytes(&[gs(counts.boundary)]));
        let max_set = counts.liquid.max(counts.solid).max(counts.boundary) as usize;
        let buffers = SimBuffers::new(&ctx.device, solver_init, [&g0, &g1, &g2], max_set, cells as usize);
        let pipelines = create_pipelines(&ctx.device, &buffers)?;
        let step_staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("perfuse.step_readback"),
            size: std::mem::size_of::<StepState>() as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut solver = GpuSolver {
            params,
            ctx,
            errors,
            buffers,
            pipelines,
            step_staging,
            counts,
            cells,
            t: st.t,
            steps: st.steps,
            objects: st.objects.clone(),
            shapes,
            pressure_modes: cpu.pressure_modes.clone(),
            boundary_x0: st.boundary.x0.clone(),
            boundary_object: st.boundary.object.clone(),
            gravity: st.gravity,
            damping: st.damping,
            damping_solid_gravity_only: st.damping_solid_gravity_only,
            solid_flags: st.solid.flags.clone(),
            bond_count0: st.solid.bond_count0.clone(),
        };
        solver.run_stages(passes::PLACE_AND_BIN)?;
        solver.errors.take("solver creation")?;
        Ok(solver)
    }

    /// Initial contents of every state slot from the CPU solver's state.
    fn state_contents(cpu: &CpuSolver, out: &mut Vec<(Slot, Vec<u8>)>) {
        let (l, s, b) = (&cpu.st.liquid, &cpu.st.solid, &cpu.st.boundary);
        let zip4 = |x: &[Vec3], w: &dyn Fn(usize) -> f32| -> Vec<[f32; 4]> {
            x.iter().enumerate().map(|(i, v)| v4(*v, w(i))).collect()
        };
        let plain = |x: &[Vec3]| zip4(x, &|_| 0.0);
        out.push((Slot::LiquidPos, bytes(&zip4(&l.x, &|i| l.m[i]))));
        out.push((Slot::LiquidVel, bytes(&plain(&l.v))));
        out.push((Slot::LiquidVelAdv, bytes(&plain(&l.vx))));
        out.push((Slot::LiquidAcc, bytes(&plain(&l.a))));
        out.push((Slot::LiquidAcc0, bytes(&plain(&l.a0))));
        let ld: Vec<[f32; 4]> = (0..l.x.len()).map(|i| [l.rho[i], l.n_l[i], l.n_s[i], l.p[i]]).collect();
        out.push((Slot::LiquidDens, bytes(&ld)));
        out.push((Slot::SolidPos, bytes(&zip4(&s.x, &|i| s.m[i]))));
        out.push((Slot::SolidVel, bytes(&zip4(&s.v, &|i| s.m_bl[i]))));
        out.push((Slot::SolidVelAdv, bytes(&plain(&s.vx))));
        out.push((Slot::SolidAcc, bytes(&plain(&s.a))));
        out.push((Slot::SolidAcc0, bytes(&plain(&s.a0))));
        out.push((Slot::SolidDisp, bytes(&plain(&s.dx))));
        let sd: Vec<[f32; 4]> = (0..s.x.len()).map(|i| [s.rho[i], s.n_l[i], s.n_s[i], s.p[i]]).collect();
        out.push((Slot::SolidDens, bytes(&sd)));
        let dr: Vec<[f32; 2]> = (0..s.x.len()).map(|i| [s.drho[i], s.drho0[i]]).collect();
        out.push((Slot::SolidDrho, bytes(&dr)));
        out.push((Slot::SolidFlags, bytes(&s.flags)));
        let f: Vec<Mat3Gpu> = s.def_grad.iter().map(|m| (*m).into()).collect();
        out.push((Slot::SolidDefGrad, bytes(&f)));
        let st: Vec<StressGpu> =
            (0..s.x.len()).map(|i| StressGpu { tau: s.tau[i].into(), art: s.art[i].into() }).collect();
        out.push((Slot::SolidStress, bytes(&st)));
        out.push((Slot::BondTable, bytes(&s.bonds)));
        out.push((Slot::BondCount, bytes(&s.bond_count)));
        out.push((Slot::BoundaryPos, bytes(&zip4(&b.x, &|i| b.m_l[i]))));
        out.push((Slot::BoundaryVel, bytes(&zip4(&b.v, &|i| b.m_s[i]))));
        let p0: Vec<[f32; 4]> = (0..b.x.len()).map(|i| v4(b.x0[i], f32::from_bits(b.object[i]))).collect();
        out.push((Slot::BoundaryPos0, bytes(&p0)));
    }

    /// Simulation clock [s].
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Device memory used by particle storage, grids and the last-good backups [bytes].
    pub fn memory_bytes(&self) -> usize {
        self.buffers.memory_bytes() as usize
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    fn buffer(&self, slot: Slot) -> Result<&wgpu::Buffer, GpuError> {
        self.buffers.get(slot, None).ok_or_else(|| GpuError::Validation {
            context: "buffer table".into(),
            message: format!("no buffer for {}", slot.name()),
        })
    }

    fn workgroups(&self, spec: &PassSpec, grid: Option<GridOf>) -> u32 {
        let set_n = match grid {
            Some(GridOf::Liquid) => self.counts.liquid,
            Some(GridOf::Solid) => self.counts.solid,
            Some(GridOf::Boundary) => self.counts.boundary,
            None => 0,
        };
        let n = match spec.dispatch {
            Dispatch::Liquid => self.counts.liquid,
            Dispatch::Solid => self.counts.solid,
            Dispatch::Boundary => self.counts.boundary,
            Dispatch::GridParticles => set_n,
            Dispatch::GridCells => self.cells,
            Dispatch::GridCellsPlusOne => self.cells + 1,
            Dispatch::One => return 1,
        };
        n.div_ceil(spec.workgroup_size)
    }

    /// Encodes `stages` into one compute pass (wgpu orders the dispatches with barriers).
    fn encode(&self, enc: &mut wgpu::CommandEncoder, stages: &[Stage]) {
        let mut pass = enc
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("perfuse.step"), timestamp_writes: None });
        let mut dispatch = |spec: &PassSpec, grid: Option<GridOf>| {
            let wg = self.workgroups(spec, grid);
            if wg == 0 {
                return;
            }
            if grid.is_some() && self.workgroups(&passes::GRID_COUNT, grid) == 0 {
                return; // empty set: its cell list stays all-zero (empty)
            }
            let Some(p) = self.pipelines.get(spec.entry) else { return };
            let Some((_, bg)) = p.groups.iter().find(|(g, _)| *g == grid) else { return };
            pass.set_pipeline(&p.pipeline);
            pass.set_bind_group(0, bg, &[]);
            pass.dispatch_workgroups(wg, 1, 1);
        };
        for stage in stages {
            match stage {
                Stage::Pass(spec) => dispatch(spec, None),
                Stage::Grid(set) => {
                    for spec in passes::GRID_BUILD {
                        dispatch(spec, Some(*set));
                    }
                }
            }
        }
    }

    /// Runs `stages` now and waits for them (tests: single passes; apply: boundaries + grids).
    pub fn run_stages(&mut self, stages: &[Stage]) -> Result<(), GpuError> {
        let mut enc =
            self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.stages") });
        self.encode(&mut enc, stages);
        self.ctx.queue.submit([enc.finish()]);
        self.ctx.device.poll(wgpu::PollType::wait_indefinitely())?;
        self.errors.take("run_stages")
    }

    /// Submits `enc` with a copy of `StepState` appended and returns it.
    fn submit_and_read_step(&self, mut enc: wgpu::CommandEncoder) -> Result<StepState, GpuError> {
        let step = self.buffer(Slot::Step)?;
        enc.copy_buffer_to_buffer(step, 0, &self.step_staging, 0, std::mem::size_of::<StepState>() as u64);
        self.ctx.queue.submit([enc.finish()]);
        let v: Vec<StepState> = buffers::map_and_read(
            &self.ctx.device,
            &self.step_staging,
            std::mem::size_of::<StepState>() as u64,
            "step",
        )?;
        self.errors.take("step")?;
        v.first().copied().ok_or(GpuError::Readback { buffer: "step".into(), message: "empty".into() })
    }

    fn upload_params(&self) -> Result<(), GpuError> {
        let gravity_liquid = !(self.damping > 0.0 && self.damping_solid_gravity_only);
        let sp = SimParams::new(&self.params, self.counts, self.gravity, self.damping, gravity_liquid);
        self.ctx.queue.write_buffer(self.buffer(Slot::Params)?, 0, bytemuck::bytes_of(&sp));
        Ok(())
    }

    fn upload_objects(&self, t: f64) -> Result<(), GpuError> {
        let objs = objects_at(&self.params, &self.objects, &self.shapes, &self.pressure_modes, t);
        if !objs.is_empty() {
            self.ctx.queue.write_buffer(self.buffer(Slot::Objects)?, 0, bytemuck::cast_slice(&objs));
        }
        Ok(())
    }

    /// One predictor–corrector step (SPEC §5.1–5.2); on divergence the last good state is restored.
    pub fn step(&mut self) -> Result<StepInfo, SimError> {
        // First half: back up, evaluation 0 (+XSPH), Δt.
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.step_first") });
        self.buffers.encode_backup(&mut enc, false);
        self.encode(&mut enc, passes::STEP_FIRST);
        let s = self.submit_and_read_step(enc)?;
        let limit = dt_limit(s.limit);
        if s.status & gpu_types::status::DT_COLLAPSED != 0 {
            self.restore()?;
            return Err(diverged(
                self.steps,
                self.t,
                String::from("(time step)"),
                format!("time step collapsed to {:.3e} s (limited by {limit:?}), below dt_min", s.dt),
            ));
        }
        let dt = s.dt;
        let t_next = self.t + dt as f64;
        // Boundaries at tⁿ⁺¹ (host f64 clock, as the CPU's move_boundaries).
        self.upload_objects(t_next)?;
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.step_second") });
        self.encode(&mut enc, passes::STEP_SECOND);
        let s = self.submit_and_read_step(enc)?;
        if s.status & (gpu_types::status::NONFINITE_LIQUID | gpu_types::status::NONFINITE_SOLID) != 0 {
            let particle = if s.status & gpu_types::status::NONFINITE_LIQUID != 0 {
                format!("liquid #{}", s.bad_liquid)
            } else {
                format!("solid #{}", s.bad_solid)
            };
            let (step, t) = (self.steps + 1, t_next);
            self.restore()?;
            return Err(diverged(
                step,
                t,
                particle,
                format!("non-finite or runaway state (limit {:.3e} m/s)", self.params.max_speed),
            ));
        }
        self.t = t_next;
        self.steps += 1;
        Ok(StepInfo { t: self.t, dt, limit, broken_bonds: u64::from(s.broken_ends) / 2 })
    }

    /// Copies the backups back and re-places boundaries and grids at the kept clock.
    fn restore(&mut self) -> Result<(), GpuError> {
        let mut enc =
            self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.restore") });
        self.buffers.encode_backup(&mut enc, true);
        self.ctx.queue.submit([enc.finish()]);
        self.upload_objects(self.t)?;
        self.run_stages(passes::PLACE_AND_BIN)
    }

    /// Applies a command (same semantics as `CpuSolver::apply`).
    pub fn apply(&mut self, cmd: &Command) -> Result<(), SimError> {
        match cmd {
            Command::SetBoundaryMotion { object, motion } => {
                let o = self
                    .objects
                    .get_mut(*object)
                    .ok_or_else(|| SimError::BadCommand(format!("no boundary object #{object}")))?;
                let (d_now, _) = motion_at(&o.motion, self.t);
                let (d_new, _) = motion_at(motion, self.t);
                o.motion = motion.clone();
                let shift =
                    Vec3::new((d_now[0] - d_new[0]) as f32, (d_now[1] - d_new[1]) as f32, (d_now[2] - d_new[2]) as f32);
                for i in 0..self.boundary_x0.len() {
                    if self.boundary_object[i] as usize == *object {
                        self.boundary_x0[i] += shift;
                    }
                }
                self.shapes[*object].a += shift;
                if self.shapes[*object].kind == 0 {
                    self.shapes[*object].b += shift;
                }
                let p0: Vec<[f32; 4]> = self
                    .boundary_x0
                    .iter()
                    .zip(&self.boundary_object)
                    .map(|(x, o)| v4(*x, f32::from_bits(*o)))
                    .collect();
                if !p0.is_empty() {
                    self.ctx.queue.write_buffer(self.buffer(Slot::BoundaryPos0)?, 0, bytemuck::cast_slice(&p0));
                }
                self.upload_objects(self.t)?;
                self.run_stages(passes::PLACE_AND_BIN)?;
            }
            Command::SetGravity(g) => {
                let gv = Vec3::new(g[0] as f32, g[1] as f32, if self.params.dim.n() == 3 { g[2] as f32 } else { 0.0 });
                if !gv.is_finite() {
                    return Err(SimError::BadCommand("gravity must be finite".into()));
                }
                self.gravity = gv;
                self.upload_params()?;
            }
            Command::SetDamping { damping, gravity_solid_only } => {
                if !damping.is_finite() || *damping < 0.0 {
                    return Err(SimError::BadCommand("damping must be finite and ≥ 0".into()));
                }
                self.damping = *damping as f32;
                self.damping_solid_gravity_only = *gravity_solid_only;
                self.upload_params()?;
            }
            Command::SetTime(t) => {
                self.t = *t;
                self.upload_objects(*t)?;
                self.run_stages(passes::PLACE_AND_BIN)?;
            }
        }
        Ok(())
    }

    /// Reads `count` elements of slot `slot` back (tests, diagnostics).
    pub fn read_slot<T: Pod>(&self, slot: Slot, count: usize) -> Result<Vec<T>, GpuError> {
        buffers::read_buffer(&self.ctx.device, &self.ctx.queue, self.buffer(slot)?, count, slot.name())
    }

    /// Reads the whole state back (blocking).
    pub fn read_state(&self) -> Result<State, SimError> {
        let (nl, ns, nb) = (self.counts.liquid as usize, self.counts.solid as usize, self.counts.boundary as usize);
        let xyz = |v: &[f32; 4]| Vec3::new(v[0], v[1], v[2]);
        let lp: Vec<[f32; 4]> = self.read_slot(Slot::LiquidPos, nl)?;
        let lv: Vec<[f32; 4]> = self.read_slot(Slot::LiquidVel, nl)?;
        let ld: Vec<[f32; 4]> = self.read_slot(Slot::LiquidDens, nl)?;
        let sp: Vec<[f32; 4]> = self.read_slot(Slot::SolidPos, ns)?;
        let sv: Vec<[f32; 4]> = self.read_slot(Slot::SolidVel, ns)?;
        let sd: Vec<[f32; 4]> = self.read_slot(Slot::SolidDens, ns)?;
        let f: Vec<Mat3Gpu> = self.read_slot(Slot::SolidDefGrad, ns)?;
        let cap = self.counts.bond_capacity as usize;
        let table: Vec<u32> = self.read_slot(Slot::BondTable, ns * cap)?;
        let count: Vec<u32> = self.read_slot(Slot::BondCount, ns)?;
        let bp: Vec<[f32; 4]> = self.read_slot(Slot::BoundaryPos, nb)?;
        let phase = |p: &[[f32; 4]], v: &[[f32; 4]], d: &[[f32; 4]]| PhaseState {
            id: (0..p.len() as u32).collect(),
            pos: p.iter().map(xyz).collect(),
            vel: v.iter().map(xyz).collect(),
            rho: d.iter().map(|x| x[0]).collect(),
            n_l: d.iter().map(|x| x[1]).collect(),
            n_s: d.iter().map(|x| x[2]).collect(),
            p: d.iter().map(|x| x[3]).collect(),
            mass: p.iter().map(|x| x[3]).collect(),
        };
        Ok(State {
            t: self.t,
            steps: self.steps,
            liquid: phase(&lp, &lv, &ld),
            solid: phase(&sp, &sv, &sd),
            solid_extra: SolidExtra {
                flags: self.solid_flags.clone(),
                def_grad: f.into_iter().map(Mat3::from).collect(),
                bonds: count.clone(),
                bonds_initial: self.bond_count0.clone(),
                bond_lists: (0..ns).map(|i| table[i * cap..i * cap + count[i] as usize].to_vec()).collect(),
            },
            boundary: BoundaryState { pos: bp.iter().map(xyz).collect(), object: self.boundary_object.clone() },
        })
    }
}

fn dt_limit(code: u32) -> DtLimit {
    match code {
        0 => DtLimit::Viscous,
        1 => DtLimit::Sound,
        2 => DtLimit::Force,
        3 => DtLimit::Friction,
        5 => DtLimit::Fixed,
        _ => DtLimit::Max,
    }
}

/// Object shapes at rest in simulation coordinates (as `CpuSolver::new`).
fn object_shapes(params: &Params, objects: &[BoundaryObject]) -> Vec<ObjectGeom> {
    objects
        .iter()
        .map(|o| match &o.shape {
            crate::scenario::Region::Box { min, max } => {
                ObjectGeom { kind: 0, a: params.to_sim(*min), b: params.to_sim(*max) }
            }
            crate::scenario::Region::Sphere { centre, radius } => {
                ObjectGeom { kind: 1, a: params.to_sim(*centre), b: Vec3::new(*radius as f32, 0.0, 0.0) }
            }
        })
        .collect()
}

/// The object table at time t (twin of `CpuSolver::move_boundaries`: same f64 → f32 conversions).
fn objects_at(
    params: &Params,
    objects: &[BoundaryObject],
    shapes: &[ObjectGeom],
    modes: &[ObjectPressure],
    t: f64,
) -> Vec<ObjectGpu> {
    let three = params.dim.n() == 3;
    let z = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, if three { a[2] as f32 } else { 0.0 });
    objects
        .iter()
        .enumerate()
        .map(|(k, o)| {
            let (d, v) = motion_at(&o.motion, t);
            let (d, v) = (z(d), z(v));
            let mut g = shapes[k];
            g.a += d;
            if g.kind == 0 {
                g.b += d;
            }
            let m = modes.get(k).copied().unwrap_or(ObjectPressure { density: -1.0, pressure: 0.0 });
            ObjectGpu {
                geom_a: v4(g.a, 0.0),
                geom_b: v4(g.b, 0.0),
                disp: v4(d, 0.0),
                vel: v4(v, 0.0),
                density: m.density,
                pressure: m.pressure,
                kind: g.kind,
                _pad: 0,
            }
        })
        .collect()
}

/// One pipeline per entry point, with its explicit layout and bind group(s).
fn create_pipelines(device: &wgpu::Device, buffers: &SimBuffers) -> Result<HashMap<&'static str, Pipeline>, GpuError> {
    let mut modules: HashMap<&'static str, wgpu::ShaderModule> = HashMap::new();
    let mut out = HashMap::new();
    for spec in passes::ALL_PASSES {
        if !modules.contains_key(spec.family) {
            let src = shaders::shader_source(spec.family).map_err(|e| GpuError::Validation {
                context: format!("shader {}", spec.family),
                message: e.to_string(),
            })?;
            let m = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(&format!("perfuse.{}", spec.family)),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            });
            modules.insert(spec.family, m);
        }
        let Some(module) = modules.get(spec.family) else { continue };
        let label = format!("perfuse.{}", spec.entry);
        let layout = bindings::create_layout(device, &label, spec.slots);
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&label),
            layout: Some(&pl),
            module,
            entry_point: Some(spec.entry),
            compilation_options: Default::default(),
            cache: None,
        });
        let instances: &[Option<GridOf>] = if spec.family == "grid" {
            &[Some(GridOf::Liquid), Some(GridOf::Solid), Some(GridOf::Boundary)]
        } else {
            &[None]
        };
        let mut groups = Vec::new();
        for grid in instances {
            let mut entries = Vec::new();
            for slot in spec.slots {
                let buf = buffers.get(*slot, *grid).ok_or_else(|| GpuError::Validation {
                    context: format!("bind group {}", spec.entry),
                    message: format!("no buffer for slot {}", slot.name()),
                })?;
                entries.push(wgpu::BindGroupEntry { binding: slot.binding(), resource: buf.as_entire_binding() });
            }
            let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(&label),
                layout: &layout,
                entries: &entries,
            });
            groups.push((*grid, bg));
        }
        out.insert(spec.entry, Pipeline { pipeline, groups });
    }
    Ok(out)
}
