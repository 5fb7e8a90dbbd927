//! Host↔GPU structs, `#[repr(C)]` + `Pod`, each mirroring the WGSL struct of the same name in
//! `shaders/common.wgsl` (must be kept in sync; `tests/shader_validation.rs` compares every size and
//! member offset in [`LAYOUTS`] with naga's layout of the WGSL struct). No `vec3` in storage arrays:
//! vectors travel as `[f32; 4]` (STYLE §5.4).

use super::super::params::{Params, TensionRegion};
use crate::scenario::{MAX_OUTLETS, MAX_TENSION_REGIONS};
use crate::sim::kernels::{Dim, Kernel};
use bytemuck::{Pod, Zeroable};
use std::mem::{offset_of, size_of};

/// `KernelConsts` (common.wgsl): one kernel's constants (sim::kernels::Kernel, §2.2.1).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct KernelConsts {
    pub h: f32,
    pub r: f32,
    pub alpha_c: f32,
    pub alpha_6: f32,
    pub alpha_s: f32,
    pub c_v: f32,
    pub _pad0: f32,
    pub _pad1: f32,
}

impl From<&Kernel> for KernelConsts {
    fn from(k: &Kernel) -> Self {
        KernelConsts {
            h: k.h,
            r: k.r,
            alpha_c: k.alpha_c,
            alpha_6: k.alpha_6,
            alpha_s: k.alpha_s,
            c_v: k.c_v,
            _pad0: 0.0,
            _pad1: 0.0,
        }
    }
}

/// `SimParams` (common.wgsl): the uniform block every pass reads (from [`Params`] plus the
/// command-controlled damping and gravity).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct SimParams {
    pub k_liquid: KernelConsts,
    pub k_solid: KernelConsts,
    pub k_cross: KernelConsts,
    pub grid_min: [f32; 4],
    pub grid_cell: [f32; 4],
    pub grid_n: [u32; 4],
    pub period: [f32; 4],
    pub domain_min: [f32; 4],
    pub domain_max: [f32; 4],
    pub gravity: [f32; 4],
    pub counts: [u32; 4],
    pub switches: [u32; 4],
    /// `Params::liquid_tension_in`, two vec4s per region: box (min, 1) (max, 0), sphere (centre, 2)
    /// (0, 0, 0, r²), unused (0, 0, 0, 0) twice.
    pub tension: [[f32; 4]; 2 * MAX_TENSION_REGIONS],
    /// `Params::outlets_in_effect`, three vec4s per outlet: (min, density) (max, absolute pressure)
    /// (normal, 0); none: zeros.
    pub outlet: [[f32; 4]; 3 * MAX_OUTLETS],
    pub rho0_l: f32,
    pub rho0_s: f32,
    pub eta: f32,
    pub k_l: f32,
    pub c1: f32,
    pub k_s: f32,
    pub k_sat: f32,
    pub n_sat: f32,
    pub c10: f32,
    pub c01: f32,
    pub kbar: f32,
    pub c_l: f32,
    pub c_s: f32,
    pub av_alpha: f32,
    pub av_beta: f32,
    pub av_gamma: f32,
    pub as_eps: f32,
    pub as_exp: i32,
    pub xsph_s: f32,
    pub xsph_l: f32,
    pub kappa_v: f32,
    pub wc_dx: f32,
    pub rho_ref_l: f32,
    pub rho_ref_s: f32,
    pub cfl_factor: f32,
    pub cfl_viscous: f32,
    pub cfl_sound: f32,
    pub cfl_force: f32,
    pub cfl_friction: f32,
    pub dt_min: f32,
    pub dt_max: f32,
    pub fixed_dt: f32,
    pub h_min: f32,
    pub c_max: f32,
    pub max_speed: f32,
    pub damping: f32,
    pub has_liquid: u32,
    pub has_solid: u32,
    pub kappa_s: f32,
    /// γ of (3.4) [N/m]; 0: off.
    pub wicking: f32,
    /// s_ll, s_lb of (3.3) \[N\]; 0: off.
    pub cohesion_ll: f32,
    pub cohesion_lb: f32,
    /// Upper bound of Δt (`Params::dt_upper`): the stick relaxation time of wall friction.
    pub dt_upper: f32,
    /// Hourglass-control coefficient c (`numerics.hourglass`); 0: off.
    pub hourglass: f32,
    /// Ligament springs (`Params::tether_omega2`, `tether_damping`): ω² [1/s²], 2ζω [1/s].
    pub tether_omega2: f32,
    pub tether_damping: f32,
    /// `Params::membrane_stiffness`: capsule C10, C01 over the tissue's.
    pub membrane_stiffness: f32,
    /// Liquid artificial pressure (`Params::ap_eps`, `ap_exp`, `wc_dx_l`); ε = 0: off.
    pub ap_eps: f32,
    pub ap_exp: i32,
    pub wc_dx_l: f32,
    pub ambient_pressure: f32,
    /// `Params::bond_reach` (0: every particle tests its bonds against the blades).
    pub bond_reach: f32,
    /// `Params::capsule_dx_liquid`, `capsule_dx_solid`: the spacings of the capsule's ghosts and seal.
    pub capsule_dx_liquid: f32,
    pub capsule_dx_solid: f32,
    /// `Params::capsule_seal`.
    pub capsule_seal: f32,
    /// The capsule's ghost sites in use (0: none) and `forces::capsule_seal_offset`.
    pub capsule_ghosts: u32,
    pub capsule_seal_offset: f32,
    pub _pad_seal2: f32,
    pub _pad_seal3: f32,
    pub _pad_seal4: f32,
}

/// Set counts of a scene, as the uniform block carries them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    pub liquid: u32,
    pub solid: u32,
    pub boundary: u32,
    pub bond_capacity: u32,
    pub objects: u32,
    /// The capsule's ghost sites (`sim::ghosts`).
    pub ghosts: u32,
}

impl SimParams {
    /// The uniform block for `p`; `gravity`, `damping`, `gravity_liquid`, `suction_held` are the
    /// command-set values.
    pub fn new(
        p: &Params,
        c: Counts,
        gravity: glam::Vec3,
        damping: f32,
        gravity_liquid: bool,
        suction_held: bool,
    ) -> SimParams {
        let v4 = |v: glam::Vec3| [v.x, v.y, v.z, 0.0];
        let per = p.periodic_len();
        SimParams {
            k_liquid: (&p.k_liquid).into(),
            k_solid: (&p.k_solid).into(),
            k_cross: (&p.k_cross).into(),
            grid_min: v4(p.grid.min),
            grid_cell: [p.grid.cell[0], p.grid.cell[1], p.grid.cell[2], 0.0],
            grid_n: [p.grid.n[0], p.grid.n[1], p.grid.n[2], p.grid.cell_count() as u32],
            period: v4(per),
            domain_min: v4(p.domain_min),
            domain_max: v4(p.domain_max),
            gravity: [gravity.x, gravity.y, gravity.z, if gravity_liquid { 1.0 } else { 0.0 }],
            counts: [c.liquid, c.solid, c.boundary, c.bond_capacity],
            switches: [
                u32::from(p.dim == Dim::Three),
                u32::from(p.av_liquid),
                p.liquid_tension_below_ns.to_bits(),
                c.objects,
            ],
            tension: {
                let mut t = [[0.0; 4]; 2 * MAX_TENSION_REGIONS];
                for (k, r) in p.liquid_tension_in.iter().take(MAX_TENSION_REGIONS).enumerate() {
                    (t[2 * k], t[2 * k + 1]) = match *r {
                        TensionRegion::Box { min, max } => ([min.x, min.y, min.z, 1.0], [max.x, max.y, max.z, 0.0]),
                        TensionRegion::Sphere { centre, radius } => {
                            ([centre.x, centre.y, centre.z, 2.0], [0.0, 0.0, 0.0, radius * radius])
                        }
                    };
                }
                t
            },
            outlet: {
                let mut t = [[0.0; 4]; 3 * MAX_OUTLETS];
                for (k, o) in p.outlets_in_effect(suction_held).iter().take(MAX_OUTLETS).enumerate() {
                    t[3 * k] = [o.min.x, o.min.y, o.min.z, o.density];
                    t[3 * k + 1] = [o.max.x, o.max.y, o.max.z, o.pressure];
                    t[3 * k + 2] = [o.normal.x, o.normal.y, o.normal.z, 0.0];
                }
                t
            },
            rho0_l: p.rho0_l,
            rho0_s: p.rho0_s,
            eta: p.eta,
            k_l: p.k_l,
            c1: p.c1,
            k_s: p.k_s,
            k_sat: p.k_sat,
            n_sat: p.n_sat,
            c10: p.c10,
            c01: p.c01,
            kbar: p.kbar,
            c_l: p.c_l,
            c_s: p.c_s,
            av_alpha: p.av_alpha,
            av_beta: p.av_beta,
            av_gamma: p.av_gamma,
            as_eps: p.as_eps,
            as_exp: p.as_exp,
            xsph_s: p.xsph_s,
            xsph_l: p.xsph_l,
            kappa_v: p.kappa_v,
            wc_dx: p.wc_dx,
            rho_ref_l: p.rho_ref_l,
            rho_ref_s: p.rho_ref_s,
            cfl_factor: p.cfl_factor,
            cfl_viscous: p.cfl_viscous,
            cfl_sound: p.cfl_sound,
            cfl_force: p.cfl_force,
            cfl_friction: p.cfl_friction,
            dt_min: p.dt_min,
            dt_max: p.dt_max,
            fixed_dt: p.fixed_dt.unwrap_or(-1.0),
            h_min: p.h_min(),
            c_max: p.c_max(),
            max_speed: p.max_speed,
            damping,
            has_liquid: u32::from(p.has_liquid),
            has_solid: u32::from(p.has_solid),
            kappa_s: p.kappa_s,
            wicking: p.wicking,
            cohesion_ll: p.cohesion_ll,
            cohesion_lb: p.cohesion_lb,
            dt_upper: p.dt_upper(),
            hourglass: p.hourglass,
            tether_omega2: p.tether_omega2,
            tether_damping: p.tether_damping,
            membrane_stiffness: p.membrane_stiffness,
            ap_eps: p.ap_eps,
            ap_exp: p.ap_exp,
            wc_dx_l: p.wc_dx_l,
            ambient_pressure: p.ambient_pressure,
            bond_reach: p.bond_reach(),
            capsule_dx_liquid: p.capsule_dx_liquid,
            capsule_dx_solid: p.capsule_dx_solid,
            capsule_seal: p.capsule_seal,
            capsule_ghosts: if p.capsule_ghosts { c.ghosts } else { 0 },
            capsule_seal_offset: crate::sim::cpu::forces::capsule_seal_offset(p),
            _pad_seal2: 0.0,
            _pad_seal3: 0.0,
            _pad_seal4: 0.0,
        }
    }
}

/// Bits of `StepState::status`, mirrored by `STATUS_*` in common.wgsl.
pub mod status {
    pub const NONFINITE_LIQUID: u32 = 1;
    pub const NONFINITE_SOLID: u32 = 2;
    pub const DT_COLLAPSED: u32 = 4;
}

/// `StepState` (common.wgsl): GPU-resident Δt, its limiting criterion and the step status.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct StepState {
    pub dt: f32,
    pub limit: u32,
    pub status: u32,
    pub broken_ends: u32,
    pub a_max_bits: u32,
    pub rho_min_bits: u32,
    pub fric_max_bits: u32,
    pub bad_liquid: u32,
    pub bad_solid: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// `ObjectGpu` (common.wgsl): one boundary object's current pose, velocity, pressure mode and
/// Coulomb friction coefficient of solid contact.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct ObjectGpu {
    pub geom_a: [f32; 4],
    pub geom_b: [f32; 4],
    pub disp: [f32; 4],
    pub vel: [f32; 4],
    pub density: f32,
    pub pressure: f32,
    pub kind: u32,
    /// 1 + the cut axis of a `blade_cut` scalpel (`cpu::fracture::blade_axis`); 0 for any other object.
    pub blade: u32,
    pub friction: f32,
    /// 1 + the index of a moulded bed's heightfield in `bed_table` (`sim::bed::BedTable::offsets`); 0: none.
    pub bed: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// `MotionGpu` (common.wgsl): one boundary object's rest shape, pressure mode and analytic motion.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct MotionGpu {
    pub rest_a: [f32; 4],
    pub rest_b: [f32; 4],
    pub vec: [f32; 4],
    pub times: [f32; 4],
    pub density: f32,
    pub pressure: f32,
    pub kind: u32,
    pub motion: u32,
    pub friction: f32,
    /// 1 + the index of a moulded bed's heightfield in `bed_table` (`sim::bed::BedTable::offsets`); 0: none.
    pub bed: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Steps per batch: the length of `BatchState`'s per-step arrays.
pub const MAX_BATCH: usize = 64;

/// `BatchState::stop` values (batch.wgsl `STOP_*`).
pub mod stop {
    pub const RUNNING: u32 = 0;
    pub const END: u32 = 1;
    pub const FAILED: u32 = 2;
}

/// `BatchState` (common.wgsl): the GPU clock (f32 pair) and one batch's control and statistics.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct BatchState {
    pub t_hi: f32,
    pub t_lo: f32,
    pub tn_hi: f32,
    pub tn_lo: f32,
    pub end_hi: f32,
    pub end_lo: f32,
    pub steps: u32,
    pub stop: u32,
    pub fail_status: u32,
    pub bad_liquid: u32,
    pub bad_solid: u32,
    pub broken_ends: u32,
    pub fail_dt: f32,
    /// Live liquid particles; particles emitted and sunk since t = 0 (emit.wgsl).
    pub n_liquid: u32,
    pub emitted: u32,
    pub sunk: u32,
    /// An emitter found the liquid capacity full during the batch.
    pub capacity_hit: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
    pub wg: [u32; 8],
    pub dt: [f32; MAX_BATCH],
    pub limit: [u32; MAX_BATCH],
}

/// Byte offset of `BatchState::end_hi`: the host rewrites the block from here per batch, leaving the
/// GPU clock (t_hi, t_lo) untouched.
pub const BATCH_HEADER_OFFSET: u64 = offset_of!(BatchState, end_hi) as u64;

/// `EmitterGpu` (common.wgsl): one inlet (twin `sim::cpu::emit::Emitter`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct EmitterGpu {
    /// xyz: unit direction, w: buffer speed per unit flow.
    pub dir: [f32; 4],
    pub velocity: [f32; 4],
    pub region_a: [f32; 4],
    pub region_b: [f32; 4],
    pub slot_start: u32,
    pub slot_count: u32,
    pub cursor: u32,
    pub count: u32,
    pub mass: f32,
    pub volume: f32,
    pub acc: f32,
    pub region_kind: u32,
}

/// `SinkGpu` (common.wgsl): a sink region (box [a, b] or sphere centre a, radius b.x).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct SinkGpu {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub kind: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// High bit of a boundary particle's object word in `boundary_pos0.w` (common.wgsl): the particle stands
/// in a cavity in the tissue's place and shows the liquid's nˢ its solid-equivalent mass
/// (`BoundarySet::m_sn`).
pub const BOUNDARY_IN_TISSUE: u32 = 0x8000_0000;

/// Emitters and sinks per scenario (`EmitState`'s fixed arrays; `scenario` validation limits).
pub const MAX_EMITTERS: usize = 8;
pub const MAX_SINKS: usize = 8;
/// Floats per emitter in the flow-table buffer: [entries (bits), period, 0, 0, times, rates].
pub const FLOW_STRIDE: usize = 4 + 2 * crate::sim::cpu::emit::FLOW_MAX;

/// `EmitState` (common.wgsl): emitters, sinks and the liquid capacity.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct EmitStateGpu {
    pub n_emitters: u32,
    pub n_sinks: u32,
    pub n_slots: u32,
    pub capacity: u32,
    pub id_base: u32,
    pub sink_hits: u32,
    pub block_r2: f32,
    pub _pad0: u32,
    pub emitters: [EmitterGpu; MAX_EMITTERS],
    pub sinks: [SinkGpu; MAX_SINKS],
}

/// `Mat3Gpu` (common.wgsl): glam's column-major `Mat3`, one `vec4` per column.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Mat3Gpu {
    pub c0: [f32; 4],
    pub c1: [f32; 4],
    pub c2: [f32; 4],
}

impl From<glam::Mat3> for Mat3Gpu {
    fn from(m: glam::Mat3) -> Self {
        let c = |v: glam::Vec3| [v.x, v.y, v.z, 0.0];
        Mat3Gpu { c0: c(m.x_axis), c1: c(m.y_axis), c2: c(m.z_axis) }
    }
}

impl From<Mat3Gpu> for glam::Mat3 {
    fn from(m: Mat3Gpu) -> Self {
        let c = |v: [f32; 4]| glam::Vec3::new(v[0], v[1], v[2]);
        glam::Mat3::from_cols(c(m.c0), c(m.c1), c(m.c2))
    }
}

/// `StressGpu` (common.wgsl): τ and the artificial stress R (2.59), both symmetric, as their upper
/// triangles — `a` = (τxx, τyy, τzz, τxy), `b` = (τxz, τyz, Rxx, Ryy), `c` = (Rzz, Rxy, Rxz, Ryz) —
/// so that a bond of the stress loop gathers 6 components of τ_j and a neighbour of the
/// artificial-stress sum 6 of R_j instead of a 3×3 matrix each (the gathers are most of the force
/// passes' cost on the software adapter). The CPU twin's τ and R are symmetric bit for bit
/// (`sim::cpu::solid` tests), so the packing loses nothing.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct StressGpu {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

impl StressGpu {
    /// Packs τ and R from their upper triangles (row r, column c with r ≤ c).
    pub fn pack(tau: glam::Mat3, art: glam::Mat3) -> StressGpu {
        let (t, r) = (tau.to_cols_array_2d(), art.to_cols_array_2d()); // [column][row]
        StressGpu {
            a: [t[0][0], t[1][1], t[2][2], t[1][0]],
            b: [t[2][0], t[2][1], r[0][0], r[1][1]],
            c: [r[2][2], r[1][0], r[2][0], r[2][1]],
        }
    }

    /// τ (common.wgsl `stress_tau`).
    pub fn tau(&self) -> glam::Mat3 {
        sym3([self.a[0], self.a[1], self.a[2]], [self.a[3], self.b[0], self.b[1]])
    }

    /// R (common.wgsl `stress_art`).
    pub fn art(&self) -> glam::Mat3 {
        sym3([self.b[2], self.b[3], self.c[0]], [self.c[1], self.c[2], self.c[3]])
    }
}

/// The symmetric matrix of diagonal (xx, yy, zz) and off-diagonal (xy, xz, yz).
fn sym3(d: [f32; 3], o: [f32; 3]) -> glam::Mat3 {
    glam::Mat3::from_cols_array_2d(&[[d[0], o[0], o[1]], [o[0], d[1], o[2]], [o[1], o[2], d[2]]])
}

/// `CellEntry` (common.wgsl): one entry of a set's cell list, the particle index with its position at
/// the grid build (the neighbour loops test distances without an indirection).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct CellEntry {
    pub pos: [f32; 3],
    pub id: u32,
}

/// `GridSet` (common.wgsl): the set a grid pass instance bins.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GridSet {
    pub n: u32,
    pub cells: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

const _: () = assert!(size_of::<KernelConsts>() == 32);
const _: () = assert!(size_of::<SimParams>() == 704);
// common.wgsl's `tension: array<vec4<f32>, 8>` and density.wgsl's loop over 4 regions
const _: () = assert!(MAX_TENSION_REGIONS == 4);
// common.wgsl's `outlet: array<vec4<f32>, 6>` and outlet_find's loop over 2 outlets
const _: () = assert!(MAX_OUTLETS == 2);
const _: () = assert!(size_of::<StepState>() == 48);
const _: () = assert!(size_of::<ObjectGpu>() == 96);
const _: () = assert!(size_of::<Mat3Gpu>() == 48);
const _: () = assert!(size_of::<StressGpu>() == 48);
const _: () = assert!(size_of::<GridSet>() == 16);
const _: () = assert!(size_of::<CellEntry>() == 16);
const _: () = assert!(size_of::<MotionGpu>() == 96);
const _: () = assert!(size_of::<BatchState>() == 112 + 8 * MAX_BATCH);
const _: () = assert!(size_of::<EmitterGpu>() == 96);
const _: () = assert!(size_of::<SinkGpu>() == 48);
const _: () = assert!(size_of::<EmitStateGpu>() == 32 + (96 + 48) * 8);

/// One struct's layout: (WGSL struct name, Rust size, [(member, Rust offset)]).
pub type StructLayout = (&'static str, usize, &'static [(&'static str, usize)]);

/// Layouts of every host↔WGSL struct, for the layout test.
pub const LAYOUTS: &[StructLayout] = &[
    (
        "KernelConsts",
        size_of::<KernelConsts>(),
        &[("h", offset_of!(KernelConsts, h)), ("c_v", offset_of!(KernelConsts, c_v))],
    ),
    (
        "SimParams",
        size_of::<SimParams>(),
        &[
            ("k_cross", offset_of!(SimParams, k_cross)),
            ("grid_min", offset_of!(SimParams, grid_min)),
            ("switches", offset_of!(SimParams, switches)),
            ("tension", offset_of!(SimParams, tension)),
            ("outlet", offset_of!(SimParams, outlet)),
            ("ambient_pressure", offset_of!(SimParams, ambient_pressure)),
            ("rho0_l", offset_of!(SimParams, rho0_l)),
            ("as_exp", offset_of!(SimParams, as_exp)),
            ("fixed_dt", offset_of!(SimParams, fixed_dt)),
            ("damping", offset_of!(SimParams, damping)),
            ("kappa_s", offset_of!(SimParams, kappa_s)),
            ("wicking", offset_of!(SimParams, wicking)),
            ("cohesion_lb", offset_of!(SimParams, cohesion_lb)),
            ("ap_eps", offset_of!(SimParams, ap_eps)),
            ("wc_dx_l", offset_of!(SimParams, wc_dx_l)),
            ("dt_upper", offset_of!(SimParams, dt_upper)),
            ("hourglass", offset_of!(SimParams, hourglass)),
        ],
    ),
    (
        "StepState",
        size_of::<StepState>(),
        &[
            ("dt", offset_of!(StepState, dt)),
            ("broken_ends", offset_of!(StepState, broken_ends)),
            ("bad_solid", offset_of!(StepState, bad_solid)),
        ],
    ),
    (
        "ObjectGpu",
        size_of::<ObjectGpu>(),
        &[
            ("vel", offset_of!(ObjectGpu, vel)),
            ("density", offset_of!(ObjectGpu, density)),
            ("kind", offset_of!(ObjectGpu, kind)),
            ("friction", offset_of!(ObjectGpu, friction)),
            ("bed", offset_of!(ObjectGpu, bed)),
        ],
    ),
    ("Mat3Gpu", size_of::<Mat3Gpu>(), &[("c1", offset_of!(Mat3Gpu, c1)), ("c2", offset_of!(Mat3Gpu, c2))]),
    ("StressGpu", size_of::<StressGpu>(), &[("b", offset_of!(StressGpu, b)), ("c", offset_of!(StressGpu, c))]),
    ("GridSet", size_of::<GridSet>(), &[("cells", offset_of!(GridSet, cells))]),
    ("CellEntry", size_of::<CellEntry>(), &[("id", offset_of!(CellEntry, id))]),
    (
        "MotionGpu",
        size_of::<MotionGpu>(),
        &[
            ("times", offset_of!(MotionGpu, times)),
            ("motion", offset_of!(MotionGpu, motion)),
            ("friction", offset_of!(MotionGpu, friction)),
            ("bed", offset_of!(MotionGpu, bed)),
        ],
    ),
    (
        "BatchState",
        size_of::<BatchState>(),
        &[
            ("end_hi", offset_of!(BatchState, end_hi)),
            ("fail_dt", offset_of!(BatchState, fail_dt)),
            ("n_liquid", offset_of!(BatchState, n_liquid)),
            ("capacity_hit", offset_of!(BatchState, capacity_hit)),
            ("wg", offset_of!(BatchState, wg)),
            ("dt", offset_of!(BatchState, dt)),
            ("limit", offset_of!(BatchState, limit)),
        ],
    ),
    (
        "EmitterGpu",
        size_of::<EmitterGpu>(),
        &[
            ("velocity", offset_of!(EmitterGpu, velocity)),
            ("slot_start", offset_of!(EmitterGpu, slot_start)),
            ("acc", offset_of!(EmitterGpu, acc)),
            ("region_kind", offset_of!(EmitterGpu, region_kind)),
        ],
    ),
    ("SinkGpu", size_of::<SinkGpu>(), &[("b", offset_of!(SinkGpu, b)), ("kind", offset_of!(SinkGpu, kind))]),
    (
        "EmitState",
        size_of::<EmitStateGpu>(),
        &[
            ("sink_hits", offset_of!(EmitStateGpu, sink_hits)),
            ("block_r2", offset_of!(EmitStateGpu, block_r2)),
            ("emitters", offset_of!(EmitStateGpu, emitters)),
            ("sinks", offset_of!(EmitStateGpu, sinks)),
        ],
    ),
];
