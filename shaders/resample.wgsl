// A tileable output made on a torus (mirror: src/passes/resample.rs): output pixel x of n
// takes the coordinate of the torus pixel nearest to u = (x + 0.5) m / n - 0.5 (m the
// torus period) plus J'(q) (u - q), so the texture advances across the output as the field
// asks and repeats with the output's period. Reads the finest level (parent_size,
// parent_coord_base), writes the output's region (size, coord_base); rounded to whole
// texels along no field (NEAREST).
#include "shared/common.wgsl"

// Torus pixel and u - q in 1/256 pixel, per axis (non-negative integer division only).
fn source(x: vec2<i32>, n: vec2<i32>, m: vec2<i32>) -> array<vec2<i32>, 2> {
    let t = vec2<u32>((2 * x + 1) * m);
    let un = vec2<u32>(n);
    let q = t / (2u * un);
    let r = t - 2u * un * q;
    let f = vec2<i32>((256u * r + un) / (2u * un)) - vec2<i32>(128);
    return array<vec2<i32>, 2>(vec2<i32>(q), f);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    if (any(p >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let s = source(p, params.size, params.parent_size);
    let q = s[0];
    let f = s[1];
    let src = params.parent_coord_base + u32(q.y * params.parent_size.x + q.x);
    let j = jac_at(src);
    let o = (vec2<i32>(j.x * f.x + j.y * f.y, j.z * f.x + j.w * f.y) + vec2<i32>(512)) >> vec2<u32>(10u);
    var c = coords[src] + o;
    if (NEAREST) {
        // Along no field: whole texels, as isometric synthesis has (the gather reads the
        // nearest one anyway).
        c = ((c + vec2<i32>(128)) >> vec2<u32>(8u)) << vec2<u32>(8u);
    }
    coords[params.coord_base + u32(p.y * params.size.x + p.x)] = fit_coord(c);
}
