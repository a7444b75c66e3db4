#![no_main]
//! The `nff` target: see `xtask::fuzz::checks::nff` for what it checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = xtask::fuzz::checks::nff(data) {
        panic!("{e}");
    }
});
