#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mmic_fuzz::ground_tm_frames::run(data));
