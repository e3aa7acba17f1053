//! Mirror of `shaders/shared/common.wgsl`: the hash, coordinate wrapping and clamping,
//! and the uniform block every pass reads.

use bytemuck::{Pod, Zeroable};

/// Fractional bits of anisometric (continuous) coordinates: 1/256 exemplar pixel.
pub const COORD_FRAC: u32 = 8;

/// Uniform block shared by every pass (one copy per dispatch, at a dynamic offset).
/// Layout must match `Params` in `shaders/shared/common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PassParams {
    /// Exemplar width, height.
    /// Exemplar size in pixels.
    pub ex_size: [i32; 2],
    /// Absolute position of this level's region origin.
    pub origin: [i32; 2],
    /// Size of this level's region in level pixels.
    pub size: [i32; 2],
    /// Absolute origin of the parent (coarser) level's region; upsample reads it.
    pub parent_origin: [i32; 2],
    /// Size of the parent's region ([0, 0] at level 0).
    pub parent_size: [i32; 2],
    /// Correction subpass parity (absolute pixel position mod 2).
    pub parity: [i32; 2],
    /// `h_l` reduced modulo the exemplar size per axis when tileable (`h_l` otherwise):
    /// what the correction adds to coordinates, so [`wrap_near`] suffices to wrap them.
    pub step: [i32; 2],
    /// `h_l`.
    pub spacing: i32,
    /// 1 if coordinates wrap around the exemplar, 0 if they are clamped to the margin.
    pub tileable: i32,
    /// Valid-region margin (non-tileable).
    pub margin: i32,
    /// Level index `l`.
    pub level: u32,
    /// Jitter hash seed.
    pub seed: u32,
    /// Jitter amplitude `h_l * r_l` in 1/16 pixel.
    pub jitter_amp: i32,
    /// Similarity-set size.
    pub k: i32,
    /// Right shift applied to projected neighbourhoods.
    pub shift: u32,
    /// Coherence bias in 1/16: non-coherent candidates pay `dist * (1 + bias/16)`.
    pub coherence: u32,
    /// Element offset of this level's `Et` and `qe` tables in the shared buffers.
    pub et_base: u32,
    /// Offset of this level's similarity offsets.
    pub off_base: u32,
    /// Offset of this level's projection blocks.
    pub proj_base: u32,
    /// Offset of this level's coordinates in the coordinate array.
    pub coord_base: u32,
    /// Offset of the parent level's coordinates.
    pub parent_coord_base: u32,
    /// Offset of the output window inside this level's region (gather pass).
    pub window_offset: [i32; 2],
    /// Output window size in pixels.
    pub window_size: [i32; 2],
    /// 1: full 32D distance, 0: projected 8D distance (see `correct.rs`).
    pub full_distance: u32,
    /// Fractional bits of the coordinates: 0 (isometric, integer exemplar pixels) or
    /// [`COORD_FRAC`] (anisometric, continuous coordinates in fixed point).
    pub coord_frac: u32,
    /// 1: the region is one period of a tileable output and wraps around.
    pub periodic: u32,
    /// Map gather only: 0 for a plain map; tangent-space normals (rotated with the
    /// field): 1 with green = y down the image (DirectX), 2 with green = y up (OpenGL,
    /// glTF).
    pub map_kind: u32,
    /// Magnify pass only: size of the high-resolution exemplar.
    pub hi_size: [i32; 2],
    /// Magnification factor.
    pub magnify: u32,
    /// Atlas synthesis: 1 if the correction skips texels outside the charts (their
    /// mask bits start at word `mask_base` of the surface buffer), 0 otherwise.
    pub masked: u32,
    /// Word offset of this level's chart mask in the surface buffer.
    pub mask_base: u32,
    /// Fill pass: this level's indirection entries, `fill_count` of them from word
    /// `fill_base` of the surface buffer (4 words each, see `fill.rs`).
    pub fill_base: u32,
    /// Indirection entries this fill dispatch processes.
    pub fill_count: u32,
    /// Advection: index in the coordinate buffer of the per-pixel distortion flags
    /// (the upsample then only rewrites flagged pixels); 0 = upsample every pixel.
    /// Corrections: where the change stamps start (see `stamp`).
    pub flag_base: u32,
    /// Advection: the output window's absolute origin (the velocity field covers the
    /// window, finest-level pixels).
    pub window_origin: [i32; 2],
    /// Advection: distortion threshold, `(c h 256)^2` (see `advect.rs`).
    pub distortion_max: u32,
    /// This level's distance from the finest (`2^steps` finest pixels per pixel).
    pub steps: u32,
    /// Anisometric gather: 1 reads the exemplar texel nearest to the coordinate instead
    /// of interpolating (advection: sub-pixel motion must not blur the texture).
    pub nearest: u32,
    /// Advection: the frame's rounding offset for `J V` (see `advect.rs`).
    pub dither: u32,
    /// Gathers: 1 blends the colours that the 4 neighbours predict across patch seams
    /// (see `gather.rs`), 0 copies the exemplar at the coordinate.
    pub seam_blend: u32,
    /// Correction subpasses: only pixels at least `inset` from every edge of the region
    /// are updated (the outer ring cannot reach the exact part of the region any more;
    /// see `SynthPlan::schedule`).
    pub inset: i32,
    /// Anisometric correction, projected distance: 1 scores the similarity-set
    /// candidates with `qe` interpolated like the coherent ones (advection frames), 0 at
    /// their nearest texel (synthesis; see `correct_aniso.rs`).
    pub kset_interp: u32,
    /// Anisometric correction, projected distance: 1 reads `Et` and `qe` at the quarter
    /// pixel nearest to each position (then bilinearly, as at any position), 0 at the
    /// position itself (1/256 pixel). The GPU reads the quarter pixels of the finest
    /// level from 16x supersampled tables, one read instead of four (advection frames;
    /// see `correct_aniso.rs`).
    pub quarter: u32,
    /// Corrections (GPU only; the CPU mirror computes every pixel, the same values):
    /// the subpass's stamp, written at `flag_base` + the pixel's region index
    /// for a pixel that changes and its 8 neighbours, and `clean_before`: a pixel whose
    /// stamp is below it has had the same 3x3 neighbourhood since its class's previous
    /// subpass, which left it unchanged, so it is skipped (0: none is). See
    /// `SynthPlan::schedule_with`.
    pub stamp: u32,
    /// Pixels whose stamp is below this are skipped (see `stamp`).
    pub clean_before: u32,
    /// Anisometric correction (advection frames): 1 leaves a pixel whose 8 neighbours
    /// all continue its patch within a quarter pixel (see `correct_aniso.rs`).
    pub coherent_skip: u32,
    /// Advection frames: index in the coordinate buffer of the frames' drift
    /// ([`crate::passes::plan::SynthPlan::drift_index`]: the whole finest pixels the
    /// flow's centre has moved since frame 0, before and after this frame), from which
    /// the advect pass takes each level's whole-pixel shift and the finest level's
    /// upsampling its phase (see `advect.rs`); 0: none (synthesis). Also keeps the size
    /// a multiple of 8 bytes, as WGSL rounds the uniform struct.
    pub drift: u32,
    /// Advection frames' fade pass (see `fade.rs`): where the fade state this frame
    /// reads starts in the coordinate buffer (0: none, every pixel starts unfaded) and
    /// where it writes the new one, the frames a fade lasts, and the exemplar's mean
    /// colour (RGBA8, packed) the blend keeps the contrast around.
    pub fade_src: u32,
    /// Where the fade pass writes the new fade state.
    pub fade_dst: u32,
    /// Frames a fade lasts.
    pub fade_frames: u32,
    /// The exemplar's mean colour (RGBA8, packed) the fade's blend is centred on.
    pub fade_mean: u32,
    /// The fade's pop test: how much a jump must change a pixel's colour, of 255
    /// ([`crate::passes::advect::AdvectOptions::fade_change`]).
    pub fade_change: u32,
    /// Advection's distortion pass: anchored renewals (see `distortion.wgsl`): the
    /// anchors' spacing in the low byte (0: flagged pixels are upsampled from the
    /// coarser level, the paper's scheme), and above it the share of renewals, of 256,
    /// upsampled anyway ([`crate::passes::advect::AdvectOptions::anchor_spacing`]).
    pub anchor: u32,
}

/// Dynamic uniform offsets must be multiples of this (the WebGPU default limit).
pub const PARAMS_STRIDE: u64 = 256;

// Each dispatch's parameters sit in one stride of the uniform buffer, and WGSL rounds the
// struct to a multiple of 8 bytes (its vec2 alignment): both must hold as fields are added.
const _: () = assert!(std::mem::size_of::<PassParams>() as u64 <= PARAMS_STRIDE);
const _: () = assert!(std::mem::size_of::<PassParams>().is_multiple_of(8));

/// Integer hash with good avalanche ("lowbias32", C. Wellons). Same in WGSL.
#[inline]
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// `H(p, l, seed)`: two independent 32-bit hashes of an absolute pixel position, the
/// level and the seed. Absolute positions make every window of the infinite texture agree.
#[inline]
pub fn hash_pixel(p: [i32; 2], level: u32, seed: u32) -> [u32; 2] {
    let h = hash32(seed ^ hash32(level.wrapping_add(0x9e37_79b9)));
    let h = hash32(h ^ p[0] as u32);
    let hx = hash32(h ^ (p[1] as u32).wrapping_mul(0x2c1b_3c6d));
    let hy = hash32(hx ^ 0x68e3_1da4);
    [hx, hy]
}

/// `c` modulo `n`, in `[0, n)`.
#[inline]
pub fn wrap(c: i32, n: i32) -> i32 {
    ((c % n) + n) % n
}

/// `wrap` for `c` in `[-2n, 3n)`, without a division: integer division is by far the
/// most expensive operation on CPU implementations of Vulkan, and the correction wraps
/// about 30 coordinates per pixel. Its callers stay in range: a
/// coordinate in `[0, n)`, an offset of at most `n/2`, and a step below `n`.
#[inline]
pub fn wrap_near(c: i32, n: i32) -> i32 {
    let mut v = c;
    if v < 0 {
        v += n;
    }
    if v < 0 {
        v += n;
    }
    if v >= n {
        v -= n;
    }
    if v >= n {
        v -= n;
    }
    v
}

/// A candidate or read position in the correction: wrapped with [`wrap_near`]
/// (tileable) or clamped to the valid region (non-tileable; only called on valid ones).
#[inline]
pub fn fit_near(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    if p.tileable != 0 {
        [wrap_near(c[0], p.ex_size[0]), wrap_near(c[1], p.ex_size[1])]
    } else {
        fit_coord(c, p)
    }
}

/// A coordinate after upsampling or jittering: wrapped (tileable) or clamped into the
/// valid region (non-tileable). In units of `2^-coord_frac` exemplar pixels.
#[inline]
pub fn fit_coord(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    let f = p.coord_frac;
    if p.tileable != 0 {
        [wrap(c[0], p.ex_size[0] << f), wrap(c[1], p.ex_size[1] << f)]
    } else {
        [
            c[0].clamp(p.margin << f, (p.ex_size[0] - 1 - p.margin) << f),
            c[1].clamp(p.margin << f, (p.ex_size[1] - 1 - p.margin) << f),
        ]
    }
}

/// An exemplar read position in the correction: wrapped (tileable, with
/// [`wrap_near`]) or clamped to the image (non-tileable).
#[inline]
pub fn read_coord(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    if p.tileable != 0 {
        [wrap_near(c[0], p.ex_size[0]), wrap_near(c[1], p.ex_size[1])]
    } else {
        [
            c[0].clamp(0, p.ex_size[0] - 1),
            c[1].clamp(0, p.ex_size[1] - 1),
        ]
    }
}

/// Whether a candidate coordinate may be chosen (always for tileable exemplars).
#[inline]
pub fn is_valid(c: [i32; 2], p: &PassParams) -> bool {
    p.tileable != 0
        || (c[0] >= p.margin
            && c[0] <= p.ex_size[0] - 1 - p.margin
            && c[1] >= p.margin
            && c[1] <= p.ex_size[1] - 1 - p.margin)
}

/// Index of region pixel `q` (clamped into the region, or wrapped around it for a
/// periodic output; neighbours are at most one pixel outside) in the level's array.
#[inline]
pub fn region_index(q: [i32; 2], p: &PassParams) -> usize {
    let (x, y) = if p.periodic != 0 {
        let w = |v: i32, n: i32| {
            let v = if v < 0 { v + n } else { v };
            if v >= n {
                v - n
            } else {
                v
            }
        };
        (w(q[0], p.size[0]), w(q[1], p.size[1]))
    } else {
        (q[0].clamp(0, p.size[0] - 1), q[1].clamp(0, p.size[1] - 1))
    };
    (y * p.size[0] + x) as usize
}

// ---------------------------------------------------------------------------------------
// Anisometric helpers (mirror of shaders/shared/aniso.wgsl). Coordinates are in
// 1/2^COORD_FRAC exemplar pixels, Jacobians row-major (a, b, c, d) in 1/2^JAC_FRAC.
// ---------------------------------------------------------------------------------------

/// `h * J * d` in coordinate units (1/256 px), rounded: `J d` is in 1/1024, so the
/// product is shifted right by 2. Exact (`256 h d`) when `J = I`.
#[inline]
pub fn scaled_jd(h: i32, j: [i32; 4], d: [i32; 2]) -> [i32; 2] {
    let x = j[0] * d[0] + j[1] * d[1];
    let y = j[2] * d[0] + j[3] * d[1];
    [(h * x + 2) >> 2, (h * y + 2) >> 2]
}

/// `phi(J^-1 d) = round(v / |v|)`: the immediate neighbour in the direction of
/// `J^-1 d`. Only the direction matters, so `v = sign(det J) adj(J) d` (no division);
/// a component rounds to +-1 when `|v_i| / |v| >= 1/2`, i.e. `3 v_i^2 >= v_j^2`.
/// Entries are at most 2^13 in magnitude (|J| <= 8), so the squares fit an i32.
#[inline]
pub fn phi_inv(j: [i32; 4], d: [i32; 2]) -> [i32; 2] {
    let det = j[0] * j[3] - j[1] * j[2];
    let mut vx = j[3] * d[0] - j[1] * d[1];
    let mut vy = j[0] * d[1] - j[2] * d[0];
    if det < 0 {
        vx = -vx;
        vy = -vy;
    }
    let (ax, ay) = (vx.abs(), vy.abs());
    [
        if 3 * ax * ax >= ay * ay {
            vx.signum()
        } else {
            0
        },
        if 3 * ay * ay >= ax * ax {
            vy.signum()
        } else {
            0
        },
    ]
}

/// A difference of two fitted fixed-point coordinates, the shortest way around a
/// tileable exemplar.
pub fn coord_delta(d: [i32; 2], p: &PassParams) -> [i32; 2] {
    if p.tileable == 0 {
        return d;
    }
    let wrap = |e: i32, n: i32| {
        let n = n << COORD_FRAC;
        if e > n >> 1 {
            e - n
        } else if e < -(n >> 1) {
            e + n
        } else {
            e
        }
    };
    [wrap(d[0], p.ex_size[0]), wrap(d[1], p.ex_size[1])]
}

/// Whether two fitted coordinates are less than 3/4 pixel apart on both axes: the same
/// patch, up to the sub-pixel misfit a field that is not a gradient leaves.
pub fn same_patch(a: [i32; 2], b: [i32; 2], p: &PassParams) -> bool {
    let e = coord_delta([a[0] - b[0], a[1] - b[1]], p);
    e[0].abs() < 3 << (COORD_FRAC - 2) && e[1].abs() < 3 << (COORD_FRAC - 2)
}

/// Full wrap (tileable) or clamp to the image (non-tileable) of a fixed-point read
/// position. The anisometric passes cannot use [`wrap_near`]: `h J d` is not bounded by
/// the exemplar size.
#[inline]
pub fn read_coord_fx(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    let n = [p.ex_size[0] << COORD_FRAC, p.ex_size[1] << COORD_FRAC];
    if p.tileable != 0 {
        [wrap(c[0], n[0]), wrap(c[1], n[1])]
    } else {
        [
            c[0].clamp(0, n[0] - (1 << COORD_FRAC)),
            c[1].clamp(0, n[1] - (1 << COORD_FRAC)),
        ]
    }
}

/// Quarter pixels per pixel, as a shift (`PassParams::quarter`).
pub const QUARTER_BITS: u32 = 2;

/// The quarter pixel nearest to a wrapped/clamped position ([`read_coord_fx`]), in
/// quarter pixels: wrapped for tileable exemplars; a clamped position stays within the
/// last pixel.
#[inline]
pub fn quarter_texel(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    let sh = COORD_FRAC - QUARTER_BITS;
    let r = [
        (c[0] + (1 << (sh - 1))) >> sh,
        (c[1] + (1 << (sh - 1))) >> sh,
    ];
    if p.tileable != 0 {
        let n = [p.ex_size[0] << QUARTER_BITS, p.ex_size[1] << QUARTER_BITS];
        [
            if r[0] >= n[0] { r[0] - n[0] } else { r[0] },
            if r[1] >= n[1] { r[1] - n[1] } else { r[1] },
        ]
    } else {
        r
    }
}

/// Whether a fixed-point candidate may be chosen (always for tileable exemplars).
#[inline]
pub fn is_valid_fx(c: [i32; 2], p: &PassParams) -> bool {
    let lo = p.margin << COORD_FRAC;
    p.tileable != 0
        || (c[0] >= lo
            && c[0] <= (p.ex_size[0] - 1 - p.margin) << COORD_FRAC
            && c[1] >= lo
            && c[1] <= (p.ex_size[1] - 1 - p.margin) << COORD_FRAC)
}

/// The exemplar pixel nearest to an in-range fixed-point coordinate (rounded, wrapped
/// or clamped into the image).
#[inline]
pub fn nearest_texel(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    let half = 1 << (COORD_FRAC - 1);
    let r = [(c[0] + half) >> COORD_FRAC, (c[1] + half) >> COORD_FRAC];
    if p.tileable != 0 {
        [
            if r[0] >= p.ex_size[0] {
                r[0] - p.ex_size[0]
            } else {
                r[0]
            },
            if r[1] >= p.ex_size[1] {
                r[1] - p.ex_size[1]
            } else {
                r[1]
            },
        ]
    } else {
        [r[0].min(p.ex_size[0] - 1), r[1].min(p.ex_size[1] - 1)]
    }
}

/// Bilinear texel positions and weights (1/65536) of a wrapped or clamped fixed-point
/// position: `(x0, y0, x1, y1, fx, fy)`.
#[inline]
pub fn bilinear_taps(u: [i32; 2], p: &PassParams) -> ([i32; 2], [i32; 2], [i32; 2]) {
    let mask = (1 << COORD_FRAC) - 1;
    let i0 = [u[0] >> COORD_FRAC, u[1] >> COORD_FRAC];
    let f = [u[0] & mask, u[1] & mask];
    let i1 = if p.tileable != 0 {
        [
            if i0[0] + 1 == p.ex_size[0] {
                0
            } else {
                i0[0] + 1
            },
            if i0[1] + 1 == p.ex_size[1] {
                0
            } else {
                i0[1] + 1
            },
        ]
    } else {
        [
            (i0[0] + 1).min(p.ex_size[0] - 1),
            (i0[1] + 1).min(p.ex_size[1] - 1),
        ]
    };
    (i0, i1, f)
}

/// Region coordinates a correction subpass updates along one axis (mirror of
/// `subpass_axis` in common.wgsl): the pixels of absolute parity `class`, except that a
/// periodic region of odd size >= 3 puts its last pixel in class 2 (it neighbours pixel 0
/// across the wrap, which has the same parity), so no two updated pixels are neighbours.
pub fn subpass_axis(class: i32, origin: i32, size: i32, periodic: bool, inset: i32) -> Vec<i32> {
    let odd_wrap = periodic && size & 1 == 1 && size >= 3;
    if class == 2 {
        return vec![size - 1];
    }
    let start = inset + ((class - origin - inset) & 1);
    (start..size - inset)
        .step_by(2)
        .filter(|&v| !(odd_wrap && v == size - 1))
        .collect()
}

/// Whether an axis of this size needs the extra class-2 subpasses.
pub fn has_wrap_class(size: i32, periodic: bool) -> bool {
    periodic && size & 1 == 1 && size >= 3
}

/// The pixels a correction subpass updates, row by row.
pub fn subpass_pixels(p: &PassParams) -> Vec<[i32; 2]> {
    let periodic = p.periodic != 0;
    let xs = subpass_axis(p.parity[0], p.origin[0], p.size[0], periodic, p.inset);
    let ys = subpass_axis(p.parity[1], p.origin[1], p.size[1], periodic, p.inset);
    ys.iter()
        .flat_map(|&y| xs.iter().map(move |&x| [x, y]))
        .collect()
}

/// An RGBA8 table of `size` (exemplar colours, an extra map, or the high-resolution
/// exemplar of magnification) bilinearly interpolated at a fixed-point position (1/256
/// texel; wrapped when `tileable`, else clamped), weights in 1/65536, rounded.
pub fn bilinear_rgba(table: &[[u8; 4]], size: [i32; 2], tileable: bool, u: [i32; 2]) -> [i32; 4] {
    let n = [size[0] << COORD_FRAC, size[1] << COORD_FRAC];
    let u = if tileable {
        [wrap(u[0], n[0]), wrap(u[1], n[1])]
    } else {
        [
            u[0].clamp(0, n[0] - (1 << COORD_FRAC)),
            u[1].clamp(0, n[1] - (1 << COORD_FRAC)),
        ]
    };
    let i0 = [u[0] >> COORD_FRAC, u[1] >> COORD_FRAC];
    let next = |i: i32, n: i32| {
        if tileable {
            if i + 1 == n {
                0
            } else {
                i + 1
            }
        } else {
            (i + 1).min(n - 1)
        }
    };
    let i1 = [next(i0[0], size[0]), next(i0[1], size[1])];
    let mask = (1 << COORD_FRAC) - 1;
    let f = [u[0] & mask, u[1] & mask];
    let at = |c: [i32; 2]| table[(c[1] * size[0] + c[0]) as usize].map(|v| v as i32);
    let w = [
        (256 - f[0]) * (256 - f[1]),
        f[0] * (256 - f[1]),
        (256 - f[0]) * f[1],
        f[0] * f[1],
    ];
    let t = [at(i0), at([i1[0], i0[1]]), at([i0[0], i1[1]]), at(i1)];
    let mut out = [0i32; 4];
    for (ch, o) in out.iter_mut().enumerate() {
        let s: i32 = (0..4).map(|i| w[i] * t[i][ch]).sum();
        *o = (s + 32768) >> 16;
    }
    out
}
