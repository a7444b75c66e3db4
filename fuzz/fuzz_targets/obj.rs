#![no_main]
//! The `obj` target: see `xtask::fuzz::checks::obj` for what it checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = xtask::fuzz::checks::obj(data) {
        panic!("{e}");
    }
});
