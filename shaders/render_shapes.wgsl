// render_shapes.wgsl — boundary objects (walls, plates, tools) drawn from their analytic shapes at
// the published pose (src/render/renderer.rs): boxes as 12 flat-shaded triangles, spheres as exact
// impostors, a scalpel's blade as a wedge (the box with its cutting edge side collapsed to the
// mid-plane of its thickness). 36 vertices per instance; a sphere uses the first six and collapses
// the rest.

#import render_common

// Mirrors `ShapeGpu` in src/render/gpu_data.rs.
struct Shape {
    // box: min corner; sphere: centre (simulation coordinates)
    a: vec4<f32>,
    // box: max corner; sphere: radius in x
    b: vec4<f32>,
    // linear RGB and opacity
    colour: vec4<f32>,
    // x: 0 box, 1 sphere, 2 blade (y: thickness axis, z: height axis; the edge on its min side)
    kind: vec4<u32>,
}

@group(1) @binding(0) var<storage, read> shapes: array<Shape>;

struct ShapeOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) view_pos: vec3<f32>,
    @location(1) @interpolate(flat) normal: vec3<f32>,
    @location(2) centre_view: vec3<f32>,
    @location(3) radius: f32,
    @location(4) colour: vec4<f32>,
    @location(5) @interpolate(flat) kind: u32,
}

// Corner k (bit 0: x, bit 1: y, bit 2: z) of each box face's two triangles, and the face normals.
fn box_corner(vi: u32) -> u32 {
    var idx = array<u32, 36>(
        0u, 4u, 6u, 0u, 6u, 2u, // -x
        1u, 3u, 7u, 1u, 7u, 5u, // +x
        0u, 1u, 5u, 0u, 5u, 4u, // -y
        2u, 6u, 7u, 2u, 7u, 3u, // +y
        0u, 2u, 3u, 0u, 3u, 1u, // -z
        4u, 5u, 7u, 4u, 7u, 6u, // +z
    );
    return idx[vi];
}

fn box_normal(face: u32) -> vec3<f32> {
    var n = array<vec3<f32>, 6>(
        vec3<f32>(-1.0, 0.0, 0.0),
        vec3<f32>(1.0, 0.0, 0.0),
        vec3<f32>(0.0, -1.0, 0.0),
        vec3<f32>(0.0, 1.0, 0.0),
        vec3<f32>(0.0, 0.0, -1.0),
        vec3<f32>(0.0, 0.0, 1.0),
    );
    return n[face];
}

// Corner k of a box or blade in simulation coordinates: a blade's corners on the min side of its
// height axis (the cutting edge) move to the mid-plane of its thickness axis.
fn corner_pos(s: Shape, k: u32) -> vec3<f32> {
    var p = vec3<f32>(
        select(s.a.x, s.b.x, (k & 1u) != 0u),
        select(s.a.y, s.b.y, (k & 2u) != 0u),
        select(s.a.z, s.b.z, (k & 4u) != 0u),
    );
    if (s.kind.x == 2u && (k & (1u << s.kind.z)) == 0u) {
        let t = s.kind.y;
        p[t] = 0.5 * (s.a[t] + s.b[t]);
    }
    return p;
}

@vertex
fn vs_shape(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> ShapeOut {
    let s = shapes[ii];
    var o: ShapeOut;
    o.colour = s.colour;
    o.kind = s.kind.x;
    if (s.kind.x == 1u) {
        let r = s.b.x;
        let imp = impostor_vertex(s.a.xyz, r, vi);
        o.clip = imp.clip;
        o.view_pos = imp.quad_view;
        o.centre_view = imp.centre_view;
        o.radius = r;
        o.normal = vec3<f32>(0.0, 0.0, 1.0);
        if (vi >= 6u) {
            // collapse the unused triangles
            o.clip = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        }
        return o;
    }
    let p = corner_pos(s, box_corner(vi));
    let v = cam.view * vec4<f32>(p, 1.0);
    o.clip = cam.proj * v;
    o.view_pos = v.xyz;
    // flat normal of this vertex's triangle (a wedge's faces are not the box's)
    let tri = 3u * (vi / 3u);
    let p0 = corner_pos(s, box_corner(tri));
    let e = cross(corner_pos(s, box_corner(tri + 1u)) - p0, corner_pos(s, box_corner(tri + 2u)) - p0);
    var n = box_normal(vi / 6u);
    if (dot(e, e) > 1e-30) {
        n = normalize(e);
    }
    o.normal = (cam.view * vec4<f32>(n, 0.0)).xyz;
    o.centre_view = vec3<f32>(0.0);
    o.radius = 0.0;
    return o;
}

struct ShapeFrag {
    @location(0) colour: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_shape(in: ShapeOut) -> ShapeFrag {
    var o: ShapeFrag;
    if (in.kind == 1u) {
        let hit = sphere_hit(in.view_pos, in.centre_view, in.radius);
        if (hit.w < 0.0) {
            discard;
        }
        let n = (hit.xyz - in.centre_view) / in.radius;
        o.colour = vec4<f32>(shade(in.colour.rgb, n, hit.xyz, 64.0, 0.6), in.colour.a);
        o.depth = view_depth(hit.xyz);
        return o;
    }
    // Two-sided: light the face turned towards the eye.
    var n = normalize(in.normal);
    if (n.x * in.view_pos.x + n.y * in.view_pos.y + n.z * in.view_pos.z > 0.0) {
        n = -n;
    }
    o.colour = vec4<f32>(shade(in.colour.rgb, n, in.view_pos, 48.0, 0.3), in.colour.a);
    o.depth = view_depth(in.view_pos);
    return o;
}
