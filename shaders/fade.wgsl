// The last pass of an advection frame with fading (mirror: src/passes/fade.rs): the
// finest level's colours, where a pixel's coordinate jumped since the previous frame (it
// landed more than FADE_JUMP from where the flow carried the previous frame's) and the
// jumps around it changed the colour by more than params.fade_change on average (a pop: a
// renewed or remade patch) the pixel fades from what it showed to its new content over
// params.fade_frames frames. Per pixel of the finest level's region the fade state holds the coordinate (A),
// the ghost's coordinate (B) and the frames the ghost has left (w); this frame reads the
// state at params.fade_src (none: 0) k pixels upstream, moves A (and B) with the flow as
// advect.wgsl moves coordinates, and writes the new state at params.fade_dst (two halves,
// swapped every frame, so no pixel reads what another writes). With one-frame fades the
// ghost shows on the frame of the pop only, so the state is A alone (B and w are neither
// read nor written). Ghosts are coordinates, not colours: they move with the texture
// without being resampled, so nothing blurs. The two colours are blended so that the
// contrast stays (variance-preserving, around the exemplar's mean colour): a linear blend
// of two unrelated patches is a flat, washed-out patch halfway through.
//
// The pop test is the mean change over the pixel's 3x3 neighbourhood within its 8x8
// workgroup tile (pixels that did not jump count 0), shared through workgroup memory: an
// isolated speck that changed is no pop, a patch that changed is. A neighbourhood that
// crossed tiles would need a pass of its own and nine reads per pixel, about twice this
// pass's cost.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"
#include "shared/advect.wgsl"
#include "shared/exemplar_color.wgsl"
#include "shared/fade.wgsl"

// The new colour c and the ghost's g, w frames left of N: mean + (a (c - mean) + w (g -
// mean)) / sqrt(a^2 + w^2) with a = N + 2 - w (the new content leads by one step: a
// one-frame fade shows the ghost at 1 against 2), in fixed point, clamped to 0..255.
fn fade_blend(c: vec4<i32>, g: vec4<i32>, w: i32) -> vec4<i32> {
    let m = vec4<i32>(vec4<u32>(params.fade_mean, params.fade_mean >> 8u, params.fade_mean >> 16u,
        params.fade_mean >> 24u) & vec4<u32>(255u));
    let a = i32(params.fade_frames) + 2 - w;
    // w > 0, so a^2 + w^2 >= 2 and isqrt's argument stays below 2^30.
    let f = isqrt(i32((1u << 30u) / u32(a * a + w * w)));
    let num = a * (c - m) + w * (g - m);
    return clamp(m + ((num * f + vec4<i32>(1 << 14u)) >> vec4<u32>(15u)), vec4<i32>(0), vec4<i32>(255));
}

// Per pixel of the workgroup's tile: how much its jump changed its colour, NO_JUMP if it
// did not jump, OUTSIDE if it lies outside the region (not counted).
var<workgroup> tile_change: array<i32, 64>;
const NO_JUMP: i32 = -1;
const OUTSIDE: i32 = -2;

// Whether a pixel that jumped popped: the mean change over its 3x3 neighbourhood within
// the tile (l: its place in the tile) exceeds params.fade_change.
fn popped(l: vec2<i32>) -> bool {
    var sum = 0;
    var n = 0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let m = l + vec2<i32>(dx, dy);
            if (all(m >= vec2<i32>(0)) && all(m < vec2<i32>(8))) {
                let c = tile_change[m.y * 8 + m.x];
                sum += max(c, 0);
                n += select(0, 1, c != OUTSIDE);
            }
        }
    }
    return sum > n * i32(params.fade_change);
}

@compute @workgroup_size(8, 8, 1)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    // Every invocation reaches the barrier: no early return before it.
    let inside = all(q < (params.size | vec2<i32>(opaque)));
    let t = u32(q.y * params.size.x + q.x);
    let i = params.coord_base + t;
    var s = vec2<i32>(0);
    var v = vec4<i32>(0);
    var a = vec2<i32>(0);
    var ca = vec4<i32>(0);
    var o = vec2<i32>(0);
    var si = -1;
    var change = OUTSIDE;
    if (inside) {
        s = coords[i];
        v = color_at(s);
        change = NO_JUMP;
        // Mixed with `opaque`: it changes every frame (see common.wgsl).
        if ((params.fade_src | u32(opaque)) != 0u) {
            let k = whole_shift();
            si = upstream(q, k);
            if (si >= 0) {
                let j = jac_at(i);
                o = displacement(j, velocity_at(params.origin + q), k);
                a = fit_coord(coords[u32(si)] - o);
                // Most jumps are not pops: seams that moved, patches remade alike.
                if (jumped(s, a, j)) {
                    ca = color_at(a);
                    change = grey_change(v, ca);
                }
            }
        }
    }
    let l = vec2<i32>(lid.xy);
    tile_change[l.y * 8 + l.x] = change;
    workgroupBarrier();
    if (!inside) {
        return;
    }
    var ghost = s;
    var w = 0;
    var g = v;
    // Compiled out of one-frame fades: the ghost's reads and writes (as a uniform branch
    // the CPU driver ran them anyway).
    let longer = LONG_FADE;
    if (si >= 0) {
        // At most N: a fade saved under a longer N (set_options between frames) goes on
        // with the new one.
        var left = 0;
        if (longer) {
            left = clamp(coords[u32(si) + 2u].x - 1, 0, i32(params.fade_frames));
        }
        let pop = change >= 0 && popped(l);
        // A pop while a ghost shows: the one shown most stays the ghost.
        if (pop && 2 * left <= i32(params.fade_frames)) {
            ghost = a;
            w = i32(params.fade_frames);
            g = ca;
        } else if (left > 0) {
            ghost = fit_coord(coords[u32(si) + 1u] - o);
            w = left;
            g = color_at(ghost);
        }
    }
    let d = params.fade_dst + 3u * t;
    coords[d] = s;
    if (longer) {
        coords[d + 1u] = ghost;
        coords[d + 2u] = vec2<i32>(w, 0);
    }
    let p = q - params.window_offset;
    if (any(p < vec2<i32>(0)) || any(p >= (params.window_size | vec2<i32>(opaque)))) {
        return;
    }
    if (w > 0) {
        v = fade_blend(v, g, w);
    }
    textureStore(out_color, p, vec4<f32>(v) / 255.0);
}
