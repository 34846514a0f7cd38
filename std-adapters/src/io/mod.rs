//! File plumbing every room shares: errors that name the file, the line or record and the
//! reason ([`FileError`]), and outputs written to a temporary name then renamed ([`atomic`]).
//! What is read and written lives in the rooms above: [`crate::formats`] (file formats),
//! [`crate::sources`] (where frames come from) and [`crate::outputs`] (what a run writes).
//!
//! | what | module |
//! |---|---|
//! | errors naming the file, line and reason | [`error`] |
//! | write-then-rename | [`atomic`] |
//! | little-endian records of a run's state | [`le`] |
//! | the log's lines to a second way out (the node's `/rosout`) | [`log_tap`] |

pub mod atomic;
pub mod error;
pub mod le;
pub mod log_tap;

pub use error::FileError;
