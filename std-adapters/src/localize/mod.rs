//! Finding a run's pose in the saved map it started from (docs/design.md §1.13), and paging
//! that map under a memory cap (§1.12): in a run, a stage ([`stage`]).
//!
//! | what | module |
//! |---|---|
//! | the candidates of a search, and what the report says of it | [`search`] |
//! | a saved map paged in by tile under a memory cap | [`pager`] |
//! | the search and the pager as one of a run's stages | [`stage`] |

pub mod pager;
pub mod search;
pub mod stage;
