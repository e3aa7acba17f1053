// Magnification (mirror: src/passes/magnify.rs; Lefebvre & Hoppe 2006 §5-6): renders the
// synthesized window at `magnify` times its resolution from a higher-resolution
// exemplar E_H (bound as the colours, size hi_size = magnify x the analysed one).
// Output pixel o sits at x = (o + 1/2) / F - 1/2 in synthesized pixels; it blends the
// four nearest synthesized pixels q with bilinear weights, each predicting
// E_H[F (S[q] + J(q) (x - q))]. Integer arithmetic: 2F(x - q) is an integer. Material
// sets: a tangent-space normal map (map_kind 1 or 2) has each prediction rotated by its J.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

fn hi_u(c: vec2<i32>) -> vec4<i32> {
    let w = colors[u32(c.y * params.hi_size.x + c.x)];
    return vec4<i32>(vec4<u32>(w, w >> 8u, w >> 16u, w >> 24u) & vec4<u32>(255u));
}

// E_H bilinearly at a position in 1/256 high-resolution texels (wrapped or clamped).
fn hi_bilinear(u_in: vec2<i32>) -> vec4<i32> {
    let n = params.hi_size << vec2<u32>(COORD_FRAC);
    var u: vec2<i32>;
    if (TILEABLE) {
        u = vec2<i32>(wrap(u_in.x, n.x), wrap(u_in.y, n.y));
    } else {
        u = clamp(u_in, vec2<i32>(0), n - vec2<i32>(1 << COORD_FRAC));
    }
    let i0 = u >> vec2<u32>(COORD_FRAC);
    var i1: vec2<i32>;
    if (TILEABLE) {
        i1 = select(i0 + vec2<i32>(1), vec2<i32>(0), i0 + vec2<i32>(1) == params.hi_size);
    } else {
        i1 = min(i0 + vec2<i32>(1), params.hi_size - vec2<i32>(1));
    }
    let f = u & vec2<i32>((1 << COORD_FRAC) - 1);
    let g = vec2<i32>(256) - f;
    let s = g.x * g.y * hi_u(i0) + f.x * g.y * hi_u(vec2<i32>(i1.x, i0.y))
        + g.x * f.y * hi_u(vec2<i32>(i0.x, i1.y)) + f.x * f.y * hi_u(i1);
    return (s + vec4<i32>(32768)) >> vec4<u32>(16u);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let o = vec2<i32>(gid.xy);
    let big = i32(params.magnify);
    if (any(o >= (params.window_size | vec2<i32>(opaque)) * big)) {
        return;
    }
    let den = 2 * big;
    let num = 2 * o + vec2<i32>(1 - big);
    // floor(num / den) for num > -den.
    let q0 = (num + vec2<i32>(den)) / den - vec2<i32>(1);
    let r = num - den * q0;
    var acc = vec4<i32>(0);
    for (var dy = 0; dy <= 1; dy++) {
        for (var dx = 0; dx <= 1; dx++) {
            let d = vec2<i32>(dx, dy);
            let idx = region_index(q0 + d + params.window_offset);
            let s = coords[idx] << vec2<u32>(COORD_FRAC - params.coord_frac);
            let v = r - den * d;
            var off = vec2<i32>(128) * v;
            if ((params.coord_frac | u32(opaque)) != 0u) {
                let j = jac[idx];
                off = (vec2<i32>(j.x * v.x + j.y * v.y, j.z * v.x + j.w * v.y) + vec2<i32>(4)) >> vec2<u32>(3u);
            }
            let w = select(den - r.x, r.x, dx == 1) * select(den - r.y, r.y, dy == 1);
            var c = hi_bilinear(big * s + off);
            // Normal maps rotate with the texture, by each prediction's own J.
            if ((params.coord_frac | u32(opaque)) != 0u && (params.map_kind | u32(opaque)) != 0u) {
                c = rotate_normal(c, jac[idx], params.map_kind == 2u);
            }
            acc += w * c;
        }
    }
    let total = den * den;
    let rgba = (acc + vec4<i32>(total / 2)) / total;
    textureStore(out_color, o, vec4<f32>(rgba) / 255.0);
}
