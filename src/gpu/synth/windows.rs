//! Outputs larger than the device takes in one piece: synthesized in windows that agree
//! where they meet, and assembled on the host.

use super::{ExtraMap, GpuSynthesizer};
use crate::error::{Error, Result};
use crate::passes::{SynthParams, Synthesis};

/// The most pixels [`GpuSynthesizer::synthesize_in_windows`] assembles (16384 x 16384:
/// 1 GiB of colours and 2 GiB of coordinates on the host).
pub const MAX_WINDOWED_PIXELS: usize = 1 << 28;

impl GpuSynthesizer {
    /// [`Self::synthesize_with_maps`] for outputs of any size: the output is synthesized
    /// in square windows (the largest power of two up to 2048 pixels a side that the
    /// device takes in one piece), read back and assembled on the host. Windows of the
    /// infinite texture agree wherever they overlap, so the result is the same, byte for
    /// byte, as one synthesis of the whole output on a device large enough for it.
    /// `progress(done, total)` is called after each window. Not for periodic
    /// (`tileable_output`) or surface outputs, which are one piece by nature: those are
    /// [`Error::InvalidParameter`].
    pub fn synthesize_in_windows(
        &self,
        params: &SynthParams,
        maps: &[ExtraMap],
        mut progress: impl FnMut(usize, usize),
    ) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
        if params.tileable_output || params.surface.is_some() {
            return Err(Error::InvalidParameter(
                "a periodic or surface output is one synthesis; it cannot be split into windows"
                    .into(),
            ));
        }
        let (w, h) = (params.width, params.height);
        // Windows must fit together: each is exact (see `synthesize_in_windows_sized`).
        let window = |side: u32| SynthParams {
            width: side.min(w),
            height: side.min(h),
            standalone: false,
            ..params.clone()
        };
        let mut side = 2048u32;
        while side > 16 && !self.fits(&window(side)) {
            side /= 2;
        }
        self.synthesize_in_windows_sized(params, maps, side, &mut progress)
    }

    /// [`Self::synthesize_in_windows`] with windows `side` pixels a side (each must fit
    /// the device; see [`Self::fits`]).
    pub fn synthesize_in_windows_sized(
        &self,
        params: &SynthParams,
        maps: &[ExtraMap],
        side: u32,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
        if params.width == 0 || params.height == 0 || side == 0 {
            return Err(Error::InvalidParameter(format!(
                "output {}x{} in windows of {side}: sizes must be at least 1",
                params.width, params.height
            )));
        }
        let (w, h) = (params.width as usize, params.height as usize);
        let pixels = w
            .checked_mul(h)
            .filter(|&n| n <= MAX_WINDOWED_PIXELS)
            .ok_or_else(|| {
                Error::InvalidParameter(format!(
                    "output {w}x{h}: at most {} Mpixel are assembled in memory; synthesize \
                     windows of it (SynthParams::origin) and store them separately",
                    MAX_WINDOWED_PIXELS >> 20
                ))
            })?;
        let side = side.max(1) as usize;
        let (nx, ny) = (w.div_ceil(side), h.div_ceil(side));
        let mut out = Synthesis {
            width: params.width,
            height: params.height,
            coords: vec![[0, 0]; pixels],
            colors: vec![[0; 4]; pixels],
            coord_frac: 0,
        };
        let mut out_maps = vec![vec![[0u8; 4]; pixels]; maps.len()];
        for ty in 0..ny {
            for tx in 0..nx {
                let (x0, y0) = (tx * side, ty * side);
                let (tw, th) = (side.min(w - x0), side.min(h - y0));
                let origin = [
                    params.origin[0].checked_add(x0 as i32),
                    params.origin[1].checked_add(y0 as i32),
                ];
                let [Some(ox), Some(oy)] = origin else {
                    return Err(Error::InvalidParameter(
                        "the output reaches past the supported texture area".into(),
                    ));
                };
                // Exact windows, whatever `params.standalone` says: a standalone
                // piece would not meet its neighbours.
                let p = SynthParams {
                    width: tw as u32,
                    height: th as u32,
                    origin: [ox, oy],
                    standalone: false,
                    ..params.clone()
                };
                let (s, m) = self.synthesize_with_maps(&p, maps)?;
                out.coord_frac = s.coord_frac;
                for y in 0..th {
                    let dst = (y0 + y) * w + x0;
                    out.coords[dst..dst + tw].copy_from_slice(&s.coords[y * tw..][..tw]);
                    out.colors[dst..dst + tw].copy_from_slice(&s.colors[y * tw..][..tw]);
                    for (o, src) in out_maps.iter_mut().zip(&m) {
                        o[dst..dst + tw].copy_from_slice(&src[y * tw..][..tw]);
                    }
                }
                progress(ty * nx + tx + 1, nx * ny);
            }
        }
        Ok((out, out_maps))
    }
}
