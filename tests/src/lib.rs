//! Cross-crate tests live in `tests/`; this library only runs the README's Rust example as a
//! doctest, so the example a user copies is compiled and run by `cargo test --workspace`.
#![doc = include_str!("../../README.md")]
