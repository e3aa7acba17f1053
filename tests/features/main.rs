//! Feature-preserving appearance (Lefebvre & Hoppe 2006, section 3.2) and the choice of
//! appearance space: the signed-distance transform against brute force, the feature
//! channel's scale, clean errors for bad masks and weights (library and command line), the
//! analysis file, and a measured quality check on a structured exemplar. The CLI and
//! quality tests need a GPU adapter (lavapipe in CI).

#[path = "../common/mod.rs"]
mod common;
mod helpers;

mod appearance;
mod bad_input;
#[cfg(feature = "cli")]
mod cli;
mod distance;
mod quality;
