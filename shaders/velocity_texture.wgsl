// Advection: quantizes a caller's velocity texture (red, green = x, y velocity in
// output pixels per unit time, one texel of mip level 0 per output pixel; any float
// format) for the frame, as velocity.wgsl does a buffer (shared/velocity.wgsl; mirror:
// src/passes/velocity_texture.rs).
#include "shared/velocity.wgsl"

@group(0) @binding(1) var input: texture_2d<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.y * 65535u * 64u + gid.x;
    if (i >= vp.count) {
        return;
    }
    let p = vec2<u32>(i % vp.width, i / vp.width);
    output[i] = quantize(textureLoad(input, p, 0).xy);
}
