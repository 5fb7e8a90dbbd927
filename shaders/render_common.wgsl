// render_common.wgsl — shared declarations of the renderer's passes (render_particles, render_shapes,
// render_fluid): the per-frame camera uniform of bind group 0 (mirrors `CameraGpu` in
// src/render/gpu_data.rs; must be kept in sync, a test compares the sizes with naga) and the sphere
// impostor helpers. All positions are simulation coordinates (scenario coordinates − origin).

struct Camera {
    view: mat4x4<f32>,
    proj: mat4x4<f32>,
    // xyz: direction towards the light in view space; w: ambient fraction
    light: vec4<f32>,
    // width, height, 1/width, 1/height [px]
    viewport: vec4<f32>,
    // x: tissue particle radius [m], y: blood particle radius [m], z: field mode, w: field scale
    draw: vec4<f32>,
    // x: blood absorption [1/m] (Beer–Lambert, scaled per channel), y: filter radius [px],
    // z: depth falloff of the bilateral filter [m], w: refraction strength
    fluid: vec4<f32>,
    // rgb: background colour (linear), w: 1 when blood is drawn as a fluid, 0 as plain spheres
    background: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cam: Camera;

// The six corners of an impostor quad (two triangles), in units of the radius.
fn quad_corner(vi: u32) -> vec2<f32> {
    var c = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0),
        vec2<f32>(1.0, -1.0),
        vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0),
        vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, 1.0),
    );
    return c[vi % 6u];
}

struct Impostor {
    @builtin(position) clip: vec4<f32>,
    // the quad point in view space (on the plane through the centre, facing the eye)
    @location(0) quad_view: vec3<f32>,
    @location(1) centre_view: vec3<f32>,
    @location(2) radius: f32,
    @location(3) colour: vec4<f32>,
}

// A camera-facing quad around a sphere of radius r at `pos` (simulation coordinates). The quad is
// enlarged by 1.5 so that the perspective silhouette of the sphere is always inside it.
fn impostor_vertex(pos: vec3<f32>, r: f32, vi: u32) -> Impostor {
    let cv = (cam.view * vec4<f32>(pos, 1.0)).xyz;
    let q = vec3<f32>(cv.xy + quad_corner(vi) * r * 1.5, cv.z);
    var o: Impostor;
    o.clip = cam.proj * vec4<f32>(q, 1.0);
    o.quad_view = q;
    o.centre_view = cv;
    o.radius = r;
    o.colour = vec4<f32>(1.0);
    return o;
}

// Exact ray–sphere hit of the eye ray through `quad_view`: xyz = view-space hit point, w = chord
// length through the sphere along the ray (< 0: miss).
fn sphere_hit(quad_view: vec3<f32>, centre: vec3<f32>, r: f32) -> vec4<f32> {
    let d = normalize(quad_view);
    let b = d.x * centre.x + d.y * centre.y + d.z * centre.z;
    let c = centre.x * centre.x + centre.y * centre.y + centre.z * centre.z - r * r;
    let disc = b * b - c;
    if (disc < 0.0) {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    let s = sqrt(disc);
    return vec4<f32>(d * (b - s), 2.0 * s);
}

// Window depth (0..1) of a view-space point.
fn view_depth(p: vec3<f32>) -> f32 {
    let clip = cam.proj * vec4<f32>(p, 1.0);
    return clip.z / clip.w;
}

// Blinn–Phong in view space: `base` lit from `cam.light` with a white highlight.
fn shade(base: vec3<f32>, n: vec3<f32>, p: vec3<f32>, shininess: f32, spec: f32) -> vec3<f32> {
    let l = normalize(cam.light.xyz);
    let v = -normalize(p);
    let h = normalize(l + v);
    let diffuse = max(n.x * l.x + n.y * l.y + n.z * l.z, 0.0);
    let hl = pow(max(n.x * h.x + n.y * h.y + n.z * h.z, 0.0), shininess) * spec;
    let a = cam.light.w;
    return base * (a + (1.0 - a) * diffuse) + vec3<f32>(hl);
}

// A perceptually ordered colour map (blue → cyan → yellow → red) for scalar fields in 0..1.
fn colour_map(x: f32) -> vec3<f32> {
    let t = clamp(x, 0.0, 1.0);
    let c0 = vec3<f32>(0.05, 0.08, 0.45);
    let c1 = vec3<f32>(0.05, 0.55, 0.75);
    let c2 = vec3<f32>(0.90, 0.85, 0.15);
    let c3 = vec3<f32>(0.85, 0.10, 0.05);
    if (t < 0.3333) {
        return mix(c0, c1, t * 3.0);
    }
    if (t < 0.6667) {
        return mix(c1, c2, (t - 0.3333) * 3.0);
    }
    return mix(c2, c3, (t - 0.6667) * 3.0);
}
