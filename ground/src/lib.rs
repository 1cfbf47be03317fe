//! MMIC-I ground tool library: PUS packets, plans, links, the archive and live
//! operations. The `ground` binary is a thin CLI over these modules.

pub mod alarms;
pub use ground_archive as archive;
pub mod collect;
pub mod dashboard;
pub mod keys;
pub mod link;
pub mod link_choice;
pub mod ops;
pub mod plan;
pub mod robot_lock;
pub use ground_pus as pus;
