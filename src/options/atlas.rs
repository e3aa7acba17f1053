//! The atlas domain of a surface synthesis: what the surface layer sets in
//! [`SynthParams::surface`](super::SynthParams::surface) (built from the mesh, the atlas and
//! the tangent field by `surface::maps`); the fill pass (`passes::fill`) reads it.

/// One indirection: gutter texel `dst` takes `S[src] + h J(src) off`, where `src` is
/// the chart texel nearest to the surface point that `dst` stands for and `off` is that
/// point's position relative to `src`'s centre (level texels, 1/16). Indices are within
/// the level, row-major.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FillEntry {
    /// Gutter texel to fill (region index).
    pub dst: u32,
    /// Chart texel it copies (region index).
    pub src: u32,
    /// Surface point relative to `src`'s centre, level texels in 1/16.
    pub off: [i32; 2],
}

/// One level of an atlas domain.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AtlasLevel {
    /// Size of this level of the atlas in texels.
    pub size: [u32; 2],
    /// Quantized Jacobian per texel (see `field::JAC_FRAC`), gutter texels included.
    pub jac: Vec<[i32; 4]>,
    /// Chart mask: bit `t % 32` of word `t / 32` is set if texel `t` is inside a chart.
    pub inside: Vec<u32>,
    /// Indirection entries of the gutter texels: first the `band` texels next to a
    /// chart (what the correction reads: refilled after every pass), then the rest of
    /// the gutter (filled once per level, for the finer level's upsampling and so that
    /// the final colours are dilated into the whole gutter).
    pub fill: Vec<FillEntry>,
    /// Entries at the start of `fill` that form the band next to the charts.
    pub band: u32,
}

/// Everything atlas synthesis needs per level, built on the host from the mesh, the
/// atlas and the tangent field (`surface::maps`). `levels[0]` is the finest (the atlas
/// itself), each next one half the size (rounded up).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AtlasDomain {
    /// The levels, finest first.
    pub levels: Vec<AtlasLevel>,
}
