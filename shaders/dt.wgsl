// dt.wgsl — time-step restriction (2.70) plus the explicit-friction bound and Δt_max (SPEC §5.3, D-27);
// twin: src/sim/cpu/dt.rs. Maxima and minima of non-negative floats are reduced with integer
// atomicMax/atomicMin on their bit patterns (for x ≥ 0 the integer order is the float order), which is
// exact and order-independent; dt_finalize then evaluates the CPU's scalar formula on one invocation.
// Δt stays on the GPU in `step.dt`; the host reads it back only to advance its f64 clock.
#import common

const INF_BITS: u32 = 0x7f800000u;

@compute @workgroup_size(1)
fn dt_clear() {
    atomicStore(&step.a_max_bits, 0u);
    atomicStore(&step.rho_min_bits, INF_BITS);
    atomicStore(&step.fric_max_bits, 0u);
    atomicStore(&step.status, 0u);
    atomicStore(&step.broken_ends, 0u);
    atomicStore(&step.bad_liquid, 0xffffffffu);
    atomicStore(&step.bad_solid, 0xffffffffu);
}

@compute @workgroup_size(64)
fn dt_reduce_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let a = liquid_acc[i].xyz;
    atomicMax(&step.a_max_bits, bitcast<u32>(len3(a)));
    let d = liquid_dens[i];
    atomicMin(&step.rho_min_bits, bitcast<u32>(d.x));
    let ns = d.z;
    if (ns > 1e-6) {
        let f = params.kbar * max(1.0 - ns, 0.0) * (1.0 / d.x + 1.0 / params.rho_ref_s);
        atomicMax(&step.fric_max_bits, bitcast<u32>(f));
    }
}

@compute @workgroup_size(64)
fn dt_reduce_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let dynamic = (solid_flags[i] & SOLID_KINEMATIC) == 0u;
    if (dynamic) {
        atomicMax(&step.a_max_bits, bitcast<u32>(len3(solid_acc[i].xyz)));
    }
    // Kinematic solid particles integrate nothing: only dynamic ones bound the friction step.
    let d = solid_dens[i];
    if (d.y > 1e-6 && dynamic) {
        let f = params.kbar * max(1.0 - d.z, 0.0) * (1.0 / d.x + 1.0 / params.rho_ref_l);
        atomicMax(&step.fric_max_bits, bitcast<u32>(f));
    }
}

@compute @workgroup_size(1)
fn dt_finalize() {
    let a_max = bitcast<f32>(atomicLoad(&step.a_max_bits));
    let h = params.h_min;
    var best = params.dt_max;
    var why = LIMIT_MAX;
    if (params.has_liquid != 0u && params.eta > 0.0) {
        let rho_min = bitcast<f32>(atomicLoad(&step.rho_min_bits));
        let hl = params.k_liquid.h;
        let dt = params.cfl_viscous * rho_min * hl * hl / params.eta;
        if (dt < best) { best = dt; why = LIMIT_VISCOUS; }
    }
    let c = params.c_max;
    if (c > 0.0) {
        let dt = params.cfl_sound * h / (3.0 * c);
        if (dt < best) { best = dt; why = LIMIT_SOUND; }
    }
    if (a_max > 0.0) {
        let dt = params.cfl_force * sqrt(h / (3.0 * a_max));
        if (dt < best) { best = dt; why = LIMIT_FORCE; }
    }
    if (params.kbar > 0.0 && params.has_liquid != 0u && params.has_solid != 0u) {
        let f = bitcast<f32>(atomicLoad(&step.fric_max_bits));
        if (f > 0.0) {
            let dt = params.cfl_friction / f;
            if (dt < best) { best = dt; why = LIMIT_FRICTION; }
        }
    }
    var dt = best * params.cfl_factor;
    if (params.fixed_dt >= 0.0) {
        dt = params.fixed_dt;
        why = LIMIT_FIXED;
    }
    step.dt = dt;
    step.limit = why;
    if (!(is_finite_f32(dt) && dt >= params.dt_min)) {
        atomicOr(&step.status, STATUS_DT_COLLAPSED);
    }
}
