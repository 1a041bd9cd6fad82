// Render pipeline (not a compute kernel): the surface of a lapped solid textured model, each
// boundary triangle drawn once per layer of its tet, in paste order, alpha blended (Lapped
// Solid Textures 5.1). Entry points vs_main / fs_main. CPU reference: a ray cast in
// src/cpu/lapped_render.rs (reference_pixel) with the same sampling and shading.
//
// Colours blend premultiplied-style into an RGBA8 target cleared to 0: rgb accumulates
// alpha * colour "over" the layers below and a the coverage; the host divides rgb by a.

struct RenderParams {
    view_proj: mat4x4<f32>,
    // xyz: eye position.
    eye: vec4<f32>,
    // x: 1 when depth (texture y) clamps instead of wrapping; y: mask layers stacked along z;
    // z: exemplar size; w: mask size.
    flags: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: RenderParams;
@group(0) @binding(1) var exemplar: texture_3d<f32>;
@group(0) @binding(2) var masks: texture_3d<f32>;
@group(0) @binding(3) var repeat_linear: sampler;
@group(0) @binding(4) var clamp_linear: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) coord: vec3<f32>,
    @location(3) mask: f32,
}

struct VertexOut {
    // Invariant: the depth pre-pass and the layer passes must produce identical depths.
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) coord: vec3<f32>,
    @location(3) @interpolate(flat) mask: f32,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = params.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.coord = v.coord;
    out.mask = v.mask;
    return out;
}

@fragment
fn fs_main(i: VertexOut) -> @location(0) vec4<f32> {
    let w = i.coord;
    // Masks are 0 outside the unit cube.
    if any(w < vec3<f32>(0.0)) || any(w > vec3<f32>(1.0)) {
        return vec4<f32>(0.0);
    }
    // Mask layers are stacked along z; keep z half a voxel inside the layer so the filter
    // never blends two layers (the CPU clamps to the edge voxel the same way).
    let half_mask = 0.5 / params.flags.w;
    let mz = (i.mask + clamp(w.z, half_mask, 1.0 - half_mask)) / params.flags.y;
    let alpha = textureSampleLevel(masks, clamp_linear, vec3<f32>(w.x, w.y, mz), 0.0).r;
    var e = w;
    if params.flags.x > 0.5 {
        let half_ex = 0.5 / params.flags.z;
        e.y = clamp(w.y, half_ex, 1.0 - half_ex);
    }
    let color = textureSampleLevel(exemplar, repeat_linear, e, 0.0).rgb;
    let shade = 0.3 + 0.7 * abs(dot(normalize(i.normal), normalize(params.eye.xyz - i.world)));
    return vec4<f32>(color * shade, alpha);
}

// The depth pre-pass: depth only (its colour writes are masked off).
@fragment
fn fs_depth() -> @location(0) vec4<f32> {
    return vec4<f32>(0.0);
}
