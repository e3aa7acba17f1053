// Neighbourhood distances shared by the correction passes (mirror: the distance
// functions of src/passes/correct.rs).

fn et_at(c: vec2<i32>, lo: ptr<function, vec4<i32>>, hi: ptr<function, vec4<i32>>) {
    unpack8(et[params.et_base + ex_index(c)], lo, hi);
}

// Projected (8D) distance between the synthesized neighbourhood (ns_lo, ns_hi) and
// the exemplar side of candidate c; differences clamped so 8 squares (times the
// coherence bias) fit in a u32.
fn projected_distance(ns_lo: vec4<i32>, ns_hi: vec4<i32>, c: vec2<i32>) -> u32 {
    var e_lo: vec4<i32>;
    var e_hi: vec4<i32>;
    unpack8(qe[params.et_base + ex_index(c)], &e_lo, &e_hi);
    let m = vec4<i32>(2 * QE_MAX);
    let a = vec4<u32>(clamp(ns_lo - e_lo, -m, m));
    let b = vec4<u32>(clamp(ns_hi - e_hi, -m, m));
    let sq = a * a + b * b;
    return sq.x + sq.y + sq.z + sq.w;
}

// One diagonal's share of the full (32D) distance: prediction sums against
// 3 Et[c + h D], differences shifted right by 2 so 32 squares fit in a u32.
fn full_term(s_lo: vec4<i32>, s_hi: vec4<i32>, u: vec2<i32>) -> u32 {
    var lo: vec4<i32>;
    var hi: vec4<i32>;
    et_at(read_coord(u), &lo, &hi);
    let a = vec4<u32>((s_lo - 3 * lo) >> vec4<u32>(2u));
    let b = vec4<u32>((s_hi - 3 * hi) >> vec4<u32>(2u));
    let sq = a * a + b * b;
    return sq.x + sq.y + sq.z + sq.w;
}

// Adds P_j * sum to the accumulator. P is stored per diagonal block j as 8 columns of
// two vec4 (rows 0-3, rows 4-7), so the product is 16 vector multiply-adds.
fn project_add(j: u32, sum_lo: vec4<i32>, sum_hi: vec4<i32>, acc_lo: ptr<function, vec4<i32>>, acc_hi: ptr<function, vec4<i32>>) {
    let b = 16u * j;
    *acc_lo += proj[b + 0u] * sum_lo.x + proj[b + 2u] * sum_lo.y + proj[b + 4u] * sum_lo.z + proj[b + 6u] * sum_lo.w
        + proj[b + 8u] * sum_hi.x + proj[b + 10u] * sum_hi.y + proj[b + 12u] * sum_hi.z + proj[b + 14u] * sum_hi.w;
    *acc_hi += proj[b + 1u] * sum_lo.x + proj[b + 3u] * sum_lo.y + proj[b + 5u] * sum_lo.z + proj[b + 7u] * sum_lo.w
        + proj[b + 9u] * sum_hi.x + proj[b + 11u] * sum_hi.y + proj[b + 13u] * sum_hi.z + proj[b + 15u] * sum_hi.w;
}

