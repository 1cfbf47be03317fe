#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mmic_fuzz::cobs_deframer::run(data));
