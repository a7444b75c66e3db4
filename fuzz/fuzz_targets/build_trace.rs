#![no_main]
//! The `build_trace` target: see `xtask::fuzz::checks::build_trace` for what it checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = xtask::fuzz::checks::build_trace(data) {
        panic!("{e}");
    }
});
