//! `sim::gpu` — the wgpu/WGSL back-end: the algorithm of the CPU reference solver `sim::cpu` (thesis
//! chapter 2, SPEC §5), as compute passes, one WGSL file per CPU module of the same name (`grid`,
//! `density`, `solid`, `forces`, `integrate`, `dt`, `fracture`; shared code in `shaders/common.wgsl`).
//!
//! All particle state lives on the GPU; the host encodes the ordered pass lists of [`passes`] and reads
//! back only what it must. Particles stay in id order and every neighbour sum runs in the CPU's
//! canonical order (125 cells in a fixed offset order, ascending index inside a cell), so the two
//! back-ends differ only by f32 rounding of individual operations (transcendental functions, possible
//! FMA contraction). No float atomics: the grid uses integer atomics plus a per-cell sort, Δt a
//! bit-pattern atomicMin/Max, so a run is bit-reproducible on one adapter.
//!
//! Host synchronisation (batched stepping, [`GpuSolver::advance`]): a batch of up to
//! [`gpu_types::MAX_BATCH`] steps is encoded into one submission with ONE readback at its end (the
//! 608-byte `BatchState`). Δt, the clock and the analytic boundary motions stay on the GPU
//! (`shaders/batch.wgsl`): the clock is an f32 pair updated by two-sum, the object poses at tⁿ⁺¹ are
//! evaluated from it by `batch_motion` (the twin of `scenario::motion_at`, in f32), and every pass of a
//! step is dispatched indirectly from arguments that `batch_begin` zeroes once the batch has stopped
//! (t_end reached, Δt collapsed, non-finite state), so the rest of the batch is a no-op. The host keeps
//! the authoritative f64 clock by summing the per-step Δt read back at the end, exactly as the CPU
//! does. The state (and the object table) is backed up at the start of each batch; a diverged batch is
//! restored and re-run one step per batch (bit-identical: nothing depends on the batch length) to find
//! the diverging step, which is reported as before with the last good state kept. [`GpuSolver::step`]
//! is a batch of one. One batch in 32 is timed per pass family with timestamp queries when the device
//! has them (`pass_times`). The initial state, the bond table (built once, SPEC §4.6) and the object
//! shapes come from `CpuSolver::new`, so both back-ends start bit-identical.
//!
//! Emitters and sinks (`shaders/emit.wgsl`, twin `sim::cpu::emit`) change the liquid count on the GPU:
//! the liquid buffers hold the scenario's capacity, the live count is `batch.n_liquid`, and after the
//! emitter passes the host-encoded copy `Stage::SyncCounts` puts it into the uniforms' `counts.x` and
//! the liquid grid set, while `emit_apply` rewrites the liquid dispatch arguments; the host learns the
//! count from the batch readback. Without emitters or sinks none of this is encoded.

pub mod bindings;
pub mod buffers;
pub mod device;
pub mod gpu_types;
pub mod passes;
pub mod shaders;

use super::cpu::forces::ObjectGeom;
use super::cpu::{CpuSolver, ObjectContact, contacts_in_effect};
use super::params::Params;
use super::state::{BoundaryState, PhaseState, SolidExtra, State};
use super::{Command, DtLimit, SimError, StepInfo};
use crate::scenario::{BoundaryObject, GeneratedParticles, Motion, motion_at};
use bindings::Slot;
use buffers::SimBuffers;
use bytemuck::Pod;
pub use device::{GpuContext, GpuError};
use glam::{Mat3, Vec3};
use gpu_types::{
    BATCH_HEADER_OFFSET, BatchState, Counts, GridSet, MAX_BATCH, Mat3Gpu, MotionGpu, ObjectGpu, SimParams, StepState,
    StressGpu,
};
use passes::{Dispatch, GridOf, PassSpec, Stage};
use std::collections::{BTreeMap, HashMap};

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
    batch_staging: wgpu::Buffer,
    /// The GPU clock (f32 pair) at the end of the last batch, restored with a diverged batch's state.
    clock: [f32; 2],
    /// Workgroup counts per dispatch class (see [`dispatch_class`]), uploaded with each batch.
    wg_template: [u32; 8],
    timer: Option<PassTimer>,
    batches: u64,
    /// Host time spent pushing and popping the per-batch error scopes \[s\] (`error_scope_cost`).
    scope_host_s: f64,
    /// Whether the liquid's ρ, nˡ, nˢ and p and the solid's nˡ on the device are those of the current
    /// positions: true after a batch (its last step's evaluation 1 summed them, and the corrector and
    /// fracture move nothing), false after anything the host runs or writes between batches. The first
    /// step of a batch then skips `density_liquid` and runs `density_solid_kept` in evaluation 0, as
    /// every later step of a batch does — the CPU's reuse of its evaluation-1 sums
    /// (`CpuSolver::liquid_density_generation`, `solid_n_l_generation`).
    liquid_density_fresh: bool,
    counts: Counts,
    cells: u32,
    t: f64,
    steps: u64,
    objects: Vec<BoundaryObject>,
    /// Each object's shape at rest (simulation coordinates), as `CpuSolver::shapes`.
    shapes: Vec<ObjectGeom>,
    contacts: Vec<ObjectContact>,
    /// The moulded beds' surfaces (static; uploaded once as `bed_table`).
    beds: crate::sim::bed::BedTable,
    boundary_x0: Vec<Vec3>,
    boundary_object: Vec<u32>,
    /// Per boundary particle: it stands in the tissue's place (`BoundarySet::m_sn` > 0); uploaded as the
    /// high bit of its object word (`BOUNDARY_IN_TISSUE`).
    boundary_in_tissue: Vec<bool>,
    gravity: Vec3,
    damping: f32,
    damping_solid_gravity_only: bool,
    /// `Command::SetSuction(false)` holds: prescribed pressures show the mirror's, `n_sinks` = 0.
    suction_held: bool,
    /// Sinks of the scenario (`n_sinks` when the suction acts).
    sink_count: u32,
    solid_flags: Vec<u32>,
    bond_count0: Vec<u32>,
    /// The scenario has emitters or sinks: the liquid count changes on the GPU (emit.wgsl).
    emit_active: bool,
    /// Liquid particles the buffers hold room for (= the initial count without emitters).
    capacity: u32,
    /// Particles emitted and sunk since t = 0, as of the last batch.
    emitted: u64,
    sunk: u64,
    /// An emitter found the capacity full.
    capacity_hit: bool,
    /// Number of emitters (flow-table regions).
    emit_count: usize,
}

/// A keyframe of the GPU back-end ([`GpuSolver::snapshot`]): the state buffers byte for byte (plus
/// the emitters' flow tables, which only the device holds) and the host's mirror of the clock, counts,
/// objects and command-set values.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct GpuSnapshot {
    clock: [f32; 2],
    t: f64,
    steps: u64,
    liquid_count: u32,
    objects: Vec<BoundaryObject>,
    shapes: Vec<ObjectGeom>,
    boundary_x0: Vec<Vec3>,
    gravity: Vec3,
    damping: f32,
    damping_solid_gravity_only: bool,
    suction_held: bool,
    emitted: u64,
    sunk: u64,
    capacity_hit: bool,
    /// (slot name, contents) of every slot of [`SNAPSHOT_SLOTS`] this solver has.
    buffers: Vec<(String, Vec<u8>)>,
}

/// What a keyframe holds on the device: the evolving state and the flow tables set by commands.
fn snapshot_slots() -> impl Iterator<Item = Slot> {
    buffers::STATE_SLOTS.iter().copied().chain([Slot::EmitFlow])
}

/// One element of a batched step.
#[derive(Clone, Copy)]
enum Item {
    Dispatch(PassSpec, Option<GridOf>, Mode),
    /// Copy the live liquid count into the uniforms (after the emitters).
    SyncCounts,
}

/// `boundary_pos0.w` of a boundary particle: its object index, with `BOUNDARY_IN_TISSUE` where it
/// stands in the tissue's place (`BoundarySet::m_sn` > 0), as bits.
fn object_word(object: u32, in_tissue: bool) -> f32 {
    f32::from_bits(object | if in_tissue { gpu_types::BOUNDARY_IN_TISSUE } else { 0 })
}
fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

fn bytes<T: Pod>(v: &[T]) -> Vec<u8> {
    bytemuck::cast_slice(v).to_vec()
}

/// Per-pass GPU timers: timestamp queries around one compute pass per segment of a timed batch (every
/// [`TIMED_EVERY`]th) — a run of dispatches of one family, or with `by_entry` of one entry point —
/// resolved and read back with that batch's `BatchState`.
struct PassTimer {
    query_set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    staging: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
    /// Segments per entry point instead of per family ([`GpuSolver::time_entry_points`]).
    by_entry: bool,
    /// Measured seconds per family (or entry point), and the steps they cover.
    totals: BTreeMap<&'static str, f64>,
    timed_steps: u64,
}

/// Timestamp queries in one timed batch (wgpu's maximum query-set size).
const MAX_QUERIES: u32 = wgpu::QUERY_SET_MAX_QUERIES;
/// One batch in this many is timed per pass.
const TIMED_EVERY: u64 = 32;

/// Host accumulator of what a batch did (the GPU side of `sim::Advance`).
#[derive(Clone, Debug, Default)]
pub struct BatchTotals {
    pub steps: u64,
    pub dt_min: f32,
    pub dt_max: f32,
    /// Steps limited by each criterion, in `DtLimit::ALL` order.
    pub limited_by: [u64; 6],
    pub broken_bonds: u64,
    /// Wall time spent in batches \[s\] (whole-step timing without timestamp queries).
    pub wall_s: f64,
}

/// Index of a dispatch's class in `BatchState::wg` / `indirect_args` (batch.wgsl `write_args`).
fn dispatch_class(spec: &PassSpec, grid: Option<GridOf>) -> usize {
    match spec.dispatch {
        Dispatch::Liquid => 0,
        Dispatch::Solid => 1,
        Dispatch::Boundary => 2,
        Dispatch::GridParticles => match grid {
            Some(GridOf::Solid) => 1,
            Some(GridOf::Boundary) => 2,
            Some(GridOf::Ghost) => 6,
            _ => 0,
        },
        // a fixed count, never written to the indirect arguments: dispatched directly
        Dispatch::Ghost => 6,
        Dispatch::GridChunks => 3,
        Dispatch::GridChunksPlusOne => 4,
        Dispatch::One => 5,
    }
}

/// How an item of a batched step is dispatched.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Direct,
    Indirect,
}

/// `t` as an f32 pair hi + lo (batch.wgsl's clock format).
fn split_pair(t: f64) -> [f32; 2] {
    let hi = t as f32;
    [hi, (t - hi as f64) as f32]
}

fn diverged(step: u64, t: f64, particle: String, reason: String) -> SimError {
    SimError::Diverged { step, t, particle, reason }
}

/// Size of common.wgsl's `LiquidMove` (position, velocity, a⁰, id: four vec4s; `grid_reorder`).
const LIQUID_MOVE_BYTES: usize = 64;

/// Whether the pass `entry` is left out for a skeleton held entirely still (`Params::solid_dynamic`
/// false: every solid particle kinematic, as in the Brinkman channel), as `CpuSolver::evaluate` and
/// `step_inner` leave its work out: nothing reads the solid's continuity, stress, forces, XSPH velocity,
/// F or bond breaking there (its particles never move, and `forces_solid`/`forces_solid_xsph` would only
/// write zero and v, which the buffers hold from the upload). `density_solid` still runs when the
/// liquid–void attraction (3.4) reads the skeleton's nˡ (a fixed fabric).
fn static_skeleton_skips(entry: &str, wicking: bool) -> bool {
    let skipped = [
        passes::SOLID_STRESS.entry,
        passes::SOLID_FIT.entry,
        passes::FORCES_SOLID.entry,
        passes::FORCES_SOLID_XSPH.entry,
        passes::SOLID_DEF_GRAD.entry,
        passes::FRACTURE_APPLY.entry,
    ];
    let density_solid = [passes::DENSITY_SOLID.entry, passes::DENSITY_SOLID_KEPT.entry];
    skipped.contains(&entry) || (density_solid.contains(&entry) && !wicking)
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
        let device = ctx.device.clone();
        let scope = device::ErrorScope::push(&device);
        let built = Self::build(ctx, cpu);
        scope.pop("solver creation")?;
        built
    }

    fn build(ctx: GpuContext, cpu: &CpuSolver) -> Result<GpuSolver, SimError> {
        let errors = device::ErrorSink::install(&ctx.device);
        let params = cpu.params.clone();
        let st = &cpu.st;
        let counts = Counts {
            liquid: st.liquid.x.len() as u32,
            solid: st.solid.x.len() as u32,
            boundary: st.boundary.x.len() as u32,
            bond_capacity: st.solid.bond_capacity as u32,
            objects: st.objects.len() as u32,
            ghosts: cpu.ghosts.len() as u32,
        };
        let cells = params.grid.cell_count() as u32;
        let shapes = object_shapes(&params, &st.objects);
        let emit_active = st.emit.is_active();
        let capacity = if emit_active { st.emit.capacity.max(st.liquid.x.len()) as u32 } else { counts.liquid };
        let mut solver_init = Vec::new();
        Self::state_contents(cpu, &mut solver_init);
        Self::emit_contents(cpu, &mut solver_init);
        // Liquid buffers hold `capacity` particles (emitters append behind the live ones).
        for (slot, data) in solver_init.iter_mut() {
            let elem = match slot {
                Slot::LiquidPos
                | Slot::LiquidVel
                | Slot::LiquidVelAdv
                | Slot::LiquidAcc
                | Slot::LiquidAcc0
                | Slot::LiquidDens => 16,
                Slot::LiquidId | Slot::LiquidSees => 4,
                _ => continue,
            };
            data.resize(elem * capacity as usize, 0);
        }
        let gravity_liquid = !(st.damping > 0.0 && st.damping_solid_gravity_only);
        let sp = SimParams::new(&params, counts, st.gravity, st.damping, gravity_liquid, st.suction_held);
        solver_init.push((Slot::Params, bytes(&[sp])));
        solver_init.push((Slot::Step, bytes(&[StepState::default()])));
        let modes = contacts_in_effect(&cpu.contacts, st.suction_held);
        let objects = objects_at(&params, &st.objects, &shapes, &modes, &cpu.beds.offsets, st.t);
        solver_init.push((Slot::Objects, bytes(&objects)));
        let wg_template = [
            capacity.div_ceil(passes::WORKGROUP),
            counts.solid.div_ceil(passes::WORKGROUP),
            counts.boundary.div_ceil(passes::WORKGROUP),
            cells.div_ceil(passes::SCAN_CHUNK).div_ceil(passes::WORKGROUP),
            (cells + 1).div_ceil(passes::SCAN_CHUNK).div_ceil(passes::WORKGROUP),
            1,
            0,
            0,
        ];
        let clock = split_pair(st.t);
        let mut batch0: BatchState = bytemuck::Zeroable::zeroed();
        (batch0.t_hi, batch0.t_lo, batch0.wg) = (clock[0], clock[1], wg_template);
        (batch0.n_liquid, batch0.emitted, batch0.sunk) = (counts.liquid, st.emit.emitted as u32, st.emit.sunk as u32);
        solver_init.push((Slot::Batch, bytes(&[batch0])));
        solver_init
            .push((Slot::Motions, bytes(&motion_table(&params, &st.objects, &shapes, &modes, &cpu.beds.offsets))));
        solver_init.push((Slot::BedTable, bytes(&cpu.beds.gpu_words())));
        solver_init.push((Slot::IndirectArgs, vec![0u8; 4 * 18]));
        for (slot, n) in [
            (Slot::LiquidOrder, capacity as usize),
            (Slot::SolidOrder, counts.solid as usize),
            (Slot::BoundaryOrder, counts.boundary as usize),
        ] {
            solver_init.push((slot, vec![0u8; std::mem::size_of::<gpu_types::CellEntry>() * n]));
        }
        Self::ghost_contents(cpu, counts.liquid.max(capacity), &mut solver_init);
        solver_init.push((Slot::GhostOrder, vec![0u8; std::mem::size_of::<gpu_types::CellEntry>() * cpu.ghosts.len()]));
        for slot in [Slot::LiquidCellStart, Slot::SolidCellStart, Slot::BoundaryCellStart, Slot::GhostCellStart] {
            solver_init.push((slot, vec![0u8; 4 * (cells as usize + 1)]));
        }
        // grid_reorder's scratch: one LiquidMove (4 vec4s) per liquid particle, when it runs
        let scratch = if params.reorder_liquid { LIQUID_MOVE_BYTES * capacity as usize } else { 0 };
        solver_init.push((Slot::LiquidScratch, vec![0u8; scratch]));
        let gs = |n: u32| GridSet { n, cells, _pad0: 0, _pad1: 0 };
        let (g0, g1, g2) = (bytes(&[gs(counts.liquid)]), bytes(&[gs(counts.solid)]), bytes(&[gs(counts.boundary)]));
        let g3 = bytes(&[gs(counts.ghosts)]);
        let max_set = capacity.max(counts.solid).max(counts.boundary).max(counts.ghosts) as usize;
        let buffers = SimBuffers::new(&ctx.device, solver_init, [&g0, &g1, &g2, &g3], max_set, cells as usize);
        let periodic = params.periodic_len().cmpgt(glam::Vec3::ZERO).any();
        let pipelines = create_pipelines(&ctx.device, &buffers, params.reorder_liquid, periodic)?;
        let batch_staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("perfuse.batch_readback"),
            size: std::mem::size_of::<BatchState>() as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let timer = ctx.timestamps.then(|| PassTimer::new(&ctx));
        let mut solver = GpuSolver {
            params,
            ctx,
            errors,
            buffers,
            pipelines,
            batch_staging,
            clock,
            wg_template,
            timer,
            batches: 0,
            scope_host_s: 0.0,
            liquid_density_fresh: false,
            counts,
            cells,
            t: st.t,
            steps: st.steps,
            objects: st.objects.clone(),
            shapes,
            contacts: cpu.contacts.clone(),
            beds: cpu.beds.clone(),
            boundary_x0: st.boundary.x0.clone(),
            boundary_object: st.boundary.object.clone(),
            boundary_in_tissue: st.boundary.m_sn.iter().map(|&m| m > 0.0).collect(),
            gravity: st.gravity,
            damping: st.damping,
            damping_solid_gravity_only: st.damping_solid_gravity_only,
            suction_held: st.suction_held,
            sink_count: st.emit.sinks.len().min(gpu_types::MAX_SINKS) as u32,
            solid_flags: st.solid.flags.clone(),
            bond_count0: st.solid.bond_count0.clone(),
            emit_active,
            capacity,
            emitted: st.emit.emitted,
            sunk: st.emit.sunk,
            capacity_hit: st.emit.capacity_reached,
            emit_count: st.emit.emitters.len(),
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
        let st: Vec<StressGpu> = (0..s.x.len()).map(|i| StressGpu::pack(s.tau[i], s.art[i])).collect();
        out.push((Slot::SolidStress, bytes(&st)));
        out.push((Slot::SolidPosRef, bytes(&plain(&s.x_ref))));
        out.push((Slot::SolidNormal0, bytes(&plain(&s.normal0))));
        let fit: Vec<Mat3Gpu> =
            (0..s.x.len()).map(|i| s.hg_fit.get(i).copied().unwrap_or(s.def_grad[i]).into()).collect();
        out.push((Slot::SolidAffine, bytes(&fit)));
        out.push((Slot::BondTable, bytes(&s.bonds)));
        out.push((Slot::BondCount, bytes(&s.bond_count)));
        out.push((Slot::BondCount0, bytes(&s.bond_count0)));
        out.push((Slot::BondLimit, bytes(&s.bond_limit)));
        out.push((Slot::BoundaryPos, bytes(&zip4(&b.x, &|i| b.m_l[i]))));
        out.push((Slot::BoundaryVel, bytes(&zip4(&b.v, &|i| b.m_s[i]))));
        let p0: Vec<[f32; 4]> =
            (0..b.x.len()).map(|i| v4(b.x0[i], object_word(b.object[i], b.m_sn[i] > 0.0))).collect();
        out.push((Slot::BoundaryPos0, bytes(&p0)));
    }

    /// The capsule's ghost sites (`sim::ghosts`): reference, CSR by owner, and zeroed placement, state
    /// and per-liquid flags (`ghost_place` fills them with the first grid build).
    fn ghost_contents(cpu: &CpuSolver, liquid_capacity: u32, out: &mut Vec<(Slot, Vec<u8>)>) {
        let gh = &cpu.ghosts;
        let mut r: Vec<[f32; 4]> = Vec::with_capacity(2 * gh.len());
        for g in 0..gh.len() {
            r.push(v4(gh.d[g], f32::from_bits(gh.owner[g])));
            r.push([gh.m_s[g], gh.m_l[g], 0.0, 0.0]);
        }
        out.push((Slot::GhostRef, bytes(&r)));
        out.push((Slot::GhostStart, bytes(&gh.start)));
        out.push((Slot::GhostPos, vec![0u8; 16 * gh.len()]));
        out.push((Slot::GhostFrame, vec![0u8; 32 * gh.len()]));
        out.push((Slot::GhostState, vec![0u8; 32 * gh.len()]));
        out.push((Slot::LiquidSees, vec![0u8; 4 * liquid_capacity as usize]));
    }

    /// Emitter tables from the CPU solver's `EmitState` (same slots, flows, accounts) and the ids.
    fn emit_contents(cpu: &CpuSolver, out: &mut Vec<(Slot, Vec<u8>)>) {
        let e = &cpu.st.emit;
        let mut state: gpu_types::EmitStateGpu = bytemuck::Zeroable::zeroed();
        let mut slots: Vec<[f32; 4]> = Vec::new();
        let mut flow = vec![0f32; gpu_types::FLOW_STRIDE * e.emitters.len().max(1)];
        for (k, em) in e.emitters.iter().take(gpu_types::MAX_EMITTERS).enumerate() {
            state.emitters[k] = gpu_types::EmitterGpu {
                dir: v4(em.dir, em.speed_per_flow),
                velocity: v4(em.velocity, 0.0),
                region_a: v4(em.region.a, 0.0),
                region_b: v4(em.region.b, 0.0),
                slot_start: slots.len() as u32,
                slot_count: em.slots.len() as u32,
                cursor: em.cursor,
                count: em.count as u32,
                mass: em.mass,
                volume: em.volume,
                acc: em.acc,
                region_kind: em.region.kind,
            };
            slots.extend(em.slots.iter().map(|x| v4(*x, 0.0)));
            flow_region(&em.flow, &mut flow[k * gpu_types::FLOW_STRIDE..(k + 1) * gpu_types::FLOW_STRIDE]);
        }
        for (k, g) in e.sinks.iter().take(gpu_types::MAX_SINKS).enumerate() {
            state.sinks[k] =
                gpu_types::SinkGpu { a: v4(g.a, 0.0), b: v4(g.b, 0.0), kind: g.kind, ..Default::default() };
        }
        state.n_emitters = e.emitters.len().min(gpu_types::MAX_EMITTERS) as u32;
        state.n_sinks = if cpu.st.suction_held { 0 } else { e.sinks.len().min(gpu_types::MAX_SINKS) as u32 };
        state.n_slots = slots.len() as u32;
        state.capacity = e.capacity.max(cpu.st.liquid.x.len()) as u32;
        state.id_base = e.id_base;
        let r = super::cpu::emit::BLOCK_FACTOR * cpu.params.dx_liquid;
        state.block_r2 = r * r;
        out.push((Slot::EmitState, bytes(&[state])));
        out.push((Slot::EmitBlocked, vec![0u8; 4 * slots.len().max(1)]));
        out.push((Slot::EmitSlots, bytes(&slots)));
        out.push((Slot::EmitFlow, bytes(&flow)));
        out.push((Slot::LiquidId, bytes(&cpu.st.liquid.id)));
    }

    /// Simulation clock \[s\].
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Device memory used by particle storage, grids and the last-good backups \[bytes\].
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

    /// Liquid invocations a pass is encoded for: the capacity with emitters (the GPU's indirect
    /// arguments and `params.counts.x` then hold the live count), else the count.
    fn liquid_dispatch(&self) -> u32 {
        if self.emit_active { self.capacity } else { self.counts.liquid }
    }

    /// Copies the live liquid count (`batch.n_liquid`) into the uniforms' `counts.x` and the liquid
    /// grid set's `n` (between compute passes; emitters and sinks change it on the GPU).
    fn encode_sync(&self, enc: &mut wgpu::CommandEncoder) {
        let (Ok(batch), Ok(params), Some(gs)) = (
            self.buffer(Slot::Batch),
            self.buffer(Slot::Params),
            self.buffers.get(Slot::GridSet, Some(GridOf::Liquid)),
        ) else {
            return;
        };
        let src = std::mem::offset_of!(BatchState, n_liquid) as u64;
        enc.copy_buffer_to_buffer(batch, src, params, std::mem::offset_of!(SimParams, counts) as u64, 4);
        enc.copy_buffer_to_buffer(batch, src, gs, 0, 4);
    }

    fn workgroups(&self, spec: &PassSpec, grid: Option<GridOf>) -> u32 {
        let set_n = match grid {
            Some(GridOf::Liquid) => self.liquid_dispatch(),
            Some(GridOf::Solid) => self.counts.solid,
            Some(GridOf::Boundary) => self.counts.boundary,
            Some(GridOf::Ghost) => self.counts.ghosts,
            None => 0,
        };
        let n = match spec.dispatch {
            Dispatch::Liquid => self.liquid_dispatch(),
            Dispatch::Solid => self.counts.solid,
            Dispatch::Boundary => self.counts.boundary,
            // none unless `membrane.ghosts` built some (`CpuSolver::new`)
            Dispatch::Ghost => self.counts.ghosts,
            Dispatch::GridParticles => set_n,
            Dispatch::GridChunks => self.cells.div_ceil(passes::SCAN_CHUNK),
            Dispatch::GridChunksPlusOne => (self.cells + 1).div_ceil(passes::SCAN_CHUNK),
            Dispatch::One => return 1,
        };
        n.div_ceil(spec.workgroup_size)
    }

    /// Encodes `stages` into compute passes (wgpu orders the dispatches with barriers), split where
    /// the host copies the live liquid count ([`Stage::SyncCounts`]).
    fn encode(&self, enc: &mut wgpu::CommandEncoder, stages: &[Stage]) {
        let mut i = 0;
        while i < stages.len() {
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("perfuse.step"),
                    timestamp_writes: None,
                });
                while i < stages.len() {
                    match &stages[i] {
                        Stage::Pass(spec) => self.dispatch_item(&mut pass, spec, None, Mode::Direct),
                        Stage::Grid(set) => {
                            for spec in passes::GRID_BUILD {
                                self.dispatch_item(&mut pass, spec, Some(*set), Mode::Direct);
                            }
                        }
                        Stage::SyncCounts => break,
                    }
                    i += 1;
                }
            }
            if i < stages.len() {
                self.encode_sync(enc);
                i += 1;
            }
        }
    }

    /// Runs `stages` now and waits for them (tests: single passes; apply: boundaries + grids).
    pub fn run_stages(&mut self, stages: &[Stage]) -> Result<(), GpuError> {
        self.liquid_density_fresh = false;
        let device = self.ctx.device.clone();
        device::ErrorScope::around(&device, "run_stages", || {
            let mut enc =
                device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.stages") });
            self.encode(&mut enc, stages);
            self.ctx.queue.submit([enc.finish()]);
            device.poll(wgpu::PollType::wait_indefinitely())?;
            Ok(())
        })?;
        self.errors.take("run_stages")
    }

    fn upload_params(&mut self) -> Result<(), GpuError> {
        self.liquid_density_fresh = false;
        let gravity_liquid = !(self.damping > 0.0 && self.damping_solid_gravity_only);
        let sp =
            SimParams::new(&self.params, self.counts, self.gravity, self.damping, gravity_liquid, self.suction_held);
        self.ctx.queue.write_buffer(self.buffer(Slot::Params)?, 0, bytemuck::bytes_of(&sp));
        Ok(())
    }

    fn upload_objects(&self, t: f64) -> Result<(), GpuError> {
        let modes = contacts_in_effect(&self.contacts, self.suction_held);
        let objs = objects_at(&self.params, &self.objects, &self.shapes, &modes, &self.beds.offsets, t);
        if !objs.is_empty() {
            self.ctx.queue.write_buffer(self.buffer(Slot::Objects)?, 0, bytemuck::cast_slice(&objs));
        }
        Ok(())
    }

    fn upload_motions(&self) -> Result<(), GpuError> {
        let modes = contacts_in_effect(&self.contacts, self.suction_held);
        let m = motion_table(&self.params, &self.objects, &self.shapes, &modes, &self.beds.offsets);
        if !m.is_empty() {
            self.ctx.queue.write_buffer(self.buffer(Slot::Motions)?, 0, bytemuck::cast_slice(&m));
        }
        Ok(())
    }

    /// Writes the boundary particles' rest positions (and objects, with the in-tissue bit) from the
    /// host's copy.
    fn upload_boundary_pos0(&self) -> Result<(), GpuError> {
        let p0: Vec<[f32; 4]> = self
            .boundary_x0
            .iter()
            .zip(&self.boundary_object)
            .zip(&self.boundary_in_tissue)
            .map(|((x, o), &t)| v4(*x, object_word(*o, t)))
            .collect();
        if !p0.is_empty() {
            self.ctx.queue.write_buffer(self.buffer(Slot::BoundaryPos0)?, 0, bytemuck::cast_slice(&p0));
        }
        Ok(())
    }

    /// Writes the host's live liquid count into the liquid grid set's uniform.
    fn upload_liquid_grid_count(&self) {
        let gs = GridSet { n: self.counts.liquid, cells: self.cells, _pad0: 0, _pad1: 0 };
        if let Some(b) = self.buffers.get(Slot::GridSet, Some(GridOf::Liquid)) {
            self.ctx.queue.write_buffer(b, 0, bytemuck::bytes_of(&gs));
        }
    }

    /// Sets the GPU clock (the f32 pair of batch.wgsl) to `clock`.
    fn upload_clock(&mut self, clock: [f32; 2]) -> Result<(), GpuError> {
        self.clock = clock;
        self.ctx.queue.write_buffer(self.buffer(Slot::Batch)?, 0, bytemuck::cast_slice(&clock));
        Ok(())
    }

    /// The items of one batched step: `batch_begin`, the first half (indirect), `batch_motion`, the
    /// second half (indirect; the emitters and the count copy after the advance when there are any),
    /// `batch_end`. With `reuse_liquid_density` evaluation 0 leaves out `density_liquid` (its sums are
    /// still those of the current positions: see `liquid_density_fresh`).
    fn step_items(&self, reuse_liquid_density: bool) -> Vec<Item> {
        let mut out = vec![Item::Dispatch(passes::BATCH_BEGIN, None, Mode::Direct)];
        let push = |stages: &[Stage], out: &mut Vec<Item>| {
            for stage in stages {
                match stage {
                    // a pass that writes the indirect arguments cannot be dispatched from them
                    Stage::Pass(spec) if spec.slots.contains(&Slot::IndirectArgs) => {
                        out.push(Item::Dispatch(*spec, None, Mode::Direct))
                    }
                    Stage::Pass(spec) => out.push(Item::Dispatch(*spec, None, Mode::Indirect)),
                    Stage::Grid(set) => out.extend(
                        passes::GRID_BUILD.iter().map(|spec| Item::Dispatch(*spec, Some(*set), Mode::Indirect)),
                    ),
                    Stage::SyncCounts => out.push(Item::SyncCounts),
                }
            }
        };
        // evaluation 0 on the positions of the last evaluation 1: the liquid's densities and the solid's
        // nˡ are still those sums (`liquid_density_fresh`)
        let first: Vec<Stage> = passes::STEP_FIRST
            .iter()
            .filter(|st| {
                !(reuse_liquid_density && matches!(st, Stage::Pass(spec) if spec.entry == passes::DENSITY_LIQUID.entry))
            })
            .map(|st| match st {
                Stage::Pass(spec) if reuse_liquid_density && spec.entry == passes::DENSITY_SOLID.entry => {
                    Stage::Pass(passes::DENSITY_SOLID_KEPT)
                }
                other => *other,
            })
            .collect();
        push(&first, &mut out);
        out.push(Item::Dispatch(passes::BATCH_MOTION, None, Mode::Direct));
        push(passes::STEP_ADVANCE, &mut out);
        if self.emit_active {
            push(passes::STEP_EMIT, &mut out);
        }
        // Boundary objects that never move (every motion Static: walls, plates) keep the poses and the
        // cell list that the last PLACE_AND_BIN gave them; a command that sets a motion re-places them and
        // the next batch places and bins them every step again.
        let fixed = self.objects.iter().all(|o| matches!(o.motion, Motion::Static));
        let second: Vec<Stage> = passes::STEP_SECOND
            .iter()
            .filter(|st| {
                let boundary_stage = match st {
                    Stage::Pass(spec) => spec.entry == passes::INTEGRATE_BOUNDARY.entry,
                    Stage::Grid(set) => *set == GridOf::Boundary,
                    Stage::SyncCounts => false,
                };
                !(fixed && boundary_stage)
            })
            .copied()
            .collect();
        push(&second, &mut out);
        out.push(Item::Dispatch(passes::BATCH_END, None, Mode::Direct));
        out
    }

    /// Records one dispatch of a batch into `pass`.
    fn dispatch_item(&self, pass: &mut wgpu::ComputePass<'_>, spec: &PassSpec, grid: Option<GridOf>, mode: Mode) {
        let wg = self.workgroups(spec, grid);
        if wg == 0 || (grid.is_some() && self.workgroups(&passes::GRID_COUNT, grid) == 0) {
            return;
        }
        // the hourglass fit is not dispatched when the control is off (the CPU does not compute it)
        if spec.entry == passes::SOLID_FIT.entry && self.params.hourglass <= 0.0 {
            return;
        }
        // nor the renumbering of the liquid when the scenario keeps its order
        let reorder = [passes::GRID_REORDER_GATHER.entry, passes::GRID_REORDER_APPLY.entry];
        if !self.params.reorder_liquid && reorder.contains(&spec.entry) {
            return;
        }
        if !self.params.solid_dynamic && static_skeleton_skips(spec.entry, self.params.wicking > 0.0) {
            return;
        }
        let Some(p) = self.pipelines.get(spec.entry) else { return };
        let Some((_, bg)) = p.groups.iter().find(|(g, _)| *g == grid) else { return };
        pass.set_pipeline(&p.pipeline);
        pass.set_bind_group(0, bg, &[]);
        let class = dispatch_class(spec, grid);
        match (mode, self.buffer(Slot::IndirectArgs)) {
            (Mode::Indirect, Ok(args)) if self.wg_template[class] == wg => {
                pass.dispatch_workgroups_indirect(args, 12 * class as u64)
            }
            _ => pass.dispatch_workgroups(wg, 1, 1),
        }
    }

    /// Encodes `n` batched steps; with `timed`, one compute pass per family (or entry-point) segment
    /// with timestamps, returning (step, name) of each segment in query order — whole steps only: the
    /// first step that would run out of queries and those after it are not timed.
    fn encode_batch(&self, enc: &mut wgpu::CommandEncoder, n: usize, timed: bool) -> Vec<(usize, &'static str)> {
        // every step after the first finds the liquid densities of the previous step's evaluation 1
        let (first, rest) = (self.step_items(self.liquid_density_fresh), self.step_items(true));
        let step_items = |k: usize| if k == 0 { &first } else { &rest };
        let mut segments = Vec::new();
        let timer = self.timer.as_ref().filter(|_| timed);
        let Some(timer) = timer else {
            // As few compute passes as possible: one per run of dispatches between count copies.
            let all: Vec<&Item> = (0..n).flat_map(|k| step_items(k).iter()).collect();
            let mut i = 0;
            while i < all.len() {
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("perfuse.batch"),
                        timestamp_writes: None,
                    });
                    while let Some(Item::Dispatch(spec, grid, mode)) = all.get(i) {
                        self.dispatch_item(&mut pass, spec, *grid, *mode);
                        i += 1;
                    }
                }
                if i < all.len() {
                    self.encode_sync(enc);
                    i += 1;
                }
            }
            return segments;
        };
        let family = |it: &Item| match it {
            Item::Dispatch(spec, _, _) => Some(if timer.by_entry { spec.entry } else { spec.family }),
            Item::SyncCounts => None,
        };
        let mut out_of_queries = false;
        for k in 0..n {
            let items = step_items(k);
            let mut i = 0;
            while i < items.len() {
                let Some(fam) = family(&items[i]) else {
                    self.encode_sync(enc);
                    i += 1;
                    continue;
                };
                let mut j = i;
                while j < items.len() && family(&items[j]) == Some(fam) {
                    j += 1;
                }
                let q = 2 * segments.len() as u32;
                if q + 2 > MAX_QUERIES && !out_of_queries {
                    // this step is timed only in part: time none of it
                    out_of_queries = true;
                    segments.retain(|(s, _)| *s < k);
                }
                let writes = (!out_of_queries).then(|| wgpu::ComputePassTimestampWrites {
                    query_set: &timer.query_set,
                    beginning_of_pass_write_index: Some(q),
                    end_of_pass_write_index: Some(q + 1),
                });
                if writes.is_some() {
                    segments.push((k, fam));
                }
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("perfuse.batch_timed"),
                    timestamp_writes: writes,
                });
                for item in &items[i..j] {
                    if let Item::Dispatch(spec, grid, mode) = item {
                        self.dispatch_item(&mut pass, spec, *grid, *mode);
                    }
                }
                i = j;
            }
        }
        if !segments.is_empty() {
            let nq = 2 * segments.len() as u32;
            enc.resolve_query_set(&timer.query_set, 0..nq, &timer.resolve, 0);
            enc.copy_buffer_to_buffer(&timer.resolve, 0, &timer.staging, 0, 8 * nq as u64);
        }
        segments
    }

    /// Runs one batch of `n` ≤ [`MAX_BATCH`] steps ending at the first step with tⁿ⁺¹ ≥ `t_end`, with
    /// one readback; the state at its start is kept in the backups.
    fn run_batch(&mut self, n: usize, t_end: f64) -> Result<BatchState, GpuError> {
        let device = self.ctx.device.clone();
        // as ErrorScope::around, with the host time of the push and the pop measured
        let t = std::time::Instant::now();
        let scope = device::ErrorScope::push(&device);
        let mut host = t.elapsed().as_secs_f64();
        let result = self.encode_and_run_batch(n, t_end);
        let t = std::time::Instant::now();
        let popped = scope.pop("batch");
        host += t.elapsed().as_secs_f64();
        self.scope_host_s += host;
        popped?;
        result
    }

    /// Whether the next batch's first step reuses the liquid densities on the device (see
    /// `liquid_density_fresh`; every later step of a batch does).
    pub fn reuses_liquid_density(&self) -> bool {
        self.liquid_density_fresh
    }

    /// What the per-batch error scopes cost the host: (seconds in push + pop, batches run).
    pub fn error_scope_cost(&self) -> (f64, u64) {
        (self.scope_host_s, self.batches)
    }

    fn encode_and_run_batch(&mut self, n: usize, t_end: f64) -> Result<BatchState, GpuError> {
        let n = n.clamp(1, MAX_BATCH);
        let mut header: BatchState = bytemuck::Zeroable::zeroed();
        let end = split_pair(t_end.min(1e30));
        (header.end_hi, header.end_lo, header.wg) = (end[0], end[1], self.wg_template);
        (header.n_liquid, header.emitted, header.sunk) = (self.counts.liquid, self.emitted as u32, self.sunk as u32);
        header.wg[0] = self.counts.liquid.div_ceil(passes::WORKGROUP);
        let hb = bytemuck::bytes_of(&header);
        let off = BATCH_HEADER_OFFSET as usize;
        let hlen = std::mem::offset_of!(BatchState, dt);
        self.ctx.queue.write_buffer(self.buffer(Slot::Batch)?, BATCH_HEADER_OFFSET, &hb[off..hlen]);
        // batch 0 (first use: cold caches, lazy driver work) is not timed; then one in TIMED_EVERY
        let timed = self.timer.is_some() && self.batches % TIMED_EVERY == 1;
        self.batches += 1;
        let mut enc =
            self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.batch") });
        self.buffers.encode_backup(&mut enc, false);
        let segments = self.encode_batch(&mut enc, n, timed);
        let size = std::mem::size_of::<BatchState>() as u64;
        enc.copy_buffer_to_buffer(self.buffer(Slot::Batch)?, 0, &self.batch_staging, 0, size);
        self.ctx.queue.submit([enc.finish()]);
        let v: Vec<BatchState> = buffers::map_and_read(&self.ctx.device, &self.batch_staging, size, "batch")?;
        self.errors.take("batch")?;
        let b = v.first().copied().ok_or(GpuError::Readback { buffer: "batch".into(), message: "empty".into() })?;
        if let Some(timer) = self.timer.as_mut().filter(|_| !segments.is_empty()) {
            let nq = 2 * segments.len() as u64;
            let ticks: Vec<u64> = buffers::map_and_read(&self.ctx.device, &timer.staging, 8 * nq, "timestamps")?;
            // steps 0 … timed − 1 are timed whole (encode_batch); later ones are no-ops after the batch
            // stopped, or were left untimed for want of queries
            let timed = segments.last().map_or(0, |(k, _)| k + 1).min(b.steps as usize);
            for (q, (k, family)) in segments.iter().enumerate() {
                if *k >= timed {
                    continue;
                }
                let (t0, t1) = (ticks.get(2 * q).copied().unwrap_or(0), ticks.get(2 * q + 1).copied().unwrap_or(0));
                *timer.totals.entry(family).or_insert(0.0) += t1.saturating_sub(t0) as f64 * timer.period_ns * 1e-9;
            }
            timer.timed_steps += timed as u64;
        }
        Ok(b)
    }

    /// Advances the host clock and `acc` by the steps `b` reports (the CPU's `t += Δt as f64`).
    fn account(&mut self, b: &BatchState, acc: &mut BatchTotals) {
        for k in 0..(b.steps as usize).min(MAX_BATCH) {
            let dt = b.dt[k];
            self.t += dt as f64;
            self.steps += 1;
            if acc.steps == 0 {
                (acc.dt_min, acc.dt_max) = (dt, dt);
            }
            acc.steps += 1;
            acc.dt_min = acc.dt_min.min(dt);
            acc.dt_max = acc.dt_max.max(dt);
            let limit = dt_limit(b.limit[k]);
            if let Some(i) = super::DtLimit::ALL.iter().position(|l| *l == limit) {
                acc.limited_by[i] += 1;
            }
        }
        acc.broken_bonds += u64::from(b.broken_ends) / 2;
        self.clock = [b.t_hi, b.t_lo];
        // the batch's last step ended with evaluation 1 at the current positions
        self.liquid_density_fresh = b.steps > 0 && b.stop != gpu_types::stop::FAILED;
        if self.emit_active {
            self.counts.liquid = b.n_liquid;
            (self.emitted, self.sunk) = (u64::from(b.emitted), u64::from(b.sunk));
            self.capacity_hit |= b.capacity_hit != 0;
        }
    }

    /// Takes up to `max_steps` steps, stopping after the first whose end time reaches `t_end` (none if
    /// the clock is already there), in batches of at most [`MAX_BATCH`] steps with one readback each.
    /// `acc` receives every step taken, also when a later one diverges (the error then reports the
    /// diverging step, and the last good state is kept, as [`GpuSolver::step`]).
    pub fn advance(&mut self, max_steps: u64, t_end: f64, acc: &mut BatchTotals) -> Result<(), SimError> {
        let start = std::time::Instant::now();
        let r = self.advance_inner(max_steps, t_end, acc);
        acc.wall_s += start.elapsed().as_secs_f64();
        r
    }

    fn advance_inner(&mut self, max_steps: u64, t_end: f64, acc: &mut BatchTotals) -> Result<(), SimError> {
        let mut left = max_steps;
        while left > 0 && self.t < t_end {
            let n = left.min(MAX_BATCH as u64) as usize;
            let b = self.run_batch(n, t_end)?;
            if b.stop == gpu_types::stop::FAILED {
                if n == 1 {
                    return Err(self.fail(&b)?);
                }
                // Back to the start of the batch, then one step per batch up to the diverging one.
                self.restore()?;
                for _ in 0..n {
                    let b1 = self.run_batch(1, t_end)?;
                    if b1.stop == gpu_types::stop::FAILED {
                        return Err(self.fail(&b1)?);
                    }
                    self.account(&b1, acc);
                    left -= u64::from(b1.steps);
                    if self.t >= t_end {
                        break;
                    }
                }
                continue;
            }
            if b.steps == 0 {
                // The first step of a batch always runs while t < t_end: none ran, so the GPU executed
                // nothing (an invalid pipeline, a lost device). Looping on would never reach t_end.
                return Err(GpuError::Validation {
                    context: "batch".into(),
                    message: format!(
                        "a batch of {n} steps ran none at t = {:.6e} s: the GPU did not execute the step",
                        self.t
                    ),
                }
                .into());
            }
            self.account(&b, acc);
            left -= u64::from(b.steps).min(left);
        }
        Ok(())
    }

    /// Restores the last good state after a failed one-step batch and builds its error.
    fn fail(&mut self, b: &BatchState) -> Result<SimError, SimError> {
        self.restore()?;
        if b.fail_status & gpu_types::status::DT_COLLAPSED != 0 {
            let s: Vec<StepState> = self.read_slot(Slot::Step, 1)?;
            let limit = dt_limit(s.first().map_or(4, |s| s.limit));
            return Ok(diverged(
                self.steps,
                self.t,
                String::from("(time step)"),
                format!("time step collapsed to {:.3e} s (limited by {limit:?}), below dt_min", b.fail_dt),
            ));
        }
        let particle = if b.fail_status & gpu_types::status::NONFINITE_LIQUID != 0 {
            format!("liquid #{}", b.bad_liquid)
        } else {
            format!("solid #{}", b.bad_solid)
        };
        Ok(diverged(
            self.steps + 1,
            self.t + b.fail_dt as f64,
            particle,
            format!("non-finite or runaway state (limit {:.3e} m/s)", self.params.max_speed),
        ))
    }

    /// One predictor–corrector step (SPEC §5.1–5.2): a batch of one. On divergence the last good state
    /// is restored.
    pub fn step(&mut self) -> Result<StepInfo, SimError> {
        let b = self.run_batch(1, f64::INFINITY)?;
        if b.stop == gpu_types::stop::FAILED || b.steps == 0 {
            return Err(self.fail(&b)?);
        }
        let mut acc = BatchTotals::default();
        self.account(&b, &mut acc);
        Ok(StepInfo { t: self.t, dt: b.dt[0], limit: dt_limit(b.limit[0]), broken_bonds: acc.broken_bonds })
    }

    /// Times the passes per entry point (`by_entry`) or per family (the default) from now on; the
    /// totals so far are dropped. Without timestamp queries there is nothing to time.
    pub fn time_entry_points(&mut self, by_entry: bool) {
        if let Some(t) = &mut self.timer {
            t.by_entry = by_entry;
            t.totals.clear();
            t.timed_steps = 0;
        }
    }

    /// Accumulated GPU time per pass family (or entry point, [`Self::time_entry_points`]) \[s\]
    /// (timestamp queries on every `TIMED_EVERY`th batch, scaled to all steps taken), or `None`
    /// without timestamp queries.
    pub fn pass_times(&self) -> Option<Vec<(String, f64)>> {
        let timer = self.timer.as_ref()?;
        let scale = if timer.timed_steps > 0 { self.steps as f64 / timer.timed_steps as f64 } else { 0.0 };
        Some(timer.totals.iter().map(|(k, v)| (k.to_string(), v * scale)).collect())
    }

    /// Copies the backups (state and object table) back, resets the GPU clock to the host's copy and
    /// re-places boundaries and grids.
    fn restore(&mut self) -> Result<(), GpuError> {
        let mut enc =
            self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.restore") });
        self.buffers.encode_backup(&mut enc, true);
        self.ctx.queue.submit([enc.finish()]);
        self.upload_clock(self.clock)?;
        if self.emit_active {
            // the live count of the restored state (the host's, as of the batch start)
            self.upload_params()?;
            self.upload_liquid_grid_count();
        }
        self.run_stages(passes::PLACE_AND_BIN)
    }

    /// Reads everything that evolves back (blocking): see [`GpuSnapshot`].
    pub fn snapshot(&self) -> Result<GpuSnapshot, SimError> {
        let mut out = Vec::new();
        for slot in snapshot_slots() {
            if let Some(b) = self.buffers.get(slot, None) {
                let bytes: Vec<u8> =
                    buffers::read_buffer(&self.ctx.device, &self.ctx.queue, b, b.size() as usize, slot.name())?;
                out.push((slot.name().to_string(), bytes));
            }
        }
        Ok(GpuSnapshot {
            clock: self.clock,
            t: self.t,
            steps: self.steps,
            liquid_count: self.counts.liquid,
            objects: self.objects.clone(),
            shapes: self.shapes.clone(),
            boundary_x0: self.boundary_x0.clone(),
            gravity: self.gravity,
            damping: self.damping,
            damping_solid_gravity_only: self.damping_solid_gravity_only,
            suction_held: self.suction_held,
            emitted: self.emitted,
            sunk: self.sunk,
            capacity_hit: self.capacity_hit,
            buffers: out,
        })
    }

    /// Restores a [`GpuSolver::snapshot`] of a solver of the same scenario: the buffers are written
    /// back, the host mirror replaced and the boundaries and grids re-placed, as after a divergence.
    pub fn restore_snapshot(&mut self, snap: GpuSnapshot) -> Result<(), SimError> {
        use crate::sim::snapshot::{SnapshotError, check_eq};
        check_eq("boundary particles", snap.boundary_x0.len(), self.boundary_x0.len())?;
        check_eq("boundary objects", snap.objects.len(), self.objects.len())?;
        check_eq("object shapes", snap.shapes.len(), self.shapes.len())?;
        if snap.liquid_count > self.capacity.max(self.counts.liquid) {
            return Err(SnapshotError::Mismatch(format!(
                "{} liquid particles in the keyframe, room for {}",
                snap.liquid_count,
                self.capacity.max(self.counts.liquid)
            ))
            .into());
        }
        let want: Vec<(&'static str, u64)> =
            snapshot_slots().filter_map(|s| self.buffers.get(s, None).map(|b| (s.name(), b.size()))).collect();
        let have: Vec<(&str, u64)> = snap.buffers.iter().map(|(n, b)| (n.as_str(), b.len() as u64)).collect();
        check_eq("device buffers (name, bytes)", have, want.clone())?;
        for (slot, (_, bytes)) in snapshot_slots().filter(|s| self.buffers.get(*s, None).is_some()).zip(&snap.buffers) {
            self.ctx.queue.write_buffer(self.buffer(slot)?, 0, bytes);
        }
        self.t = snap.t;
        self.steps = snap.steps;
        self.counts.liquid = snap.liquid_count;
        self.objects = snap.objects;
        self.shapes = snap.shapes;
        self.boundary_x0 = snap.boundary_x0;
        self.gravity = snap.gravity;
        self.damping = snap.damping;
        self.damping_solid_gravity_only = snap.damping_solid_gravity_only;
        self.suction_held = snap.suction_held;
        (self.emitted, self.sunk, self.capacity_hit) = (snap.emitted, snap.sunk, snap.capacity_hit);
        self.upload_clock(snap.clock)?;
        self.upload_params()?;
        self.upload_liquid_grid_count();
        self.upload_boundary_pos0()?;
        self.upload_motions()?;
        self.run_stages(passes::PLACE_AND_BIN)?;
        Ok(())
    }

    /// Same as `CpuSolver::set_object_motion`: re-anchor, upload x⁰, the object and motion tables, and
    /// re-place the boundary particles.
    fn set_object_motion(&mut self, object: usize, motion: &Motion, teleport: Vec3) -> Result<(), SimError> {
        let o = self
            .objects
            .get_mut(object)
            .ok_or_else(|| SimError::BadCommand(format!("no boundary object #{object}")))?;
        let (d_now, _) = motion_at(&o.motion, self.t);
        let (d_new, _) = motion_at(motion, self.t);
        o.motion = motion.clone();
        let shift = crate::sim::reanchor_shift(d_now, d_new) + teleport;
        for i in 0..self.boundary_x0.len() {
            if self.boundary_object[i] as usize == object {
                self.boundary_x0[i] += shift;
            }
        }
        self.shapes[object].a += shift;
        if self.shapes[object].kind == 0 {
            self.shapes[object].b += shift;
        }
        self.upload_boundary_pos0()?;
        self.upload_objects(self.t)?;
        self.upload_motions()?;
        self.run_stages(passes::PLACE_AND_BIN)?;
        Ok(())
    }

    /// (liquid, solid) particle counts.
    pub fn particle_counts(&self) -> (u32, u32) {
        (self.counts.liquid, self.counts.solid)
    }

    /// (liquid capacity, solid count): what a render buffer set must hold.
    pub fn frame_capacity(&self) -> (u32, u32) {
        (self.capacity.max(self.counts.liquid), self.counts.solid)
    }

    /// Emitter and sink totals (reads the emitters' accounts back when there are emitters).
    pub fn emit_totals(&self) -> Result<super::EmitTotals, SimError> {
        let mut t = super::EmitTotals {
            emitted: self.emitted,
            sunk: self.sunk,
            live_liquid: u64::from(self.counts.liquid),
            capacity: u64::from(self.capacity),
            capacity_reached: self.capacity_hit,
            ..Default::default()
        };
        if self.emit_active {
            let st: Vec<gpu_types::EmitStateGpu> = self.read_slot(Slot::EmitState, 1)?;
            if let Some(st) = st.first() {
                for em in st.emitters.iter().take(st.n_emitters as usize) {
                    t.emitted_volume_m3 += f64::from(em.count) * f64::from(em.volume);
                    t.backlog_m3 += f64::from(em.acc.max(0.0));
                    t.per_emitter.push(u64::from(em.count));
                }
            }
        }
        Ok(t)
    }

    /// Copies the render data into `frame` (buffer-to-buffer on this device, no readback) and submits.
    /// `frame` must have been created on this solver's device with its particle counts.
    pub fn publish(&self, frame: &super::frame::FrameBuffers) -> Result<(), GpuError> {
        use super::frame::{LIQUID_POS_BYTES, SOLID_DENS_BYTES, SOLID_POS_BYTES, SOLID_STRESS_BYTES, U32_BYTES};
        let (nl, ns) = (u64::from(self.counts.liquid), u64::from(self.counts.solid));
        if (frame.n_liquid as u64) < nl || frame.n_solid as u64 != ns {
            return Err(GpuError::Validation {
                context: "publish".into(),
                message: format!(
                    "render buffers hold {} liquid / {} solid particles, the simulation {nl} / {ns}",
                    frame.n_liquid, frame.n_solid
                ),
            });
        }
        let mut enc =
            self.ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("perfuse.publish") });
        let mut copy = |slot: Slot, dst: &wgpu::Buffer, bytes: u64| -> Result<(), GpuError> {
            if bytes > 0 {
                enc.copy_buffer_to_buffer(self.buffer(slot)?, 0, dst, 0, bytes);
            }
            Ok(())
        };
        copy(Slot::LiquidPos, &frame.liquid_pos, nl * LIQUID_POS_BYTES)?;
        copy(Slot::SolidPos, &frame.solid_pos, ns * SOLID_POS_BYTES)?;
        copy(Slot::SolidDens, &frame.solid_dens, ns * SOLID_DENS_BYTES)?;
        copy(Slot::SolidStress, &frame.solid_stress, ns * SOLID_STRESS_BYTES)?;
        copy(Slot::BondCount, &frame.bond_count, ns * U32_BYTES)?;
        copy(Slot::SolidFlags, &frame.solid_flags, ns * U32_BYTES)?;
        if ns > 0 {
            self.ctx.queue.write_buffer(&frame.bond_count0, 0, bytemuck::cast_slice(&self.bond_count0));
        }
        self.ctx.queue.submit([enc.finish()]);
        Ok(())
    }

    /// Current pose of every boundary object (scenario coordinates), from the host's motion table.
    pub fn object_poses(&self) -> Vec<crate::sim::ObjectPose> {
        self.objects
            .iter()
            .zip(&self.shapes)
            .map(|(o, g)| crate::sim::object_pose(&self.params, o, g, self.t))
            .collect()
    }

    /// Applies a command (same semantics as `CpuSolver::apply`).
    pub fn apply(&mut self, cmd: &Command) -> Result<(), SimError> {
        match cmd {
            Command::SetBoundaryMotion { object, motion } => self.set_object_motion(*object, motion, Vec3::ZERO)?,
            Command::PlaceObject { object, position } => {
                let o = self
                    .objects
                    .get(*object)
                    .ok_or_else(|| SimError::BadCommand(format!("no boundary object #{object}")))?;
                let pose = crate::sim::object_pose(&self.params, o, &self.shapes[*object], self.t);
                let shift = crate::sim::centre_shift(&self.params, &pose, *position)?;
                self.set_object_motion(*object, &Motion::Static, shift)?;
            }
            Command::MoveObject { .. } => {
                return Err(SimError::BadCommand("MoveObject is resolved by `Simulation::apply`".into()));
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
                self.upload_clock(split_pair(*t))?;
                self.upload_objects(*t)?;
                self.run_stages(passes::PLACE_AND_BIN)?;
            }
            Command::SetSuction(on) => {
                self.suction_held = !on;
                self.upload_params()?; // the outlets in effect (and a fresh liquid density pass)
                self.upload_objects(self.t)?;
                self.upload_motions()?;
                if let Some(b) = self.buffers.get(Slot::EmitState, None) {
                    let n = if *on { self.sink_count } else { 0 };
                    let off = std::mem::offset_of!(gpu_types::EmitStateGpu, n_sinks) as u64;
                    self.ctx.queue.write_buffer(b, off, bytemuck::bytes_of(&n));
                }
            }
            Command::SetInflow { emitter, times, rates } => {
                let table = crate::sim::inflow_table(times, rates)?;
                let n = self.emit_count;
                if *emitter >= n {
                    return Err(SimError::BadCommand(format!("no emitter #{emitter}")));
                }
                let mut region = vec![0f32; gpu_types::FLOW_STRIDE];
                flow_region(&table, &mut region);
                let off = (*emitter * gpu_types::FLOW_STRIDE * 4) as u64;
                self.ctx.queue.write_buffer(self.buffer(Slot::EmitFlow)?, off, bytemuck::cast_slice(&region));
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
        let liquid_ids: Vec<u32> = self.read_slot(Slot::LiquidId, nl)?;
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
            liquid: PhaseState { id: liquid_ids, ..phase(&lp, &lv, &ld) }.in_id_order(),
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

/// Writes `table` into one emitter's region of the flow buffer (`FLOW_STRIDE` floats, emit.wgsl).
fn flow_region(table: &super::cpu::emit::FlowTable, out: &mut [f32]) {
    let n = table.times.len().min(table.rates.len()).min(super::cpu::emit::FLOW_MAX);
    out.fill(0.0);
    out[0] = f32::from_bits(n as u32);
    out[1] = table.period;
    let fm = super::cpu::emit::FLOW_MAX;
    out[4..4 + n].copy_from_slice(&table.times[..n]);
    out[4 + fm..4 + fm + n].copy_from_slice(&table.rates[..n]);
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
    objects.iter().map(|o| super::cpu::emit::object_geom(params, o)).collect()
}

/// The object table at time t (twin of `CpuSolver::move_boundaries`: same f64 → f32 conversions).
fn objects_at(
    params: &Params,
    objects: &[BoundaryObject],
    shapes: &[ObjectGeom],
    modes: &[ObjectContact],
    beds: &[u32],
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
            let m = modes.get(k).copied().unwrap_or(ObjectContact::MIRROR);
            ObjectGpu {
                geom_a: v4(g.a, 0.0),
                geom_b: v4(g.b, 0.0),
                disp: v4(d, 0.0),
                vel: v4(v, 0.0),
                density: m.density,
                pressure: m.pressure,
                kind: g.kind,
                blade: blade_code(params, o),
                friction: m.friction,
                bed: beds.get(k).copied().unwrap_or(0),
                ..ObjectGpu::default()
            }
        })
        .collect()
}

/// `ObjectGpu::blade`: 1 + the cut axis of a `blade_cut` scalpel, 0 for any other object.
fn blade_code(params: &Params, o: &BoundaryObject) -> u32 {
    super::cpu::fracture::blade_axis(o, params.dim.n()).map_or(0, |a| a as u32 + 1)
}

/// The motion table of batch.wgsl: each object's rest shape (simulation coordinates, after any
/// `SetBoundaryMotion` shift), pressure mode and motion parameters (z zeroed in 2-D, as `objects_at`).
fn motion_table(
    params: &Params,
    objects: &[BoundaryObject],
    shapes: &[ObjectGeom],
    modes: &[ObjectContact],
    beds: &[u32],
) -> Vec<MotionGpu> {
    use crate::scenario::Motion;
    let three = params.dim.n() == 3;
    let z = |a: [f64; 3]| [a[0] as f32, a[1] as f32, if three { a[2] as f32 } else { 0.0 }, 0.0];
    objects
        .iter()
        .zip(shapes)
        .enumerate()
        .map(|(k, (o, g))| {
            let m = modes.get(k).copied().unwrap_or(ObjectContact::MIRROR);
            let (vec, times, motion) = match &o.motion {
                Motion::Static => ([0.0; 4], [0.0; 4], 0),
                Motion::Translate { velocity, start, stop } => {
                    let (s, e) = (split_pair(*start), split_pair(stop.unwrap_or(1e30).min(1e30)));
                    (z(*velocity), [s[0], s[1], e[0], e[1]], 1)
                }
                Motion::Oscillate { amplitude, frequency, phase } => {
                    let w = 2.0 * std::f64::consts::PI * frequency;
                    (z(*amplitude), [w as f32, *phase as f32, 0.0, 0.0], 2)
                }
            };
            MotionGpu {
                rest_a: v4(g.a, blade_code(params, o) as f32),
                rest_b: v4(g.b, 0.0),
                vec,
                times,
                density: m.density,
                pressure: m.pressure,
                kind: g.kind,
                motion,
                friction: m.friction,
                bed: beds.get(k).copied().unwrap_or(0),
                ..MotionGpu::default()
            }
        })
        .collect()
}

/// CPU twin of batch.wgsl's `motion_eval`: displacement and velocity of motion `m` at the clock pair
/// `t` (hi, lo), in the same f32 operations. The CPU solver keeps evaluating `scenario::motion_at` in
/// f64 (its results are unchanged); the two agree to f32 rounding (tests/gpu_advance.rs).
pub fn motion_twin(m: &MotionGpu, t: [f32; 2]) -> (Vec3, Vec3) {
    let diff = |a: [f32; 2], b: [f32; 2]| (a[0] - b[0]) + (a[1] - b[1]);
    let vec = Vec3::new(m.vec[0], m.vec[1], m.vec[2]);
    if t[0] < 0.0 || (t[0] == 0.0 && t[1] < 0.0) {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    match m.motion {
        1 => {
            let (start, stop) = ([m.times[0], m.times[1]], [m.times[2], m.times[3]]);
            let to_stop = diff(t, stop);
            let moved = if to_stop > 0.0 { diff(stop, start) } else { diff(t, start) }.max(0.0);
            let v = if diff(t, start) >= 0.0 && to_stop < 0.0 { vec } else { Vec3::ZERO };
            (vec * moved, v)
        }
        2 => {
            let (w, phase) = (m.times[0], m.times[1]);
            let th = w * (t[0] + t[1]) + phase;
            (vec * (th.sin() - phase.sin()), vec * (w * th.cos()))
        }
        _ => (Vec3::ZERO, Vec3::ZERO),
    }
}

/// The motion table entry of `o` (tests: the twin against `motion_at`).
pub fn motion_entry(params: &Params, o: &BoundaryObject) -> MotionGpu {
    let shapes = object_shapes(params, std::slice::from_ref(o));
    motion_table(params, std::slice::from_ref(o), &shapes, &[], &[]).first().copied().unwrap_or_default()
}

/// `t` as the f32 clock pair of batch.wgsl.
pub fn clock_pair(t: f64) -> [f32; 2] {
    split_pair(t)
}

impl PassTimer {
    fn new(ctx: &GpuContext) -> PassTimer {
        let query_set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("perfuse.pass_timer"),
            ty: wgpu::QueryType::Timestamp,
            count: MAX_QUERIES,
        });
        let size = 8 * MAX_QUERIES as u64;
        let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("perfuse.pass_timer_resolve"),
            size,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("perfuse.pass_timer_readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        PassTimer {
            query_set,
            resolve,
            staging,
            period_ns: ctx.queue.get_timestamp_period() as f64,
            by_entry: false,
            totals: BTreeMap::new(),
            timed_steps: 0,
        }
    }
}

/// One pipeline per entry point, with its explicit layout and bind group(s). `liquid_in_cell_order`
/// (`numerics.reorder_liquid`) sets the shaders' pipeline constant `LIQUID_IN_CELL_ORDER`: the liquid's
/// walks then read candidates from the particle arrays themselves (common.wgsl `liquid_candidate`).
/// `periodic` (some axis has a period > 0, `Params::periodic_len`) sets `PERIODIC`, which lets the
/// driver drop the walks' periodic paths in a scene without one.
fn create_pipelines(
    device: &wgpu::Device,
    buffers: &SimBuffers,
    liquid_in_cell_order: bool,
    periodic: bool,
) -> Result<HashMap<&'static str, Pipeline>, GpuError> {
    let constants = [
        ("LIQUID_IN_CELL_ORDER", if liquid_in_cell_order { 1.0 } else { 0.0 }),
        ("PERIODIC", if periodic { 1.0 } else { 0.0 }),
    ];
    let mut modules: HashMap<&'static str, wgpu::ShaderModule> = HashMap::new();
    let mut out = HashMap::new();
    for spec in passes::ALL_PASSES {
        if !modules.contains_key(spec.family) {
            let src = shaders::shader_source(spec.family).map_err(|e| GpuError::Validation {
                context: format!("shader {}", spec.family),
                message: e.to_string(),
            })?;
            // Every check but wgpu's loop bounding, which gives each loop a 64-bit iteration counter
            // and a divergent exit test per iteration: in the neighbour walks that is per candidate,
            // 8-12 % of the force passes on lavapipe (README, Performance).
            let mut checks = wgpu::ShaderRuntimeChecks::checked();
            checks.force_loop_bounding = false;
            // SAFETY: without loop bounding the shaders must not loop forever. Every loop of the
            // compute families (shaders/*.wgsl but render_*) terminates: `for` loops step an integer
            // by a positive amount (1, NBR_SIDE, 64, COMPACT_WG) toward a bound that does not change
            // inside the loop; the two `while` loops are a bisection (the interval halves) and the
            // emitter's slot search (`tries` grows each pass up to the slot count); the two `loop`s are
            // `powi` (b halves toward 0) and grid_sort_cells' insertion (w falls to the cell's start).
            let m = unsafe {
                device.create_shader_module_trusted(
                    wgpu::ShaderModuleDescriptor {
                        label: Some(&format!("perfuse.{}", spec.family)),
                        source: wgpu::ShaderSource::Wgsl(src.into()),
                    },
                    checks,
                )
            };
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
            compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
            cache: None,
        });
        // a pass over a grid-generic slot gets one bind group per set (grid_reorder binds the liquid's own)
        let generic = [Slot::GridSet, Slot::GridPos, Slot::GridOrder, Slot::GridCellStart, Slot::GridCellOf];
        let instances: &[Option<GridOf>] = if spec.slots.iter().any(|s| generic.contains(s)) {
            &[Some(GridOf::Liquid), Some(GridOf::Solid), Some(GridOf::Boundary), Some(GridOf::Ghost)]
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
