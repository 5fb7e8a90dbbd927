// common.wgsl — shared declarations of every Perfuse compute pass (STYLE §5.2: shared WGSL lives only here).
//
// * Host<->GPU structs, each mirrored by the `#[repr(C)]` Pod struct of the same name in
//   `src/sim/gpu/gpu_types.rs` (must be kept in sync; a test compares sizes and offsets with naga).
// * Every resource of the simulation, at the fixed (group 0, binding) numbers of the `Slot` table in
//   `src/sim/gpu/bindings.rs`. Each entry point uses a subset; its pipeline layout lists exactly that
//   subset (`passes.rs`).
// * The kernels of thesis §2.2.1 (SPEC §2), line for line as `src/sim/kernels.rs`, plus the neighbour
//   walk of `src/sim/cpu/grid.rs` (125 cells in the order dz, dy, dx ∈ -2..=2, then ascending index).
//
// Float arithmetic is written out (no dot()/length()/matrix products) so that each operation happens
// in the same order as the glam code of the CPU twin.

struct KernelConsts {
    h: f32,
    r: f32,
    alpha_c: f32,
    alpha_6: f32,
    alpha_s: f32,
    c_v: f32,
    _pad0: f32,
    _pad1: f32,
}

// Mirrors `SimParams` in gpu_types.rs (built from `sim::params::Params`).
struct SimParams {
    k_liquid: KernelConsts,
    k_solid: KernelConsts,
    k_cross: KernelConsts,
    grid_min: vec4<f32>,
    grid_cell: vec4<f32>,
    // nx, ny, nz, cell count
    grid_n: vec4<u32>,
    // periodic length per axis (0 where not periodic)
    period: vec4<f32>,
    domain_min: vec4<f32>,
    domain_max: vec4<f32>,
    // xyz: g [m/s²]; w: 1 when the liquid feels gravity
    gravity: vec4<f32>,
    // n_liquid, n_solid, n_boundary, bond_capacity
    counts: vec4<u32>,
    // three_d, av_liquid, liquid_tension_below_ns (f32 bits), n_objects
    switches: vec4<u32>,
    // Params::liquid_tension_in, regions k < MAX_TENSION_REGIONS as tension[2k], tension[2k + 1]:
    // w of the first 0 unused, 1 box (xyz min; second: xyz max), 2 sphere (xyz centre; second: w radius²)
    tension: array<vec4<f32>, 8>,
    // Params::outlets_in_effect, outlet k < MAX_OUTLETS as outlet[3k] (xyz min, w its density > 0; 0: none),
    // outlet[3k + 1] (xyz max, w its absolute pressure p_a + gauge), outlet[3k + 2] (xyz its unit normal)
    outlet: array<vec4<f32>, 6>,
    rho0_l: f32,
    rho0_s: f32,
    eta: f32,
    k_l: f32,
    c1: f32,
    k_s: f32,
    k_sat: f32,
    n_sat: f32,
    c10: f32,
    c01: f32,
    kbar: f32,
    c_l: f32,
    c_s: f32,
    av_alpha: f32,
    av_beta: f32,
    av_gamma: f32,
    as_eps: f32,
    as_exp: i32,
    xsph_s: f32,
    xsph_l: f32,
    kappa_v: f32,
    wc_dx: f32,
    rho_ref_l: f32,
    rho_ref_s: f32,
    cfl_factor: f32,
    cfl_viscous: f32,
    cfl_sound: f32,
    cfl_force: f32,
    cfl_friction: f32,
    dt_min: f32,
    dt_max: f32,
    // < 0: none
    fixed_dt: f32,
    h_min: f32,
    c_max: f32,
    max_speed: f32,
    // relaxation damping ζ [1/s]
    damping: f32,
    has_liquid: u32,
    has_solid: u32,
    // liquid pressure-gradient normalisation κ_S (1 when disabled)
    kappa_s: f32,
    // γ of (3.4) [N/m]; 0: off
    wicking: f32,
    // s_ll, s_lb of (3.3) [N]; 0: off
    cohesion_ll: f32,
    cohesion_lb: f32,
    // upper bound of Δt (Params::dt_upper): stick relaxation time of wall friction
    dt_upper: f32,
    // hourglass-control coefficient c (numerics.hourglass); 0: off
    hourglass: f32,
    // ligament springs of tethered solid particles: ω² [1/s²], 2ζω [1/s] (0: none)
    tether_omega2: f32,
    tether_damping: f32,
    // membrane (capsule) particles' C10, C01 over the tissue's (1: as the tissue)
    membrane_stiffness: f32,
    // liquid artificial pressure ε, n and W_C(Δx_l; h_l) (numerics.liquid_artificial_pressure); ε = 0: off
    ap_eps: f32,
    ap_exp: i32,
    wc_dx_l: f32,
    // ambient pressure p_a added to (2.53) (numerics.ambient_pressure; 0: none)
    ambient_pressure: f32,
    bond_reach: f32,
    // the lattice spacings Δx_l and Δx_s the capsule's ghost sites and seal are measured in
    capsule_dx_liquid: f32,
    capsule_dx_solid: f32,
    // the capsule's seal (forces.rs capsule_seal_pair): 1 on, 0 off
    capsule_seal: f32,
    // the capsule's ghost sites (sim::ghosts, ghosts.wgsl): their count (0: none, the thesis's capsule), and
    // the seal's plane beyond the capsule particle (forces.rs capsule_seal_offset)
    capsule_ghosts: u32,
    capsule_seal_offset: f32,
    _pad_seal2: f32,
    _pad_seal3: f32,
    _pad_seal4: f32,
}

// OutletRegion::find: the index k of the first outlet buffer in effect that holds x (boundaries included,
// the same comparisons; its density params.outlet[3k].w, pressure [3k + 1].w, normal [3k + 2].xyz), or -1.
fn outlet_find(x: vec3<f32>) -> i32 {
    for (var k = 0u; k < 2u; k++) {
        let a = params.outlet[3u * k];
        let b = params.outlet[3u * k + 1u];
        if (a.w != 0.0 && x.x >= a.x && x.y >= a.y && x.z >= a.z && x.x <= b.x && x.y <= b.y && x.z <= b.z) {
            return i32(k);
        }
    }
    return -1;
}

// Mirrors `StepState`: the GPU-resident Δt (SPEC §5.3) and the step status bitmask (STYLE §5.4).
struct StepState {
    dt: f32,
    limit: u32,
    status: atomic<u32>,
    broken_ends: atomic<u32>,
    // max |a| (bits of a non-negative f32: integer order = float order, exact in any order)
    a_max_bits: atomic<u32>,
    rho_min_bits: atomic<u32>,
    fric_max_bits: atomic<u32>,
    bad_liquid: atomic<u32>,
    bad_solid: atomic<u32>,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `ObjectGpu`: one boundary object's pose (SPEC §4.1), pressure mode (D-23) and Coulomb
// coefficient of solid contact (README: deviations from SPEC).
struct ObjectGpu {
    // surface: box [geom_a, geom_b] or sphere (centre geom_a, radius geom_b.x), current pose
    geom_a: vec4<f32>,
    geom_b: vec4<f32>,
    // displacement and velocity of the object at the current time
    disp: vec4<f32>,
    vel: vec4<f32>,
    // < 0: mirror
    density: f32,
    pressure: f32,
    // 0 box, 1 sphere, 2 none
    kind: u32,
    // 1 + the cut axis of a blade_cut scalpel (its box's mid-plane cuts bonds, fracture.wgsl); 0 otherwise
    blade: u32,
    // Coulomb μ of solid contact (0: frictionless)
    friction: f32,
    // 1 + the index of a moulded bed's heightfield in bed_table; 0: none
    bed: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `MotionGpu`: one boundary object's rest shape, pressure mode and analytic motion
// (`scenario::motion_at`), evaluated on the GPU from the GPU clock by `batch_motion` (batch.wgsl).
struct MotionGpu {
    // rest shape; rest_a.w = 1 + the cut axis of a blade_cut scalpel, 0 otherwise (ObjectGpu.blade)
    rest_a: vec4<f32>,
    rest_b: vec4<f32>,
    // Translate: velocity [m/s]; Oscillate: amplitude [m] (z = 0 in 2-D)
    vec: vec4<f32>,
    // Translate: start (hi, lo), stop (hi, lo) as f32 pairs [s]; Oscillate: ω = 2πf, phase
    times: vec4<f32>,
    density: f32,
    pressure: f32,
    kind: u32,
    // 0 static, 1 translate, 2 oscillate
    motion: u32,
    friction: f32,
    // ObjectGpu.bed
    bed: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `BatchState`: the GPU clock and the per-batch control/statistics of `GpuSolver::advance`.
struct BatchState {
    // clock tⁿ as an unevaluated f32 pair hi + lo (two-sum, SPEC §5.4), and tⁿ⁺¹ of the running step
    t_hi: f32,
    t_lo: f32,
    tn_hi: f32,
    tn_lo: f32,
    // t_end of the batch (pair); the batch stops after the first step with tⁿ⁺¹ ≥ t_end − margin
    end_hi: f32,
    end_lo: f32,
    steps: u32,
    // 0 running, 1 t_end reached, 2 diverged / Δt collapsed
    stop: u32,
    fail_status: u32,
    bad_liquid: u32,
    bad_solid: u32,
    broken_ends: u32,
    fail_dt: f32,
    // live liquid particles, and particles emitted / sunk since t = 0 (emit.wgsl)
    n_liquid: u32,
    emitted: u32,
    sunk: u32,
    // an emitter found the liquid capacity full during this batch
    capacity_hit: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // workgroup counts per dispatch class (liquid, solid, boundary, cells, cells + 1, one)
    wg: array<u32, 8>,
    // per step of the batch: Δt and its limiting criterion
    dt: array<f32, 64>,
    limit: array<u32, 64>,
}

// Mirrors `EmitterGpu`: one inlet (emit.wgsl, twin `sim::cpu::emit::Emitter`).
struct EmitterGpu {
    // xyz: unit inflow direction, w: buffer speed per unit flow L/(N·V_p)
    dir: vec4<f32>,
    // buffer velocity u(tⁿ⁺¹) (batch_motion)
    velocity: vec4<f32>,
    // buffer region: box [a, b] or sphere centre a, radius b.x
    region_a: vec4<f32>,
    region_b: vec4<f32>,
    slot_start: u32,
    slot_count: u32,
    cursor: u32,
    count: u32,
    mass: f32,
    // m/ρ₀ [m³]
    volume: f32,
    // volume owed and not yet placed [m³]
    acc: f32,
    region_kind: u32,
}

// Mirrors `SinkGpu`: a sink region (box [a, b] or sphere centre a, radius b.x).
struct SinkGpu {
    a: vec4<f32>,
    b: vec4<f32>,
    kind: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Mirrors `EmitStateGpu`: emitters, sinks and the liquid capacity.
struct EmitState {
    n_emitters: u32,
    n_sinks: u32,
    n_slots: u32,
    capacity: u32,
    id_base: u32,
    sink_hits: atomic<u32>,
    // (BLOCK_FACTOR·Δx_l)²
    block_r2: f32,
    _pad0: u32,
    emitters: array<EmitterGpu, 8>,
    sinks: array<SinkGpu, 8>,
}

// Mirrors `Mat3Gpu`: glam's column-major Mat3, one vec4 per column (w unused).
struct Mat3Gpu {
    c0: vec4<f32>,
    c1: vec4<f32>,
    c2: vec4<f32>,
}

// Mirrors `StressGpu`: the deviatoric Cauchy stress τ and the artificial stress R (2.59), both symmetric,
// as their upper triangles: a = (τxx, τyy, τzz, τxy), b = (τxz, τyz, Rxx, Ryy), c = (Rzz, Rxy, Rxz, Ryz).
// A bond of the stress loop gathers 6 components of τ_j, a neighbour of the artificial-stress sum 6 of
// R_j (stress_tau_of, stress_art_of), instead of a matrix each.
struct StressGpu {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

// Mirrors `CellEntry`: one entry of a set's cell list — the particle's index and its position when the
// list was built (the positions do not change between a grid build and the neighbour loops that use it),
// so a neighbour loop tests distances on consecutive memory and loads per-particle data only for the
// particles inside the kernel support.
struct CellEntry {
    pos: vec3<f32>,
    id: u32,
}

// One liquid particle's state that lives across a grid build (grid_reorder): position and mass,
// velocity, the predictor's a⁰ and the id (x of `id`; 64 bytes, vec4-aligned).
struct LiquidMove {
    pos: vec4<f32>,
    vel: vec4<f32>,
    acc0: vec4<f32>,
    id: vec4<u32>,
}

// Mirrors `GridSet`: the particle set a grid pass instance bins.
struct GridSet {
    n: u32,
    cells: u32,
    _pad0: u32,
    _pad1: u32,
}

const STATUS_NONFINITE_LIQUID: u32 = 1u;
const STATUS_NONFINITE_SOLID: u32 = 2u;
const STATUS_DT_COLLAPSED: u32 = 4u;

// Solid flags, see `scenario::SolidFlags`.
const SOLID_KINEMATIC: u32 = 1u;
const SOLID_MEMBRANE: u32 = 2u;
const SOLID_TETHERED: u32 = 4u;

// High bit of a boundary particle's object word (`boundary_pos0.w`): the particle stands in a cavity in
// the tissue's place and shows the liquid's nˢ its solid-equivalent mass (CPU `BoundarySet::m_sn`).
const BOUNDARY_IN_TISSUE: u32 = 0x80000000u;

// The boundary object of boundary particle j.
fn boundary_object(j: u32) -> u32 {
    return bitcast<u32>(boundary_pos0[j].w) & ~BOUNDARY_IN_TISSUE;
}

// `sim::DtLimit` order.
const LIMIT_VISCOUS: u32 = 0u;
const LIMIT_SOUND: u32 = 1u;
const LIMIT_FORCE: u32 = 2u;
const LIMIT_FRICTION: u32 = 3u;
const LIMIT_MAX: u32 = 4u;
const LIMIT_FIXED: u32 = 5u;

const NO_SLIP_BETA_MAX: f32 = 1.5;
const PI: f32 = 3.14159265358979;
const JACOBI_SWEEPS: u32 = 6u;

// ---- resources (bindings.rs `Slot`) ----
@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<storage, read_write> step: StepState;
@group(0) @binding(2) var<storage, read_write> objects: array<ObjectGpu>;
// liquid: xyz position [m], w mass [kg]
@group(0) @binding(3) var<storage, read_write> liquid_pos: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> liquid_vel: array<vec4<f32>>;
// XSPH advection velocity ṽ (2.69)
@group(0) @binding(5) var<storage, read_write> liquid_vel_adv: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> liquid_acc: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> liquid_acc0: array<vec4<f32>>;
// ρ (2.46), nˡ, nˢ, p (2.53)
@group(0) @binding(8) var<storage, read_write> liquid_dens: array<vec4<f32>>;
// solid: xyz position, w mass
@group(0) @binding(9) var<storage, read_write> solid_pos: array<vec4<f32>>;
// xyz velocity, w membrane mass shown to the liquid
@group(0) @binding(10) var<storage, read_write> solid_vel: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> solid_vel_adv: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read_write> solid_acc: array<vec4<f32>>;
@group(0) @binding(13) var<storage, read_write> solid_acc0: array<vec4<f32>>;
// displacement increment Δt ṽ + ½Δt² a⁰ (D-11)
@group(0) @binding(14) var<storage, read_write> solid_disp: array<vec4<f32>>;
// ρ (2.47), nˡ, nˢ, p (2.52)
@group(0) @binding(15) var<storage, read_write> solid_dens: array<vec4<f32>>;
// dρ/dt of the current evaluation, D⁰
@group(0) @binding(16) var<storage, read_write> solid_drho: array<vec2<f32>>;
@group(0) @binding(17) var<storage, read_write> solid_flags: array<u32>;
@group(0) @binding(18) var<storage, read_write> solid_f: array<Mat3Gpu>;
@group(0) @binding(19) var<storage, read_write> solid_tau_art: array<StressGpu>;
@group(0) @binding(20) var<storage, read_write> bond_table: array<u32>;
@group(0) @binding(21) var<storage, read_write> bond_count: array<u32>;
// boundary: xyz position, w liquid-equivalent mass
@group(0) @binding(22) var<storage, read_write> boundary_pos: array<vec4<f32>>;
// xyz velocity, w solid-equivalent mass
@group(0) @binding(23) var<storage, read_write> boundary_vel: array<vec4<f32>>;
// xyz rest position, w object index (bits)
@group(0) @binding(24) var<storage, read_write> boundary_pos0: array<vec4<f32>>;
@group(0) @binding(25) var<storage, read_write> liquid_order: array<CellEntry>;
@group(0) @binding(26) var<storage, read_write> liquid_cell_start: array<u32>;
@group(0) @binding(27) var<storage, read_write> solid_order: array<CellEntry>;
@group(0) @binding(28) var<storage, read_write> solid_cell_start: array<u32>;
@group(0) @binding(29) var<storage, read_write> boundary_order: array<CellEntry>;
@group(0) @binding(30) var<storage, read_write> boundary_cell_start: array<u32>;
// grid passes: the set being binned (one bind group per set)
@group(0) @binding(31) var<uniform> grid_set: GridSet;
@group(0) @binding(32) var<storage, read_write> grid_pos: array<vec4<f32>>;
@group(0) @binding(33) var<storage, read_write> grid_order: array<CellEntry>;
@group(0) @binding(34) var<storage, read_write> grid_cell_start: array<u32>;
@group(0) @binding(35) var<storage, read_write> grid_cell_of: array<u32>;
@group(0) @binding(36) var<storage, read_write> grid_cursor: array<atomic<u32>>;
// three-phase prefix sum: per-block counts, then the blocks' offsets (one entry per GRID_WG cells)
@group(0) @binding(46) var<storage, read_write> grid_block_sums: array<u32>;
// batched stepping (batch.wgsl): control block, motion table, indirect dispatch arguments
@group(0) @binding(37) var<storage, read_write> batch: BatchState;
@group(0) @binding(38) var<storage, read_write> motions: array<MotionGpu>;
@group(0) @binding(39) var<storage, read_write> indirect_args: array<u32>;
// squared breaking length of each bond slot (layout of bond_table): max(R², (λ_c r₀)²)
@group(0) @binding(40) var<storage, read_write> bond_limit: array<f32>;
// emitters and sinks (emit.wgsl): state, slot positions, slot blocked flags, flow tables
@group(0) @binding(41) var<storage, read_write> emit_state: EmitState;
@group(0) @binding(42) var<storage, read_write> emit_slots: array<vec4<f32>>;
@group(0) @binding(43) var<storage, read_write> emit_blocked: array<atomic<u32>>;
// per emitter FLOW_STRIDE floats: [entries (bits), period, 0, 0, times[FLOW_MAX], rates[FLOW_MAX]]
@group(0) @binding(44) var<storage, read_write> emit_flow: array<f32>;
// liquid particle ids (emitted particles get new ids; sinks compact the arrays)
@group(0) @binding(45) var<storage, read_write> liquid_id: array<u32>;
// hourglass control (solid.wgsl solid_fit): solid positions in the generated configuration (xyz) and the
// best affine fit F̃ of each particle's bonds
@group(0) @binding(47) var<storage, read_write> solid_pos_ref: array<vec4<f32>>;
@group(0) @binding(48) var<storage, read_write> solid_affine: array<Mat3Gpu>;
// the moulded beds' heightfields (twin: src/sim/bed.rs BedTable): per bed BED_HEADER words, then the
// column tops; ObjectGpu.bed = 1 + its header's index
@group(0) @binding(49) var<storage, read_write> bed_table: array<f32>;
// grid_reorder (grid.wgsl): the liquid's live arrays gathered in cell order, copied back by the apply pass
@group(0) @binding(50) var<storage, read_write> liquid_scratch: array<LiquidMove>;
// a membrane particle's outward unit normal in the generated configuration (xyz; zero for the tissue)
@group(0) @binding(51) var<storage, read_write> solid_normal0: array<vec4<f32>>;
// each solid particle's bond count in the generated configuration (SolidSet::bond_count0; static)
@group(0) @binding(52) var<storage, read_write> bond_count0: array<u32>;
// The capsule's ghost sites (sim::ghosts; ghosts.wgsl): per ghost, 2 vec4 of reference (d, owner bits;
// m_s, m_l), the placed position (w: 1 where the owner seals), 2 vec4 of frame (F_o d, m_l; n̂_o, m_s),
// 2 vec4 of state (p, ρ; reaction), the ghost cell list; per solid particle its first ghost (+ the end);
// per liquid particle whether it sees a blood ghost (density_liquid writes it).
@group(0) @binding(53) var<storage, read_write> ghost_ref: array<vec4<f32>>;
@group(0) @binding(54) var<storage, read_write> ghost_pos: array<vec4<f32>>;
@group(0) @binding(55) var<storage, read_write> ghost_frame: array<vec4<f32>>;
@group(0) @binding(56) var<storage, read_write> ghost_state: array<vec4<f32>>;
@group(0) @binding(57) var<storage, read_write> ghost_order: array<CellEntry>;
@group(0) @binding(58) var<storage, read_write> ghost_cell_start: array<u32>;
@group(0) @binding(59) var<storage, read_write> ghost_start: array<u32>;
@group(0) @binding(60) var<storage, read_write> liquid_sees: array<u32>;

// ---- emitters (twin: src/sim/cpu/emit.rs) ----
const FLOW_MAX: u32 = 1024u;
// 4 + 2·FLOW_MAX floats per emitter in `emit_flow`
const FLOW_STRIDE: u32 = 2052u;

fn in_region(kind: u32, a: vec3<f32>, b: vec3<f32>, x: vec3<f32>, three_d: bool) -> bool {
    if (kind == 0u) {
        let inside_xy = x.x >= a.x && x.x <= b.x && x.y >= a.y && x.y <= b.y;
        return inside_xy && (!three_d || (x.z >= a.z && x.z <= b.z));
    }
    let d = x - a;
    var r2 = d.x * d.x + d.y * d.y;
    if (three_d) {
        r2 = r2 + d.z * d.z;
    }
    return r2 <= b.x * b.x;
}

// Q(t) of emitter e (twin of `FlowTable::rate_at`).
fn flow_at(e: u32, t: f32) -> f32 {
    let base = e * FLOW_STRIDE;
    let n = min(bitcast<u32>(emit_flow[base]), FLOW_MAX);
    if (n == 0u) {
        return 0.0;
    }
    let period = emit_flow[base + 1u];
    let tb = base + 4u;
    let qb = base + 4u + FLOW_MAX;
    var tt = t;
    if (period > 0.0) {
        tt = t - period * floor(t / period);
    }
    if (tt <= emit_flow[tb]) {
        return emit_flow[qb];
    }
    if (tt >= emit_flow[tb + n - 1u]) {
        return emit_flow[qb + n - 1u];
    }
    var lo = 0u;
    var hi = n - 1u;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (emit_flow[tb + mid] <= tt) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let w = (tt - emit_flow[tb + lo]) / (emit_flow[tb + hi] - emit_flow[tb + lo]);
    return emit_flow[qb + lo] + (emit_flow[qb + hi] - emit_flow[qb + lo]) * w;
}

// Buffer velocity of the first inlet containing x (xyz) and 1 in w, or w = 0 outside every inlet.
fn inlet_velocity(x: vec3<f32>) -> vec4<f32> {
    let three_d = params.switches.x != 0u;
    for (var e = 0u; e < emit_state.n_emitters; e = e + 1u) {
        let em = emit_state.emitters[e];
        if (in_region(em.region_kind, em.region_a.xyz, em.region_b.xyz, x, three_d)) {
            return vec4<f32>(em.velocity.xyz, 1.0);
        }
    }
    return vec4<f32>(0.0);
}

// ---- small helpers mirroring glam (same operation order) ----
// Nearest face of box o to a point x inside it, over the first `dims` axes (cpu::forces::nearest_face):
// side −1 for the low face, +1 for the high one; the first axis and the low side win ties.
struct BoxFace {
    axis: i32,
    side: f32,
}

fn nearest_face(o: ObjectGpu, x: vec3<f32>, dims: i32) -> BoxFace {
    var best = 3.0e38;
    var face = BoxFace(0, -1.0);
    for (var a = 0; a < dims; a++) {
        let lo = x[a] - o.geom_a[a];
        let hi = o.geom_b[a] - x[a];
        if (lo < best) {
            best = lo;
            face = BoxFace(a, -1.0);
        }
        if (hi < best) {
            best = hi;
            face = BoxFace(a, 1.0);
        }
    }
    return face;
}

// A box holding y on the side n points to (cpu::forces::box_covering): its index, or -1.
fn box_covering(y: vec3<f32>, n: vec3<f32>, dims: i32) -> i32 {
    for (var j = 0u; j < params.switches.w; j++) {
        let o = objects[j];
        if (o.kind != 0u) {
            continue;
        }
        var holds = true;
        for (var a = 0; a < dims; a++) {
            var ok: bool;
            if (n[a] < 0.0) {
                ok = y[a] > o.geom_a[a] && y[a] <= o.geom_b[a];
            } else if (n[a] > 0.0) {
                ok = y[a] >= o.geom_a[a] && y[a] < o.geom_b[a];
            } else {
                ok = y[a] >= o.geom_a[a] && y[a] <= o.geom_b[a];
            }
            if (!ok) {
                holds = false;
            }
        }
        if (holds) {
            return i32(j);
        }
    }
    return -1;
}

struct BoxExit {
    d: f32,
    found: bool,
    y: vec3<f32>,
    n: vec3<f32>,
}

// y (normals n) moved onto face s (0 low, 1 high) of box c on axis b, with its distance from x.
fn face_move(c: ObjectGpu, b: i32, s: i32, x: vec3<f32>, y: vec3<f32>, n: vec3<f32>) -> BoxExit {
    var y2 = y;
    var n2 = n;
    if (s == 0) {
        y2[b] = c.geom_a[b];
        n2[b] = -1.0;
    } else {
        y2[b] = c.geom_b[b];
        n2[b] = 1.0;
    }
    return BoxExit(len3(y2 - x), false, y2, n2);
}

// WGSL has no recursion, so cpu::forces::exit_via's two levels below the first face are two
// functions: exit_via, then this (after it every axis has a normal).
// box_exit's last level (cpu::forces::exit_via with two axes used): y (normals n) is covered by box j;
// y moved onto each face of j on an unused axis, the nearest uncovered result kept.
fn exit_via_last(j: u32, x: vec3<f32>, y: vec3<f32>, n: vec3<f32>, dims: i32, best_in: BoxExit) -> BoxExit {
    var best = best_in;
    let c = objects[j];
    for (var b = 0; b < dims; b++) {
        if (n[b] != 0.0) {
            continue;
        }
        for (var s = 0; s < 2; s++) {
            let m = face_move(c, b, s, x, y, n);
            let y2 = m.y;
            let n2 = m.n;
            let d = m.d;
            if (d >= best.d) {
                continue;
            }
            if (box_covering(y2, n2, dims) < 0) {
                best = BoxExit(d, true, y2, n2);
            }
        }
    }
    return best;
}

// box_exit's middle level (cpu::forces::exit_via with one axis used): as exit_via_last, a covered
// result going on to exit_via_last.
fn exit_via(j: u32, x: vec3<f32>, y: vec3<f32>, n: vec3<f32>, dims: i32, best_in: BoxExit) -> BoxExit {
    var best = best_in;
    let c = objects[j];
    for (var b = 0; b < dims; b++) {
        if (n[b] != 0.0) {
            continue;
        }
        for (var s = 0; s < 2; s++) {
            let m = face_move(c, b, s, x, y, n);
            let y2 = m.y;
            let n2 = m.n;
            let d = m.d;
            if (d >= best.d) {
                continue;
            }
            let j2 = box_covering(y2, n2, dims);
            if (j2 < 0) {
                best = BoxExit(d, true, y2, n2);
            } else {
                best = exit_via_last(u32(j2), x, y2, n2, dims, best);
            }
        }
    }
    return best;
}

// Where a point x strictly inside box objects[k] is put back out (cpu::forces::box_exit): the nearest
// uncovered point among box k's faces and, where another box covers a face at the landing point, the
// landing point moved onto the covering box's faces on other axes (twice at most); else the nearest face.
fn box_exit(k: u32, x: vec3<f32>, dims: i32) -> BoxExit {
    let g = objects[k];
    var best = BoxExit(3.0e38, false, x, vec3<f32>(0.0));
    for (var a = 0; a < dims; a++) {
        for (var s = 0; s < 2; s++) {
            var side = -1.0;
            var face = g.geom_a[a];
            var d = x[a] - g.geom_a[a];
            if (s == 1) {
                side = 1.0;
                face = g.geom_b[a];
                d = g.geom_b[a] - x[a];
            }
            if (d >= best.d) {
                continue;
            }
            var y = x;
            y[a] = face;
            var n = vec3<f32>(0.0);
            n[a] = side;
            let j = box_covering(y, n, dims);
            if (j < 0) {
                best = BoxExit(d, true, y, n);
            } else {
                best = exit_via(u32(j), x, y, n, dims, best);
            }
        }
    }
    if (!best.found) {
        let f = nearest_face(g, x, dims);
        var y = x;
        var n = vec3<f32>(0.0);
        if (f.side < 0.0) {
            y[f.axis] = g.geom_a[f.axis];
        } else {
            y[f.axis] = g.geom_b[f.axis];
        }
        n[f.axis] = f.side;
        best = BoxExit(0.0, true, y, n);
    }
    return best;
}

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return (a.x * b.x) + (a.y * b.y) + (a.z * b.z);
}

fn len3(a: vec3<f32>) -> f32 {
    return sqrt(dot3(a, a));
}

fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// is_finite_f32 of each component.
fn finite_each(v: vec3<f32>) -> vec3<bool> {
    return (bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u)) != vec3<u32>(0x7f800000u);
}

fn is_finite3(v: vec3<f32>) -> bool {
    return all(finite_each(v));
}

// Rust f32::round of each component: half away from zero (WGSL round() is half to even).
fn round_away3(x: vec3<f32>) -> vec3<f32> {
    let t = trunc(x);
    return select(t, t + select(vec3<f32>(1.0), vec3<f32>(-1.0), x < vec3<f32>(0.0)), abs(x - t) >= vec3<f32>(0.5));
}

// Rust f32::signum (NaN passes through as NaN via copysign semantics of 1.0).
fn signum(x: f32) -> f32 {
    return select(1.0, -1.0, (bitcast<u32>(x) & 0x80000000u) != 0u);
}

// compiler-rt __powisf2, as used by Rust's f32::powi. For 0 ≤ b < 16 (the scenario's exponents are
// 1..=12) its multiplications unrolled without branches: r picks up a^(2^s) where bit s of b is set, in
// the loop's order (1·a = a exactly), so the bits are the loop's; the artificial stress and pressure
// call it once per neighbour pair.
fn powi(a_in: f32, b_in: i32) -> f32 {
    var a = a_in;
    var b = b_in;
    if (b >= 0 && b < 16) {
        var r = 1.0;
        for (var s = 0; s < 4; s++) {
            r = select(r, r * a, (b & 1) != 0);
            b = b / 2;
            a = a * a;
        }
        return r;
    }
    let recip = b < 0;
    var r = 1.0;
    loop {
        if ((b & 1) != 0) {
            r = r * a;
        }
        b = b / 2;
        if (b == 0) {
            break;
        }
        a = a * a;
    }
    if (recip) {
        return 1.0 / r;
    }
    return r;
}

fn m3(c0: vec3<f32>, c1: vec3<f32>, c2: vec3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(c0, c1, c2);
}

// Twin of forces.rs capsule_normal: cof(F) n̂₀ = det F · F⁻ᵀ n̂₀ (Nanson), normalised; zero where F is
// degenerate.
fn capsule_normal(fm: Mat3Gpu, n0: vec3<f32>) -> vec3<f32> {
    let n = cross(fm.c1.xyz, fm.c2.xyz) * n0.x + cross(fm.c2.xyz, fm.c0.xyz) * n0.y + cross(fm.c0.xyz, fm.c1.xyz) * n0.z;
    let l2 = dot3(n, n);
    if (l2 > 1e-12) {
        return n / sqrt(l2);
    }
    return vec3<f32>(0.0);
}

// Twin of forces.rs capsule_inner: whether liquid i (x_ij = x_i − x_j) lies beneath membrane particle j's
// capsule, where the capsule's ghost sites are the wall.
fn capsule_inner(n: vec3<f32>, xij: vec3<f32>) -> bool {
    return params.capsule_ghosts != 0u && any(n != vec3<f32>(0.0)) && dot3(xij, n) <= 0.0;
}

// Steps over which the capsule's seal walks liquid beyond the capsule's plane back to it, by its advection
// velocity alone (forces.rs CAPSULE_SEAL_STEPS).
const CAPSULE_SEAL_STEPS: f32 = 128.0;
// Steps over which the seal stops liquid moving out through the capsule (forces.rs CAPSULE_SEAL_STOP_STEPS).
const CAPSULE_SEAL_STOP_STEPS: f32 = 4.0;

// Twin of forces.rs capsule_seals: membrane particle j still seals (three quarters of its bonds intact).
fn capsule_seals(j: u32) -> bool {
    return 4u * bond_count[j] >= 3u * bond_count0[j];
}

// Twin of forces.rs capsule_seal_share: the liquid's share m_j/(m_i + m_j) of the seal's stop of liquid
// i (mass m_liquid) against membrane particle j (m_membrane), the membrane's m_i/(m_i + m_j).
fn capsule_seal_share(m_liquid: f32, m_membrane: f32) -> f32 {
    return m_membrane / (m_liquid + m_membrane);
}

// Twin of forces.rs capsule_seal_walks: the seal walks liquid at pressure pr back to the capsule's plane
// only where the mirror pressure does not hold it (p ≤ 0); with the capsule's ghost sites, back to the
// organ's surface (capsule_seal_offset).
fn capsule_seal_walks(pr: f32) -> bool {
    return pr <= 0.0;
}

// What ghost_side_counts reads of ghost g: whether its owner seals and its frame — the offset F_o d with the
// blood's mass (frame0), the owner's normal with the tissue's mass (frame1). A walk around one ghost
// (ghost_pressure) loads it once instead of for every liquid particle in reach, and a walk over ghosts
// reads the masses from it instead of loading the frame again.
struct GhostSide {
    seals: bool,
    frame0: vec4<f32>,
    frame1: vec4<f32>,
}

fn ghost_side(g: u32) -> GhostSide {
    return GhostSide(ghost_pos[g].w != 0.0, ghost_frame[2u * g], ghost_frame[2u * g + 1u]);
}

// Whether liquid at x_i − x_g = xig counts the ghost of `side` (its owner sealing): x_i beneath the
// organ's surface at the owner (capsule_seal_offset beyond its particle) by its normal or along the
// ghost's offset. Twin of ghosts.rs ghost_counts.
fn ghost_side_counts(side: GhostSide, xig: vec3<f32>) -> bool {
    if (!side.seals) {
        return false;
    }
    let fd = side.frame0.xyz;
    let xio = xig + fd;
    let s = params.capsule_seal_offset;
    let n = side.frame1.xyz;
    return (any(n != vec3<f32>(0.0)) && dot3(xio, n) <= s) || dot3(xio, fd) <= s * sqrt(dot3(fd, fd));
}

// Acceleration of a liquid particle from one boundary-like neighbour (forces.rs
// `liquid_from_boundary`); density < 0 is the mirror mode with hydrostatic p_b.
fn liquid_from_boundary(rho: f32, pr: f32, n_l: f32, vi: vec3<f32>, m_b: f32, vb: vec3<f32>, xib: vec3<f32>, r: f32,
                        density: f32, pressure: f32, no_slip: f32, g: vec3<f32>, outside: f32) -> vec3<f32> {
    let k = params.k_liquid;
    let grad = xib * grad_spiky_factor(k, r);
    var bracket: f32;
    if (density < 0.0) {
        let pb = max(pr + rho * dot3(g, -xib), 0.0);
        bracket = (max(pr, 0.0) + pb - 2.0 * outside) / (rho * rho);
    } else {
        bracket = pr / (rho * rho) + pressure / (density * density);
    }
    var a = grad * (-n_l * m_b * bracket * params.kappa_s);
    a += (vb - vi) * (no_slip * params.kappa_v * params.eta / rho * (m_b / rho) * lap_viscosity(k, r));
    return a;
}

// Twin of ghosts.rs ghost_on_liquid: liquid_from_boundary with the ghost's wall pressure p_g and density
// ρ_g, `outside` taken off both pressures.
fn ghost_on_liquid(rho: f32, pr: f32, n_l: f32, vi: vec3<f32>, m_g: f32, v_o: vec3<f32>, xig: vec3<f32>, r: f32,
                   p_g: f32, rho_g: f32, outside: f32) -> vec3<f32> {
    return liquid_from_boundary(rho, pr - outside, n_l, vi, m_g, v_o, xig, r, rho_g, p_g - outside, 1.0,
                                vec3<f32>(0.0), 0.0);
}

// Twin of forces.rs SealPair: one intact membrane particle's part in the seal on one liquid particle.
struct SealPair {
    // w (v_n)⁺ n̂: the outward relative normal velocity it stops, weighted
    stop: vec3<f32>,
    // −w (sd)⁺ n̂ / (s Δt_max): the walk back to its plane, weighted (an advection velocity)
    back: vec3<f32>,
    // W_P(r; h_l), 0 beyond Δx_s
    w: f32,
}

// Twin of forces.rs capsule_seal_pair: intact membrane particle j (outward normal n) for liquid i,
// x_ij = x_i − x_j, v_rel = v_i − v_j.
fn capsule_seal_pair(n: vec3<f32>, xij: vec3<f32>, r: f32, v_rel: vec3<f32>) -> SealPair {
    var sp = SealPair(vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    if (r >= params.capsule_dx_solid || all(n == vec3<f32>(0.0))) {
        return sp;
    }
    sp.w = w_poly6(params.k_liquid, r);
    let depth = 0.25 * params.capsule_dx_liquid;
    let sd = dot3(xij, n) - params.capsule_seal_offset;
    if (sd <= -depth || sd >= depth) {
        return sp;
    }
    sp.back = n * (-sp.w * max(sd, 0.0) / (CAPSULE_SEAL_STEPS * params.dt_upper));
    sp.stop = n * (sp.w * max(dot3(v_rel, n), 0.0));
    return sp;
}

fn m3_load(m: Mat3Gpu) -> mat3x3<f32> {
    return mat3x3<f32>(m.c0.xyz, m.c1.xyz, m.c2.xyz);
}

fn m3_store(m: mat3x3<f32>) -> Mat3Gpu {
    return Mat3Gpu(vec4<f32>(m[0], 0.0), vec4<f32>(m[1], 0.0), vec4<f32>(m[2], 0.0));
}

// glam Mat3::mul_vec3: x_axis·v.x, + y_axis·v.y, + z_axis·v.z.
fn m3_mul_v(m: mat3x3<f32>, v: vec3<f32>) -> vec3<f32> {
    var res = m[0] * v.x;
    res = res + m[1] * v.y;
    res = res + m[2] * v.z;
    return res;
}

fn m3_mul(a: mat3x3<f32>, b: mat3x3<f32>) -> mat3x3<f32> {
    return m3(m3_mul_v(a, b[0]), m3_mul_v(a, b[1]), m3_mul_v(a, b[2]));
}

fn m3_add(a: mat3x3<f32>, b: mat3x3<f32>) -> mat3x3<f32> {
    return m3(a[0] + b[0], a[1] + b[1], a[2] + b[2]);
}

fn m3_sub(a: mat3x3<f32>, b: mat3x3<f32>) -> mat3x3<f32> {
    return m3(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

fn m3_scale(a: mat3x3<f32>, s: f32) -> mat3x3<f32> {
    return m3(a[0] * s, a[1] * s, a[2] * s);
}

fn m3_div(a: mat3x3<f32>, s: f32) -> mat3x3<f32> {
    return m3(a[0] / s, a[1] / s, a[2] / s);
}

fn m3_transpose(a: mat3x3<f32>) -> mat3x3<f32> {
    return m3(vec3<f32>(a[0].x, a[1].x, a[2].x), vec3<f32>(a[0].y, a[1].y, a[2].y), vec3<f32>(a[0].z, a[1].z, a[2].z));
}

fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
}

// glam Mat3::determinant: x_axis · (y_axis × z_axis).
fn m3_det(a: mat3x3<f32>) -> f32 {
    return dot3(a[0], cross3(a[1], a[2]));
}

// The symmetric matrix of diagonal d = (xx, yy, zz) and off-diagonal o = (xy, xz, yz).
fn sym3(d: vec3<f32>, o: vec3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(vec3<f32>(d.x, o.x, o.y), vec3<f32>(o.x, d.y, o.z), vec3<f32>(o.y, o.z, d.z));
}

// StressGpu of τ and R from their upper triangles (gpu_types.rs `StressGpu::pack`); m[c][r] is row r of
// column c.
fn stress_pack(t: mat3x3<f32>, r: mat3x3<f32>) -> StressGpu {
    return StressGpu(vec4<f32>(t[0][0], t[1][1], t[2][2], t[1][0]), vec4<f32>(t[2][0], t[2][1], r[0][0], r[1][1]),
                     vec4<f32>(r[2][2], r[1][0], r[2][0], r[2][1]));
}

// τ_j and R_j from solid_tau_art, each a gather of its 6 components.
fn stress_tau_of(j: u32) -> mat3x3<f32> {
    let a = solid_tau_art[j].a;
    let b = solid_tau_art[j].b.xy;
    return sym3(a.xyz, vec3<f32>(a.w, b.x, b.y));
}

fn stress_art_of(j: u32) -> mat3x3<f32> {
    let b = solid_tau_art[j].b.zw;
    let c = solid_tau_art[j].c;
    return sym3(vec3<f32>(b.x, b.y, c.x), c.yzw);
}

fn m3_identity() -> mat3x3<f32> {
    return m3(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

// u ⊗ w (M_ab = u_a w_b), columns u·w_b.
fn outer3(u: vec3<f32>, w: vec3<f32>) -> mat3x3<f32> {
    return m3(u * w.x, u * w.y, u * w.z);
}

// ---- kernels (2.29)–(2.39), SPEC D-1/D-4; twins in src/sim/kernels.rs ----
// Branch-free: both pieces are computed and select() keeps the twin's value (the same operations in the
// same order, so the same bits). They run once per neighbour pair, and a divergent `if` costs a SIMD
// driver (lavapipe) mask bookkeeping that the few flops it would skip do not repay.
// Cubic spline W_C(r; h) (2.29).
fn w_cubic(k: KernelConsts, r: f32) -> f32 {
    let q = r / k.h;
    let inner = k.alpha_c * (1.0 - 1.5 * q * q + 0.75 * q * q * q);
    let t = 2.0 - q;
    let outer = k.alpha_c * 0.25 * t * t * t;
    return select(select(0.0, outer, q < 2.0), inner, q < 1.0);
}

// g of ∇W_C = g · x_ij (2.30).
fn grad_cubic_factor(k: KernelConsts, r: f32) -> f32 {
    let q = r / k.h;
    let t = 2.0 - q;
    let dw = select(0.75 * t * t, 3.0 * q - 2.25 * q * q, q < 1.0);
    return select(-(k.alpha_c / k.h) * dw / r, 0.0, r <= 0.0 || q >= 2.0);
}

// Poly6 W6(r; R) (2.35).
fn w_poly6(k: KernelConsts, r: f32) -> f32 {
    let s = r / k.r;
    let t = 1.0 - s * s;
    return select(k.alpha_6 * t * t * t, 0.0, r >= k.r);
}

// g of ∇W_S = g · x_ij for the spiky kernel (2.39).
fn grad_spiky_factor(k: KernelConsts, r: f32) -> f32 {
    let t = 1.0 - r / k.r;
    return select(-(3.0 * k.alpha_s / k.r) * t * t / r, 0.0, r <= 0.0 || r >= k.r);
}

// ∇²W_V(r; R) (2.34, SPEC D-4).
fn lap_viscosity(k: KernelConsts, r: f32) -> f32 {
    return select(k.c_v * (1.0 - r / k.r), 0.0, r >= k.r);
}

// ---- grid (twin: src/sim/cpu/grid.rs) ----
// Cell-ordered dispatch: the neighbour passes (density_*, forces_*) give invocation k the k-th
// particle of its set in the grid's canonical list (`liquid_order[k].id`, …), not particle k. The
// lanes of a workgroup then sit in neighbouring cells, so they walk nearly the same cell rows and
// read the same candidates (fewer divergent iterations, cache hits). Each particle's sums keep their
// neighbours and their order, so the results do not depend on which invocation computes them (the
// CPU twin iterates in id order). The lists are current whenever a neighbour pass runs: the grids
// are rebuilt after every advance and every host-side state change (passes.rs PLACE_AND_BIN).

// Pipeline constant (mod.rs `create_pipelines`, from `numerics.reorder_liquid`): the liquid is stored in
// the cell order of its list — every liquid grid build is followed by grid_reorder, on both back-ends
// (passes.rs PLACE_AND_BIN and STEP_SECOND; CpuSolver::build_grids) — so entry q of the liquid's list
// is particle q and its list position is liquid_pos[q].xyz, bit for bit. A walk over the liquid then
// reads a candidate's position and mass in one load of liquid_pos[q] instead of the list entry and,
// inside the support, the particle's mass: on lavapipe, which loads a storage buffer lane by lane, the
// density passes ran ≈ 15 % faster on the 64k block (README, Performance).
override LIQUID_IN_CELL_ORDER: bool = true;

// Pipeline constant (mod.rs `create_pipelines`): some axis of the domain is periodic (params.period has
// a component > 0). The neighbour walks test it for every row and candidate; as a constant the driver
// drops the periodic paths of a scene without one instead of branching on params.period each time.
override PERIODIC: bool = true;

// Candidate q of the liquid's cell list: xyz its position at the list's build, w its mass when
// LIQUID_IN_CELL_ORDER (else unused: read it with liquid_candidate_mass); and its index.
struct LiquidCandidate {
    pos_m: vec4<f32>,
    j: u32,
}

fn liquid_candidate(q: u32) -> LiquidCandidate {
    if (LIQUID_IN_CELL_ORDER) {
        return LiquidCandidate(liquid_pos[q], q);
    }
    let e = liquid_order[q];
    return LiquidCandidate(vec4<f32>(e.pos, 0.0), e.id);
}

fn liquid_candidate_mass(c: LiquidCandidate) -> f32 {
    if (LIQUID_IN_CELL_ORDER) {
        return c.pos_m.w;
    }
    return liquid_pos[c.j].w;
}

// The k-th liquid particle of the cell-ordered dispatch (`liquid_order[k].id`).
fn liquid_dispatched(k: u32) -> u32 {
    if (LIQUID_IN_CELL_ORDER) {
        return k;
    }
    return liquid_order[k].id;
}

// Factor on C10, C01 of a solid particle with these flags (params.rs `stiffness_factor`):
// membrane_stiffness for the capsule, 1 for the tissue.
fn stiffness_factor(flags: u32) -> f32 {
    return select(1.0, params.membrane_stiffness, (flags & SOLID_MEMBRANE) != 0u);
}

// Integer cell coordinates of x, clamped into the grid (grid_cell_coords).
fn cell_coords(x: vec3<f32>) -> vec3<i32> {
    // Per component, no vector-index loop (dynamic indexing of a vector is slow on several drivers).
    let f = floor((x - params.grid_min.xyz) / params.grid_cell.xyz);
    // A non-finite coordinate (a NaN state, the unused axis of a 2-D grid) bins to cell 0 on that axis.
    let k = select(vec3<i32>(0), vec3<i32>(f), finite_each(f));
    return clamp(k, vec3<i32>(0), vec3<i32>(params.grid_n.xyz) - vec3<i32>(1));
}

fn cell_index(c: vec3<i32>) -> u32 {
    return u32(c.x) + params.grid_n.x * (u32(c.y) + params.grid_n.y * u32(c.z));
}

// Cells per search radius (twin: grid::GRID_REACH): the neighbour block is ±GRID_REACH cells per axis.
const GRID_REACH: i32 = 2;
// Cells per axis of the neighbour block.
const NBR_SIDE: u32 = u32(2 * GRID_REACH + 1);

// Range of neighbour-cell offsets k (k = 25(dz+2) + 5(dy+2) + (dx+2)): 125 cells in 3-D, 25 in 2-D.
fn nbr_begin() -> u32 {
    return select(2u * NBR_SIDE * NBR_SIDE, 0u, params.switches.x != 0u);
}

fn nbr_end() -> u32 {
    return select(3u * NBR_SIDE * NBR_SIDE, NBR_SIDE * NBR_SIDE * NBR_SIDE, params.switches.x != 0u);
}

// Cell index of neighbour offset k of cell c, or -1 when it lies outside a non-periodic axis.
fn nbr_cell(c: vec3<i32>, k: u32) -> i32 {
    let off = vec3<i32>(i32(k % NBR_SIDE), i32((k / NBR_SIDE) % NBR_SIDE), i32(k / (NBR_SIDE * NBR_SIDE))) - GRID_REACH;
    let nc = c + off;
    let n = vec3<i32>(params.grid_n.xyz);
    let outside = (nc < vec3<i32>(0)) | (nc >= n);
    let periodic = params.period.xyz > vec3<f32>(0.0);
    if (any(outside & !periodic)) {
        return -1;
    }
    return i32(cell_index(select(nc, wrap_cells(nc, n), outside)));
}

// nc mod n (Euclidean) for nc in [−GRID_REACH, n − 1 + GRID_REACH], n ≥ 1: the CPU's rem_euclid, by
// two rounds of one conditional add or subtract. No integer division: a vector `%` by a runtime n is
// scalarised into one division per lane and component by lavapipe and many GPUs, and this runs once
// per neighbour row.
fn wrap_cells(nc: vec3<i32>, n: vec3<i32>) -> vec3<i32> {
    var w = select(nc, nc + n, nc < vec3<i32>(0));
    w = select(w, w - n, w >= n);
    w = select(w, w + n, w < vec3<i32>(0));
    return select(w, w - n, w >= n);
}

// Whether the rows of c's neighbour block wrap around a periodic x axis.
fn nbr_wraps(c: vec3<i32>) -> bool {
    let nx = i32(params.grid_n.x);
    return PERIODIC && params.period.x > 0.0 && (c.x < GRID_REACH || c.x >= nx - GRID_REACH);
}

// Stride of the neighbour-offset loop `for (k = nbr_begin(); k < nbr_end(); k += nbr_step(c))`: a whole
// row (dx = −2 … 2) per k where the row's cells are consecutive, one cell per k where x wraps.
fn nbr_step(c: vec3<i32>) -> u32 {
    return select(NBR_SIDE, 1u, nbr_wraps(c));
}

// Neighbour offset k (a row start, or any k where x wraps — see nbr_step) as a span of consecutive cells
// [lo, hi] (lo = −1: nothing to visit). The cells dx = −2 … 2 of one row (dy, dz) have consecutive
// indices unless x wraps, so a row is one range of a cell list; where a periodic x wraps, each k is its
// own cell as in nbr_cell. Either way the particles come in nbr_cell's canonical order.
fn nbr_span(c: vec3<i32>, k: u32) -> vec2<i32> {
    let nx = i32(params.grid_n.x);
    // No periodic axis (the usual scene): the row's cells straight from its (y, z), without nbr_cell's
    // per-axis wrap and the vector of offsets; the same span as the general path below.
    if (!PERIODIC) {
        let y = c.y + i32((k / NBR_SIDE) % NBR_SIDE) - GRID_REACH;
        let z = c.z + i32(k / (NBR_SIDE * NBR_SIDE)) - GRID_REACH;
        let ny = i32(params.grid_n.y);
        if (y < 0 || y >= ny || z < 0 || z >= i32(params.grid_n.z)) {
            return vec2<i32>(-1, -1);
        }
        let row = nx * (y + ny * z);
        return vec2<i32>(row + max(c.x - GRID_REACH, 0), row + min(c.x + GRID_REACH, nx - 1));
    }
    if (nbr_wraps(c)) {
        let one = nbr_cell(c, k);
        return vec2<i32>(one, one);
    }
    // the row's centre cell (dx = 0), then its clipped x extent
    let mid = nbr_cell(c, k + u32(GRID_REACH));
    if (mid < 0) {
        return vec2<i32>(-1, -1);
    }
    let lo = max(c.x - GRID_REACH, 0) - c.x;
    let hi = min(c.x + GRID_REACH, nx - 1) - c.x;
    return vec2<i32>(mid + lo, mid + hi);
}

// min_image for a neighbour walk's candidates (twin of grid.rs's min_image_wrapped): positions are
// wrapped into the domain, so |d| < l and one add or subtract of l is the minimum image, without the
// division; it equals min_image except half a period apart, beyond every search radius.
fn min_image_wrapped(d: vec3<f32>) -> vec3<f32> {
    if (!PERIODIC) {
        return d;
    }
    let l = params.period.xyz;
    let half = 0.5 * l;
    let w = select(select(d, d + l, d < -half), d - l, d > half);
    return select(d, w, l > vec3<f32>(0.0));
}

// Minimum-image difference on periodic axes (SPEC §4.3), per component without a loop (it runs for
// every neighbour candidate): d − l·round(d/l) where l > 0, d elsewhere (the unselected quotient of a
// non-periodic axis, d/0, is discarded).
fn min_image(d: vec3<f32>) -> vec3<f32> {
    if (!PERIODIC) {
        return d;
    }
    let l = params.period.xyz;
    return select(d, d - l * round_away3(d / l), l > vec3<f32>(0.0));
}
