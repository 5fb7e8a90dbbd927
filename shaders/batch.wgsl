// batch.wgsl — batched stepping without per-step readback (`GpuSolver::advance`). One batch encodes
// up to 64 steps; every pass of a step is dispatched indirectly from `indirect_args`, which
// `batch_begin` fills with the real workgroup counts while the batch runs and with zeros once it has
// stopped (t_end reached, Δt collapsed, divergence), so the remaining steps are no-ops.
//
// Clock (SPEC §5.4 warns about f32 time): the GPU keeps tⁿ as an unevaluated f32 pair hi + lo updated
// by Knuth's two-sum (error ~2⁻⁴⁸ t per step, i.e. ≲ 10⁻⁸ t after 10⁶ steps, far below one Δt). The
// host keeps the authoritative f64 clock by summing the per-step Δt it reads back at the end of the
// batch exactly as the CPU does (t += Δt as f64); the pair only drives the analytic motions and the
// t_end test here. Motion evaluation mirrors `scenario::motion_at` (t < 0 → rest) in f32.
#import common

const STOP_RUNNING: u32 = 0u;
const STOP_END: u32 = 1u;
const STOP_FAILED: u32 = 2u;

// (a + b) as an f32 pair (two-sum + fast renormalisation).
fn pair_add(a_hi: f32, a_lo: f32, b: f32) -> vec2<f32> {
    let s = a_hi + b;
    let bb = s - a_hi;
    let err = (a_hi - (s - bb)) + (b - bb);
    let lo = a_lo + err;
    let hi = s + lo;
    return vec2<f32>(hi, lo - (hi - s));
}

// (a − b) of two pairs, rounded to f32.
fn pair_diff(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return (a.x - b.x) + (a.y - b.y);
}

fn write_args(run: bool) {
    for (var k = 0u; k < 6u; k = k + 1u) {
        var n = 0u;
        if (run) {
            n = batch.wg[k];
        }
        indirect_args[3u * k] = n;
        indirect_args[3u * k + 1u] = 1u;
        indirect_args[3u * k + 2u] = 1u;
    }
}

// Start of each step of the batch (direct dispatch): arm or disarm the step's indirect dispatches.
@compute @workgroup_size(1)
fn batch_begin() {
    write_args(batch.stop == STOP_RUNNING);
}

// Displacement and velocity of motion `m` at time t (twin of `scenario::motion_at`, f32).
fn motion_eval(m: MotionGpu, t: vec2<f32>) -> array<vec3<f32>, 2> {
    var d = vec3<f32>(0.0);
    var v = vec3<f32>(0.0);
    let negative = t.x < 0.0 || (t.x == 0.0 && t.y < 0.0);
    if (negative) {
        return array<vec3<f32>, 2>(d, v);
    }
    if (m.motion == 1u) {
        let start = m.times.xy;
        let stop = m.times.zw;
        // active = max(min(t, stop) − start, 0)
        var moved = pair_diff(t, start);
        let to_stop = pair_diff(t, stop);
        if (to_stop > 0.0) {
            moved = pair_diff(stop, start);
        }
        moved = max(moved, 0.0);
        d = m.vec.xyz * moved;
        if (pair_diff(t, start) >= 0.0 && to_stop < 0.0) {
            v = m.vec.xyz;
        }
    } else if (m.motion == 2u) {
        let w = m.times.x;
        let phase = m.times.y;
        let th = w * (t.x + t.y) + phase;
        let s = sin(th) - sin(phase);
        let c = w * cos(th);
        d = m.vec.xyz * s;
        v = m.vec.xyz * c;
    }
    return array<vec3<f32>, 2>(d, v);
}

// After Δt (dt.wgsl): stop on a collapsed Δt, else tⁿ⁺¹ = tⁿ + Δt and the objects' poses at tⁿ⁺¹
// (what the host's `move_boundaries` did at tⁿ⁺¹ before the second half of the step).
@compute @workgroup_size(1)
fn batch_motion() {
    if (batch.stop != STOP_RUNNING) {
        return;
    }
    let status = atomicLoad(&step.status);
    if ((status & STATUS_DT_COLLAPSED) != 0u) {
        batch.stop = STOP_FAILED;
        batch.fail_status = status;
        batch.fail_dt = step.dt;
        write_args(false);
        return;
    }
    let tn = pair_add(batch.t_hi, batch.t_lo, step.dt);
    batch.tn_hi = tn.x;
    batch.tn_lo = tn.y;
    let n = params.switches.w;
    for (var k = 0u; k < n; k = k + 1u) {
        let m = motions[k];
        let dv = motion_eval(m, tn);
        var o: ObjectGpu;
        o.geom_a = vec4<f32>(m.rest_a.xyz + dv[0], 0.0);
        if (m.kind == 0u) {
            o.geom_b = vec4<f32>(m.rest_b.xyz + dv[0], 0.0);
        } else {
            o.geom_b = vec4<f32>(m.rest_b.xyz, 0.0);
        }
        o.disp = vec4<f32>(dv[0], 0.0);
        o.vel = vec4<f32>(dv[1], 0.0);
        o.density = m.density;
        o.pressure = m.pressure;
        o.kind = m.kind;
        o.blade = u32(m.rest_a.w);
        o.friction = m.friction;
        o.bed = m.bed;
        objects[k] = o;
    }
    // Inlet buffer velocities u(tⁿ⁺¹) = direction · Q(tⁿ⁺¹) · L/(N·V_p) (twin: emit::emit_velocities).
    let t = tn.x + tn.y;
    for (var e = 0u; e < emit_state.n_emitters; e = e + 1u) {
        let d = emit_state.emitters[e].dir;
        let speed = flow_at(e, t) * d.w;
        emit_state.emitters[e].velocity = vec4<f32>(d.x * speed, d.y * speed, d.z * speed, 0.0);
    }
}

// End of a step: record it (Δt, criterion, broken bonds), commit the clock, and stop the batch on
// divergence or once tⁿ⁺¹ reaches t_end (less a margin of Δt/100 that absorbs the pair clock's
// rounding; the host re-checks in f64 and simply starts another batch when the GPU stopped early).
@compute @workgroup_size(1)
fn batch_end() {
    if (batch.stop != STOP_RUNNING) {
        return;
    }
    let status = atomicLoad(&step.status);
    if ((status & (STATUS_NONFINITE_LIQUID | STATUS_NONFINITE_SOLID)) != 0u) {
        batch.stop = STOP_FAILED;
        batch.fail_status = status;
        batch.fail_dt = step.dt;
        batch.bad_liquid = atomicLoad(&step.bad_liquid);
        batch.bad_solid = atomicLoad(&step.bad_solid);
        return;
    }
    let k = batch.steps;
    batch.dt[k] = step.dt;
    batch.limit[k] = step.limit;
    batch.broken_ends = batch.broken_ends + atomicLoad(&step.broken_ends);
    batch.steps = k + 1u;
    batch.t_hi = batch.tn_hi;
    batch.t_lo = batch.tn_lo;
    let tn = vec2<f32>(batch.tn_hi, batch.tn_lo);
    if (pair_diff(tn, vec2<f32>(batch.end_hi, batch.end_lo)) >= -0.01 * step.dt) {
        batch.stop = STOP_END;
    }
}
