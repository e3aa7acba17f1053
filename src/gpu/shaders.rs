//! The pass shaders and the render shaders, embedded at build time.
//!
//! `build.rs` expands the `#include`s of every `shaders/*.wgsl`, parses and validates the
//! result with naga (so a WGSL error is a build error reported at its original
//! `file:line:col`), and generates one [`ShaderSource`] constant per file, named after
//! the file in upper case (`shaders/upsample.wgsl` -> `UPSAMPLE`), plus [`ALL`].
//! The preprocessed text is also written to `$OUT_DIR/shaders/<name>.wgsl`, which is the
//! file that line numbers in wgpu's runtime shader errors refer to.
//!
//! `shaders/render/*.wgsl` are render shaders (one `@vertex` and one `@fragment` entry
//! point each, `#include` paths still relative to `shaders/`). They are validated the same
//! way and become [`RenderShaderSource`] constants in module [`render`]
//! (`shaders/render/mesh.wgsl` -> `render::MESH`, plus `render::ALL`); [`ALL`] lists the
//! compute passes only. Their preprocessed text goes to `$OUT_DIR/shaders/render/`.

/// One compute pass shader, preprocessed and validated at build time.
///
/// `source` is self-contained WGSL (every `#include` expanded), ready for
/// `wgpu::ShaderSource::Wgsl(source.into())`. `entry_point` and `workgroup_size` are those
/// of the shader's single `@compute` entry point, so the host can build the pipeline and
/// compute dispatch counts (`ceil(width / workgroup_size[0])`, ...) without repeating them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ShaderSource {
    /// The file stem, e.g. `"upsample"`; handy as a wgpu label.
    pub name: &'static str,
    /// The root file relative to the crate root, e.g. `"shaders/upsample.wgsl"`.
    pub file: &'static str,
    /// The preprocessed WGSL.
    pub source: &'static str,
    /// Name of the `@compute` entry point.
    pub entry_point: &'static str,
    /// `@workgroup_size` of the entry point, `[x, y, z]` (missing dimensions are 1).
    pub workgroup_size: [u32; 3],
}

/// One render shader (`shaders/render/*.wgsl`), preprocessed and validated at build time.
///
/// `source` is self-contained WGSL with exactly one `@vertex` entry point
/// (`vertex_entry`) and one `@fragment` entry point (`fragment_entry`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RenderShaderSource {
    /// The file stem, e.g. `"mesh"`; handy as a wgpu label.
    pub name: &'static str,
    /// The root file relative to the crate root, e.g. `"shaders/render/mesh.wgsl"`.
    pub file: &'static str,
    /// The preprocessed WGSL.
    pub source: &'static str,
    /// Name of the `@vertex` entry point.
    pub vertex_entry: &'static str,
    /// Name of the `@fragment` entry point.
    pub fragment_entry: &'static str,
}

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// The render shaders (`shaders/render/*.wgsl`), one constant per file plus `ALL`.
pub mod render {
    use super::RenderShaderSource;

    include!(concat!(env!("OUT_DIR"), "/render_shaders.rs"));
}
