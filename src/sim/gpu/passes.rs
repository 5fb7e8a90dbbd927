//! The ordered pass list of one step (STYLE §5.2, SPEC §5.2): entry point, WGSL family, workgroup size,
//! the slots it binds and its dispatch rule. The GPU back-end encodes exactly these lists; the CPU
//! solver (`sim::cpu`, `CpuSolver::step_inner`) calls the twins of the same names in the same order:
//! evaluation 0 (with XSPH) → Δt → predictor, F update, advance → boundaries and grids on xⁿ⁺¹ →
//! evaluation 1 → corrector → fracture → divergence check.

use super::bindings::Slot;
use Slot::*;

/// Workgroup size of every family's particle passes (`@workgroup_size(64)` in the WGSL).
pub const WORKGROUP: u32 = 64;
/// `grid_scan_top` runs as one workgroup of this size.
pub const SCAN_WORKGROUP: u32 = 256;
/// Cells per invocation of `grid_clear`, `grid_scan_blocks` and `grid_scan_apply` (`SCAN_CHUNK` in
/// grid.wgsl).
pub const SCAN_CHUNK: u32 = 8;

/// How many invocations a pass needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dispatch {
    Liquid,
    Solid,
    Boundary,
    /// The capsule's ghost sites (a fixed count: always dispatched directly).
    Ghost,
    /// Particles of the grid instance's set.
    GridParticles,
    /// Blocks of [`SCAN_CHUNK`] cells of the grid (one invocation each: the two block passes of the scan).
    GridChunks,
    /// Blocks of [`SCAN_CHUNK`] of the grid's cells + 1 (the cursor array's sentinel): `grid_clear`.
    GridChunksPlusOne,
    /// One workgroup.
    One,
}

/// One entry point and what it needs.
#[derive(Clone, Copy, Debug)]
pub struct PassSpec {
    pub entry: &'static str,
    pub family: &'static str,
    pub workgroup_size: u32,
    pub slots: &'static [Slot],
    pub dispatch: Dispatch,
}

const fn pass(entry: &'static str, family: &'static str, slots: &'static [Slot], dispatch: Dispatch) -> PassSpec {
    PassSpec { entry, family, workgroup_size: WORKGROUP, slots, dispatch }
}

const GRID_SLOTS: &[Slot] = &[Params, GridSet, GridPos, GridOrder, GridCellStart, GridCellOf, GridCursor];
const NBR_ALL: [Slot; 6] = [LiquidOrder, LiquidCellStart, SolidOrder, SolidCellStart, BoundaryOrder, BoundaryCellStart];

pub const GRID_CLEAR: PassSpec = pass("grid_clear", "grid", GRID_SLOTS, Dispatch::GridChunksPlusOne);
pub const GRID_COUNT: PassSpec = pass("grid_count", "grid", GRID_SLOTS, Dispatch::GridParticles);
/// Prefix sum of the cell counts in three phases (integer sums: bit-identical to the CPU's sequential
/// scan): block counts, one workgroup over the block counts, block-local scans plus block offsets.
const SCAN_SLOTS: &[Slot] = &[GridSet, GridCellStart, GridCursor, GridBlockSums];
pub const GRID_SCAN_BLOCKS: PassSpec = pass("grid_scan_blocks", "grid", SCAN_SLOTS, Dispatch::GridChunks);
pub const GRID_SCAN_TOP: PassSpec = PassSpec {
    entry: "grid_scan_top",
    family: "grid",
    workgroup_size: SCAN_WORKGROUP,
    slots: SCAN_SLOTS,
    dispatch: Dispatch::One,
};
pub const GRID_SCAN_APPLY: PassSpec = pass("grid_scan_apply", "grid", SCAN_SLOTS, Dispatch::GridChunks);
pub const GRID_SCATTER: PassSpec = pass("grid_scatter", "grid", GRID_SLOTS, Dispatch::GridParticles);
/// One invocation per particle of the set: the first to claim its cell sorts the cell's range.
pub const GRID_SORT_CELLS: PassSpec = pass("grid_sort_cells", "grid", GRID_SLOTS, Dispatch::GridParticles);
/// The liquid renumbered into the cell order of its fresh list (twin: `grid::grid_reorder`): gather into
/// the scratch, then copy back and point the list at the new places.
const REORDER_SLOTS: &[Slot] = &[Params, LiquidPos, LiquidVel, LiquidAcc0, LiquidId, LiquidOrder, LiquidScratch];
pub const GRID_REORDER_GATHER: PassSpec = pass("grid_reorder_gather", "grid", REORDER_SLOTS, Dispatch::Liquid);
pub const GRID_REORDER_APPLY: PassSpec = pass("grid_reorder_apply", "grid", REORDER_SLOTS, Dispatch::Liquid);

pub const DENSITY_LIQUID: PassSpec = pass(
    "density_liquid",
    "density",
    &[
        Params,
        LiquidPos,
        LiquidDens,
        SolidPos,
        SolidVel,
        SolidFlags,
        SolidDefGrad,
        SolidNormal0,
        BoundaryPos,
        BoundaryVel,
        BoundaryPos0,
        NBR_ALL[0],
        NBR_ALL[1],
        NBR_ALL[2],
        NBR_ALL[3],
        NBR_ALL[4],
        NBR_ALL[5],
        GhostOrder,
        GhostCellStart,
        GhostPos,
        GhostFrame,
        LiquidSees,
    ],
    Dispatch::Liquid,
);
const DENSITY_SOLID_SLOTS: &[Slot] = &[
    Params,
    LiquidPos,
    SolidPos,
    SolidDens,
    SolidFlags,
    BoundaryPos,
    NBR_ALL[0],
    NBR_ALL[1],
    NBR_ALL[2],
    NBR_ALL[3],
    NBR_ALL[4],
    NBR_ALL[5],
];
pub const DENSITY_SOLID: PassSpec = pass("density_solid", "density", DENSITY_SOLID_SLOTS, Dispatch::Solid);
/// `density_solid` with the nˡ of the previous step's evaluation 1: evaluation 0 where the liquid's
/// densities are kept (`GpuSolver::step_items`).
pub const DENSITY_SOLID_KEPT: PassSpec = pass("density_solid_kept", "density", DENSITY_SOLID_SLOTS, Dispatch::Solid);
pub const SOLID_STRESS: PassSpec =
    pass("solid_stress", "solid", &[Params, SolidDefGrad, SolidDens, SolidStress, SolidFlags], Dispatch::Solid);
/// The best affine fit of each particle's bonds for the hourglass control (a no-op when it is off).
pub const SOLID_FIT: PassSpec = pass(
    "solid_fit",
    "solid",
    &[Params, SolidPos, SolidPosRef, SolidDefGrad, SolidAffine, BondTable, BondCount],
    Dispatch::Solid,
);
pub const SOLID_DEF_GRAD: PassSpec = pass(
    "solid_def_grad",
    "solid",
    &[Params, SolidPos, SolidDisp, SolidDens, SolidDefGrad, BondTable, BondCount],
    Dispatch::Solid,
);
/// The liquid forces of an evaluation; evaluation 0's pass also writes the XSPH velocities from the
/// same neighbour walk (forces.rs `forces_liquid` with `xsph`).
const FORCES_LIQUID_SLOTS: &[Slot] = &[
    Params,
    Objects,
    LiquidPos,
    LiquidVel,
    LiquidDens,
    LiquidAcc,
    LiquidVelAdv,
    SolidPos,
    SolidVel,
    SolidDens,
    SolidFlags,
    SolidDefGrad,
    SolidNormal0,
    BondCount,
    BondCount0,
    BoundaryPos,
    BoundaryVel,
    BoundaryPos0,
    NBR_ALL[0],
    NBR_ALL[1],
    NBR_ALL[2],
    NBR_ALL[3],
    NBR_ALL[4],
    NBR_ALL[5],
    GhostOrder,
    GhostCellStart,
    GhostPos,
    GhostFrame,
    GhostState,
    GhostRef,
    LiquidSees,
];
pub const FORCES_LIQUID: PassSpec = pass("forces_liquid", "forces", FORCES_LIQUID_SLOTS, Dispatch::Liquid);
pub const FORCES_LIQUID_XSPH: PassSpec = pass("forces_liquid_xsph", "forces", FORCES_LIQUID_SLOTS, Dispatch::Liquid);
/// The same for the solid (forces.rs `forces_solid` with `xsph`).
const FORCES_SOLID_SLOTS: &[Slot] = &[
    Params,
    Objects,
    LiquidPos,
    LiquidVel,
    LiquidDens,
    SolidPos,
    SolidVel,
    SolidDens,
    SolidDrho,
    SolidFlags,
    SolidStress,
    SolidAcc,
    SolidVelAdv,
    BondTable,
    BondCount,
    BoundaryPos,
    BoundaryVel,
    BoundaryPos0,
    SolidPosRef,
    SolidAffine,
    SolidDefGrad,
    SolidNormal0,
    BondCount0,
    LiquidAcc,
    NBR_ALL[0],
    NBR_ALL[1],
    NBR_ALL[2],
    NBR_ALL[3],
    NBR_ALL[4],
    NBR_ALL[5],
    GhostStart,
    GhostState,
    LiquidSees,
];
pub const FORCES_SOLID: PassSpec = pass("forces_solid", "forces", FORCES_SOLID_SLOTS, Dispatch::Solid);
pub const FORCES_SOLID_XSPH: PassSpec = pass("forces_solid_xsph", "forces", FORCES_SOLID_SLOTS, Dispatch::Solid);
/// The capsule's ghost sites placed at x_o + F_o d with their owner's frame (ghosts.wgsl; twin:
/// `ghosts::ghost_place`), before the ghost grid is built.
pub const GHOST_PLACE: PassSpec = pass(
    "ghost_place",
    "ghosts",
    &[Params, SolidPos, SolidDefGrad, SolidNormal0, BondCount, BondCount0, GhostRef, GhostPos, GhostFrame],
    Dispatch::Ghost,
);
/// Each blood ghost's wall pressure, density and reaction, after `density_liquid` (twin:
/// `ghosts::ghost_pressure`).
pub const GHOST_PRESSURE: PassSpec = pass(
    "ghost_pressure",
    "ghosts",
    &[
        Params,
        LiquidPos,
        LiquidVel,
        LiquidDens,
        LiquidOrder,
        LiquidCellStart,
        SolidVel,
        GhostRef,
        GhostPos,
        GhostFrame,
        GhostState,
    ],
    Dispatch::Ghost,
);
pub const DT_CLEAR: PassSpec =
    PassSpec { entry: "dt_clear", family: "dt", workgroup_size: 1, slots: &[Params, Step], dispatch: Dispatch::One };
pub const DT_REDUCE_LIQUID: PassSpec =
    pass("dt_reduce_liquid", "dt", &[Params, Step, LiquidAcc, LiquidDens], Dispatch::Liquid);
pub const DT_REDUCE_SOLID: PassSpec =
    pass("dt_reduce_solid", "dt", &[Params, Step, SolidAcc, SolidDens, SolidFlags], Dispatch::Solid);
pub const DT_FINALIZE: PassSpec =
    PassSpec { entry: "dt_finalize", family: "dt", workgroup_size: 1, slots: &[Params, Step], dispatch: Dispatch::One };
pub const INTEGRATE_PREDICT_LIQUID: PassSpec = pass(
    "integrate_predict_liquid",
    "integrate",
    &[Params, Step, LiquidPos, LiquidVel, LiquidVelAdv, LiquidAcc, LiquidAcc0, EmitState],
    Dispatch::Liquid,
);
pub const INTEGRATE_PREDICT_SOLID: PassSpec = pass(
    "integrate_predict_solid",
    "integrate",
    &[Params, Step, SolidVel, SolidVelAdv, SolidAcc, SolidAcc0, SolidDrho, SolidDisp, SolidFlags],
    Dispatch::Solid,
);
pub const INTEGRATE_ADVANCE_LIQUID: PassSpec = pass(
    "integrate_advance_liquid",
    "integrate",
    &[Params, Step, LiquidPos, LiquidVel, LiquidVelAdv, LiquidAcc0, EmitState, Objects, BedTable],
    Dispatch::Liquid,
);
pub const INTEGRATE_ADVANCE_SOLID: PassSpec = pass(
    "integrate_advance_solid",
    "integrate",
    &[Params, Step, SolidPos, SolidVel, SolidDisp, SolidDens, SolidDrho, SolidFlags, Objects, BedTable],
    Dispatch::Solid,
);
pub const INTEGRATE_BOUNDARY: PassSpec = pass(
    "integrate_boundary",
    "integrate",
    &[Params, Objects, BoundaryPos, BoundaryVel, BoundaryPos0],
    Dispatch::Boundary,
);
pub const INTEGRATE_CORRECT_LIQUID: PassSpec = pass(
    "integrate_correct_liquid",
    "integrate",
    &[Params, Step, LiquidPos, LiquidVel, LiquidAcc, LiquidAcc0, EmitState],
    Dispatch::Liquid,
);
pub const INTEGRATE_CORRECT_SOLID: PassSpec = pass(
    "integrate_correct_solid",
    "integrate",
    &[Params, Step, SolidVel, SolidAcc, SolidAcc0, SolidDrho, SolidDens, SolidFlags],
    Dispatch::Solid,
);
pub const FRACTURE_APPLY: PassSpec = pass(
    "fracture_apply",
    "fracture",
    &[Params, Step, Objects, SolidPos, BondTable, BondCount, BondLimit],
    Dispatch::Solid,
);
pub const INTEGRATE_CHECK_LIQUID: PassSpec = pass(
    "integrate_check_liquid",
    "integrate",
    &[Params, Step, LiquidPos, LiquidVel, LiquidDens, LiquidId],
    Dispatch::Liquid,
);
pub const INTEGRATE_CHECK_SOLID: PassSpec =
    pass("integrate_check_solid", "integrate", &[Params, Step, SolidPos, SolidVel, SolidDens], Dispatch::Solid);

pub const BATCH_BEGIN: PassSpec = PassSpec {
    entry: "batch_begin",
    family: "batch",
    workgroup_size: 1,
    slots: &[Batch, IndirectArgs],
    dispatch: Dispatch::One,
};
pub const BATCH_MOTION: PassSpec = PassSpec {
    entry: "batch_motion",
    family: "batch",
    workgroup_size: 1,
    slots: &[Params, Step, Objects, Batch, Motions, IndirectArgs, EmitState, EmitFlow],
    dispatch: Dispatch::One,
};
pub const BATCH_END: PassSpec =
    PassSpec { entry: "batch_end", family: "batch", workgroup_size: 1, slots: &[Step, Batch], dispatch: Dispatch::One };

pub const EMIT_CLEAR: PassSpec = PassSpec {
    entry: "emit_clear",
    family: "emit",
    workgroup_size: WORKGROUP,
    slots: &[Params, Batch, EmitState, EmitBlocked],
    dispatch: Dispatch::One,
};
pub const EMIT_MARK: PassSpec =
    pass("emit_mark", "emit", &[Params, EmitState, EmitSlots, EmitBlocked, LiquidPos], Dispatch::Liquid);
/// One workgroup of this size compacts the liquid arrays (emit.wgsl `COMPACT_WG`).
pub const COMPACT_WORKGROUP: u32 = 256;
pub const EMIT_COMPACT: PassSpec = PassSpec {
    entry: "emit_compact",
    family: "emit",
    workgroup_size: COMPACT_WORKGROUP,
    slots: &[Params, Batch, EmitState, LiquidPos, LiquidVel, LiquidAcc0, LiquidId],
    dispatch: Dispatch::One,
};
pub const EMIT_APPLY: PassSpec = PassSpec {
    entry: "emit_apply",
    family: "emit",
    workgroup_size: 1,
    slots: &[
        Step,
        Batch,
        IndirectArgs,
        EmitState,
        EmitSlots,
        EmitBlocked,
        EmitFlow,
        LiquidPos,
        LiquidVel,
        LiquidVelAdv,
        LiquidAcc,
        LiquidAcc0,
        LiquidDens,
        LiquidId,
    ],
    dispatch: Dispatch::One,
};

/// Sinks and emitters of one step (`emit::emit_step`), after the advance, before the grids; the host
/// then copies the live liquid count into the uniforms (`Stage::SyncCounts`).
pub const STEP_EMIT: &[Stage] = &[
    Stage::Pass(EMIT_CLEAR),
    Stage::Pass(EMIT_MARK),
    Stage::Pass(EMIT_COMPACT),
    Stage::Pass(EMIT_APPLY),
    Stage::SyncCounts,
];

/// Every entry point (pipelines are created for each; tests check each against naga).
pub const ALL_PASSES: &[PassSpec] = &[
    GRID_CLEAR,
    GRID_COUNT,
    GRID_SCAN_BLOCKS,
    GRID_SCAN_TOP,
    GRID_SCAN_APPLY,
    GRID_SCATTER,
    GRID_SORT_CELLS,
    GRID_REORDER_GATHER,
    GRID_REORDER_APPLY,
    DENSITY_LIQUID,
    DENSITY_SOLID,
    DENSITY_SOLID_KEPT,
    GHOST_PLACE,
    GHOST_PRESSURE,
    SOLID_STRESS,
    SOLID_FIT,
    SOLID_DEF_GRAD,
    FORCES_LIQUID,
    FORCES_SOLID,
    FORCES_LIQUID_XSPH,
    FORCES_SOLID_XSPH,
    DT_CLEAR,
    DT_REDUCE_LIQUID,
    DT_REDUCE_SOLID,
    DT_FINALIZE,
    INTEGRATE_PREDICT_LIQUID,
    INTEGRATE_PREDICT_SOLID,
    INTEGRATE_ADVANCE_LIQUID,
    INTEGRATE_ADVANCE_SOLID,
    INTEGRATE_BOUNDARY,
    INTEGRATE_CORRECT_LIQUID,
    INTEGRATE_CORRECT_SOLID,
    FRACTURE_APPLY,
    INTEGRATE_CHECK_LIQUID,
    INTEGRATE_CHECK_SOLID,
    BATCH_BEGIN,
    BATCH_MOTION,
    BATCH_END,
    EMIT_CLEAR,
    EMIT_MARK,
    EMIT_COMPACT,
    EMIT_APPLY,
];

/// A set binned by the grid passes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridOf {
    Liquid,
    Solid,
    Boundary,
    /// The capsule's ghost sites.
    Ghost,
}

/// One element of an ordered pass list.
#[derive(Clone, Copy, Debug)]
pub enum Stage {
    Pass(PassSpec),
    /// grid_clear · grid_count · grid_scan_blocks · grid_scan_top · grid_scan_apply · grid_scatter ·
    /// grid_sort_cells for one set.
    Grid(GridOf),
    /// Not a dispatch: the host copies `batch.n_liquid` into the uniforms' liquid count (emitters).
    SyncCounts,
}

/// The grid build of one set (twin: `grid::grid_build`).
pub const GRID_BUILD: &[PassSpec] =
    &[GRID_CLEAR, GRID_COUNT, GRID_SCAN_BLOCKS, GRID_SCAN_TOP, GRID_SCAN_APPLY, GRID_SCATTER, GRID_SORT_CELLS];

/// Boundaries to the current pose and the three cell lists, then the capsule's ghost sites placed and
/// binned (`move_boundaries` + `build_grids`), the
/// liquid renumbered in its cell order when `numerics.reorder_liquid` (as every liquid grid build is:
/// the liquid walks rely on it, common.wgsl `LIQUID_IN_CELL_ORDER`). The state the host hands the device
/// is already in that order (the CPU twin's, or a batch's), so here the renumbering finds nothing to
/// move; were it to move anything, the liquid's ρ, p, a and ṽ would stay behind until the next step's
/// evaluation rewrites them (grid_reorder moves only what lives across a step).
pub const PLACE_AND_BIN: &[Stage] = &[
    Stage::Pass(INTEGRATE_BOUNDARY),
    Stage::Grid(GridOf::Liquid),
    Stage::Pass(GRID_REORDER_GATHER),
    Stage::Pass(GRID_REORDER_APPLY),
    Stage::Grid(GridOf::Solid),
    Stage::Grid(GridOf::Boundary),
    Stage::Pass(GHOST_PLACE),
    Stage::Grid(GridOf::Ghost),
];

/// One force evaluation (`CpuSolver::evaluate`), without XSPH.
pub const EVALUATE: &[Stage] = &[
    Stage::Pass(DENSITY_LIQUID),
    Stage::Pass(GHOST_PRESSURE),
    Stage::Pass(DENSITY_SOLID),
    Stage::Pass(SOLID_STRESS),
    Stage::Pass(SOLID_FIT),
    Stage::Pass(FORCES_LIQUID),
    Stage::Pass(FORCES_SOLID),
];

/// First half of a step: evaluation 0 with XSPH, then Δt (2.70) into `step.dt`.
pub const STEP_FIRST: &[Stage] = &[
    Stage::Pass(DT_CLEAR),
    Stage::Pass(DENSITY_LIQUID),
    Stage::Pass(GHOST_PRESSURE),
    Stage::Pass(DENSITY_SOLID),
    Stage::Pass(SOLID_STRESS),
    Stage::Pass(SOLID_FIT),
    Stage::Pass(FORCES_LIQUID_XSPH),
    Stage::Pass(FORCES_SOLID_XSPH),
    Stage::Pass(DT_REDUCE_LIQUID),
    Stage::Pass(DT_REDUCE_SOLID),
    Stage::Pass(DT_FINALIZE),
];

/// Second half, up to the advance: predictor, F update, advance to xⁿ⁺¹ (then [`STEP_EMIT`] when the
/// scenario has emitters or sinks).
pub const STEP_ADVANCE: &[Stage] = &[
    Stage::Pass(INTEGRATE_PREDICT_LIQUID),
    Stage::Pass(INTEGRATE_PREDICT_SOLID),
    Stage::Pass(SOLID_DEF_GRAD),
    Stage::Pass(INTEGRATE_ADVANCE_LIQUID),
    Stage::Pass(INTEGRATE_ADVANCE_SOLID),
];

/// Rest of the second half: boundaries and grids at tⁿ⁺¹ (the liquid renumbered by cell when
/// `numerics.reorder_liquid`), evaluation 1, corrector, fracture, divergence check.
pub const STEP_SECOND: &[Stage] = &[
    Stage::Pass(INTEGRATE_BOUNDARY),
    Stage::Grid(GridOf::Liquid),
    Stage::Pass(GRID_REORDER_GATHER),
    Stage::Pass(GRID_REORDER_APPLY),
    Stage::Grid(GridOf::Solid),
    Stage::Grid(GridOf::Boundary),
    Stage::Pass(GHOST_PLACE),
    Stage::Grid(GridOf::Ghost),
    Stage::Pass(DENSITY_LIQUID),
    Stage::Pass(GHOST_PRESSURE),
    Stage::Pass(DENSITY_SOLID),
    Stage::Pass(SOLID_STRESS),
    Stage::Pass(SOLID_FIT),
    Stage::Pass(FORCES_LIQUID),
    Stage::Pass(FORCES_SOLID),
    Stage::Pass(INTEGRATE_CORRECT_LIQUID),
    Stage::Pass(INTEGRATE_CORRECT_SOLID),
    Stage::Pass(FRACTURE_APPLY),
    Stage::Pass(INTEGRATE_CHECK_LIQUID),
    Stage::Pass(INTEGRATE_CHECK_SOLID),
];
