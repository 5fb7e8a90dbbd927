// render_particles.wgsl — tissue and blood particles as sphere impostors (src/render/renderer.rs).
// Bind group 1 is one published set of `sim::frame::FrameBuffers` (the solver's own layouts,
// common.wgsl): the render thread draws whichever set the simulation published last.
//
// Entry points: vs_tissue/fs_tissue (lit, coloured by the selected field), vs_blood with
// fs_blood_depth (eye distance of the front surface, for the screen-space fluid renderer),
// fs_blood_thickness (additive chord length) and fs_blood_plain (lit spheres, fluid rendering off).

#import render_common

// Mirrors `StressGpu`: the upper triangles of the deviatoric Cauchy stress τ and the artificial stress
// R; a = (τxx, τyy, τzz, τxy), b = (τxz, τyz, Rxx, Ryy), c = (Rzz, Rxy, Rxz, Ryz).
struct Stress {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

@group(1) @binding(0) var<storage, read> liquid_pos: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read> solid_pos: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read> solid_dens: array<vec4<f32>>;
@group(1) @binding(3) var<storage, read> solid_stress: array<Stress>;
@group(1) @binding(4) var<storage, read> bond_count: array<u32>;
@group(1) @binding(5) var<storage, read> bond_count0: array<u32>;
@group(1) @binding(6) var<storage, read> solid_flags: array<u32>;

// SolidFlags (src/scenario/generate.rs).
const FLAG_KINEMATIC: u32 = 1u;
const FLAG_MEMBRANE: u32 = 2u;
const FLAG_TETHERED: u32 = 4u;

// Field modes (`FieldMode` in src/render/gpu_data.rs).
const FIELD_PLAIN: u32 = 0u;
const FIELD_STRESS: u32 = 1u;
const FIELD_LIQUID: u32 = 2u;
const FIELD_BROKEN: u32 = 3u;

// von Mises equivalent of the deviatoric stress: sqrt(3/2 τ:τ) [Pa], τ:τ = Σ diagonal² + 2 Σ off-diagonal².
fn von_mises(s: Stress) -> f32 {
    let d = s.a.xyz;
    let o = vec3<f32>(s.a.w, s.b.x, s.b.y);
    let tt = dot(d, d) + 2.0 * dot(o, o);
    return sqrt(1.5 * tt);
}

fn tissue_colour(i: u32) -> vec3<f32> {
    let mode = u32(cam.draw.z + 0.5);
    let scale = max(cam.draw.w, 1e-30);
    let flags = solid_flags[i];
    if (mode == FIELD_STRESS) {
        return colour_map(von_mises(solid_stress[i]) / scale);
    }
    if (mode == FIELD_LIQUID) {
        return colour_map(solid_dens[i].y / scale);
    }
    if (mode == FIELD_BROKEN) {
        let c0 = bond_count0[i];
        let broken = f32(c0 - min(bond_count[i], c0)) / f32(max(c0, 1u));
        return colour_map(broken / scale);
    }
    // Plain liver parenchyma (linear RGB of a red-brown liver), the capsule lighter and glossier,
    // ligament (fixed or tethered) particles pale.
    var base = vec3<f32>(0.32, 0.07, 0.05);
    if ((flags & FLAG_MEMBRANE) != 0u) {
        base = mix(base, vec3<f32>(0.75, 0.62, 0.58), 0.3);
    }
    if ((flags & (FLAG_KINEMATIC | FLAG_TETHERED)) != 0u) {
        base = vec3<f32>(0.55, 0.50, 0.38);
    }
    return base;
}

@vertex
fn vs_tissue(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> Impostor {
    var o = impostor_vertex(solid_pos[ii].xyz, cam.draw.x, vi);
    o.colour = vec4<f32>(tissue_colour(ii), 1.0);
    return o;
}

struct LitOut {
    @location(0) colour: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_tissue(in: Impostor) -> LitOut {
    let hit = sphere_hit(in.quad_view, in.centre_view, in.radius);
    if (hit.w < 0.0) {
        discard;
    }
    let n = (hit.xyz - in.centre_view) / in.radius;
    var o: LitOut;
    o.colour = vec4<f32>(shade(in.colour.rgb, n, hit.xyz, 32.0, 0.18), 1.0);
    o.depth = view_depth(hit.xyz);
    return o;
}

@vertex
fn vs_blood(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> Impostor {
    return impostor_vertex(liquid_pos[ii].xyz, cam.draw.y, vi);
}

struct DepthOut {
    @location(0) eye_depth: f32,
    @builtin(frag_depth) depth: f32,
}

// Front surface of the blood: eye distance −z (positive) for the filter and the composite.
@fragment
fn fs_blood_depth(in: Impostor) -> DepthOut {
    let hit = sphere_hit(in.quad_view, in.centre_view, in.radius);
    if (hit.w < 0.0) {
        discard;
    }
    var o: DepthOut;
    o.eye_depth = -hit.z;
    o.depth = view_depth(hit.xyz);
    return o;
}

// Thickness: the chord of the eye ray through each sphere, summed by additive blending (depth test
// against the tissue only, so blood behind tissue adds nothing).
@fragment
fn fs_blood_thickness(in: Impostor) -> @location(0) vec4<f32> {
    let hit = sphere_hit(in.quad_view, in.centre_view, in.radius);
    if (hit.w < 0.0) {
        discard;
    }
    return vec4<f32>(hit.w, 0.0, 0.0, 0.0);
}

// Blood as lit dark-red spheres (fluid rendering switched off).
@fragment
fn fs_blood_plain(in: Impostor) -> LitOut {
    let hit = sphere_hit(in.quad_view, in.centre_view, in.radius);
    if (hit.w < 0.0) {
        discard;
    }
    let n = (hit.xyz - in.centre_view) / in.radius;
    var o: LitOut;
    o.colour = vec4<f32>(shade(vec3<f32>(0.45, 0.01, 0.01), n, hit.xyz, 64.0, 0.4), 1.0);
    o.depth = view_depth(hit.xyz);
    return o;
}
