// Fixed-point helpers of the anisometric passes (mirror: the anisometric section of
// src/passes/common.rs). Coordinates in 1/256 exemplar pixel, Jacobians in 1/1024.

const COORD_FRAC: u32 = 8u;

// h * J * d in coordinate units, rounded (exact 256 h d when J = I).
fn scaled_jd(h: i32, j: vec4<i32>, d: vec2<i32>) -> vec2<i32> {
    let v = vec2<i32>(j.x * d.x + j.y * d.y, j.z * d.x + j.w * d.y);
    return (h * v + vec2<i32>(2)) >> vec2<u32>(2u);
}

// phi(J^-1 d): the immediate neighbour in the direction of sign(det J) adj(J) d.
fn phi_inv(j: vec4<i32>, d: vec2<i32>) -> vec2<i32> {
    let det = j.x * j.w - j.y * j.z;
    var v = vec2<i32>(j.w * d.x - j.y * d.y, j.x * d.y - j.z * d.x);
    if (det < 0) {
        v = -v;
    }
    let a = abs(v);
    let sq = a * a;
    return select(vec2<i32>(0), sign(v), 3 * sq >= sq.yx);
}

// A difference of two fitted coordinates, the shortest way around a tileable exemplar.
fn coord_delta(d: vec2<i32>) -> vec2<i32> {
    var e = d;
    if (TILEABLE) {
        let n = params.ex_size << vec2<u32>(COORD_FRAC);
        e -= select(vec2<i32>(0), n, e > (n >> vec2<u32>(1u)));
        e += select(vec2<i32>(0), n, e < -(n >> vec2<u32>(1u)));
    }
    return e;
}

// Whether two fitted coordinates are less than 3/4 pixel apart on both axes: the same
// patch, up to the sub-pixel misfit a field that is not a gradient leaves.
fn same_patch(a: vec2<i32>, b: vec2<i32>) -> bool {
    return all(abs(coord_delta(a - b)) < vec2<i32>(3 << (COORD_FRAC - 2u)));
}

fn read_coord_fx(c: vec2<i32>) -> vec2<i32> {
    let n = params.ex_size << vec2<u32>(COORD_FRAC);
    if (TILEABLE) {
        return vec2<i32>(wrap(c.x, n.x), wrap(c.y, n.y));
    }
    return clamp(c, vec2<i32>(0), n - vec2<i32>(1 << COORD_FRAC));
}

fn is_valid_fx(c: vec2<i32>) -> bool {
    if (TILEABLE) {
        return true;
    }
    let m = params.margin | opaque;
    let lo = vec2<i32>(m << COORD_FRAC);
    let hi = ((params.ex_size | vec2<i32>(opaque)) - vec2<i32>(1 + m)) << vec2<u32>(COORD_FRAC);
    return all(c >= lo) && all(c <= hi);
}

fn nearest_texel(c: vec2<i32>) -> vec2<i32> {
    let r = (c + vec2<i32>(1 << (COORD_FRAC - 1u))) >> vec2<u32>(COORD_FRAC);
    if (TILEABLE) {
        return select(r, r - params.ex_size, r >= params.ex_size);
    }
    return min(r, params.ex_size - vec2<i32>(1));
}

// Quarter pixels per pixel, as a shift, of the supersampled tables (params.quarter).
const QUARTER_BITS: u32 = 2u;

// The quarter pixel nearest to a wrapped/clamped position, in quarter pixels (wrapped
// for tileable exemplars; a clamped position stays within the last pixel).
fn quarter_texel(c: vec2<i32>) -> vec2<i32> {
    let sh = COORD_FRAC - QUARTER_BITS;
    let r = (c + vec2<i32>(1 << (sh - 1u))) >> vec2<u32>(sh);
    if (TILEABLE) {
        let n = params.ex_size << vec2<u32>(QUARTER_BITS);
        return select(r, r - n, r >= n);
    }
    return r;
}

// Bilinear taps of a wrapped/clamped position: the two texel corners and the fractions
// (0..255). Returned by value: CPU drivers put locals written through pointers into
// scratch memory, which they allocate and clear on every dispatch.
struct Taps {
    i0: vec2<i32>,
    i1: vec2<i32>,
    f: vec2<i32>,
}

fn bilinear_taps(u: vec2<i32>) -> Taps {
    let a = u >> vec2<u32>(COORD_FRAC);
    var b: vec2<i32>;
    if (TILEABLE) {
        b = select(a + vec2<i32>(1), vec2<i32>(0), a + vec2<i32>(1) == params.ex_size);
    } else {
        b = min(a + vec2<i32>(1), params.ex_size - vec2<i32>(1));
    }
    return Taps(a, b, u & vec2<i32>((1 << COORD_FRAC) - 1));
}

// floor(sqrt(x)) for 0 <= x < 2^30, exact: float estimate, then one correction step.
fn isqrt(x: i32) -> i32 {
    var r = i32(sqrt(f32(x)));
    r -= select(0, 1, r * r > x);
    r += select(0, 1, (r + 1) * (r + 1) <= x);
    return r;
}

// An RGBA8 tangent-space normal (x, y in the first two channels, 0..255) rotated with
// the texture: by the rotation part of J^-1 (2x2 polar decomposition, integer
// arithmetic; mirror: crate::passes::gather_map::rotate_normal). J acts on image axes
// (y down): a map whose green is y up (OpenGL, glTF; `green_up`) has y flipped before
// and after, which turns the rotation the other way.
fn rotate_normal(v: vec4<i32>, j: vec4<i32>, green_up: bool) -> vec4<i32> {
    let flip = vec2<i32>(1, select(1, -1, green_up));
    let n = (2 * v.xy - vec2<i32>(255)) * flip;
    var r: vec2<i32>;
    if (j.x * j.w - j.y * j.z >= 0) {
        // J's rotation part is [[a, -b], [b, a]] / L; J^-1's is its transpose.
        let a = j.x + j.w;
        let b = j.z - j.y;
        let l = max(isqrt(a * a + b * b), 1);
        r = vec2<i32>(a * n.x + b * n.y, a * n.y - b * n.x) / l;
    } else {
        // Reflection: [[a, b], [b, -a]] / L is its own inverse.
        let a = j.x - j.w;
        let b = j.z + j.y;
        let l = max(isqrt(a * a + b * b), 1);
        r = vec2<i32>(a * n.x + b * n.y, b * n.x - a * n.y) / l;
    }
    return vec4<i32>(clamp((r * flip + vec2<i32>(256)) >> vec2<u32>(1u), vec2<i32>(0), vec2<i32>(255)), v.zw);
}

// The upsampling of the pixel at absolute position abs_p (its coordinate at index i of
// `coords`) from the coarser level (params.parent_*), as in upsample_aniso.wgsl:
// S_l[p] = S_{l-1}[floor(p/2)] + h_l J(p) (p mod 2); an odd child lies between two (or
// four) parents and averages their predictions when they agree within a pixel, so a
// sub-pixel misfit between parents (a non-integrable field J) is spread over the
// children instead of becoming a step. Predictions that differ by a pixel or more (a
// patch seam, and every disagreement when J = I) keep the nearest parent's: isometric
// results stay exact.
fn upsample_at(abs_p: vec2<i32>, i: u32) -> vec2<i32> {
    var c = fit_coord(vec2<i32>(0));
    if ((params.parent_size.x | opaque) > 0) {
        let odd = abs_p & vec2<i32>(1);
        let j = jac_at(i);
        let base = fit_coord(parent_at(abs_p, vec2<i32>(0)) + scaled_jd(params.spacing, j, odd));
        c = base;
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
    return c;
}

// The parent at block offset d (0 or 1 per axis) from the child's own.
fn parent_at(abs_p: vec2<i32>, d: vec2<i32>) -> vec2<i32> {
    let pp = clamp((abs_p >> vec2<u32>(1u)) + d - params.parent_origin, vec2<i32>(0), params.parent_size - vec2<i32>(1));
    return coords[params.parent_coord_base + u32(pp.y * params.parent_size.x + pp.x)];
}
