// Advection of a level's coordinates (mirror: src/passes/advect.rs), without
// resampling: S[p] = S'[p - k] - J(p) (V(p) - k), where S' is the previous frame (the
// level's coordinates; the result goes to the scratch region, which the distortion pass
// then copies back), V the velocity in output pixels per frame (1/1024) and k the
// velocity at the window's centre rounded to whole pixels of this level, the same for
// every pixel. The texture moves with the flow, colour(p, t) = colour(p - V, t - 1):
// the common drift by moving whole coordinates (patch seams included, so a uniform flow
// of whole pixels translates the texture exactly), the rest in place through J, which
// keeps neighbouring pixels coherent (a per-pixel k tears the texture where it changes).
// In frames k is the change of the drift's whole level pixels (params.drift, the centre
// velocity summed in whole finest pixels by drift.wgsl), so that each level moves by its
// share of the drift.
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
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    let vq = velocity_at(params.origin + q);
    let unit = 1024 << params.steps;
    var k: vec2<i32>;
    if (params.drift != 0u) {
        // The change of the drift's whole level pixels (see advect.rs, whole_shift).
        let s = vec2<u32>(params.steps);
        k = (coords[params.drift + 1u] >> s) - (coords[params.drift] >> s);
    } else {
        let ws = params.window_size;
        let vc = velocity[u32((ws.y / 2) * ws.x + ws.x / 2)];
        k = (vc + vec2<i32>(unit >> 1u)) >> vec2<u32>(10u + params.steps);
    }
    // The pixel k level pixels upstream: clamped into the region, or wrapped around one
    // period of a periodic output (k may be many pixels on the finest levels).
    var src = clamp(q - k, vec2<i32>(0), params.size - vec2<i32>(1));
    if (PERIODIC) {
        src = vec2<i32>(wrap(q.x - k.x, params.size.x), wrap(q.y - k.y, params.size.y));
    }
    let prev = coords[params.coord_base + u32(src.y * params.size.x + src.x)];
    let j = jac_at(i);
    // J (V - k) in 1/2^20 exemplar pixel to 1/256, rounded with this frame's offset (a
    // low-discrepancy sequence: the rounding errors of a pixel do not add up over frames).
    // J k 2^steps is taken apart into whole 1/256 units and a remainder, so nothing
    // overflows on coarse levels, where k is a whole level pixel however slow the flow
    // (see advect.rs, displacement).
    let jv = vec2<i32>(j.x * vq.x + j.y * vq.y, j.z * vq.x + j.w * vq.y);
    let jk = vec2<i32>(j.x * k.x + j.y * k.y, j.z * k.x + j.w * k.y);
    let up = params.steps + 10u;
    var hi: vec2<i32>;
    var lo = vec2<i32>(0);
    if (up >= 12u) {
        hi = jk << vec2<u32>(up - 12u);
    } else {
        hi = jk >> vec2<u32>(12u - up);
        lo = (jk - (hi << vec2<u32>(12u - up))) << vec2<u32>(up);
    }
    let o = ((jv - lo + vec2<i32>(i32(params.dither))) >> vec2<u32>(12u)) - hi;
    coords[params.flag_base + u32(q.y * params.size.x + q.x)] = fit_coord(prev - o);
}
