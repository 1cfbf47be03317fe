//! MMIC-I ground tool library: PUS packets, plans, links, the archive and live
//! operations. The `ground` binary is a thin CLI over these modules.

pub mod alarms;
pub use ground_archive as archive;
pub mod collect;
pub mod dashboard;
pub use ground_ops::{keys, link, link_choice, ops, plan, robot_lock};
pub use ground_pus as pus;
