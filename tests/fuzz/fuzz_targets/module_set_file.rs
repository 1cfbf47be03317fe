#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mmic_fuzz::module_set_file::run(data));
