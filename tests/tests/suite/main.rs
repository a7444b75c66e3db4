//! The cross-crate tests, one test binary (one build and link, and one harness that runs them
//! all on every core): the conformance suite over every registered structure, the shared
//! meshes and SPD scenes, rendering, instances and geometries, generated properties, the
//! fuzzers' saved inputs and this README's example. `pathological.rs`, which measures the
//! process's resident memory around each build, runs alone in a binary of its own.

mod conformance;
mod fuzz_inputs;
mod geometries;
mod instances;
mod models;
mod properties;
mod readme;
mod render;
mod spd;
mod trace;
mod view;
