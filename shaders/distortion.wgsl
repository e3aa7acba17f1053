// Advection: flags the pixels whose advected coordinates no longer follow the desired
// Jacobian (mirror: src/passes/advect.rs). Per axis, the observed step to a neighbour
// (the better of the two sides, so patch seams do not count) is compared with h J e;
// a pixel is flagged when |J_obs - J|_F > c, i.e. the squared errors exceed
// params.distortion_max = (c h 256)^2. Flags go to coords[flag_base + t].x.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

// A coordinate difference, wrapped to the nearest representative for tileable
// exemplars and clamped so its square cannot overflow.
fn step_err(d: vec2<i32>) -> u32 {
    var e = d;
    if ((params.tileable | opaque) != 0) {
        let n = params.ex_size << vec2<u32>(params.coord_frac);
        e -= select(vec2<i32>(0), n, e > n / 2);
        e += select(vec2<i32>(0), n, e < -n / 2);
    }
    let c = vec2<u32>(abs(clamp(e, vec2<i32>(-16384), vec2<i32>(16384))));
    return c.x * c.x + c.y * c.y;
}

fn axis_err(q: vec2<i32>, s: vec2<i32>, e: vec2<i32>, expected: vec2<i32>) -> u32 {
    let fwd = coords[region_index(q + e)] - s - expected;
    let bwd = s - coords[region_index(q - e)] - expected;
    return min(step_err(fwd), step_err(bwd));
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
    var flag = 0;
    if (in_chart(t)) {
        let s = coords[i];
        let j = jac[i];
        let h = params.spacing;
        let ex = axis_err(q, s, vec2<i32>(1, 0), scaled_jd(h, j, vec2<i32>(1, 0)));
        let ey = axis_err(q, s, vec2<i32>(0, 1), scaled_jd(h, j, vec2<i32>(0, 1)));
        flag = select(0, 1, ex + ey > params.distortion_max);
    }
    coords[params.flag_base + t] = vec2<i32>(flag, 0);
}
