//! Helpers shared by the test files: a scratch directory, the GPU context, the bundled
//! exemplars, a runner for the `texsyn` binary, image comparisons and the Khronos glTF
//! validator. A test file includes them with `mod common;` (from a folder target,
//! `#[path = "../common/mod.rs"] mod common;`); each file uses only some of them.
#![allow(dead_code, unused_imports)]

pub mod assets;
#[cfg(feature = "cli")]
pub mod cli;
pub mod gltf_validator;
pub mod gpu;
pub mod images;
mod temp_dir;

pub use assets::{asset_exemplar, asset_path, gravel, gravel_crop, gravel_crop_rect, repo};
pub use gltf_validator::{khronos_validate, run_validator};
pub use gpu::{ctx, fresh_ctx};
pub use temp_dir::TempDir;
