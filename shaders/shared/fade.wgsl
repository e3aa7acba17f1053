// What the fade pass uses (mirror: src/passes/fade.rs): when a coordinate jumped, where a
// pixel's fade state comes from, and how much a jump changed its look. Included
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

// How much a pixel's colour changed from a to c: (|dR| + 2 |dG| + |dB|) / 4, 0..255.
fn grey_change(c: vec4<i32>, a: vec4<i32>) -> i32 {
    let d = abs(c - a);
    return (d.x + 2 * d.y + d.z) >> 2u;
}
