// Anisometric gather (mirror: src/passes/gather_aniso.rs): the exemplar colour
// bilinearly interpolated at the finest level's continuous coordinate, integer weights.
// Seam blending as in gather.wgsl: a 4-neighbour n whose prediction S[n] - h J (n - p)
// is 3/4 pixel or more from the pixel's coordinate (a patch seam, not the sub-pixel
// misfit of a varying field) adds its predicted colour at a third of the pixel's weight.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

fn color_u(c: vec2<i32>) -> vec4<i32> {
    let w = colors[ex_index(c)];
    return vec4<i32>(vec4<u32>(w, w >> 8u, w >> 16u, w >> 24u) & vec4<u32>(255u));
}

// RGBA (0..255) at a fixed-point position: bilinear, or the nearest texel (advection).
fn color_at(u: vec2<i32>) -> vec4<i32> {
    var c = u;
    if (NEAREST) {
        c = ((c + vec2<i32>(128)) >> vec2<u32>(8u)) << vec2<u32>(8u);
        // A whole pixel: the three other taps would have weight 0 (the same value, one
        // read instead of four).
        return color_u(bilinear_taps(read_coord_fx(c)).i0);
    }
    let taps = bilinear_taps(read_coord_fx(c));
    let i0 = taps.i0;
    let i1 = taps.i1;
    let f = taps.f;
    let g = vec2<i32>(256) - f;
    let v = g.x * g.y * color_u(i0) + f.x * g.y * color_u(vec2<i32>(i1.x, i0.y))
        + g.x * f.y * color_u(vec2<i32>(i0.x, i1.y)) + f.x * f.y * color_u(i1);
    return (v + vec4<i32>(32768)) >> vec4<u32>(16u);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    let wi = window_coord_index(p);
    if (wi < 0) {
        return;
    }
    let q = p + params.window_offset;
    let i = u32(wi);
    let c = coords[i];
    var v = color_at(c);
    if (SEAM_BLEND) {
        let j = jac_at(i);
        var sum = 3 * v;
        var weight = 3;
        for (var k = 0; k < 4; k++) {
            // (1, 0), (-1, 0), (0, 1), (0, -1)
            let d = select(vec2<i32>(1 - 2 * (k & 1), 0), vec2<i32>(0, 1 - 2 * (k & 1)), k >= 2);
            let pred = coords[region_index(q + d)] - scaled_jd(params.spacing, j, d);
            if (!same_patch(pred, c)) {
                sum += color_at(pred);
                weight += 1;
            }
        }
        // Rounded to nearest; weight is 3..7.
        v = vec4<i32>(mean_rounded(vec4<u32>(sum), u32(weight)));
    }
    textureStore(out_color, p, vec4<f32>(v) / 255.0);
}
