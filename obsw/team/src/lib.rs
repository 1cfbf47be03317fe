//! MMIC-I team coordination when the ground is gone: leader selection (terms persisted
//! before voting, quorum of a fixed roster, randomised timeouts, leader lease) with limited
//! authority, and the paper's Floodmax as a baseline. `no_std`, no heap, time passed in.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
