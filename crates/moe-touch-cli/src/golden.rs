//! `cargo xtask fixtures`: every golden fixture of `moe_lab::golden` recomputed and checked
//! against its committed file, or rewritten; one line per fixture on stderr.

use anyhow::{Context, Result, bail};
use moe_lab::golden::{FIXTURES, workspace_root};
use serde_json::Value;

/// What [`run`] does with each fixture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Recompute every golden fixture and fail on any difference.
    Check,
    /// Recompute every golden fixture and overwrite the committed files.
    Update,
}

/// Recomputes every golden fixture of the workspace and checks it against the committed file
/// (numbers within the fixture's relative tolerance, everything else exactly), or rewrites it.
///
/// # Errors
/// A fixture that cannot be computed, read or written, or (checking) that differs.
pub fn run(mode: Mode) -> Result<()> {
    let root = workspace_root();
    let mut failures = Vec::new();
    for fixture in FIXTURES {
        let fresh = fixture
            .compute(&mut |line| eprintln!("{line}"))
            .with_context(|| format!("computing {}", fixture.path))?;
        if mode == Mode::Update {
            fixture.write(&root, &fresh)?;
            eprintln!("fixtures: wrote {}", fixture.path);
            continue;
        }
        let text = std::fs::read_to_string(root.join(fixture.path)).with_context(|| {
            format!(
                "reading {} (run `cargo xtask fixtures --update` to create it)",
                fixture.path
            )
        })?;
        let committed: Value = if fixture.is_toml() {
            toml::from_str(&text).with_context(|| format!("parsing {}", fixture.path))?
        } else {
            serde_json::from_str(&text).with_context(|| format!("parsing {}", fixture.path))?
        };
        match fixture.first_difference(&committed, &fresh) {
            None => eprintln!("fixtures: {} ok", fixture.path),
            Some(diff) => {
                eprintln!("fixtures: {} differs: {diff}", fixture.path);
                failures.push(fixture.path);
            }
        }
    }
    if !failures.is_empty() {
        bail!(
            "{} golden fixture(s) differ: {}",
            failures.len(),
            failures.join(", ")
        );
    }
    Ok(())
}
