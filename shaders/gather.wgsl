// Gather (mirror: src/passes/gather.rs): output colour = exemplar at the finest level's
// synthesized coordinate, for the output window. With seam blending, each 4-neighbour
// whose coordinate does not continue the pixel's (a patch seam) adds its prediction
// E[S[n] - (n - p)] at a third of the pixel's own weight: seams soften, coherent pixels
// stay exact copies.
#include "shared/common.wgsl"

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    opaque = i32(gid.z);
    let p = vec2<i32>(gid.xy);
    let wi = window_coord_index(p);
    if (wi < 0) {
        return;
    }
    let q = p + params.window_offset;
    let c = coords[wi];
    let own = colors[ex_index(c)];
    if (!SEAM_BLEND) {
        textureStore(out_color, p, unpack4x8unorm(own));
        return;
    }
    var sum = 3u * unpack_rgba(own);
    var weight = 3u;
    for (var k = 0; k < 4; k++) {
        // (1, 0), (-1, 0), (0, 1), (0, -1)
        let d = select(vec2<i32>(1 - 2 * (k & 1), 0), vec2<i32>(0, 1 - 2 * (k & 1)), k >= 2);
        let pred = read_coord(coords[region_index(q + d)] - d);
        if (any(pred != c)) {
            sum += unpack_rgba(colors[ex_index(pred)]);
            weight += 1u;
        }
    }
    // Rounded to nearest; weight is 3..7.
    let v = mean_rounded(sum, weight);
    textureStore(out_color, p, vec4<f32>(v) / 255.0);
}

fn unpack_rgba(w: u32) -> vec4<u32> {
    return vec4<u32>(w & 255u, (w >> 8u) & 255u, (w >> 16u) & 255u, w >> 24u);
}
