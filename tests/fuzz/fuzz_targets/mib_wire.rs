#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mmic_fuzz::mib_wire::run(data));
