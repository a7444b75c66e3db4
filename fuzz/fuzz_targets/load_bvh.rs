#![no_main]
//! The `load_bvh` target: see `xtask::fuzz::checks::load_bvh` for what it checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = xtask::fuzz::checks::load_bvh(data) {
        panic!("{e}");
    }
});
