//! Every fuzz target's check on its seeds and on every input that once failed it
//! (`fuzz/regressions/<target>/`): the fuzzers' findings stay fixed on the stable toolchain.

use xtask::fuzz::{checks, fuzz_dir, generated_seeds, read_folder, shared_seeds};

#[test]
fn seeds_and_saved_failures_pass_every_check() {
    let mut failures = Vec::new();
    let mut inputs = 0;
    for (target, check) in checks::TARGETS {
        let mut files = Vec::new();
        for sub in ["seeds", "regressions"] {
            files.extend(read_folder(&fuzz_dir().join(sub).join(target)).unwrap());
        }
        files.extend(generated_seeds(target));
        files.extend(shared_seeds(target));
        assert!(!files.is_empty(), "{target}: no seeds");
        for (name, bytes) in files {
            inputs += 1;
            if let Err(e) = check(&bytes) {
                failures.push(format!("{target}/{name}: {e}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    println!("{inputs} inputs checked");
}

/// The decoder turns any bytes into values, special ones included.
#[test]
fn decoder_reads_lattice_special_and_raw_values() {
    let raw = 1.5f32.to_le_bytes();
    let bytes = [112, 116, 224 + 11, 240, raw[0], raw[1], raw[2], raw[3]];
    let mut d = checks::Decoder::new(&bytes);
    assert_eq!(d.value(), 0.0);
    assert_eq!(d.value(), 1.0);
    assert!(d.value().is_nan());
    assert_eq!(d.value(), 1.5);
    assert!(d.is_empty());
    assert_eq!(d.value(), -28.0, "past the end, zero bytes");
}
