// The first pass of an advection frame's fade (mirror: src/passes/fade_jump.rs): per
// pixel of the finest level's region, how much a jump of its coordinate changed its grey
// level (-1 where it moved with the flow), into the flag region, which the frame no
// longer needs; fade.wgsl then sums it over each pixel's 3x3 neighbourhood. Once per
// pixel, rather than nine times in fade.wgsl (measured: the fade took about a sixth of
// a 256x256 frame that way).
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"
#include "shared/advect.wgsl"
#include "shared/exemplar_color.wgsl"
#include "shared/fade.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let change = jump_change(q, whole_shift());
    coords[params.flag_base + u32(q.y * params.size.x + q.x)] = vec2<i32>(change, 0);
}
