//! MMIC-I ground tool library: PUS packets, plans, links, the archive and live
//! operations. The `ground` binary is a thin CLI over these modules.

pub use ground_archive as archive;
pub use ground_collect as collect;
pub use ground_collect::alarms;
pub use ground_dashboard as dashboard;
pub use ground_ops::{keys, link, link_choice, ops, plan, robot_lock};
pub use ground_pus as pus;
