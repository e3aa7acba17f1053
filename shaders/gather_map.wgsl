// Material-set gather (mirror: src/passes/gather_map.rs): an extra exemplar-aligned map
// (bound as the colours) read at the finest level's coordinates, like the colour
// gather (nearest for integer coordinates, bilinear for continuous ones). A tangent-
// space normal map (map_kind 1: green down, 2: green up) has its x, y rotated with the texture (rotate_normal).
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

fn map_u(c: vec2<i32>) -> vec4<i32> {
    let w = colors[ex_index(c)];
    return vec4<i32>(vec4<u32>(w, w >> 8u, w >> 16u, w >> 24u) & vec4<u32>(255u));
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    let wi = window_coord_index(p);
    if (wi < 0) {
        return;
    }
    let idx = u32(wi);
    let c = coords[idx];
    var v: vec4<i32>;
    if ((params.coord_frac | u32(opaque)) == 0u) {
        v = map_u(c);
    } else {
        let taps = bilinear_taps(read_coord_fx(c));
        let i0 = taps.i0;
        let i1 = taps.i1;
        let f = taps.f;
        let g = vec2<i32>(256) - f;
        let s = g.x * g.y * map_u(i0) + f.x * g.y * map_u(vec2<i32>(i1.x, i0.y))
            + g.x * f.y * map_u(vec2<i32>(i0.x, i1.y)) + f.x * f.y * map_u(i1);
        v = (s + vec4<i32>(32768)) >> vec4<u32>(16u);
        if ((params.map_kind | u32(opaque)) != 0u) {
            v = rotate_normal(v, jac[idx], params.map_kind == 2u);
        }
    }
    textureStore(out_color, p, vec4<f32>(v) / 255.0);
}
