//! The PUS services, one file each: its requests (parsed from an accepted TC), its
//! state, its reports, and its unit tests.

pub mod event;
pub mod event_action;
pub mod function;
pub mod hk;
pub mod link;
pub mod mode;
pub mod modules;
pub mod monitoring;
pub mod parameter;
pub mod plan;
pub mod scheduling;
pub mod storage;
pub mod team;
pub mod test;
pub mod time;
pub mod update;
