// Quantization of a velocity (output pixels per unit time) times the time step to
// 1/1024 pixel per frame, shared by velocity.wgsl (a caller's buffer) and
// velocity_texture.wgsl (a caller's texture); mirror: src/passes/velocity.rs
// quantize_velocity. Non-finite components count as 0 and speeds are clamped to +-64
// pixels per frame, per component.

struct VelocityParams {
    count: u32,
    dt: f32,
    // The output's width: the texture's pixel of entry i (velocity_texture.wgsl).
    width: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> vp: VelocityParams;
@group(0) @binding(2) var<storage, read_write> output: array<vec2<i32>>;

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn quantize(v: vec2<f32>) -> vec2<i32> {
    // Each non-finite component counts as 0 on its own, as quantize_velocity does.
    let c = clamp(v * vp.dt, vec2<f32>(-64.0), vec2<f32>(64.0));
    let w = select(vec2<f32>(0.0), c, vec2<bool>(finite(v.x), finite(v.y)));
    return vec2<i32>(round(w * 1024.0));
}
