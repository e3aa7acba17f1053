// Advection: quantizes a caller's velocity buffer (vec2<f32> per output pixel, pixels
// per unit time, row-major) for the frame (shared/velocity.wgsl; mirror:
// src/passes/velocity.rs).
#include "shared/velocity.wgsl"

@group(0) @binding(1) var<storage, read> input: array<vec2<f32>>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.y * 65535u * 64u + gid.x;
    if (i >= vp.count) {
        return;
    }
    output[i] = quantize(input[i]);
}
