// Jitter (mirror: src/passes/jitter.rs): S[p] += floor(h_l r_l H(p, l, seed) + 0.5) in
// fixed point: amplitude in 1/16 pixel, 12 bits of hash as a value in [-1, 1).
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let h = hash_pixel(params.origin + q, params.level, params.seed);
    let s = vec2<i32>(h & vec2<u32>(0xfffu)) - vec2<i32>(2048);
    let o = (params.jitter_amp * s + vec2<i32>(1 << 14u)) >> vec2<u32>(15u);
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    coords[i] = fit_coord(coords[i] + (o << vec2<u32>(params.coord_frac)));
}
