// Anisometric gather (mirror: src/passes/gather_aniso.rs): the exemplar colour
// bilinearly interpolated at the finest level's continuous coordinate, integer weights.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

fn color_u(c: vec2<i32>) -> vec4<i32> {
    let w = colors[ex_index(c)];
    return vec4<i32>(vec4<u32>(w, w >> 8u, w >> 16u, w >> 24u) & vec4<u32>(255u));
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    if (any(p >= (params.window_size | vec2<i32>(opaque)))) {
        return;
    }
    let q = p + params.window_offset;
    var c = coords[params.coord_base + u32(q.y * params.size.x + q.x)];
    if ((params.nearest | u32(opaque)) != 0u) {
        c = ((c + vec2<i32>(128)) >> vec2<u32>(8u)) << vec2<u32>(8u);
    }
    let taps = bilinear_taps(read_coord_fx(c));
    let i0 = taps.i0;
    let i1 = taps.i1;
    let f = taps.f;
    let g = vec2<i32>(256) - f;
    let v = g.x * g.y * color_u(i0) + f.x * g.y * color_u(vec2<i32>(i1.x, i0.y))
        + g.x * f.y * color_u(vec2<i32>(i0.x, i1.y)) + f.x * f.y * color_u(i1);
    let rgba = vec4<f32>((v + vec4<i32>(32768)) >> vec4<u32>(16u)) / 255.0;
    textureStore(out_color, p, rgba);
}
