//! The library's version agrees with its CHANGELOG and its deprecations: the manifest
//! (`Cargo.toml` at the root) carries the version the CHANGELOG's newest section describes,
//! and no `#[deprecated(since = ...)]` of the library names a later version. docs.rs shows
//! the manifest's version beside every "Deprecated since" note.

use std::fs;
use std::path::{Path, PathBuf};

/// A release version `major.minor.patch` (pre-release and build suffixes are not used here).
type Version = (u64, u64, u64);

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn parse_version(text: &str) -> Option<Version> {
    let mut parts = text.trim().split('.').map(|p| p.parse::<u64>().ok());
    let version = (parts.next()??, parts.next()??, parts.next()??);
    parts.next().is_none().then_some(version)
}

/// The `version` of the `[package]` table of a Cargo manifest.
fn manifest_version(manifest: &str) -> Option<&str> {
    let package = manifest
        .split("\n[package]\n")
        .nth(1)
        .or_else(|| manifest.strip_prefix("[package]\n"))?;
    let table = package.split("\n[").next()?;
    table.lines().find_map(|line| {
        let value = line
            .strip_prefix("version")?
            .trim_start()
            .strip_prefix('=')?;
        Some(value.trim().trim_matches('"'))
    })
}

/// The version the CHANGELOG's newest section describes: the first `## [X.Y.Z]` heading, or
/// an `## [Unreleased]` section above it that says which version it prepares (a line
/// starting `Version X.Y.Z`). An `[Unreleased]` section that names none is skipped.
fn changelog_version(changelog: &str) -> Option<String> {
    let mut sections = changelog.split("\n## [").skip(1);
    sections.find_map(|section| {
        let (heading, body) = section.split_once(']')?;
        if heading == "Unreleased" {
            body.lines().find_map(|line| {
                let rest = line.strip_prefix("Version ")?;
                let end = rest.find(|c: char| !(c.is_ascii_digit() || c == '.'))?;
                Some(rest[..end].trim_end_matches('.').to_string())
            })
        } else {
            Some(heading.to_string())
        }
    })
}

/// Every `since = "..."` of a `#[deprecated(...)]` attribute in `source`, attributes over
/// several lines included.
fn deprecated_since(source: &str) -> Vec<String> {
    source
        .split("#[deprecated(")
        .skip(1)
        .filter_map(|attribute| {
            let attribute = &attribute[..attribute.find(")]")?];
            let value = attribute
                .split("since")
                .nth(1)?
                .trim_start()
                .strip_prefix('=')?;
            let value = value.trim_start().strip_prefix('"')?;
            Some(value[..value.find('"')?].to_string())
        })
        .collect()
}

fn rust_files(dir: &Path, files: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).expect("a readable source directory") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, files);
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
}

fn library_version() -> Version {
    let manifest = fs::read_to_string(root().join("Cargo.toml")).expect("Cargo.toml");
    let version = manifest_version(&manifest).expect("a [package] version in Cargo.toml");
    parse_version(version).unwrap_or_else(|| panic!("Cargo.toml's version {version:?}"))
}

#[test]
fn the_manifest_carries_the_version_of_the_changelogs_newest_section() {
    let changelog = fs::read_to_string(root().join("CHANGELOG.md")).expect("CHANGELOG.md");
    let described = changelog_version(&changelog).expect("a version section in CHANGELOG.md");
    let described = parse_version(&described)
        .unwrap_or_else(|| panic!("CHANGELOG.md's newest version {described:?}"));
    assert_eq!(
        library_version(),
        described,
        "Cargo.toml's version is not the one CHANGELOG.md's newest section describes"
    );
}

#[test]
fn no_deprecation_names_a_version_after_the_manifests() {
    let version = library_version();
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    let mut checked = 0;
    for file in files {
        let source = fs::read_to_string(&file).expect("a readable source file");
        for since in deprecated_since(&source) {
            let parsed = parse_version(&since)
                .unwrap_or_else(|| panic!("{}: deprecated since {since:?}", file.display()));
            assert!(
                parsed <= version,
                "{}: deprecated since {since}, after the crate's version {version:?}",
                file.display()
            );
            checked += 1;
        }
    }
    assert!(
        checked > 0,
        "no #[deprecated(since = ...)] found under src/"
    );
}

#[test]
fn the_parsers_read_what_they_are_meant_to() {
    assert_eq!(parse_version("0.2.0"), Some((0, 2, 0)));
    assert_eq!(parse_version("0.2"), None);
    assert_eq!(parse_version("0.2.0.1"), None);
    let manifest =
        "[package]\nname = \"x\"\nversion = \"1.4.2\"\n\n[dependencies]\nversion = \"9\"\n";
    assert_eq!(manifest_version(manifest), Some("1.4.2"));
    let released =
        "# Change Log\n\n## [Unreleased]\n\n### Added\n\n- x\n\n## [0.3.1]\n\n## [0.3.0]\n";
    assert_eq!(changelog_version(released).as_deref(), Some("0.3.1"));
    let preparing = "# Change Log\n\n## [Unreleased]\n\nVersion 0.4.0: more.\n\n## [0.3.1]\n";
    assert_eq!(changelog_version(preparing).as_deref(), Some("0.4.0"));
    let multi_line = "#[deprecated(\n    since = \"0.3.0\",\n    note = \"(gone)\"\n)]\nfn a() {}\n\
                      #[deprecated(note = \"no since\")]\nfn b() {}";
    assert_eq!(deprecated_since(multi_line), vec!["0.3.0".to_string()]);
}
