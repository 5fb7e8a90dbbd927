// render_fluid.wgsl — screen-space fluid rendering of blood (after van der Laan, Green & Sainz 2009;
// src/render/renderer.rs runs the passes): the blood's front-surface eye depth (render_particles
// fs_blood_depth) is smoothed by a separable bilateral filter (fs_filter_h, fs_filter_v) that does
// not blur across depth jumps; normals come from the filtered depth; the colour is the tissue behind,
// refracted and attenuated by Beer–Lambert absorption over the additive thickness (fs_blood_thickness),
// plus Fresnel (Schlick) reflection (fs_composite). An eye depth of 0 marks "no blood".

#import render_common

@group(1) @binding(0) var depth_in: texture_2d<f32>;
@group(1) @binding(1) var thickness_in: texture_2d<f32>;
@group(1) @binding(2) var scene_in: texture_2d<f32>;
@group(1) @binding(3) var scene_sampler: sampler;

struct FullScreen {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

// One triangle covering the viewport.
@vertex
fn vs_fullscreen(@builtin(vertex_index) vi: u32) -> FullScreen {
    let x = f32((vi << 1u) & 2u);
    let y = f32(vi & 2u);
    var o: FullScreen;
    o.clip = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
    o.uv = vec2<f32>(x, y);
    return o;
}

fn load_depth(p: vec2<i32>) -> f32 {
    let size = vec2<i32>(textureDimensions(depth_in));
    let q = clamp(p, vec2<i32>(0), size - vec2<i32>(1));
    return textureLoad(depth_in, q, 0).x;
}

// Bilateral filter along `dir`: Gaussian in pixels (σ = radius/2) times a Gaussian in depth
// (σ_z = cam.fluid.z), skipping pixels without blood. The radius shrinks with distance so that it
// spans about two particle radii on screen.
fn bilateral(p: vec2<i32>, dir: vec2<i32>) -> f32 {
    let d0 = load_depth(p);
    if (d0 <= 0.0) {
        return 0.0;
    }
    let particle_px = cam.draw.y * cam.proj[1][1] * 0.5 * cam.viewport.y / d0;
    let radius = i32(clamp(3.0 * particle_px, 1.0, cam.fluid.y));
    let sigma_s = max(f32(radius) * 0.5, 0.5);
    let sigma_z = max(cam.fluid.z, 1e-6);
    var sum = 0.0;
    var wsum = 0.0;
    for (var k = -radius; k <= radius; k = k + 1) {
        let d = load_depth(p + dir * k);
        if (d <= 0.0) {
            continue;
        }
        let fk = f32(k);
        let dz = (d - d0) / sigma_z;
        let w = exp(-0.5 * fk * fk / (sigma_s * sigma_s) - 0.5 * dz * dz);
        sum = sum + d * w;
        wsum = wsum + w;
    }
    return sum / max(wsum, 1e-12);
}

@fragment
fn fs_filter_h(in: FullScreen) -> @location(0) f32 {
    return bilateral(vec2<i32>(in.clip.xy), vec2<i32>(1, 0));
}

@fragment
fn fs_filter_v(in: FullScreen) -> @location(0) f32 {
    return bilateral(vec2<i32>(in.clip.xy), vec2<i32>(0, 1));
}

// View-space position of pixel `p` at eye depth d (symmetric perspective projection).
fn view_pos(p: vec2<i32>, d: f32) -> vec3<f32> {
    let ndc = vec2<f32>(
        (f32(p.x) + 0.5) * cam.viewport.z * 2.0 - 1.0,
        1.0 - (f32(p.y) + 0.5) * cam.viewport.w * 2.0,
    );
    return vec3<f32>(ndc.x / cam.proj[0][0] * d, ndc.y / cam.proj[1][1] * d, -d);
}

// Normal from the filtered depth: of the two one-sided differences per axis, the smaller (so that
// silhouettes do not bend the normal, Green 2010).
fn depth_normal(p: vec2<i32>, d: f32) -> vec3<f32> {
    let c = view_pos(p, d);
    var dx = vec3<f32>(0.0);
    let dr = load_depth(p + vec2<i32>(1, 0));
    let dl = load_depth(p - vec2<i32>(1, 0));
    let r = view_pos(p + vec2<i32>(1, 0), dr) - c;
    let l = c - view_pos(p - vec2<i32>(1, 0), dl);
    if (dr > 0.0 && (dl <= 0.0 || abs(r.z) < abs(l.z))) {
        dx = r;
    } else if (dl > 0.0) {
        dx = l;
    } else {
        dx = vec3<f32>(1.0, 0.0, 0.0);
    }
    var dy = vec3<f32>(0.0);
    let du = load_depth(p - vec2<i32>(0, 1));
    let dd = load_depth(p + vec2<i32>(0, 1));
    let u = view_pos(p - vec2<i32>(0, 1), du) - c;
    let w = c - view_pos(p + vec2<i32>(0, 1), dd);
    if (du > 0.0 && (dd <= 0.0 || abs(u.z) < abs(w.z))) {
        dy = u;
    } else if (dd > 0.0) {
        dy = w;
    } else {
        dy = vec3<f32>(0.0, 1.0, 0.0);
    }
    return normalize(cross(dx, dy));
}

@fragment
fn fs_composite(in: FullScreen) -> @location(0) vec4<f32> {
    let p = vec2<i32>(in.clip.xy);
    let scene = textureSampleLevel(scene_in, scene_sampler, in.uv, 0.0).rgb;
    let d = load_depth(p);
    if (d <= 0.0 || cam.background.w < 0.5) {
        return vec4<f32>(scene, 1.0);
    }
    let thickness = textureLoad(thickness_in, p, 0).x;
    let n = depth_normal(p, d);
    let v = -normalize(view_pos(p, d));
    // Refraction: the tissue behind, displaced along the normal in proportion to the thickness.
    let offset = n.xy * min(thickness * cam.fluid.w, 0.05);
    let behind = textureSampleLevel(scene_in, scene_sampler, in.uv + vec2<f32>(offset.x, -offset.y), 0.0).rgb;
    // Beer–Lambert: whole blood absorbs blue and green far more than red.
    let absorb = cam.fluid.x * vec3<f32>(0.25, 6.0, 7.0);
    let transmit = exp(-absorb * thickness);
    let body = vec3<f32>(0.42, 0.012, 0.01);
    let l = normalize(cam.light.xyz);
    let diffuse = max(n.x * l.x + n.y * l.y + n.z * l.z, 0.0);
    let lit_body = body * (cam.light.w + (1.0 - cam.light.w) * diffuse);
    var colour = behind * transmit + lit_body * (vec3<f32>(1.0) - transmit);
    // Fresnel (Schlick, F0 = 0.02 for water-like blood plasma) against a soft sky, plus the highlight.
    let cos_t = clamp(n.x * v.x + n.y * v.y + n.z * v.z, 0.0, 1.0);
    let fresnel = 0.02 + 0.98 * pow(1.0 - cos_t, 5.0);
    let h = normalize(l + v);
    let spec = pow(max(n.x * h.x + n.y * h.y + n.z * h.z, 0.0), 96.0);
    colour = mix(colour, vec3<f32>(0.55, 0.55, 0.6), fresnel * 0.6) + vec3<f32>(spec * 0.6);
    return vec4<f32>(colour, 1.0);
}
