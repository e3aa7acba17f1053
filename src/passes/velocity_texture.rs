//! Mirror of `shaders/velocity_texture.wgsl`: a caller's velocity texture (red, green =
//! x, y velocity, one texel per output pixel) is quantized texel by texel exactly as a
//! velocity buffer is ([`quantize_velocity`]).

pub use super::velocity::quantize_velocity;
