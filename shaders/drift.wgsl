// Advection: the frames' drift (mirror: src/passes/drift.rs). One invocation adds
// the velocity at the output window's centre, rounded to whole finest pixels, to the
// drift kept in the coordinate buffer at params.drift (the entry before this frame, then
// the one after). The advect pass moves each level by the change of the drift's whole
// level pixels, and the frames' upsampling of the finest level follows its phase, so that
// a uniform flow of whole pixels moves every level's patch seams with the texture.
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    if (any(gid.xy != vec2<u32>(0u))) {
        return;
    }
    let ws = params.window_size;
    let vc = velocity[u32((ws.y / 2) * ws.x + ws.x / 2)];
    let k = (vc + vec2<i32>(512)) >> vec2<u32>(10u);
    let a = coords[params.drift + 1u];
    coords[params.drift] = a;
    coords[params.drift + 1u] = a + k;
}
