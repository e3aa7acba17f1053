// Offscreen preview of a textured mesh (src/surface/render.rs): one draw per view, with a
// depth buffer and Lambert shading (key directional light + ambient) computed on the
// sRGB-encoded colour values, so a texel lit at full strength shows its stored byte.
//
// The atlas is addressed with the mesh's TEXCOORD_0 (glTF: [0, 1], v down, texel (i, j)
// centred at ((i + 0.5) / w, (j + 0.5) / h)). Two modes:
// * mode 0 (colour): `tex` is the colour atlas (mipmapped), sampled with `samp`
//   (bilinear, trilinear between mips, clamped to the edge);
// * mode 1 (magnified, Lefebvre & Hoppe 2006 §5): `coords` holds per atlas texel q the synthesized
//   position S[q] in low-resolution exemplar pixels, `jac` the Jacobian J[q]
//   ([j00, j01, j10, j11], column 0 = d(exemplar)/d(atlas x)), and `tex` the
//   high-resolution exemplar, `factor` times larger (mipmapped, `samp` repeats it). At
//   atlas position x (texels, centres at i + 0.5) the colour blends the 4 nearest texels
//   q with bilinear weights: sum_q w_q * E_H(factor * (S[q] + J[q] (x - centre(q)))),
//   E_H sampled bilinearly in continuous high-resolution pixels (texel k covers
//   [k, k + 1)), wrapping around. Mip levels come from the explicit gradient
//   factor * J[q] * dx/dscreen, so minified views do not alias.

struct Params {
    // 0: colour atlas, 1: magnified.
    mode: u32,
    factor: f32,
    // Size of the atlas in texels (the colour atlas, or `coords` / `jac`).
    atlas_size: vec2<f32>,
    // Size of the high-resolution exemplar in pixels (mode 1).
    hi_size: vec2<f32>,
    _pad: vec2<f32>,
}

struct View {
    view_proj: mat4x4<f32>,
    // World to view space (rigid: rotation + translation).
    view: mat4x4<f32>,
    // xyz: unit direction towards the key light in view space; w: ambient term.
    light: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var tex: texture_2d<f32>;
@group(0) @binding(2) var samp: sampler;
@group(0) @binding(3) var coords: texture_2d<f32>;
@group(0) @binding(4) var jac: texture_2d<f32>;
@group(1) @binding(0) var<uniform> view: View;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) view_pos: vec3<f32>,
    @location(1) view_normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.view_pos = (view.view * vec4<f32>(v.position, 1.0)).xyz;
    out.view_normal = (view.view * vec4<f32>(v.normal, 0.0)).xyz;
    out.uv = v.uv;
    return out;
}

// The magnified colour at continuous atlas position x, with screen derivatives gx, gy of x.
fn magnified(x: vec2<f32>, gx: vec2<f32>, gy: vec2<f32>) -> vec4<f32> {
    let size = vec2<i32>(textureDimensions(coords));
    let t = x - vec2<f32>(0.5);
    let base = floor(t);
    let f = t - base;
    let q0 = vec2<i32>(base);
    var acc = vec4<f32>(0.0);
    for (var d = 0; d < 4; d++) {
        let dq = vec2<i32>(d & 1, d >> 1u);
        // Outside the atlas, extrapolate from the nearest edge texel.
        let q = clamp(q0 + dq, vec2<i32>(0), size - vec2<i32>(1));
        let s = textureLoad(coords, q, 0).xy;
        let j = textureLoad(jac, q, 0);
        // Columns (j00, j10) and (j01, j11): jm * v = (j00 v.x + j01 v.y, j10 v.x + j11 v.y).
        let jm = mat2x2<f32>(j.xz, j.yw);
        let p = params.factor * (s + jm * (x - (vec2<f32>(q) + vec2<f32>(0.5))));
        let w = select(1.0 - f.x, f.x, dq.x == 1) * select(1.0 - f.y, f.y, dq.y == 1);
        let to_uv = params.factor / params.hi_size;
        // fract keeps precision for far-away coordinates; the sampler repeats anyway.
        let uv = fract(p / params.hi_size);
        acc += w * textureSampleGrad(tex, samp, uv, to_uv * (jm * gx), to_uv * (jm * gy));
    }
    return acc;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // Derivatives in uniform control flow, before any branch.
    let duv_dx = dpdx(in.uv);
    let duv_dy = dpdy(in.uv);
    var albedo: vec4<f32>;
    if (params.mode == 0u) {
        albedo = textureSampleGrad(tex, samp, in.uv, duv_dx, duv_dy);
    } else {
        let x = in.uv * params.atlas_size;
        albedo = magnified(x, duv_dx * params.atlas_size, duv_dy * params.atlas_size);
    }

    // Two-sided lighting: turn the normal towards the viewer (the eye is at the origin).
    var n = in.view_normal;
    let len = length(n);
    n = select(vec3<f32>(0.0, 0.0, 1.0), n / len, len > 1e-12);
    if (dot(n, -in.view_pos) < 0.0) {
        n = -n;
    }
    let ambient = view.light.w;
    let shade = ambient + (1.0 - ambient) * max(dot(n, view.light.xyz), 0.0);
    return vec4<f32>(albedo.rgb * shade, 1.0);
}
