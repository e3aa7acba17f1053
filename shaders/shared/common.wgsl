// Shared by every pass; mirrored by src/passes/common.rs. All coordinate and distance
// arithmetic is integer so the CPU mirror produces the same bytes.

struct Params {
    ex_size: vec2<i32>,
    origin: vec2<i32>,
    size: vec2<i32>,
    parent_origin: vec2<i32>,
    parent_size: vec2<i32>,
    parity: vec2<i32>,
    // h_l modulo the exemplar size per axis when tileable, h_l otherwise.
    step: vec2<i32>,
    spacing: i32,
    tileable: i32,
    margin: i32,
    level: u32,
    seed: u32,
    jitter_amp: i32,
    k: i32,
    shift: u32,
    coherence: u32,
    et_base: u32,
    off_base: u32,
    proj_base: u32,
    coord_base: u32,
    parent_coord_base: u32,
    window_offset: vec2<i32>,
    window_size: vec2<i32>,
    full_distance: u32,
    // Fractional bits of the coordinates: 0 (isometric) or 8 (anisometric).
    coord_frac: u32,
    // 1: the region is one period of a tileable output and wraps around.
    periodic: u32,
    // Map gather: 1 for tangent-space normal maps.
    map_kind: u32,
    // Magnify pass: high-resolution exemplar size and factor.
    hi_size: vec2<i32>,
    magnify: u32,
    // Atlas synthesis: skip texels outside charts (mask bits from surface[mask_base]).
    masked: u32,
    mask_base: u32,
    // Fill pass: indirection entries of this level (4 words each from surface[fill_base]).
    fill_base: u32,
    fill_count: u32,
    // Advection (src/passes/advect.rs).
    flag_base: u32,
    window_origin: vec2<i32>,
    distortion_max: u32,
    steps: u32,
    // Anisometric gather: nearest exemplar texel instead of bilinear (advection).
    nearest: u32,
    // Advection: this frame's rounding offset for J V (src/passes/advect.rs).
    dither: u32,
    // Gathers: blend the neighbours' predicted colours across patch seams.
    seam_blend: u32,
    inset: i32,
    kset_interp: u32,
    quarter: u32,
    // Corrections: this subpass's stamp, and the stamps below which a pixel and its
    // neighbours count as unchanged since its class's previous subpass (0: none does).
    stamp: u32,
    clean_before: u32,
    // Anisometric correction (advection frames): leave pixels inside a coherent patch.
    coherent_skip: u32,
    drift: u32,
    // Advection frames' fade pass (src/passes/fade.rs).
    fade_src: u32,
    fade_dst: u32,
    fade_frames: u32,
    fade_mean: u32,
    fade_change: u32,
    // Advection's distortion pass: anchored renewals (distortion.wgsl).
    anchor: u32,
}

@group(0) @binding(0) var<uniform> params: Params;

// 0 at run time (the correction passes set it from global_invocation_id.z, always 0),
// but unknown to the compiler. Mixed into the uniforms that steer branches and loops:
// lavapipe otherwise specializes ("inlines") such uniforms and compiles a new variant of
// the shader for every new combination of values, i.e. for nearly every dispatch.
var<private> opaque: i32;

// Switches that stay fixed for a whole dispatch, as pipeline-overridable constants: one
// pipeline per combination, built on first use (crate::gpu::synth::Variant). A branch on
// them is compiled out. As uniforms they had to be mixed with `opaque`, which made the
// branch divergent for the compiler, and CPU drivers then ran both sides of it for every
// pixel. Each equals the PassParams field of the same name, which the CPU
// mirror reads.
override TILEABLE: bool = false;
override FULL_DISTANCE: bool = false;
override KSET_INTERP: bool = false;
override MASKED: bool = false;
override PERIODIC: bool = false;
// params.quarter (see correct_aniso.wgsl).
override QUARTER: bool = false;
// GPU only (no PassParams field): the et and qe bindings hold this level's 16x
// supersampled tables (quarter pixels, crate::gpu::synth::FineTables) instead of every
// level's tables. Set only with QUARTER, for the level the tables were built for.
override FINE_TABLES: bool = false;
// GPU only (no PassParams field): every Jacobian of the plan is the identity (an
// anisometric plan without a field: advection, `--field rotate:0`), so jac_at() returns
// the constant the jac binding holds anyway and the compiler folds the J arithmetic
// that follows it (phi(J^-1 D), h J d).
override IDENTITY_J: bool = false;
// params.nearest and params.seam_blend (the gathers). As uniforms mixed with `opaque`,
// both sides of each branch ran: the anisometric gather of an advection frame read four
// texels and the four neighbours it then ignored.
override NEAREST: bool = false;
override SEAM_BLEND: bool = false;
// params.k: the similarity-set size (1..=8), so that the candidate loop unrolls.
override K: i32 = 2;
// params.coherent_skip (see correct_aniso.wgsl).
override COHERENT_SKIP: bool = false;
// params.drift != 0: an advection frame's upsampling follows the drift's phase
// (upsample_aniso.wgsl); as a uniform branch it slowed every synthesis along a field.
override DRIFT: bool = false;
// params.fade_frames > 1 (fade.wgsl): one-frame fades keep no ghost, so their pass
// neither reads nor writes one.
override LONG_FADE: bool = false;
// Synthesized exemplar coordinates of every level's region, concatenated.
@group(0) @binding(1) var<storage, read_write> coords: array<vec2<i32>>;
// Quantized transformed exemplar Et_l: 8 x i16 per pixel, all levels.
@group(0) @binding(2) var<storage, read> et: array<vec4<u32>>;
// Exemplar side of the distance, 3 P N_E >> shift: 8 x i16 per pixel, all levels.
@group(0) @binding(3) var<storage, read> qe: array<vec4<u32>>;
// k-coherence offsets: (k-1) x (i16 x, i16 y) per pixel, all levels.
@group(0) @binding(4) var<storage, read> offsets: array<u32>;
// Quantized projection P_l, 64 x vec4<i32> per level: per diagonal block j (8x8), per
// column c, rows 0-3 then rows 4-7.
// A uniform (bound at this level's offset), not storage: every invocation reads the
// same 64 vectors, and CPU drivers load storage per invocation but uniforms once.
@group(0) @binding(5) var<uniform> proj: array<vec4<i32>, 64>;
// Exemplar colours, RGBA8.
@group(0) @binding(6) var<storage, read> colors: array<u32>;
@group(0) @binding(7) var out_color: texture_storage_2d<rgba8unorm, write>;
// Anisometric passes: quantized Jacobian per region pixel (row-major a, b, c, d in
// 1/1024), in the layout of `coords`. A 16-byte placeholder for isometric synthesis.
@group(0) @binding(8) var<storage, read> jac: array<vec4<i32>>;
// The Jacobian of region entry i (the anisometric passes): jac[i], or with IDENTITY_J
// the identity it holds (1024 = 1).
fn jac_at(i: u32) -> vec4<i32> {
    if (IDENTITY_J) {
        return vec4<i32>(1024, 0, 0, 1024);
    }
    return jac[i];
}

// Atlas synthesis (src/passes/fill.rs): per level, the chart mask (one bit per region
// texel) and the indirection entries. A 16-byte placeholder otherwise.
@group(0) @binding(9) var<storage, read> surface: array<u32>;

// Advection: velocity per output-window pixel, in 1/16 pixel per frame (vec2<i32>).
// A placeholder otherwise.
@group(0) @binding(10) var<storage, read> velocity: array<vec2<i32>>;

// Whether region texel t (index within the level) lies inside a chart; always true
// outside atlas synthesis.
fn in_chart(t: u32) -> bool {
    if (!MASKED) {
        return true;
    }
    return ((surface[params.mask_base + (t >> 5u)] >> (t & 31u)) & 1u) != 0u;
}

// Same as crate::analysis::QE_MAX.
const QE_MAX: i32 = 4095;

fn hash32(v: u32) -> u32 {
    var x = v;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn hash_pixel(p: vec2<i32>, level: u32, seed: u32) -> vec2<u32> {
    var h = hash32(seed ^ hash32(level + 0x9e3779b9u));
    h = hash32(h ^ bitcast<u32>(p.x));
    let hx = hash32(h ^ (bitcast<u32>(p.y) * 0x2c1b3c6du));
    let hy = hash32(hx ^ 0x68e31da4u);
    return vec2<u32>(hx, hy);
}

// c mod n in [0, n) (n > 0). Integer division is scalarized by CPU Vulkan drivers, so
// the quotient comes from a float division and is corrected by one step each way: the
// float quotient is off by less than 1 for |c| < 2^30, and the remainder is exact
// integer arithmetic, hence the same value as the CPU mirror's `rem_euclid`.
fn wrap(c: i32, n: i32) -> i32 {
    let q = i32(floor(f32(c) / f32(n)));
    var r = c - q * n;
    r += select(0, n, r < 0);
    r -= select(0, n, r >= n);
    return r;
}

// Rounded-to-nearest mean of the gathers' colour sums: (x + w / 2) / w (x up to 7 * 255,
// weights w of 3..7). CPU Vulkan drivers scalarize integer division (4 per output pixel
// here), so the quotient comes from a float division and is corrected by one step each
// way, as in wrap(): the same integer quotient as the CPU mirror's, however the device
// rounds the float division.
fn mean_rounded(x: vec4<u32>, w: u32) -> vec4<u32> {
    let n = vec4<i32>(x + vec4<u32>(w >> 1u));
    let d = i32(w);
    var q = vec4<i32>(floor(vec4<f32>(n) / f32(d)));
    let r = n - q * d;
    q += select(vec4<i32>(0), vec4<i32>(1), r >= vec4<i32>(d));
    q -= select(vec4<i32>(0), vec4<i32>(1), r < vec4<i32>(0));
    return vec4<u32>(q);
}

// In units of 2^-coord_frac exemplar pixels.
fn fit_coord(c: vec2<i32>) -> vec2<i32> {
    let f = vec2<u32>(params.coord_frac);
    if (TILEABLE) {
        let n = params.ex_size << f;
        return vec2<i32>(wrap(c.x, n.x), wrap(c.y, n.y));
    }
    return clamp(c, vec2<i32>(params.margin) << f, (params.ex_size - vec2<i32>(1 + params.margin)) << f);
}

// wrap() for c in [-2n, 3n) without integer division, which CPU Vulkan drivers
// scalarize; the correction's coordinates always stay in that range.
fn wrap_near(c: vec2<i32>) -> vec2<i32> {
    let n = params.ex_size;
    let z = vec2<i32>(0);
    var v = c;
    v += select(z, n, v < z);
    v += select(z, n, v < z);
    v -= select(z, n, v >= n);
    v -= select(z, n, v >= n);
    return v;
}

fn fit_near(c: vec2<i32>) -> vec2<i32> {
    if (TILEABLE) {
        return wrap_near(c);
    }
    return fit_coord(c);
}

fn read_coord(c: vec2<i32>) -> vec2<i32> {
    if (TILEABLE) {
        return wrap_near(c);
    }
    return clamp(c, vec2<i32>(0), params.ex_size - vec2<i32>(1));
}

fn is_valid(c: vec2<i32>) -> bool {
    if (TILEABLE) {
        return true;
    }
    let m = params.margin | opaque;
    let hi = (params.ex_size | vec2<i32>(opaque)) - vec2<i32>(1 + m);
    return all(c >= vec2<i32>(m)) && all(c <= hi);
}


// Index into `coords` of region pixel q (clamped into the region).
// Periodic output (params.periodic != 0): the region is one period and wraps around
// (neighbours are at most one pixel outside).
fn region_index(q: vec2<i32>) -> u32 {
    var c: vec2<i32>;
    if (PERIODIC) {
        let n = params.size;
        c = q + select(vec2<i32>(0), n, q < vec2<i32>(0));
        c = c - select(vec2<i32>(0), n, c >= n);
    } else {
        c = clamp(q, vec2<i32>(0), params.size - vec2<i32>(1));
    }
    return params.coord_base + u32(c.y * params.size.x + c.x);
}

// Change stamps of the corrections (crate::passes::plan::SynthPlan::schedule_with),
// one per region pixel after every level's coordinates (params.flag_base): whether
// region pixel q and its 8 neighbours are as they were when its class's previous
// subpass left it unchanged (then this one would leave it too).
fn unchanged_since_last_look(q: vec2<i32>) -> bool {
    let clean_before = params.clean_before | u32(opaque);
    // Not even the read in subpasses that skip nothing.
    if (clean_before == 0u) {
        return false;
    }
    let stamp = coords[params.flag_base + region_index(q) - params.coord_base].x;
    return u32(stamp) < clean_before;
}

// After region pixel q changed: stamps it and its 8 neighbours (several pixels may
// stamp the same one, all with the same value). Nothing without a stamp (dispatches
// not from SynthPlan::schedule_with, advection frames).
fn stamp_change(q: vec2<i32>) {
    if ((params.stamp | u32(opaque)) == 0u) {
        return;
    }
    let s = vec2<i32>(i32(params.stamp), 0);
    let base = params.flag_base - params.coord_base;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            coords[base + region_index(q + vec2<i32>(dx, dy))] = s;
        }
    }
}

// The coordinates of a pixel's 3x3 neighbourhood, loaded once per correction: every
// storage read costs CPU drivers a loop over the SIMD lanes, and the predictions and the
// candidates read the same nine pixels (names: x then y, m = -1, z = 0, p = +1).
struct Neighbours {
    mm: vec2<i32>, zm: vec2<i32>, pm: vec2<i32>,
    mz: vec2<i32>, zz: vec2<i32>, pz: vec2<i32>,
    mp: vec2<i32>, zp: vec2<i32>, pp: vec2<i32>,
}

fn load_neighbours(q: vec2<i32>) -> Neighbours {
    return Neighbours(
        coords[region_index(q + vec2<i32>(-1, -1))],
        coords[region_index(q + vec2<i32>(0, -1))],
        coords[region_index(q + vec2<i32>(1, -1))],
        coords[region_index(q + vec2<i32>(-1, 0))],
        coords[region_index(q)],
        coords[region_index(q + vec2<i32>(1, 0))],
        coords[region_index(q + vec2<i32>(-1, 1))],
        coords[region_index(q + vec2<i32>(0, 1))],
        coords[region_index(q + vec2<i32>(1, 1))],
    );
}

// The neighbour at offset d (components in -1..=1): selects, no memory access.
fn neighbour(n: Neighbours, d: vec2<i32>) -> vec2<i32> {
    let m = select(select(n.mz, n.pz, d.x > 0), n.zz, d.x == 0);
    let lo = select(select(n.mm, n.pm, d.x > 0), n.zm, d.x == 0);
    let hi = select(select(n.mp, n.pp, d.x > 0), n.zp, d.x == 0);
    return select(select(lo, hi, d.y > 0), m, d.y == 0);
}

fn ex_index(c: vec2<i32>) -> u32 {
    return u32(c.y * params.ex_size.x + c.x);
}

// Gathers: the index in `coords` of output-window pixel p (finest level), or -1 outside
// the window.
fn window_coord_index(p: vec2<i32>) -> i32 {
    if (any(p >= (params.window_size | vec2<i32>(opaque)))) {
        return -1;
    }
    let q = p + params.window_offset;
    return i32(params.coord_base) + q.y * params.size.x + q.x;
}

fn lo16(w: u32) -> i32 {
    return bitcast<i32>(w << 16u) >> 16u;
}

fn hi16(w: u32) -> i32 {
    return bitcast<i32>(w) >> 16u;
}

// 8 packed i16 as two vec4<i32>.
fn unpack8(v: vec4<u32>, out_lo: ptr<function, vec4<i32>>, out_hi: ptr<function, vec4<i32>>) {
    *out_lo = vec4<i32>(lo16(v.x), hi16(v.x), lo16(v.y), hi16(v.y));
    *out_hi = vec4<i32>(lo16(v.z), hi16(v.z), lo16(v.w), hi16(v.w));
}

// Correction subpasses: along each axis a pixel's class is its absolute parity, except
// that a periodic region of odd size >= 3 puts its last pixel in class 2 (it neighbours
// pixel 0 across the wrap, which has the same parity). One subpass updates one class
// pair, so no two updated pixels are neighbours. Returns the region coordinate this
// invocation updates along one axis, or -1.
fn subpass_axis(cls: i32, origin: i32, size: i32, g: i32) -> i32 {
    let odd_wrap = PERIODIC && (size & 1) == 1 && size >= 3;
    if (cls == 2) {
        return select(-1, size - 1, g == 0);
    }
    let inset = params.inset;
    let v = inset + ((cls - origin - inset) & 1) + 2 * g;
    if (v >= size - inset || (odd_wrap && v == size - 1)) {
        return -1;
    }
    return v;
}

fn subpass_pixel(g: vec2<i32>) -> vec2<i32> {
    let parity = params.parity | vec2<i32>(opaque);
    let size = params.size | vec2<i32>(opaque);
    return vec2<i32>(
        subpass_axis(parity.x, params.origin.x, size.x, g.x),
        subpass_axis(parity.y, params.origin.y, size.y, g.y),
    );
}
