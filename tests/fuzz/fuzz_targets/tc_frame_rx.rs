#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mmic_fuzz::tc_frame_rx::run(data));
