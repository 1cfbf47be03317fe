//! On-target tests of the MMIC-I no_std core, for QEMU `virt` (RV32IMC).
//!
//! Run: `cargo run` in this directory (the runner is qemu-system-riscv32 with
//! semihosting). Prints one line per test and `N passed, N failed`; the exit code is 0
//! only when every test passed.
#![no_std]
#![no_main]
#![deny(warnings)]
// A failure carries its message by value (no heap on this target); tests are not hot.
#![allow(clippy::result_large_err)]

mod harness;
mod mock;
mod t_boot;
mod t_budget;
mod t_codec;
mod t_cycle;
mod t_domain;
mod t_filehk;
mod t_files;
mod t_framelink;
mod t_framing;
mod t_link;
mod t_modules;
mod t_obsw;
mod t_packets;
mod t_periph;
mod t_reconfig;
mod t_spacelink;
mod t_store;
mod t_support;
mod t_team;
mod t_update;

/// No heap: every allocation fails (`fw_core::no_heap`: why one is named at all).
#[global_allocator]
static NO_HEAP: fw_core::no_heap::NoHeap = fw_core::no_heap::NoHeap;

#[riscv_rt::entry]
fn main() -> ! {
    let code = harness::run(&[
        t_codec::TESTS,
        t_packets::TESTS,
        t_framing::TESTS,
        t_periph::TESTS,
        t_link::TESTS,
        t_support::TESTS,
        t_boot::TESTS,
        t_reconfig::TESTS,
        t_domain::TESTS,
        t_obsw::TESTS,
        t_cycle::TESTS,
        t_spacelink::TESTS,
        t_framelink::TESTS,
        t_team::TESTS,
        t_modules::TESTS,
        t_store::TESTS,
        t_update::TESTS,
        t_files::TESTS,
        t_filehk::TESTS,
        t_budget::TESTS,
    ]);
    semihosting::process::exit(code)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    harness::report_panic(info);
    semihosting::process::exit(101)
}
