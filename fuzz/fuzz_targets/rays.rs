#![no_main]
//! The `rays` target: see `xtask::fuzz::checks::rays` for what it checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = xtask::fuzz::checks::rays(data) {
        panic!("{e}");
    }
});
