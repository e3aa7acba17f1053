//! Mirror of `shaders/velocity.wgsl` (and `shared/velocity.wgsl`): a caller's velocities,
//! output pixels per unit time, quantized for an advection frame.

/// Fractional bits of velocities (1/1024 output pixel per frame): a smooth flow's
/// quantization error is the same every frame and adds up, so it must be small.
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

/// The uniform block of `velocity.wgsl` and `velocity_texture.wgsl` (`VelocityParams` in
/// `shaders/shared/velocity.wgsl`; build.rs checks the two layouts agree).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct VelocityParams {
    /// Velocities to quantize (the output's pixels).
    pub count: u32,
    /// Time step the velocities are scaled by.
    pub dt: f32,
    /// The output's width: the texture pixel of entry `i` is `(i % width, i / width)`.
    pub width: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}
