//! On-board plans (PUS 18 on-board operations procedures): a component with its own
//! state that the obsw composes.
//!
//! - [`image`]: the compact, checksummed form of one robot's share of a plan (layout in
//!   `mib::plan`), parsed on board with every check the format allows and emitted by the
//!   ground's compiler from the same code.
//! - [`exec`]: the executor. It never runs a TC itself: it hands the obsw the next step's
//!   TC when the step may start (its own earlier steps done, every dependency announced
//!   completed by the robot it names, its wait over), and learns the step's outcome from
//!   the obsw's verification. A failed or late step suspends the plan; nothing is guessed
//!   (an unconfirmed dependency waits).
//!
//! Interface to the obsw: the TCs of service 18 ([`exec::Plan::load`], `commit`, `start`,
//! `suspend`, `resume`, `abort`, `skip`, `status`), the parameters of HK structure PLAN
//! ([`exec::Plan::param`]), the step TCs it asks to run ([`exec::Plan::poll`]), the state
//! changes it reports ([`exec::Change`]) and the progress announcements it sends and takes
//! on the team link ([`exec::Plan::announcement`], [`exec::Plan::peer_progress`]).
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

pub mod exec;
pub mod image;

pub use exec::{Change, Control, Plan, Poll, Refusal, State};
pub use image::{Dep, Image, ImageError, StepKind, StepRepr, StepView};
