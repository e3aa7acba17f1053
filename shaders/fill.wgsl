// Atlas indirection fill (mirror: src/passes/fill.rs): every gutter texel around a
// chart takes the coordinate of the same surface point in the neighbouring chart,
// S[dst] = S[src] + h J(src) off, so the correction reads across chart seams.
#include "shared/common.wgsl"

const FILL_ROW: u32 = 2048u;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let e = gid.y * FILL_ROW + gid.x;
    if (gid.x >= FILL_ROW || e >= (params.fill_count | u32(opaque))) {
        return;
    }
    let w = params.fill_base + 4u * e;
    let dst = params.coord_base + surface[w];
    let src = params.coord_base + surface[w + 1u];
    let off = vec2<i32>(bitcast<i32>(surface[w + 2u]), bitcast<i32>(surface[w + 3u]));
    let j = jac[src];
    let jo = (vec2<i32>(j.x * off.x + j.y * off.y, j.z * off.x + j.w * off.y) + vec2<i32>(8)) >> vec2<u32>(4u);
    let o = (params.spacing * jo + vec2<i32>(2)) >> vec2<u32>(2u);
    coords[dst] = fit_coord(coords[src] + o);
}
