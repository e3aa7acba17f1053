// Anisometric gather (mirror: src/passes/gather_aniso.rs): the exemplar colour
// bilinearly interpolated at the finest level's continuous coordinate, integer weights.
// Seam blending as in gather.wgsl: a 4-neighbour n whose prediction S[n] - h J (n - p)
// is 3/4 pixel or more from the pixel's coordinate (a patch seam, not the sub-pixel
// misfit of a varying field) adds its predicted colour at a third of the pixel's weight.
#include "shared/common.wgsl"
#include "shared/aniso.wgsl"
#include "shared/exemplar_color.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    let wi = window_coord_index(p);
    if (wi < 0) {
        return;
    }
    let q = p + params.window_offset;
    let i = u32(wi);
    let c = coords[i];
    var v = color_at(c);
    if (SEAM_BLEND) {
        let j = jac_at(i);
        var sum = 3 * v;
        var weight = 3;
        for (var k = 0; k < 4; k++) {
            // (1, 0), (-1, 0), (0, 1), (0, -1)
            let d = select(vec2<i32>(1 - 2 * (k & 1), 0), vec2<i32>(0, 1 - 2 * (k & 1)), k >= 2);
            let pred = coords[region_index(q + d)] - scaled_jd(params.spacing, j, d);
            if (!same_patch(pred, c)) {
                sum += color_at(pred);
                weight += 1;
            }
        }
        // Rounded to nearest; weight is 3..7.
        v = vec4<i32>(mean_rounded(vec4<u32>(sum), u32(weight)));
    }
    textureStore(out_color, p, vec4<f32>(v) / 255.0);
}
