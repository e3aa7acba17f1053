//! The `texsyn` binary end to end: every subcommand on the bundled exemplar, and every
//! kind of bad input exiting non-zero with a message and no output file. Needs a GPU
//! adapter (lavapipe in CI). Sizes are small so the runs take seconds.

#[path = "../common/mod.rs"]
mod common;

mod advect;
mod bad_input;
mod controls;
mod json;
mod process;
mod synth;
