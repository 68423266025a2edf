//! The guide's code blocks against the files they show: the pages quote example crates,
//! and the tests check that each quote is the file as it is.

use std::path::{Path, PathBuf};

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("host-tests lives in the repository")
        .to_path_buf()
}

/// The file at `path` (relative to the repository's root).
pub fn read(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The body of the first code block after the line `marker` in `doc` (`page` names the
/// page in the panic message when the marker is missing).
pub fn block_after(doc: &str, marker: &str, page: &str) -> String {
    let start = doc
        .find(marker)
        .unwrap_or_else(|| panic!("{page} has no `{marker}`"));
    let rest = &doc[start..];
    let open = rest.find("```").expect("a code block after the marker");
    let body = &rest[open..];
    let body = &body[body.find('\n').expect("a fence line") + 1..];
    body[..body.find("\n```").expect("a closing fence") + 1].to_string()
}

/// Lines of code in Rust source: neither blank nor a comment line (`//`, `//!`, `///`).
/// A line with code and a trailing comment counts.
pub fn code_lines(source: &str) -> usize {
    source
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("//"))
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn code_lines_skip_blanks_and_comment_lines_only() {
        let src = "//! doc\n\nuse a; // why\n    /// item doc\nfn f() {}\n  // note\n";
        assert_eq!(code_lines(src), 2);
    }

    #[test]
    fn block_after_takes_the_next_fenced_block() {
        let doc = "x\n<!-- m -->\ntext\n```rust\nfn a() {}\n```\n```\nno\n```\n";
        assert_eq!(block_after(doc, "<!-- m -->", "doc"), "fn a() {}\n");
    }
}
