//! The GPU context of the tests: whatever adapter the machine has (Mesa's lavapipe, a CPU
//! Vulkan driver, in CI).

use std::sync::OnceLock;

use texsyn::gpu::GpuContext;

/// The context shared by every test of a test binary (device creation costs a moment).
pub fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(fresh_ctx)
}

/// A context of the caller's own: for tests that count what is built on it
/// (`GpuContext::built_pipelines`), read its errors, or need a second device.
pub fn fresh_ctx() -> GpuContext {
    match GpuContext::headless() {
        Ok(ctx) => ctx,
        Err(e) => panic!(
            "no GPU context: a Vulkan adapter is required (install mesa-vulkan-drivers for \
             lavapipe): {e}"
        ),
    }
}
