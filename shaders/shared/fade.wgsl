// What the fade passes share (mirror: src/passes/fade.rs): when a coordinate jumped,
// where a pixel's fade state comes from, and how much a jump changed its look. Included
// after common.wgsl, aniso.wgsl, advect.wgsl and exemplar_color.wgsl.

// A jump: more than 1.5 exemplar pixels (1/256 units) per unit of the Jacobian's
// largest column (at least 1), on either axis.
const FADE_JUMP: i32 = 384;

fn jumped(s: vec2<i32>, a: vec2<i32>, j: vec4<i32>) -> bool {
    var d = s - a;
    if (TILEABLE) {
        let n = params.ex_size << vec2<u32>(params.coord_frac);
        d -= select(vec2<i32>(0), n, d > n / 2);
        d += select(vec2<i32>(0), n, d < -n / 2);
    }
    let col = max(abs(j.x) + abs(j.z), abs(j.y) + abs(j.w));
    let limit = (FADE_JUMP * max(1024, col)) >> 10u;
    return any(abs(d) > vec2<i32>(limit));
}

// The fade state at region pixel q's upstream pixel, k pixels up the flow, if it lies
// in the region (a pixel whose upstream lies outside is new to the region: nothing to
// fade): its index.
fn upstream(q: vec2<i32>, k: vec2<i32>) -> i32 {
    var src = q - k;
    if (PERIODIC) {
        src = vec2<i32>(wrap(src.x, params.size.x), wrap(src.y, params.size.y));
    } else if (any(src < vec2<i32>(0)) || any(src >= (params.size | vec2<i32>(opaque)))) {
        return -1;
    }
    return i32(params.fade_src + 3u * u32(src.y * params.size.x + src.x));
}

// How much region pixel q's grey level changed by a jump of its coordinate (0..255), or
// -1 where it did not jump or has no history.
fn jump_change(q: vec2<i32>, k: vec2<i32>) -> i32 {
    let si = upstream(q, k);
    if (si < 0) {
        return -1;
    }
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    let j = jac_at(i);
    let o = displacement(j, velocity_at(params.origin + q), k);
    let a = fit_coord(coords[u32(si)] - o);
    let s = coords[i];
    if (!jumped(s, a, j)) {
        return -1;
    }
    let d = abs(color_at(s) - color_at(a));
    return (d.x + 2 * d.y + d.z) >> 2u;
}
