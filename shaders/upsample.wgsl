// Upsample (mirror: src/passes/upsample.rs):
// S_l[p] = S_{l-1}[floor(p/2)] + h_l * (p mod 2), absolute positions p.
// Level 0 (parent_size == 0) starts from (0, 0).
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let abs_p = params.origin + q;
    var c = vec2<i32>(0);
    if ((params.parent_size.x | opaque) > 0) {
        let pp = clamp((abs_p >> vec2<u32>(1u)) - params.parent_origin, vec2<i32>(0), params.parent_size - vec2<i32>(1));
        let parent = coords[params.parent_coord_base + u32(pp.y * params.parent_size.x + pp.x)];
        c = parent + params.spacing * (abs_p & vec2<i32>(1));
    }
    coords[params.coord_base + u32(q.y * params.size.x + q.x)] = fit_coord(c);
}
