//! MMIC-I team coordination when the ground is gone: leader selection (terms persisted
//! before voting, quorum of a fixed roster, randomised timeouts, leader lease) with limited
//! authority, and the paper's Floodmax as a baseline. `no_std`, no heap, time passed in.
//!
//! - [`wire`]: team messages on the inter-robot link (checked parse/emit);
//! - [`node`]: one robot's election and authority state machine;
//! - [`floodmax`]: the paper's Floodmax (Lynch's FloodMax), the baseline.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]

pub mod floodmax;
pub mod node;
pub mod wire;

pub use node::{
    Action, Authorisation, Dest, Effect, Effects, HoldTarget, Input, Node, Persisted, Role, TeamEvent, TeamStatus,
};
pub use wire::{Body, Directive, Message, PlanRef, RobotId, TeamFunction};
