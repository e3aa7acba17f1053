// Anisometric upsample (mirror: src/passes/upsample_aniso.rs):
// S_l[p] = S_{l-1}[floor(p/2)] + h_l J(p) (p mod 2), fixed point, absolute positions p;
// odd children average the predictions of their 2 or 4 parents when those agree
// (upsample_at in shared/aniso.wgsl, which the distortion pass shares).
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let q = vec2<i32>(gid.xy);
    if (any(q >= (params.size | vec2<i32>(opaque)))) {
        return;
    }
    let i = params.coord_base + u32(q.y * params.size.x + q.x);
    if (!DRIFT) {
        coords[i] = upsample_at(params.origin + q, i);
        return;
    }
    // Advection frames, the levels a frame upsamples: as the pixel at q - f, plus h J f,
    // with f the phase of the drift's whole level pixels (see upsample_aniso.rs, run).
    let f = (coords[params.drift + 1u] >> vec2<u32>(params.steps)) & vec2<i32>(1);
    let c = upsample_at(params.origin + q - f, i);
    coords[i] = fit_coord(c + scaled_jd(params.spacing, jac_at(i), f));
}
