//! Evaluation behind `slamesh eval` and the demo: how far a trajectory and a mesh are from the
//! truth (docs/design.md §3, [`docs/design.md`](../../docs/design.md) §3).
//!
//! | what | module |
//! |---|---|
//! | consecutive-frame errors, end-point drift, ATE, KITTI segment errors | [`odometry`] |
//! | mesh precision, recall and F-score against a point cloud | [`mesh`] |
//! | what of the movers a mesh kept, against labelled scans (ghost area, SA, DA) | [`dynamic`] |
//! | a mesh's boundary and non-manifold edges, and its connected pieces | [`topology`] |
//! | why a welded mesh has boundary edges, edge by edge | [`seams`] |
//! | one surface mapped twice (a loop left open) | [`duplicates`] |

pub mod duplicates;
pub mod dynamic;
pub mod mesh;
pub mod odometry;
pub mod seams;
pub mod topology;
