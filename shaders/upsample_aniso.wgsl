// Anisometric upsample (mirror: src/passes/upsample_aniso.rs):
// S_l[p] = S_{l-1}[floor(p/2)] + h_l J(p) (p mod 2), fixed point, absolute positions p.
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
    if ((params.flag_base | u32(opaque)) != 0u && coords[params.flag_base + t].x == 0) {
        return;
    }
    var c = vec2<i32>(0);
    if ((params.parent_size.x | opaque) > 0) {
        let pp = clamp((abs_p >> vec2<u32>(1u)) - params.parent_origin, vec2<i32>(0), params.parent_size - vec2<i32>(1));
        let parent = coords[params.parent_coord_base + u32(pp.y * params.parent_size.x + pp.x)];
        c = parent + scaled_jd(params.spacing, jac[i], abs_p & vec2<i32>(1));
    }
    coords[i] = fit_coord(c);
}
