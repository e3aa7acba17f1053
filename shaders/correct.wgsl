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

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let start = (params.parity - params.origin) & vec2<i32>(1);
    let q = start + 2 * vec2<i32>(gid.xy);
    if (any(q >= params.size)) {
        return;
    }
    let h = params.step;

    // Synthesized neighbourhood: per diagonal, the sum of three predictions, projected.
    var acc = array<i32, 8>(0, 0, 0, 0, 0, 0, 0, 0);
    let diag = array<vec2<i32>, 4>(vec2<i32>(1, 1), vec2<i32>(1, -1), vec2<i32>(-1, 1), vec2<i32>(-1, -1));
    for (var j = 0u; j < 4u; j++) {
        let d = diag[j];
        var sum_lo = vec4<i32>(0);
        var sum_hi = vec4<i32>(0);
        let preds = array<vec2<i32>, 3>(d, vec2<i32>(d.x, 0), vec2<i32>(0, d.y));
        for (var t = 0u; t < 3u; t++) {
            let dp = preds[t];
            let s = coords[region_index(q + dp)];
            var lo: vec4<i32>;
            var hi: vec4<i32>;
            et_at(read_coord(s + h * (d - dp)), &lo, &hi);
            sum_lo += lo;
            sum_hi += hi;
        }
        let pb = params.proj_base + 2u * j;
        for (var r = 0u; r < 8u; r++) {
            acc[r] += dot(proj[pb + 8u * r], sum_lo) + dot(proj[pb + 8u * r + 1u], sum_hi);
        }
    }
    let ns_lo = vec4<i32>(acc[0], acc[1], acc[2], acc[3]) >> vec4<u32>(params.shift);
    let ns_hi = vec4<i32>(acc[4], acc[5], acc[6], acc[7]) >> vec4<u32>(params.shift);

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
