// Correction subpass (mirror: src/passes/correct.rs). Updates the pixels whose absolute
// position has parity params.parity with the best k-coherent candidate; every other
// pixel is only read, so the pass runs in place. Integer arithmetic throughout.
#include "shared/common.wgsl"
#include "shared/distance.wgsl"

// Sum of the three predictions of Et at q + d (3 N_S(q; d)), from the neighbours'
// coordinates.
fn prediction_sum(n: Neighbours, d: vec2<i32>, h: vec2<i32>, s_lo: ptr<function, vec4<i32>>, s_hi: ptr<function, vec4<i32>>) {
    var lo: vec4<i32>;
    var hi: vec4<i32>;
    et_at(read_coord(neighbour(n, d)), &lo, &hi);
    var sum_lo = lo;
    var sum_hi = hi;
    et_at(read_coord(neighbour(n, vec2<i32>(d.x, 0)) + vec2<i32>(0, h.y * d.y)), &lo, &hi);
    sum_lo += lo;
    sum_hi += hi;
    et_at(read_coord(neighbour(n, vec2<i32>(0, d.y)) + vec2<i32>(h.x * d.x, 0)), &lo, &hi);
    *s_lo = sum_lo + lo;
    *s_hi = sum_hi + hi;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = subpass_pixel(vec2<i32>(gid.xy));
    if (any(q < vec2<i32>(0))) {
        return;
    }
    // The same inputs as when this class's previous subpass left the pixel unchanged.
    if (unchanged_since_last_look(q)) {
        return;
    }
    let h = params.step;
    let n = load_neighbours(q);

    // Synthesized neighbourhood: per diagonal, the sum of three predictions. Written
    // out without local arrays: CPU drivers turn dynamically indexed local arrays into
    // per-lane memory traffic.
    var s0l: vec4<i32>; var s0h: vec4<i32>;
    var s1l: vec4<i32>; var s1h: vec4<i32>;
    var s2l: vec4<i32>; var s2h: vec4<i32>;
    var s3l: vec4<i32>; var s3h: vec4<i32>;
    prediction_sum(n, vec2<i32>(1, 1), h, &s0l, &s0h);
    prediction_sum(n, vec2<i32>(1, -1), h, &s1l, &s1h);
    prediction_sum(n, vec2<i32>(-1, 1), h, &s2l, &s2h);
    prediction_sum(n, vec2<i32>(-1, -1), h, &s3l, &s3h);
    let full = FULL_DISTANCE;
    var ns_lo = vec4<i32>(0);
    var ns_hi = vec4<i32>(0);
    if (!full) {
        project_add(0u, s0l, s0h, &ns_lo, &ns_hi);
        project_add(1u, s1l, s1h, &ns_lo, &ns_hi);
        project_add(2u, s2l, s2h, &ns_lo, &ns_hi);
        project_add(3u, s3l, s3h, &ns_lo, &ns_hi);
        ns_lo = ns_lo >> vec4<u32>(params.shift);
        ns_hi = ns_hi >> vec4<u32>(params.shift);
    }

    // Candidates: the current value first (ties keep it), then the k-coherent
    // candidates of the 3x3 neighbours, row-major from (-1, -1).
    let self_index = region_index(q);
    var best = n.zz;
    var best_d = 0xffffffffu;
    if (is_valid(best)) {
        if (full) {
            best_d = full_term(s0l, s0h, best + h) + full_term(s1l, s1h, best + vec2<i32>(h.x, -h.y))
                + full_term(s2l, s2h, best + vec2<i32>(-h.x, h.y)) + full_term(s3l, s3h, best - h);
        } else {
            best_d = projected_distance(ns_lo, ns_hi, best);
        }
    }
    let km1 = u32(K - 1);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let dd = vec2<i32>(dx, dy);
            let s = neighbour(n, dd);
            let obase = params.off_base + ex_index(s) * km1;
            for (var i = 0; i < K; i++) {
                var o = vec2<i32>(0);
                if (i > 0) {
                    let w = offsets[obase + u32(i - 1)];
                    o = vec2<i32>(lo16(w), hi16(w));
                }
                let raw = s + o - h * dd;
                if (!is_valid(raw)) {
                    continue;
                }
                let c = fit_near(raw);
                // The best so far cannot be beaten by itself (ties keep it, the bias
                // only adds): skipping it changes nothing and saves most of the work
                // in coherent areas, where the neighbours all propose the same pixel.
                if (all(c == best)) {
                    continue;
                }
                var dist: u32;
                if (full) {
                    dist = full_term(s0l, s0h, c + h) + full_term(s1l, s1h, c + vec2<i32>(h.x, -h.y))
                        + full_term(s2l, s2h, c + vec2<i32>(-h.x, h.y)) + full_term(s3l, s3h, c - h);
                } else {
                    dist = projected_distance(ns_lo, ns_hi, c);
                }
                if (i > 0) {
                    dist += (dist >> 4u) * params.coherence;
                }
                if (dist < best_d) {
                    best_d = dist;
                    best = c;
                }
            }
        }
    }
    coords[self_index] = best;
    if (any(best != n.zz)) {
        stamp_change(q);
    }
}
