//! Early checks of an output's size against the device's limits.

/// Hint of the "output too large" errors.
pub const WINDOW_HINT: &str = "synthesize it in windows (--window X,Y) and assemble them";

/// The error the library gives for an output larger than the device, checked early:
/// before the analysis (the library checks once the plan exists, i.e. after it) and
/// before the plan (which rejects huge outputs with a less specific message). The
/// buffer check is a lower bound (the finest level alone); the library checks the
/// whole pyramid.
pub fn check_output_size(
    ctx: &texsyn::gpu::GpuContext,
    width: u32,
    height: u32,
) -> texsyn::Result<()> {
    check_output_size_hint(ctx, width, height, WINDOW_HINT)
}

/// The largest buffer a synthesis can bind in one piece (its coordinate pyramid and
/// Jacobian field live in one buffer each).
pub fn max_buffer_binding(ctx: &texsyn::gpu::GpuContext) -> u64 {
    let limits = ctx.limits();
    limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size)
}

/// [`check_output_size`] with the advice to give when the size is too large.
pub fn check_output_size_hint(
    ctx: &texsyn::gpu::GpuContext,
    width: u32,
    height: u32,
    hint: &'static str,
) -> texsyn::Result<()> {
    let limits = ctx.limits();
    let max_dim = limits.max_texture_dimension_2d;
    let too_large = |limit: String| texsyn::Error::TooLarge {
        what: "output",
        width,
        height,
        limit,
        hint,
    };
    if width > max_dim || height > max_dim {
        return Err(too_large(format!("at most {max_dim} pixels a side")));
    }
    let bytes = width as u64 * height as u64 * 8;
    let max = max_buffer_binding(ctx);
    if bytes > max {
        return Err(too_large(format!(
            "its coordinate pyramid needs more than {} MiB in one buffer, the device allows {} MiB",
            bytes >> 20,
            max >> 20
        )));
    }
    Ok(())
}
