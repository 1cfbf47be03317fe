//! MMIC-I ground operations: the per-robot commanding engine ([`ops::Session`], the
//! commanding book, the plan executor and its runs), the plans it executes ([`plan`]),
//! the live link of every front end ([`live`]: link state, sequence tracking, gap
//! retrieval), the links it commands over ([`link`]: the space link through `ground-link`, or a
//! bare-packet lab link; [`link_choice`]), one commanding ground per robot
//! ([`robot_lock`]) and the space link's key files ([`keys`]).
//!
//! Below the collector and the dashboard (crate `ground`, which re-exports these modules
//! under the same paths); it needs neither axum nor tokio, nor clap or anyhow: its errors
//! are typed.

pub mod keys;
pub mod link;
pub mod link_choice;
pub mod live;
pub mod ops;
pub mod plan;
pub mod robot_lock;

// The crates below, under the names the modules use (`crate::pus`, `crate::archive`).
use ground_archive as archive;
use ground_pus as pus;
