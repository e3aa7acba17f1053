// Anisometric upsample (mirror: src/passes/upsample_aniso.rs):
// S_l[p] = S_{l-1}[floor(p/2)] + h_l J(p) (p mod 2), fixed point, absolute positions p;
// odd children average the predictions of their 2 or 4 parents when those agree.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let abs_p = params.origin + q;
    let t = u32(q.y * params.size.x + q.x);
    let i = params.coord_base + t;
    // Advection: only the pixels the distortion pass flagged are upsampled again.
    if ((params.flag_base | u32(opaque)) != 0u && coords[i].x != FLAGGED) {
        return;
    }
    var c = fit_coord(vec2<i32>(0));
    if ((params.parent_size.x | opaque) > 0) {
        let odd = abs_p & vec2<i32>(1);
        let j = jac_at(i);
        let base = fit_coord(parent_at(abs_p, vec2<i32>(0)) + scaled_jd(params.spacing, j, odd));
        c = base;
        // An odd child lies between two (or four) parents: average their predictions
        // when they agree within a pixel, so a sub-pixel misfit between parents (a
        // non-integrable field J) is spread over the children instead of becoming a
        // step. Predictions that differ by a pixel or more (a patch seam, and every
        // disagreement when J = I) keep the nearest parent's: isometric results stay
        // exact.
        if (any(odd != vec2<i32>(0))) {
            var sum = vec2<i32>(0);
            var agree = true;
            for (var k = 1; k < 4; k++) {
                let d = vec2<i32>(k & 1, k >> 1u);
                if (any(d > odd)) {
                    continue;
                }
                let pred = fit_coord(parent_at(abs_p, d) + scaled_jd(params.spacing, j, odd - 2 * d));
                agree = agree && same_patch(pred, base);
                sum += coord_delta(pred - base);
            }
            if (agree) {
                let shift = u32(odd.x + odd.y);
                c = fit_coord(base + ((sum + vec2<i32>(i32(1u << shift) >> 1u)) >> vec2<u32>(shift)));
            }
        }
    }
    coords[i] = c;
}

// The parent at block offset d (0 or 1 per axis) from the child's own.
fn parent_at(abs_p: vec2<i32>, d: vec2<i32>) -> vec2<i32> {
    let pp = clamp((abs_p >> vec2<u32>(1u)) + d - params.parent_origin, vec2<i32>(0), params.parent_size - vec2<i32>(1));
    return coords[params.parent_coord_base + u32(pp.y * params.parent_size.x + pp.x)];
}

