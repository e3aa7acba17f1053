// What the advection passes share (mirror: src/passes/advect.rs): the velocity under a
// level pixel, the frame's whole shift k of a level, and the in-place displacement
// J (V - k). Included after common.wgsl.

// The velocity at the finest-level pixel under this level's pixel p (absolute),
// clamped to the output window.
fn velocity_at(abs_p: vec2<i32>) -> vec2<i32> {
    let s = params.steps;
    let half = i32((1u << s) >> 1u);
    let f = (abs_p << vec2<u32>(s)) + vec2<i32>(half) - params.window_origin;
    let c = clamp(f, vec2<i32>(0), params.window_size - vec2<i32>(1));
    return velocity[u32(c.y * params.window_size.x + c.x)];
}

// The whole level pixels k by which this frame moves the level's coordinates (advect.rs,
// whole_shift): in frames the change of the drift's whole level pixels, else the
// centre velocity rounded to whole level pixels.
fn whole_shift() -> vec2<i32> {
    if ((params.drift | u32(opaque)) != 0u) {
        let s = vec2<u32>(params.steps);
        return (coords[params.drift + 1u] >> s) - (coords[params.drift] >> s);
    }
    let unit = 1024 << params.steps;
    let ws = params.window_size;
    let vc = velocity[u32((ws.y / 2) * ws.x + ws.x / 2)];
    return (vc + vec2<i32>(unit >> 1u)) >> vec2<u32>(10u + params.steps);
}

// J (V - k) in 1/2^20 exemplar pixel to 1/256, rounded with this frame's offset (a
// low-discrepancy sequence: the rounding errors of a pixel do not add up over frames).
// J k 2^steps is taken apart into whole 1/256 units and a remainder, so nothing
// overflows on coarse levels, where k is a whole level pixel however slow the flow
// (see advect.rs, displacement).
fn displacement(j: vec4<i32>, vq: vec2<i32>, k: vec2<i32>) -> vec2<i32> {
    let jv = vec2<i32>(j.x * vq.x + j.y * vq.y, j.z * vq.x + j.w * vq.y);
    let jk = vec2<i32>(j.x * k.x + j.y * k.y, j.z * k.x + j.w * k.y);
    let up = params.steps + 10u;
    var hi: vec2<i32>;
    var lo = vec2<i32>(0);
    if (up >= 12u) {
        hi = jk << vec2<u32>(up - 12u);
    } else {
        hi = jk >> vec2<u32>(12u - up);
        lo = (jk - (hi << vec2<u32>(12u - up))) << vec2<u32>(up);
    }
    return ((jv - lo + vec2<i32>(i32(params.dither))) >> vec2<u32>(12u)) - hi;
}
