// Correction subpass (mirror: src/passes/correct.rs). Updates the pixels whose absolute
// position has parity params.parity with the best k-coherent candidate; every other
// pixel is only read, so the pass runs in place. Integer arithmetic throughout.
#include "shared/common.wgsl"

fn et_at(c: vec2<i32>, lo: ptr<function, vec4<i32>>, hi: ptr<function, vec4<i32>>) {
    unpack8(et[params.et_base + ex_index(c)], lo, hi);
}

// Squared distance between the synthesized neighbourhood (ns_lo, ns_hi) and the
// exemplar neighbourhood of candidate c; differences clamped so 8 squares fit in a u32.
fn cand_distance(ns_lo: vec4<i32>, ns_hi: vec4<i32>, c: vec2<i32>) -> u32 {
    var e_lo: vec4<i32>;
    var e_hi: vec4<i32>;
    unpack8(qe[params.et_base + ex_index(c)], &e_lo, &e_hi);
    let m = vec4<i32>(2 * QE_MAX);
    let a = vec4<u32>(clamp(ns_lo - e_lo, -m, m));
    let b = vec4<u32>(clamp(ns_hi - e_hi, -m, m));
    let sq = a * a + b * b;
    return sq.x + sq.y + sq.z + sq.w;
}

// Adds P_j * (sum of the three predictions of the appearance at q + d) to the
// accumulator. P is stored per diagonal block j as 8 columns of two vec4 (rows 0-3,
// rows 4-7), so the product is 16 vector multiply-adds.
fn project_diagonal(q: vec2<i32>, d: vec2<i32>, h: vec2<i32>, j: u32, acc_lo: ptr<function, vec4<i32>>, acc_hi: ptr<function, vec4<i32>>) {
    var lo: vec4<i32>;
    var hi: vec4<i32>;
    et_at(read_coord(coords[region_index(q + d)]), &lo, &hi);
    var sum_lo = lo;
    var sum_hi = hi;
    et_at(read_coord(coords[region_index(q + vec2<i32>(d.x, 0))] + vec2<i32>(0, h.y * d.y)), &lo, &hi);
    sum_lo += lo;
    sum_hi += hi;
    et_at(read_coord(coords[region_index(q + vec2<i32>(0, d.y))] + vec2<i32>(h.x * d.x, 0)), &lo, &hi);
    sum_lo += lo;
    sum_hi += hi;
    let b = 16u * j;
    *acc_lo += proj[b + 0u] * sum_lo.x + proj[b + 2u] * sum_lo.y + proj[b + 4u] * sum_lo.z + proj[b + 6u] * sum_lo.w
        + proj[b + 8u] * sum_hi.x + proj[b + 10u] * sum_hi.y + proj[b + 12u] * sum_hi.z + proj[b + 14u] * sum_hi.w;
    *acc_hi += proj[b + 1u] * sum_lo.x + proj[b + 3u] * sum_lo.y + proj[b + 5u] * sum_lo.z + proj[b + 7u] * sum_lo.w
        + proj[b + 9u] * sum_hi.x + proj[b + 11u] * sum_hi.y + proj[b + 13u] * sum_hi.z + proj[b + 15u] * sum_hi.w;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let start = (params.parity - params.origin) & vec2<i32>(1);
    let q = start + 2 * vec2<i32>(gid.xy);
    if (any(q >= params.size)) {
        return;
    }
    let h = params.step;

    // Synthesized neighbourhood: per diagonal, the sum of three predictions, projected
    // by that diagonal's 8x8 block of P. Written out without local arrays: CPU drivers
    // turn dynamically indexed local arrays into per-lane memory traffic.
    var acc_lo = vec4<i32>(0);
    var acc_hi = vec4<i32>(0);
    project_diagonal(q, vec2<i32>(1, 1), h, 0u, &acc_lo, &acc_hi);
    project_diagonal(q, vec2<i32>(1, -1), h, 1u, &acc_lo, &acc_hi);
    project_diagonal(q, vec2<i32>(-1, 1), h, 2u, &acc_lo, &acc_hi);
    project_diagonal(q, vec2<i32>(-1, -1), h, 3u, &acc_lo, &acc_hi);
    let ns_lo = acc_lo >> vec4<u32>(params.shift);
    let ns_hi = acc_hi >> vec4<u32>(params.shift);

    // Candidates: the current value first (ties keep it), then the k-coherent
    // candidates of the 3x3 neighbours, row-major from (-1, -1).
    let self_index = region_index(q);
    var best = coords[self_index];
    var best_d = 0xffffffffu;
    if (is_valid(best)) {
        best_d = cand_distance(ns_lo, ns_hi, best);
    }
    let km1 = u32(max(params.k - 1, 0));
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let dd = vec2<i32>(dx, dy);
            let s = coords[region_index(q + dd)];
            let obase = params.off_base + ex_index(s) * km1;
            for (var i = 0; i < params.k; i++) {
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
                var dist = cand_distance(ns_lo, ns_hi, c);
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
}
