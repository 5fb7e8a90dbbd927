// grid.wgsl — uniform-grid neighbour search (thesis §2.2.5, §2.2.9); twin: src/sim/cpu/grid.rs.
//
// Counting sort of one particle set (bound as grid_pos / grid_order / grid_cell_start):
// grid_clear → grid_count (integer atomics only) → grid_scan (one workgroup, fixed order) →
// grid_scatter (atomic cursor: order inside a cell is arbitrary) → grid_sort_cells (insertion sort of
// each cell's range by index). The result is the CPU's canonical list: cells ascending, ascending index
// inside a cell, bit for bit.
#import common

const GRID_WG: u32 = 64u;
const SCAN_WG: u32 = 256u;

@compute @workgroup_size(64)
fn grid_clear(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if (c > grid_set.cells) {
        return;
    }
    atomicStore(&grid_cursor[c], 0u);
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

// Exclusive prefix sum of the counts into grid_cell_start[0..=cells]; resets the cursors to the
// cell starts for grid_scatter. One workgroup; each invocation owns a contiguous chunk of cells.
@compute @workgroup_size(256)
fn grid_scan(@builtin(local_invocation_id) lid: vec3<u32>) {
    let cells = grid_set.cells;
    let chunk = (cells + SCAN_WG - 1u) / SCAN_WG;
    let begin = min(lid.x * chunk, cells);
    let end = min(begin + chunk, cells);
    var sum = 0u;
    for (var c = begin; c < end; c++) {
        sum += atomicLoad(&grid_cursor[c]);
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
    for (var c = begin; c < end; c++) {
        let n = atomicLoad(&grid_cursor[c]);
        grid_cell_start[c] = run;
        atomicStore(&grid_cursor[c], run);
        run += n;
    }
    if (lid.x == SCAN_WG - 1u) {
        grid_cell_start[cells] = run;
    }
}

@compute @workgroup_size(64)
fn grid_scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= grid_set.n) {
        return;
    }
    let slot = atomicAdd(&grid_cursor[grid_cell_of[i]], 1u);
    grid_order[slot] = i;
}

// Restores ascending index inside each cell (the CPU scatter visits particles in ascending order).
@compute @workgroup_size(64)
fn grid_sort_cells(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if (c >= grid_set.cells) {
        return;
    }
    let s = grid_cell_start[c];
    let e = grid_cell_start[c + 1u];
    for (var q = s + 1u; q < e; q++) {
        let v = grid_order[q];
        var w = q;
        loop {
            if (w <= s) {
                break;
            }
            let u = grid_order[w - 1u];
            if (u <= v) {
                break;
            }
            grid_order[w] = u;
            w -= 1u;
        }
        grid_order[w] = v;
    }
}
