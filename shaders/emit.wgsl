// emit.wgsl — emitters and sinks (issue 7; thesis §3.1.5/§4.2.4 fed the hepatic-artery flow as new
// liquid particles). Twin: `src/sim/cpu/emit.rs` (same steps, same f32 operations, same order).
// Runs once per step after the advance to xⁿ⁺¹, before the grids: emit_clear → emit_mark (slots
// blocked by a particle closer than BLOCK_FACTOR·Δx_l that is not in a sink; sink hits counted) →
// emit_compact (one workgroup: liquid inside sinks removed, order kept) → emit_apply (one thread:
// volume accounts, new particles on free slots, live count and the liquid dispatch arguments). The host
// then copies `batch.n_liquid` into the uniforms' liquid count (`GpuSolver`, `Item::SyncCounts`).
#import common

const COMPACT_WG: u32 = 256u;

fn in_sink(x: vec3<f32>, three_d: bool) -> bool {
    for (var k = 0u; k < emit_state.n_sinks; k = k + 1u) {
        let s = emit_state.sinks[k];
        if (in_region(s.kind, s.a.xyz, s.b.xyz, x, three_d)) {
            return true;
        }
    }
    return false;
}

@compute @workgroup_size(64)
fn emit_clear(@builtin(local_invocation_id) lid: vec3<u32>) {
    for (var s = lid.x; s < emit_state.n_slots; s = s + 64u) {
        atomicStore(&emit_blocked[s], 0u);
    }
    if (lid.x == 0u) {
        atomicStore(&emit_state.sink_hits, 0u);
        batch.n_liquid = params.counts.x;
    }
}

@compute @workgroup_size(64)
fn emit_mark(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let three_d = params.switches.x != 0u;
    let x = liquid_pos[i].xyz;
    if (in_sink(x, three_d)) {
        atomicAdd(&emit_state.sink_hits, 1u);
        return;
    }
    let r2 = emit_state.block_r2;
    for (var s = 0u; s < emit_state.n_slots; s = s + 1u) {
        let d = x - emit_slots[s].xyz;
        var d2 = d.x * d.x + d.y * d.y;
        if (three_d) {
            d2 = d2 + d.z * d.z;
        }
        if (d2 < r2) {
            atomicOr(&emit_blocked[s], 1u);
        }
    }
}

var<workgroup> wg_scan: array<u32, 256>;
var<workgroup> wg_n: u32;
var<workgroup> wg_hits: u32;

// Order-preserving in-place compaction by one workgroup, chunk after chunk: each chunk is read into
// registers before any thread writes, and writes go to indices ≤ the read ones, so nothing unread is
// overwritten.
@compute @workgroup_size(256)
fn emit_compact(@builtin(local_invocation_id) lid: vec3<u32>) {
    if (lid.x == 0u) {
        wg_n = params.counts.x;
        wg_hits = atomicLoad(&emit_state.sink_hits);
    }
    let hits = workgroupUniformLoad(&wg_hits);
    if (hits == 0u) {
        return;
    }
    let n = workgroupUniformLoad(&wg_n);
    let three_d = params.switches.x != 0u;
    var base = 0u;
    for (var start = 0u; start < n; start = start + COMPACT_WG) {
        let i = start + lid.x;
        var keep = 0u;
        var p = vec4<f32>(0.0);
        var v = vec4<f32>(0.0);
        var a0 = vec4<f32>(0.0);
        var id = 0u;
        if (i < n) {
            p = liquid_pos[i];
            v = liquid_vel[i];
            a0 = liquid_acc0[i];
            id = liquid_id[i];
            keep = select(1u, 0u, in_sink(p.xyz, three_d));
        }
        wg_scan[lid.x] = keep;
        workgroupBarrier();
        // Hillis–Steele inclusive scan of the keep flags
        for (var off = 1u; off < COMPACT_WG; off = off * 2u) {
            var add = 0u;
            if (lid.x >= off) {
                add = wg_scan[lid.x - off];
            }
            workgroupBarrier();
            wg_scan[lid.x] = wg_scan[lid.x] + add;
            workgroupBarrier();
        }
        let total = wg_scan[COMPACT_WG - 1u];
        if (keep == 1u) {
            let dst = base + wg_scan[lid.x] - 1u;
            liquid_pos[dst] = p;
            liquid_vel[dst] = v;
            liquid_acc0[dst] = a0;
            liquid_id[dst] = id;
        }
        base = base + total;
        storageBarrier();
        workgroupBarrier();
    }
    if (lid.x == 0u) {
        batch.sunk = batch.sunk + (n - base);
        batch.n_liquid = base;
    }
}

// One thread: volume accounts and new particles (twin of `emit_apply`), then the live count, the
// liquid workgroup count and this step's remaining liquid dispatches.
// Dispatched directly (it writes the indirect arguments): a no-op once the batch has stopped.
@compute @workgroup_size(1)
fn emit_apply() {
    if (batch.stop != 0u) {
        return;
    }
    var n = batch.n_liquid;
    let dt = step.dt;
    let t = batch.tn_hi + batch.tn_lo;
    var slot_start = 0u;
    for (var e = 0u; e < emit_state.n_emitters; e = e + 1u) {
        var em = emit_state.emitters[e];
        let q = flow_at(e, t);
        em.acc = em.acc + q * dt;
        var tries = 0u;
        while (em.acc >= em.volume && tries < em.slot_count) {
            if (n >= emit_state.capacity) {
                batch.capacity_hit = 1u;
                break;
            }
            let s = em.cursor;
            em.cursor = (em.cursor + 1u) % em.slot_count;
            tries = tries + 1u;
            if (atomicLoad(&emit_blocked[em.slot_start + s]) != 0u) {
                continue;
            }
            liquid_id[n] = emit_state.id_base + batch.emitted;
            liquid_pos[n] = vec4<f32>(emit_slots[em.slot_start + s].xyz, em.mass);
            liquid_vel[n] = vec4<f32>(em.velocity.xyz, 0.0);
            liquid_vel_adv[n] = vec4<f32>(em.velocity.xyz, 0.0);
            liquid_acc[n] = vec4<f32>(0.0);
            liquid_acc0[n] = vec4<f32>(0.0);
            liquid_dens[n] = vec4<f32>(0.0);
            em.acc = em.acc - em.volume;
            em.count = em.count + 1u;
            batch.emitted = batch.emitted + 1u;
            n = n + 1u;
        }
        emit_state.emitters[e] = em;
        slot_start = slot_start + em.slot_count;
    }
    batch.n_liquid = n;
    let wg = (n + 63u) / 64u;
    batch.wg[0] = wg;
    if (batch.stop == 0u) {
        indirect_args[0] = wg;
    }
}
