//! Mirror of `shaders/velocity.wgsl` (and `shared/velocity.wgsl`): a caller's velocities,
//! output pixels per unit time, quantized for an advection frame.

/// Fractional bits of velocities (1/1024 output pixel per frame). The precision matters
/// because a smooth flow's quantization error is the same every frame and adds up: at 1/16 pixel,
/// a vortex's velocities came in bands a few pixels wide whose edges tore the texture
/// by a whole pixel every 16 frames.
pub const VELOCITY_FRAC: u32 = 10;
/// Largest speed, output pixels per frame.
pub const MAX_SPEED: f32 = 64.0;

/// One velocity quantized as `velocity.wgsl` does on the GPU: scaled by `dt`, clamped to
/// [`MAX_SPEED`] per component, a non-finite component 0.
pub fn quantize_velocity(v: [f32; 2], dt: f32) -> [i32; 2] {
    let s = (1u32 << VELOCITY_FRAC) as f32;
    v.map(|c| {
        if !c.is_finite() {
            return 0;
        }
        ((c * dt).clamp(-MAX_SPEED, MAX_SPEED) * s).round_ties_even() as i32
    })
}
