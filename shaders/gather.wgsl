// Gather (mirror: src/passes/gather.rs): output colour = exemplar at the finest level's
// synthesized coordinate, for the output window.
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    if (any(p >= (params.window_size | vec2<i32>(opaque)))) {
        return;
    }
    let q = p + params.window_offset;
    let c = coords[params.coord_base + u32(q.y * params.size.x + q.x)];
    let rgba = unpack4x8unorm(colors[ex_index(c)]);
    textureStore(out_color, p, rgba);
}
