// Advection of a level's coordinates (mirror: src/passes/advect.rs), semi-Lagrangian
// without resampling: S[p] = S'[p - k] - J(p) (V - k), where S' is the previous frame
// (copied to the scratch region), V the velocity at the pixel in output pixels per frame
// (1/16) and k its nearest whole number of this level's pixels. The texture moves with
// the flow, colour(p, t) = colour(p - V, t - 1): whole pixels by moving coordinates
// (patch seams included), the rest through J within the patches.
#include "shared/common.wgsl"

// The velocity at the finest-level pixel under this level's pixel p (absolute),
// clamped to the output window.
fn velocity_at(abs_p: vec2<i32>) -> vec2<i32> {
    let s = params.steps;
    let half = i32((1u << s) >> 1u);
    let f = (abs_p << vec2<u32>(s)) + vec2<i32>(half) - params.window_origin;
    let c = clamp(f, vec2<i32>(0), params.window_size - vec2<i32>(1));
    return velocity[u32(c.y * params.window_size.x + c.x)];
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = vec2<i32>(gid.xy);
    if (any(q >= params.size)) {
        return;
    }
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    let vq = velocity_at(params.origin + q);
    let unit = 16 << params.steps;
    let k = (vq + vec2<i32>(unit >> 1u)) >> vec2<u32>(4u + params.steps);
    let v = vq - k * unit;
    let src = clamp(q - k, vec2<i32>(0), params.size - vec2<i32>(1));
    let prev = coords[params.flag_base + u32(src.y * params.size.x + src.x)];
    let j = jac[i];
    // J V in 1/1024 exemplar pixel, then 1/256 (same rounding as the fill pass).
    let jv = (vec2<i32>(j.x * v.x + j.y * v.y, j.z * v.x + j.w * v.y) + vec2<i32>(8)) >> vec2<u32>(4u);
    let o = (jv + vec2<i32>(2)) >> vec2<u32>(2u);
    coords[i] = fit_coord(prev - o);
}
