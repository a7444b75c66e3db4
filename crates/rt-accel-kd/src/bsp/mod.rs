//! General BSP trees: splitting planes of any orientation, taken from the primitives' own
//! planes (autopartition) or axis-aligned, traversed front to back by signed distance.
//!
//! Nodes are [`KdNode`](crate::KdNode)s whose `data` indexes [`BspTree::planes`]. A primitive goes below a
//! plane if all of it is below `margin` (see [`SplitPlane`]), above if all of it is above
//! `-margin`, to one side (the cheaper) if it lies within the margin, and to both otherwise.
//! The walk pads each crossing by the margin over `|n . dir|`, so that a hit within the band
//! is inside both children's intervals.
//!
//! | file | what it holds |
//! |---|---|
//! | `params.rs` | [`BspParams`] with presets `standard()` and `autopartition()` |
//! | `tree.rs` | [`BspTree`] and [`SplitPlane`]: the type, its build entry point, `stats()` and `validate()` |
//! | `build.rs` | candidate planes, classification of primitives against a plane, the SAH on cell boxes |
//! | `walk.rs` | how a ray meets an arbitrary plane (in `f64`), for the kd-tree's walk |

mod build;
mod params;
mod tree;
mod walk;

pub use params::BspParams;
pub use tree::{BspTree, SplitPlane};
pub(crate) use walk::PlaneRay;
