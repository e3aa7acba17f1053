//! Texture advection (Lefebvre & Hoppe 2006, applied to flows): GPU =
//! CPU, uniform flows translate, vortices keep the texture, fading, and bad input. The
//! frame loop they share is in `harness`.

#[path = "../common/mod.rs"]
mod common;
mod harness;

mod bad_input;
mod fading;
mod flows;
mod gpu_vs_cpu;
#[cfg(feature = "xatlas")]
mod mesh;
mod schedules;
