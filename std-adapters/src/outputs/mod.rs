//! What a run writes beside its trajectories and report: the mesh on its way to disk and the
//! picture of it. Outputs write through [`crate::formats`], each to a temporary name then
//! renamed ([`crate::io::atomic`]).
//!
//! | what | module |
//! |---|---|
//! | the run's mesh on its way to disk | [`mesh_spool`] |
//! | one indexed mesh from map layers, shared vertices merged, with normals | [`mesh_weld`] |
//! | a picture of the mesh from above (PNG), with its legend and plots | [`topview`] |

pub mod mesh_spool;
pub mod mesh_weld;
pub mod topview;
