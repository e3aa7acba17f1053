//! Link bridge for `xatlas-rs` 0.1.3 on non-MSVC targets.
//!
//! The crate compiles xatlas' C++ for the target, but its pregenerated bindings name
//! the functions by their MSVC-mangled symbols (`?Create@xatlas@@...`), which only a
//! Windows build defines; elsewhere the C++ compiler emits Itanium names
//! (`_ZN6xatlas6CreateEv`). These forwarders export the names the bindings ask for and
//! call the Itanium ones. The signatures are xatlas.h's: pointers, an enum as `i32`,
//! and two plain-data option structs by value, which the C and Itanium C++ ABIs pass
//! alike. Only the four functions `xatlas_rs` calls are bridged.

#![cfg(not(target_env = "msvc"))]
#![allow(non_snake_case)]

use std::ffi::c_void;

/// xatlas::ChartOptions (8 floats, 2 uint32), passed through untouched.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ChartOptions {
    floats: [f32; 8],
    ints: [u32; 2],
}

/// xatlas::PackOptions, passed through untouched.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct PackOptions {
    attempts: i32,
    texels_per_unit: f32,
    resolution: u32,
    max_chart_size: u32,
    block_align: bool,
    conservative: bool,
    padding: u32,
}

type ProgressFunc = Option<unsafe extern "C" fn(i32, i32, *mut c_void)>;
type ParameterizeFunc = *const c_void;

unsafe extern "C" {
    #[link_name = "_ZN6xatlas6CreateEv"]
    fn xatlas_create() -> *mut c_void;
    #[link_name = "_ZN6xatlas7DestroyEPNS_5AtlasE"]
    fn xatlas_destroy(atlas: *mut c_void);
    #[link_name = "_ZN6xatlas7AddMeshEPNS_5AtlasERKNS_8MeshDeclE"]
    fn xatlas_add_mesh(atlas: *mut c_void, decl: *const c_void) -> i32;
    #[link_name = "_ZN6xatlas8GenerateEPNS_5AtlasENS_12ChartOptionsEPFvPKfPfjPKjjbENS_11PackOptionsEPFvNS_16ProgressCategory4EnumEiPvESD_"]
    fn xatlas_generate(
        atlas: *mut c_void,
        chart: ChartOptions,
        param: ParameterizeFunc,
        pack: PackOptions,
        progress: ProgressFunc,
        user: *mut c_void,
    );
}

#[unsafe(export_name = "?Create@xatlas@@YAPEAUAtlas@1@XZ")]
extern "C" fn create() -> *mut c_void {
    // SAFETY: forwards to the function of the same signature.
    unsafe { xatlas_create() }
}

#[unsafe(export_name = "?Destroy@xatlas@@YAXPEAUAtlas@1@@Z")]
extern "C" fn destroy(atlas: *mut c_void) {
    // SAFETY: forwards to the function of the same signature.
    unsafe { xatlas_destroy(atlas) }
}

#[unsafe(export_name = "?AddMesh@xatlas@@YA?AW4Enum@AddMeshError@1@PEAUAtlas@1@AEBUMeshDecl@1@@Z")]
extern "C" fn add_mesh(atlas: *mut c_void, decl: *const c_void) -> i32 {
    // SAFETY: forwards to the function of the same signature.
    unsafe { xatlas_add_mesh(atlas, decl) }
}

#[unsafe(export_name = "?Generate@xatlas@@YAXPEAUAtlas@1@UChartOptions@1@P6AXPEBMPEAMIPEBII_N@ZUPackOptions@1@P6AXW4Enum@ProgressCategory@1@HPEAX@Z9@Z")]
extern "C" fn generate(
    atlas: *mut c_void,
    chart: ChartOptions,
    param: ParameterizeFunc,
    pack: PackOptions,
    progress: ProgressFunc,
    user: *mut c_void,
) {
    // SAFETY: forwards to the function of the same signature.
    unsafe { xatlas_generate(atlas, chart, param, pack, progress, user) }
}
