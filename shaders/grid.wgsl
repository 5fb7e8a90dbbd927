// grid.wgsl — uniform-grid neighbour search (thesis §2.2.5, §2.2.9); twin: src/sim/cpu/grid.rs.
//
// Counting sort of one particle set (bound as grid_pos / grid_order / grid_cell_start):
// grid_clear → grid_count (integer atomics only) → grid_scan_blocks · grid_scan_top · grid_scan_apply
// (three-phase prefix sum, integer: fixed result) →
// grid_scatter (atomic cursor: order inside a cell is arbitrary) → grid_sort_cells (insertion sort of
// each cell's range by index). The result is the CPU's canonical list: cells ascending, ascending index
// inside a cell, bit for bit. Each entry also carries the particle's position (`CellEntry`), so the
// neighbour loops read candidates from consecutive memory.
#import common

const GRID_WG: u32 = 64u;
const SCAN_WG: u32 = 256u;

// The cursors of cells 0 ..= cells (the last a sentinel) to 0, SCAN_CHUNK consecutive cells per lane.
@compute @workgroup_size(64)
fn grid_clear(@builtin(global_invocation_id) gid: vec3<u32>) {
    let first = gid.x * SCAN_CHUNK;
    for (var c = first; c < first + SCAN_CHUNK && c <= grid_set.cells; c++) {
        atomicStore(&grid_cursor[c], 0u);
    }
}

@compute @workgroup_size(64)
fn grid_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= grid_set.n) {
        return;
    }
    let c = cell_index(cell_coords(grid_pos[i].xyz));
    grid_cell_of[i] = c;
    atomicAdd(&grid_cursor[c], 1u);
}

var<workgroup> scan_partial: array<u32, 256>;
var<workgroup> scan_local: array<u32, 64>;

// Cells per invocation of grid_clear and the scan's two block passes (twin: passes.rs SCAN_CHUNK): a
// block is GRID_WG lanes of SCAN_CHUNK consecutive cells each, so the lane-0 loop that combines a
// block's lanes runs once per 512 cells, not per 64 (the grid has a cell per (R/2)³ of the whole
// domain, mostly empty; the 64k block's 170k cells per set: the block passes 8.3 → 2.0 ms per step on
// lavapipe, 4 cells per lane 2.7).
const SCAN_CHUNK: u32 = 8u;

// The counts of this lane's SCAN_CHUNK cells of block b (0 past the last cell); their sum goes to
// scan_local[lane] for the whole workgroup. Called from uniform control flow (it holds a barrier).
fn load_block_counts(lane: u32, b: u32) -> array<u32, 8> {
    let first = (b * GRID_WG + lane) * SCAN_CHUNK;
    var n = array<u32, 8>();
    var sum = 0u;
    for (var t = 0u; t < SCAN_CHUNK; t++) {
        let c = first + t;
        if (c < grid_set.cells) {
            n[t] = atomicLoad(&grid_cursor[c]);
            sum += n[t];
        }
    }
    scan_local[lane] = sum;
    workgroupBarrier();
    return n;
}

// The prefix sum of the counts into grid_cell_start[0..=cells] in three phases, so that no single
// workgroup walks all cells (the cell count grows as (domain / (R/2))³). Integer sums, so the result is
// the CPU's sequential scan bit for bit. Phase 1: the count of each block of GRID_WG·SCAN_CHUNK cells.
@compute @workgroup_size(64)
fn grid_scan_blocks(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    load_block_counts(lid.x, wid.x);
    if (lid.x == 0u) {
        var sum = 0u;
        for (var t = 0u; t < GRID_WG; t++) {
            sum += scan_local[t];
        }
        grid_block_sums[wid.x] = sum;
    }
}

// Phase 2 (one workgroup): the block counts become exclusive block offsets; the total goes to
// grid_cell_start[cells]. Each invocation owns a contiguous chunk of blocks.
@compute @workgroup_size(256)
fn grid_scan_top(@builtin(local_invocation_id) lid: vec3<u32>) {
    let per_block = GRID_WG * SCAN_CHUNK;
    let blocks = (grid_set.cells + per_block - 1u) / per_block;
    let chunk = (blocks + SCAN_WG - 1u) / SCAN_WG;
    let begin = min(lid.x * chunk, blocks);
    let end = min(begin + chunk, blocks);
    var sum = 0u;
    for (var b = begin; b < end; b++) {
        sum += grid_block_sums[b];
    }
    scan_partial[lid.x] = sum;
    workgroupBarrier();
    if (lid.x == 0u) {
        var acc = 0u;
        for (var t = 0u; t < SCAN_WG; t++) {
            let v = scan_partial[t];
            scan_partial[t] = acc;
            acc += v;
        }
    }
    workgroupBarrier();
    var run = scan_partial[lid.x];
    for (var b = begin; b < end; b++) {
        let n = grid_block_sums[b];
        grid_block_sums[b] = run;
        run += n;
    }
    if (lid.x == SCAN_WG - 1u) {
        grid_cell_start[grid_set.cells] = run;
    }
}

// Phase 3: each block's exclusive scan from its offset into grid_cell_start; the cursors are reset to
// the cell starts for grid_scatter.
@compute @workgroup_size(64)
fn grid_scan_apply(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = load_block_counts(lid.x, wid.x);
    if (lid.x == 0u) {
        var acc = grid_block_sums[wid.x];
        for (var t = 0u; t < GRID_WG; t++) {
            let v = scan_local[t];
            scan_local[t] = acc;
            acc += v;
        }
    }
    workgroupBarrier();
    var start = scan_local[lid.x];
    let first = (wid.x * GRID_WG + lid.x) * SCAN_CHUNK;
    for (var t = 0u; t < SCAN_CHUNK; t++) {
        let c = first + t;
        if (c < grid_set.cells) {
            grid_cell_start[c] = start;
            atomicStore(&grid_cursor[c], start);
            start += n[t];
        }
    }
}

@compute @workgroup_size(64)
fn grid_scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= grid_set.n) {
        return;
    }
    let slot = atomicAdd(&grid_cursor[grid_cell_of[i]], 1u);
    grid_order[slot] = CellEntry(grid_pos[i].xyz, i);
}

// Restores ascending index inside each cell (the CPU scatter visits particles in ascending order). One
// invocation per particle of the set, not per cell (most cells are empty): of a cell's particles, the
// one whose claim on the cell's cursor comes first sorts the cell's range (after grid_scatter the cursor
// is at the range's end; which particle sorts does not matter), the others return without touching it.
@compute @workgroup_size(64)
fn grid_sort_cells(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= grid_set.n) {
        return;
    }
    let c = grid_cell_of[i];
    let s = grid_cell_start[c];
    let e = grid_cell_start[c + 1u];
    if (e - s < 2u || atomicAdd(&grid_cursor[c], 1u) != e) {
        return;
    }
    for (var q = s + 1u; q < e; q++) {
        let v = grid_order[q];
        var w = q;
        loop {
            if (w <= s) {
                break;
            }
            let u = grid_order[w - 1u];
            if (u.id <= v.id) {
                break;
            }
            grid_order[w] = u;
            w -= 1u;
        }
        grid_order[w] = v;
    }
}

// grid_reorder (issue 4, "particle arrays reordered by cell"; twin: grid::grid_reorder): after the
// liquid's grid build of a step, its storage order becomes the cell order of the fresh list, so the
// neighbour walks gather the velocities and densities of a cell's particles from nearby memory however
// far the blood has flowed and mixed (the candidates' positions already come from the list). Only the
// arrays that live across the grid build move — position and mass, velocity, the predictor's a⁰ (read
// by the corrector) and the id — as emit_compact moves them: ρ, nˡ, nˢ, p, a and ṽ are written by
// evaluation 1 before anything reads them. Two passes through liquid_scratch (a gather cannot write
// the arrays it reads); the apply pass makes the list's entries point at their new places.
@compute @workgroup_size(64)
fn grid_reorder_gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if (k >= params.counts.x) {
        return;
    }
    let i = liquid_order[k].id;
    liquid_scratch[k] = LiquidMove(liquid_pos[i], liquid_vel[i], liquid_acc0[i], vec4<u32>(liquid_id[i], 0u, 0u, 0u));
}

@compute @workgroup_size(64)
fn grid_reorder_apply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if (k >= params.counts.x) {
        return;
    }
    let m = liquid_scratch[k];
    liquid_pos[k] = m.pos;
    liquid_vel[k] = m.vel;
    liquid_acc0[k] = m.acc0;
    liquid_id[k] = m.id.x;
    liquid_order[k].id = k;
}
