//! # xtask: the command-line face of rt
//!
//! `cargo xtask accels | verify | bench | render | view | trace | rays | stress | fuzz`. Everything is a library function first
//! (so that tests call it directly) and a subcommand second (`main.rs`).
//!
//! | module | what it holds |
//! |---|---|
//! | [`registry`] | the one list of structures by name ([`registry::REGISTRY`]) |
//! | [`obvhs_accel`] | obvhs's BVH2 and CWBVH behind the `Accel` trait (the references) |
//! | [`verify`] | every structure against brute force and obvhs |
//! | [`bench`](mod@bench) | throughput, build time, memory, beside obvhs in the same run |
//! | [`report`] | `bench --report DIR`: bench, sweep and SPD renders written as index.md with verdicts and PNG plots |
//! | [`table`] | one record as one table row, for `bench`'s text and the report's Markdown |
//! | [`stress`] | pathological scenes: every structure's build time, peak memory, size and answers |
//! | [`sweep`] | the scaling sweep: build time and time per ray against N (`bench --sweep`) |
//! | [`render`] | Whitted renders of the chess, OBJ and NFF scenes with any structure (rt-shade) |
//! | [`view`] | frame after frame: the interactive window (feature `window`) and its headless frame-rate mode |
//! | [`trace`] | ray files in, hit files out; standard ray sets out |
//! | [`rayfile`] | the `.rays` / `.hits` formats (re-exported from rt-testkit, which reads and writes them) |
//! | [`run`] | timed parallel tracing, medians, progress bars |
//! | `embree` | Intel Embree 3 behind `Accel` (feature `embree`, system `libembree-dev`) |
//! | [`fuzz`] | the fuzz targets' properties ([`fuzz::checks`]) and `cargo xtask fuzz`, which runs them |
//! | `tinybvh` | tinybvh's `BVH8_CPU` behind `Accel` (feature `tinybvh`, crate `tinybvh-rs`) |
//! | [`native`] | re-running `bench`/`trace` as the release build a dependent crate gets (or `--native`) |

pub mod animate;
pub mod bench;
#[cfg(feature = "embree")]
pub mod embree;
pub mod far;
pub mod fuzz;
pub mod heatmap;
pub mod native;
pub mod obvhs_accel;
pub mod registry;
pub mod render;
pub mod report;
pub mod run;
pub mod stress;
pub mod sweep;
pub mod table;
#[cfg(feature = "tinybvh")]
pub mod tinybvh;
pub mod trace;
pub mod verify;
pub mod view;

/// `.rays` and `.hits` files (the one module, in rt-testkit).
pub use rt_testkit::rayfile;
