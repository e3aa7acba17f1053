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
#include "shared/advect.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    let vq = velocity_at(params.origin + q);
    let k = whole_shift();
    // The pixel k level pixels upstream: clamped into the region, or wrapped around one
    // period of a periodic output (k may be many pixels on the finest levels).
    var src = clamp(q - k, vec2<i32>(0), params.size - vec2<i32>(1));
    if (PERIODIC) {
        src = vec2<i32>(wrap(q.x - k.x, params.size.x), wrap(q.y - k.y, params.size.y));
    }
    let prev = coords[params.coord_base + u32(src.y * params.size.x + src.x)];
    let o = displacement(jac_at(i), vq, k);
    coords[params.flag_base + u32(q.y * params.size.x + q.x)] = fit_coord(prev - o);
}
