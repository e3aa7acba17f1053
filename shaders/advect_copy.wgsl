// Advection: copies a level's coordinates to the scratch region, which the advect pass
// then reads from (it reads other pixels than it writes). Mirror: src/passes/advect.rs.
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let t = u32(q.y * params.size.x + q.x);
    coords[params.flag_base + t] = coords[params.coord_base + t];
}
