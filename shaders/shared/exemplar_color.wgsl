// The exemplar's colour at a continuous coordinate, for the gathers (mirror:
// src/passes/gather_aniso.rs, color_at). Included after common.wgsl and aniso.wgsl.

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
