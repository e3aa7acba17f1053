//! Exemplar loading, atomic writes, image and coordinate-map output, and the files refused
//! on the way in.

#[path = "../common/mod.rs"]
mod common;
mod helpers;

mod atomic_write;
mod coords;
mod few_channel_exr;
mod load;
mod refused;
mod save;
