//! Evaluation behind `slamesh eval` and the demo: how far a trajectory and a mesh are from the
//! truth (docs/design.md §3, [`docs/design.md`](../../docs/design.md) §3).
//!
//! | what | module |
//! |---|---|
//! | consecutive-frame errors, end-point drift, ATE, KITTI segment errors | [`odometry`] |
//! | mesh precision, recall and F-score against a point cloud | [`mesh`] |

pub mod mesh;
pub mod odometry;
