// Anisometric correction subpass (mirror: src/passes/correct_aniso.rs). Continuous
// (fixed-point) coordinates, J(p) per pixel; neighbourhood predictions read Et and the
// projected distance reads qe with integer bilinear weights; the full distance scores a
// candidate at its nearest exemplar pixel.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"
#include "shared/distance.wgsl"

// Texel of table 0 (Et) or 1 (qe).
fn table_at(table: u32, c: vec2<i32>, lo: ptr<function, vec4<i32>>, hi: ptr<function, vec4<i32>>) {
    if (table == 0u) {
        unpack8(et[params.et_base + ex_index(c)], lo, hi);
    } else {
        unpack8(qe[params.et_base + ex_index(c)], lo, hi);
    }
}

// Table 0 (Et) or 1 (qe) bilinearly interpolated at a fixed-point position, added to
// (acc_lo, acc_hi).
fn add_bilinear(table: u32, u: vec2<i32>, acc_lo: ptr<function, vec4<i32>>, acc_hi: ptr<function, vec4<i32>>) {
    let taps = bilinear_taps(read_coord_fx(u));
    let i0 = taps.i0;
    let i1 = taps.i1;
    let f = taps.f;
    var lo: vec4<i32>;
    var hi: vec4<i32>;
    table_at(table, i0, &lo, &hi);
    if (all(f == vec2<i32>(0))) {
        *acc_lo += lo;
        *acc_hi += hi;
        return;
    }
    let g = vec2<i32>(256) - f;
    var s_lo = g.x * g.y * lo;
    var s_hi = g.x * g.y * hi;
    table_at(table, vec2<i32>(i1.x, i0.y), &lo, &hi);
    s_lo += f.x * g.y * lo;
    s_hi += f.x * g.y * hi;
    table_at(table, vec2<i32>(i0.x, i1.y), &lo, &hi);
    s_lo += g.x * f.y * lo;
    s_hi += g.x * f.y * hi;
    table_at(table, i1, &lo, &hi);
    s_lo += f.x * f.y * lo;
    s_hi += f.x * f.y * hi;
    let r = vec4<i32>(32768);
    *acc_lo += (s_lo + r) >> vec4<u32>(16u);
    *acc_hi += (s_hi + r) >> vec4<u32>(16u);
}

// Projected distance against qe interpolated at candidate c.
fn projected_distance_at(ns_lo: vec4<i32>, ns_hi: vec4<i32>, c: vec2<i32>) -> u32 {
    var e_lo = vec4<i32>(0);
    var e_hi = vec4<i32>(0);
    add_bilinear(1u, c, &e_lo, &e_hi);
    let m = vec4<i32>(2 * QE_MAX);
    let a = vec4<u32>(clamp(ns_lo - e_lo, -m, m));
    let b = vec4<u32>(clamp(ns_hi - e_hi, -m, m));
    let sq = a * a + b * b;
    return sq.x + sq.y + sq.z + sq.w;
}

// One prediction of Et at q + D from the neighbour in the direction of J^-1 D'.
fn predict(q: vec2<i32>, j: vec4<i32>, d: vec2<i32>, dp: vec2<i32>, acc_lo: ptr<function, vec4<i32>>, acc_hi: ptr<function, vec4<i32>>) {
    let delta = phi_inv(j, dp);
    let s = coords[region_index(q + delta)];
    let h = params.spacing;
    let u = s - scaled_jd(h, j, delta) + (h << COORD_FRAC) * d;
    add_bilinear(0u, u, acc_lo, acc_hi);
}

fn prediction_sum(q: vec2<i32>, j: vec4<i32>, d: vec2<i32>, s_lo: ptr<function, vec4<i32>>, s_hi: ptr<function, vec4<i32>>) {
    var lo = vec4<i32>(0);
    var hi = vec4<i32>(0);
    predict(q, j, d, d, &lo, &hi);
    predict(q, j, d, vec2<i32>(d.x, 0), &lo, &hi);
    predict(q, j, d, vec2<i32>(0, d.y), &lo, &hi);
    *s_lo = lo;
    *s_hi = hi;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = subpass_pixel(vec2<i32>(gid.xy));
    if (any(q < vec2<i32>(0))) {
        return;
    }
    let self_index = region_index(q);
    let j = jac[self_index];
    let h = params.step;

    var s0l: vec4<i32>; var s0h: vec4<i32>;
    var s1l: vec4<i32>; var s1h: vec4<i32>;
    var s2l: vec4<i32>; var s2h: vec4<i32>;
    var s3l: vec4<i32>; var s3h: vec4<i32>;
    prediction_sum(q, j, vec2<i32>(1, 1), &s0l, &s0h);
    prediction_sum(q, j, vec2<i32>(1, -1), &s1l, &s1h);
    prediction_sum(q, j, vec2<i32>(-1, 1), &s2l, &s2h);
    prediction_sum(q, j, vec2<i32>(-1, -1), &s3l, &s3h);
    let full = params.full_distance != 0u;
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

    var best = coords[self_index];
    var best_d = 0xffffffffu;
    if (is_valid_fx(best)) {
        if (full) {
            let n = nearest_texel(best);
            best_d = full_term(s0l, s0h, n + h) + full_term(s1l, s1h, n + vec2<i32>(h.x, -h.y))
                + full_term(s2l, s2h, n + vec2<i32>(-h.x, h.y)) + full_term(s3l, s3h, n - h);
        } else {
            best_d = projected_distance_at(ns_lo, ns_hi, best);
        }
    }
    let km1 = u32(max(params.k - 1, 0));
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let dd = vec2<i32>(dx, dy);
            let s = coords[region_index(q + dd)];
            let hjd = scaled_jd(params.spacing, j, dd);
            let obase = params.off_base + ex_index(nearest_texel(s)) * km1;
            for (var i = 0; i < params.k; i++) {
                var o = vec2<i32>(0);
                if (i > 0) {
                    let w = offsets[obase + u32(i - 1)];
                    o = vec2<i32>(lo16(w), hi16(w)) << vec2<u32>(COORD_FRAC);
                }
                let raw = s + o - hjd;
                if (!is_valid_fx(raw)) {
                    continue;
                }
                let c = fit_coord(raw);
                if (all(c == best)) {
                    continue;
                }
                var dist: u32;
                if (full) {
                    let n = nearest_texel(c);
                    dist = full_term(s0l, s0h, n + h) + full_term(s1l, s1h, n + vec2<i32>(h.x, -h.y))
                        + full_term(s2l, s2h, n + vec2<i32>(-h.x, h.y)) + full_term(s3l, s3h, n - h);
                } else {
                    dist = projected_distance_at(ns_lo, ns_hi, c);
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
}
