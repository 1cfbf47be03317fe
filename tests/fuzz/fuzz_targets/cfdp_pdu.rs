#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| mmic_fuzz::cfdp_pdu::run(data));
