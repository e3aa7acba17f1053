//! The pass shaders, embedded at build time.
//!
//! `build.rs` expands the `#include`s of every `shaders/*.wgsl`, parses and validates the
//! result with naga (so a WGSL error is a build error reported at its original
//! `file:line:col`), and generates one [`ShaderSource`] constant per file, named after
//! the file in upper case (`shaders/upsample.wgsl` -> `UPSAMPLE`), plus [`ALL`].
//! The preprocessed text is also written to `$OUT_DIR/shaders/<name>.wgsl`, which is the
//! file that line numbers in wgpu's runtime shader errors refer to.

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

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
