//! The README's Rust example is this crate's `src/main.rs`, which depends on `moe-touch` alone.

use std::path::Path;

/// The code after the file's leading `//!` lines.
fn code_of(text: &str) -> String {
    text.lines()
        .skip_while(|l| l.starts_with("//!") || l.is_empty())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_readme_example_is_this_crate_and_needs_moe_touch_alone() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(here.join("../../README.md")).unwrap();
    let block = readme
        .split("```rust")
        .nth(1)
        .and_then(|rest| rest.split_once('\n'))
        .and_then(|(_, rest)| rest.split("```").next())
        .expect("README has a Rust example");
    let main = std::fs::read_to_string(here.join("src/main.rs")).unwrap();
    assert_eq!(block.trim(), code_of(&main).trim());
    // The manifest's only dependency is the runtime.
    let manifest = std::fs::read_to_string(here.join("Cargo.toml")).unwrap();
    let deps: Vec<&str> = manifest
        .split("[dependencies]")
        .nth(1)
        .unwrap()
        .lines()
        .take_while(|l| !l.starts_with('['))
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .collect();
    assert_eq!(deps.len(), 1, "{deps:?}");
    assert!(deps[0].starts_with("moe-touch "), "{deps:?}");
}

/// Run from the repository's root, the example prints one line per frame of the demo episode
/// and finds the plate's press on finger 0 (none in the first frame, some later).
#[test]
fn the_example_runs_and_finds_the_press() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_moe-touch-quickstart"))
        .current_dir(&root)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let contacts: Vec<usize> = text
        .lines()
        .map(|l| {
            let (head, _) = l.split_once(" contact points").unwrap();
            head.rsplit(' ').next().unwrap().parse().unwrap()
        })
        .collect();
    assert_eq!(contacts.len(), 7, "{text}");
    assert_eq!(contacts[0], 0, "{text}");
    assert!(contacts.iter().any(|&n| n > 0), "{text}");
}
