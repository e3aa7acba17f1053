// Advection: flags the pixels whose advected coordinates no longer follow the desired
// Jacobian (mirror: src/passes/distortion.rs). Per axis, the observed step to a neighbour
// (the better of the two sides, so a patch seam on one side does not count) is compared
// with h J e; an axis whose better side is still off by a whole pixel step or more lies
// between two seams (a thin strip of its own patch, e.g. a line of mortar) and counts
// 0: flow distortion grows a fraction of a pixel per frame and is caught below that,
// while re-upsampling such strips every frame broke them apart. A pixel is flagged
// when |J_obs - J|_F > c, i.e. the squared errors exceed params.distortion_max =
// (c h 256)^2, and also when both of its axes lie between two seams: a pixel that
// continues no neighbour on either axis belongs to no patch, and left alone such pixels
// spread under a turning flow. The correction then settles them on the exemplar's
// flattest content (the best match for an incoherent neighbourhood), and the texture
// blurs. params.distortion_max = 0xffffffff flags
// nothing (level 0, the pyramid's coarsest, which has nothing to upsample from).
// Reads the advected coordinates from the scratch region (flag_base) and writes them
// back to the level, flagged pixels upsampled again from the coarser level
// (upsample_at, shared with upsample_aniso.wgsl; it reads only the coarser level) or,
// with anchored renewals, continued from an anchor (renewal(), below).
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

// A coordinate difference, wrapped to the nearest representative for tileable
// exemplars and clamped so its square cannot overflow.
fn step_err(d: vec2<i32>) -> u32 {
    var e = d;
    if (TILEABLE) {
        let n = params.ex_size << vec2<u32>(params.coord_frac);
        e -= select(vec2<i32>(0), n, e > n / 2);
        e += select(vec2<i32>(0), n, e < -n / 2);
    }
    let c = vec2<u32>(abs(clamp(e, vec2<i32>(-16384), vec2<i32>(16384))));
    return c.x * c.x + c.y * c.y;
}

// The advected coordinate of region pixel q (clamped), in the scratch region.
fn advected(q: vec2<i32>) -> vec2<i32> {
    return coords[params.flag_base + region_index(q) - params.coord_base];
}

// (h 256)^2, the squared error of a whole pixel step at spacing h (h capped: step_err
// is below 2^30 anyway).
fn seam_step(h: i32) -> u32 {
    let hc = min(h, 128);
    return u32(hc * hc) << 16u;
}

// axis_err's value for an axis with a seam on both sides (step errors stay below 2^30).
const BETWEEN_SEAMS: u32 = 0xffffffffu;

fn axis_err(q: vec2<i32>, s: vec2<i32>, e: vec2<i32>, expected: vec2<i32>) -> u32 {
    let fwd = advected(q + e) - s - expected;
    let bwd = s - advected(q - e) - expected;
    let err = min(step_err(fwd), step_err(bwd));
    return select(err, BETWEEN_SEAMS, err > seam_step(params.spacing));
}

// Where a flagged pixel's new coordinate comes from. By default (params.anchor = 0, the
// paper's scheme) it is upsampled again from the coarser level, which brings content
// unrelated to what the pixel showed: under a turning flow a renewed patch pops. With
// anchored renewals (AdvectOptions::anchor_spacing) it continues one of the four anchors
// around it, the pixels of a grid of spacing B (low byte of params.anchor), along the
// desired Jacobian: advected(a) + h J (q - a). The pixel then shows nearly what it
// showed (off by the distortion times its distance to the anchor), but follows J again.
// Of the four anchors the one whose continuation lands nearest the pixel's own advected
// coordinate wins (the anchor on its side of a patch seam); if even that one is off by a
// whole pixel step or more (no anchor in the same patch) the pixel is upsampled. Only
// anchors in the chart with the pixel's own desired Jacobian count: along a varying field
// the flowing content must be turned back all the time, and continuing anchors there
// popped more than upsampling. A share
// of the renewals (params.anchor >> 8, of 256; decided per anchor block and the content
// it shows) is upsampled anyway: only anchored renewals never bring back the coarse
// levels' large structures, which then break up at the block edges over hundreds of
// frames (a marble's veins).
fn renewal(q: vec2<i32>, i: u32, s: vec2<i32>) -> vec2<i32> {
    let b = i32((params.anchor | u32(opaque)) & 255u);
    if (b == 0) {
        return upsample_at(params.origin + q, i);
    }
    let own = min(q / b * b + b / 2, params.size - 1);
    let key = vec2<u32>(advected(own) >> vec2<u32>(10u));
    if ((hash32((key.x * 73856093u) ^ (key.y * 19349663u)) & 255u) < (params.anchor >> 8u)) {
        return upsample_at(params.origin + q, i);
    }
    let j = jac_at(i);
    // The anchors' grid cell that holds q: anchors k0 * b + b / 2 and the next ones
    // (k0 by floor division: q - b / 2 may be negative).
    let k0 = (q - b / 2 + 64 * b) / b - 64;
    // The first nearest continuation, within a whole pixel step.
    var best = seam_step(params.spacing) + 1u;
    var pick = vec2<i32>(0);
    var found = false;
    for (var k = 0; k < 4; k++) {
        // Anchors outside the region do not count (clamped onto its edge, an edge pixel
        // would continue itself and never be renewed).
        let a = (k0 + vec2<i32>(k & 1, k >> 1u)) * b + b / 2;
        if (any(a < vec2<i32>(0)) || any(a >= params.size)) {
            continue;
        }
        let ta = u32(a.y * params.size.x + a.x);
        if (!in_chart(ta) || any(jac_at(params.coord_base + ta) != j)) {
            continue;
        }
        let c = fit_coord(advected(a) + scaled_jd(params.spacing, j, q - a));
        let e = step_err(c - s);
        if (e < best) {
            best = e;
            pick = c;
            found = true;
        }
    }
    if (!found) {
        return upsample_at(params.origin + q, i);
    }
    return pick;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let t = u32(q.y * params.size.x + q.x);
    let i = params.coord_base + t;
    let s = coords[params.flag_base + t];
    var flag = false;
    if (in_chart(t)) {
        let j = jac_at(i);
        let h = params.spacing;
        let ex = axis_err(q, s, vec2<i32>(1, 0), scaled_jd(h, j, vec2<i32>(1, 0)));
        let ey = axis_err(q, s, vec2<i32>(0, 1), scaled_jd(h, j, vec2<i32>(0, 1)));
        let isolated = ex == BETWEEN_SEAMS && ey == BETWEEN_SEAMS;
        let err = select(ex, 0u, ex == BETWEEN_SEAMS) + select(ey, 0u, ey == BETWEEN_SEAMS);
        flag = params.distortion_max != 0xffffffffu && (isolated || err > params.distortion_max);
    }
    if (flag) {
        coords[i] = renewal(q, i, s);
    } else {
        coords[i] = s;
    }
}
