// Jitter (mirror: src/passes/jitter.rs): S[p] += floor(h_l r_l H(p, l, seed) + 0.5) in
// fixed point: amplitude in 1/16 pixel, 12 bits of hash as a value in [-1, 1); mirrored
// back into the valid range (wrapped for tileable exemplars).
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let h = hash_pixel(params.origin + q, params.level, params.seed);
    let s = vec2<i32>(h & vec2<u32>(0xfffu)) - vec2<i32>(2048);
    let o = (params.jitter_amp * s + vec2<i32>(1 << 14u)) >> vec2<u32>(15u);
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    coords[i] = fit_jittered(coords[i] + (o << vec2<u32>(params.coord_frac)));
}

// t mirrored into [0, n] (period 2n); 0 where n <= 0.
fn mirror(t: i32, n: i32) -> i32 {
    if (n <= 0) {
        return 0;
    }
    let m = wrap(t, 2 * n);
    return select(m, 2 * n - m, m > n);
}

// A jittered coordinate back into the exemplar: wrapped (tileable), else mirrored at the
// edges of the valid range. Clamping there piled the jitter of the coarse levels (whose
// range is narrower than their jitter) onto the range's edges, so many pixels shared a
// coordinate and the output repeated the exemplar's layout.
fn fit_jittered(c: vec2<i32>) -> vec2<i32> {
    if (TILEABLE) {
        return fit_coord(c);
    }
    let f = vec2<u32>(params.coord_frac);
    // `opaque` keeps mirror()'s branch on n from depending on uniforms alone: lavapipe
    // would otherwise specialize the shader on the margin and size and compile a new
    // variant for every level.
    let m = params.margin | opaque;
    let lo = vec2<i32>(m) << f;
    let hi = ((params.ex_size | vec2<i32>(opaque)) - vec2<i32>(1 + m)) << f;
    return lo + vec2<i32>(mirror(c.x - lo.x, hi.x - lo.x), mirror(c.y - lo.y, hi.y - lo.y));
}
