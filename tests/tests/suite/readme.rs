//! The README's list of structures is the registry's own Markdown table, so it cannot drift
//! from the code (regenerate it with `cargo xtask accels --markdown`).

#[test]
fn readme_structures_table_is_the_registry() {
    let readme = include_str!("../../../README.md");
    let (begin, end) = ("<!-- accels:begin -->\n", "<!-- accels:end -->");
    let start = readme
        .find(begin)
        .expect("README has the accels:begin marker")
        + begin.len();
    let stop = readme[start..]
        .find(end)
        .expect("README has the accels:end marker")
        + start;
    assert_eq!(
        &readme[start..stop],
        xtask::registry::markdown_table(),
        "README's structures table differs from `cargo xtask accels --markdown`"
    );
}
