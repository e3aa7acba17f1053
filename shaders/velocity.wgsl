// Advection: quantizes a caller's velocity field (vec2<f32> per output pixel, pixels
// per unit time) times the time step to 1/1024 pixel per frame (mirror:
// src/gpu/advect.rs quantize_velocity). Non-finite values become 0 and speeds are
// clamped to +-64 pixels per frame, per component.

struct VelocityParams {
    count: u32,
    dt: f32,
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> vp: VelocityParams;
@group(0) @binding(1) var<storage, read> input: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> output: array<vec2<i32>>;

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.y * 65535u * 64u + gid.x;
    if (i >= vp.count) {
        return;
    }
    let v = input[i];
    // Each non-finite component counts as 0 on its own, as quantize_velocity does.
    let c = clamp(v * vp.dt, vec2<f32>(-64.0), vec2<f32>(64.0));
    let w = select(vec2<f32>(0.0), c, vec2<bool>(finite(v.x), finite(v.y)));
    output[i] = vec2<i32>(round(w * 1024.0));
}
