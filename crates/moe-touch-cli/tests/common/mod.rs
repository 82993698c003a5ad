//! Shared by the data, training and evaluation tests: small, fast randomised scenes and scratch directories.

use std::path::PathBuf;

/// Small, fast scenes: a coarse finger and a 0.2 s press.
pub(crate) const PARAMS: &str = "press_secs = 0.1\nhold_secs = 0.05\nretract_secs = 0.05\n\
    save_every_steps = 4\n[finger]\nvertex_budget = 120\n";

/// A fresh empty directory under the system's temporary directory.
pub(crate) fn scratch(test: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("moe-touch-{test}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
