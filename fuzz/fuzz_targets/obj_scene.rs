#![no_main]
//! The `obj_scene` target: see `xtask::fuzz::checks::obj_scene` for what it checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = xtask::fuzz::checks::obj_scene(data) {
        panic!("{e}");
    }
});
