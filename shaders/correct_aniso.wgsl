// Anisometric correction subpass (mirror: src/passes/correct_aniso.rs). Continuous
// (fixed-point) coordinates, J(p) per pixel; neighbourhood predictions read Et and the
// projected distance reads qe with integer bilinear weights (similarity-set candidates:
// at the nearest texel), at the position or (QUARTER) at its nearest quarter pixel; the
// full distance scores a candidate at its nearest exemplar pixel.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"
#include "shared/distance.wgsl"

// 8 i16 values (an Et or qe texel, or sums of them) as two vec4<i32>. Helpers return it
// by value: passing pointers through nested calls made lavapipe put the variables in
// scratch memory, allocated on every dispatch.
struct Vec8 {
    lo: vec4<i32>,
    hi: vec4<i32>,
}

fn unpack_vec8(v: vec4<u32>) -> Vec8 {
    return Vec8(
        vec4<i32>(lo16(v.x), hi16(v.x), lo16(v.y), hi16(v.y)),
        vec4<i32>(lo16(v.z), hi16(v.z), lo16(v.w), hi16(v.w)),
    );
}

// Texels of Et and qe. Two functions, not a select() between tables: select evaluates
// both loads.
fn et_texel(c: vec2<i32>) -> Vec8 {
    return unpack_vec8(et[params.et_base + ex_index(c)]);
}

fn qe_texel(c: vec2<i32>) -> Vec8 {
    return unpack_vec8(qe[params.et_base + ex_index(c)]);
}

// With FINE_TABLES, et and qe hold this level's tables at every quarter pixel
// (QUARTER_BITS): one read where bilinear interpolation takes four.
fn fine_index(s: vec2<i32>) -> u32 {
    return u32(s.y * (params.ex_size.x << QUARTER_BITS) + s.x);
}

// A wrapped/clamped position as the tables are read: rounded to its quarter pixel with
// QUARTER.
fn table_position(c: vec2<i32>) -> vec2<i32> {
    if (QUARTER) {
        return quarter_texel(c) << vec2<u32>(COORD_FRAC - QUARTER_BITS);
    }
    return c;
}

// Bilinear blend of four texels with fractions f (weights in 1/65536, rounded).
fn blend(e00: Vec8, e10: Vec8, e01: Vec8, e11: Vec8, f: vec2<i32>) -> Vec8 {
    let g = vec2<i32>(256) - f;
    let w = vec4<i32>(g.x * g.y, f.x * g.y, g.x * f.y, f.x * f.y);
    let r = vec4<i32>(32768);
    return Vec8(
        (w.x * e00.lo + w.y * e10.lo + w.z * e01.lo + w.w * e11.lo + r) >> vec4<u32>(16u),
        (w.x * e00.hi + w.y * e10.hi + w.z * e01.hi + w.w * e11.hi + r) >> vec4<u32>(16u),
    );
}

// Et bilinearly interpolated at a fixed-point position (exact at whole pixels), or at
// its quarter pixel.
fn bilinear_et(u: vec2<i32>) -> Vec8 {
    let c = table_position(read_coord_fx(u));
    if (FINE_TABLES) {
        return unpack_vec8(et[fine_index(c >> vec2<u32>(COORD_FRAC - QUARTER_BITS))]);
    }
    let t = bilinear_taps(c);
    let e00 = et_texel(t.i0);
    if (all(t.f == vec2<i32>(0))) {
        return e00;
    }
    return blend(e00, et_texel(vec2<i32>(t.i1.x, t.i0.y)), et_texel(vec2<i32>(t.i0.x, t.i1.y)), et_texel(t.i1), t.f);
}

// The same for qe.
fn bilinear_qe(u: vec2<i32>) -> Vec8 {
    let c = table_position(read_coord_fx(u));
    if (FINE_TABLES) {
        return unpack_vec8(qe[fine_index(c >> vec2<u32>(COORD_FRAC - QUARTER_BITS))]);
    }
    let t = bilinear_taps(c);
    let e00 = qe_texel(t.i0);
    if (all(t.f == vec2<i32>(0))) {
        return e00;
    }
    return blend(e00, qe_texel(vec2<i32>(t.i1.x, t.i0.y)), qe_texel(vec2<i32>(t.i0.x, t.i1.y)), qe_texel(t.i1), t.f);
}

// Projected distance against qe interpolated at candidate c.
fn projected_distance_at(ns_lo: vec4<i32>, ns_hi: vec4<i32>, c: vec2<i32>) -> u32 {
    return projected_distance_to(ns_lo, ns_hi, bilinear_qe(c));
}

// Projected distance against an exemplar side e.
fn projected_distance_to(ns_lo: vec4<i32>, ns_hi: vec4<i32>, e: Vec8) -> u32 {
    let m = vec4<i32>(2 * QE_MAX);
    let a = vec4<u32>(clamp(ns_lo - e.lo, -m, m));
    let b = vec4<u32>(clamp(ns_hi - e.hi, -m, m));
    let sq = a * a + b * b;
    return sq.x + sq.y + sq.z + sq.w;
}

// Where the prediction from the neighbour in the direction of J^-1 D' starts:
// S[q + delta] - h J delta, delta = phi(J^-1 D'). Inside a coherent patch the three
// neighbours of a diagonal usually agree on it exactly.
fn prediction_base(n: Neighbours, j: vec4<i32>, dp: vec2<i32>) -> vec2<i32> {
    let delta = phi_inv(j, dp);
    return neighbour(n, delta) - scaled_jd(params.spacing, j, delta);
}

// The sum of the three predictions of Et at q + D (3 N_S(q;D)). A base equal to an
// earlier one (same key: the same read) reuses its read: the same sum as three reads
// (mirror), at a third of the memory traffic in coherent areas. With the full distance (coarse levels, where Et is
// smooth at the pixel scale and candidates are scored at their nearest texel too) each
// prediction reads the nearest texel; the projected distance (finest level) reads Et
// bilinearly.
fn prediction_sum(n: Neighbours, j: vec4<i32>, d: vec2<i32>) -> Vec8 {
    let off = (params.spacing << COORD_FRAC) * d;
    let ka = prediction_key(prediction_base(n, j, d) + off);
    let kb = prediction_key(prediction_base(n, j, vec2<i32>(d.x, 0)) + off);
    let kc = prediction_key(prediction_base(n, j, vec2<i32>(0, d.y)) + off);
    let a = prediction_read(ka);
    var b = a;
    if (any(kb != ka)) {
        b = prediction_read(kb);
    }
    var c = a;
    if (all(kc == kb)) {
        c = b;
    } else if (any(kc != ka)) {
        c = prediction_read(kc);
    }
    return Vec8(a.lo + b.lo + c.lo, a.hi + b.hi + c.hi);
}

// What a prediction reads, as a key that equal reads share: the nearest texel with the
// full distance, the quarter pixel with QUARTER, the fixed-point position otherwise
// (pipeline constants, so each pipeline keeps one branch).
fn prediction_key(u: vec2<i32>) -> vec2<i32> {
    if (FULL_DISTANCE) {
        return nearest_texel(read_coord_fx(u));
    }
    if (QUARTER) {
        return table_position(read_coord_fx(u));
    }
    return u;
}

fn prediction_read(k: vec2<i32>) -> Vec8 {
    if (FULL_DISTANCE) {
        return et_texel(k);
    }
    return bilinear_et(k);
}

// With COHERENT_SKIP (advection frames): whether all 8 neighbours continue the pixel's
// patch, S[q + d] = S[q] + h J d within COHERENT_TOL (a quarter pixel) per axis. The
// correction would keep such a pixel or nudge it within the pixel (its own coordinate
// predicts its neighbourhood), so it is left as it is: its loads are saved (CPU drivers
// still run its SIMD group's arithmetic, masked).
const COHERENT_TOL: i32 = 64;

fn coherent_interior(n: Neighbours, j: vec4<i32>) -> bool {
    var ok = true;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let d = vec2<i32>(dx, dy);
            let e = coord_delta(neighbour(n, d) - n.zz - scaled_jd(params.spacing, j, d));
            ok = ok && all(abs(e) <= vec2<i32>(COHERENT_TOL));
        }
    }
    return ok;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = subpass_pixel(vec2<i32>(gid.xy));
    if (any(q < vec2<i32>(0))) {
        return;
    }
    let self_index = region_index(q);
    // Atlas synthesis leaves texels outside the charts to the fill pass.
    if (!in_chart(self_index - params.coord_base)) {
        return;
    }
    // The same inputs as when this class's previous subpass left the pixel unchanged.
    if (unchanged_since_last_look(q)) {
        return;
    }
    let j = jac_at(self_index);
    let h = params.step;
    let n = load_neighbours(q);
    if (COHERENT_SKIP && coherent_interior(n, j)) {
        return;
    }

    let p0 = prediction_sum(n, j, vec2<i32>(1, 1));
    let p1 = prediction_sum(n, j, vec2<i32>(1, -1));
    let p2 = prediction_sum(n, j, vec2<i32>(-1, 1));
    let p3 = prediction_sum(n, j, vec2<i32>(-1, -1));
    let s0l = p0.lo; let s0h = p0.hi;
    let s1l = p1.lo; let s1h = p1.hi;
    let s2l = p2.lo; let s2h = p2.hi;
    let s3l = p3.lo; let s3h = p3.hi;
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

    var best = n.zz;
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
    // With the full distance a candidate scores as its nearest texel does: one on the
    // best one's texel cannot beat it (unless it is coherent and the best is a
    // similarity-set candidate, which carries the coherence penalty), so its reads are
    // skipped. Under a turning flow the neighbours' predictions differ by sub-pixel
    // amounts and land on a few texels.
    var best_texel = nearest_texel(best);
    var best_from_set = false;
    let km1 = u32(K - 1);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let dd = vec2<i32>(dx, dy);
            let s = neighbour(n, dd);
            let hjd = scaled_jd(params.spacing, j, dd);
            let obase = params.off_base + ex_index(nearest_texel(s)) * km1;
            for (var i = 0; i < K; i++) {
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
                if (full && best_d != 0xffffffffu && all(nearest_texel(c) == best_texel)
                    && (i > 0 || !best_from_set)) {
                    continue;
                }
                var dist: u32;
                if (full) {
                    let n = nearest_texel(c);
                    dist = full_term(s0l, s0h, n + h) + full_term(s1l, s1h, n + vec2<i32>(h.x, -h.y))
                        + full_term(s2l, s2h, n + vec2<i32>(-h.x, h.y)) + full_term(s3l, s3h, n - h);
                } else {
                    // Similarity-set candidates at their nearest texel (see the mirror).
                    if (i > 0 && !KSET_INTERP) {
                        let t = nearest_texel(c);
                        if (FINE_TABLES) {
                            dist = projected_distance_to(ns_lo, ns_hi, unpack_vec8(qe[fine_index(t << vec2<u32>(QUARTER_BITS))]));
                        } else {
                            dist = projected_distance(ns_lo, ns_hi, t);
                        }
                    } else {
                        dist = projected_distance_at(ns_lo, ns_hi, c);
                    }
                }
                if (i > 0) {
                    dist += (dist >> 4u) * params.coherence;
                }
                if (dist < best_d) {
                    best_d = dist;
                    best = c;
                    best_texel = nearest_texel(c);
                    best_from_set = i > 0;
                }
            }
        }
    }
    coords[self_index] = best;
    if (any(best != n.zz)) {
        stamp_change(q);
    }
}
