//! The getting-started page's firmware is `examples/minimal-adapter` as it is, and the code
//! a user writes to make a PD adaptive stays within 30 lines. (CI builds that crate from a
//! copy outside the repository and runs it on QEMU: `scripts/firmware-ci`.)

use host_tests::guide::{block_after, code_lines, read};

const PAGE: &str = "docs/getting-started.md";

/// Checks: each file of the example that the page quotes is shown byte for byte.
#[test]
fn the_page_shows_the_example_as_it_is() {
    let doc = read(PAGE);
    for file in [
        "examples/minimal-adapter/src/main.rs",
        "examples/minimal-adapter/src/my_pd.rs",
    ] {
        let shown = block_after(&doc, &format!("<!-- {file} -->"), PAGE);
        assert!(
            shown == read(file),
            "{PAGE} shows another {file}: copy the file into the page"
        );
    }
}

/// Checks: the integration code (main.rs; rustfmt-formatted, which CI checks) is at most
/// 30 lines of code, imports included, comments and blank lines not. `my_pd.rs` is the PD
/// the user already had, and `robot.rs` stands for the board's I/O.
#[test]
fn wrapping_a_pd_takes_at_most_30_lines() {
    let lines = code_lines(&read("examples/minimal-adapter/src/main.rs"));
    println!("examples/minimal-adapter/src/main.rs: {lines} lines of code");
    assert!(lines <= 30, "{lines} lines");
}
