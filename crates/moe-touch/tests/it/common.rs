//! Helpers shared by the command-line tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `moe-touch` binary with `args`.
pub(crate) fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_moe-touch"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("the moe-touch binary runs")
}

/// A fresh, empty scratch directory for one test.
pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("moe-touch-it-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// The workspace's `fixtures/` directory.
pub(crate) fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

/// Asserts that a command failed with exactly one line on stderr starting with `error:`.
pub(crate) fn assert_one_line_error(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "expected failure, got {:?}",
        out.status
    );
    let stderr = String::from_utf8_lossy(&out.stderr).trim_end().to_owned();
    assert_eq!(
        stderr.lines().count(),
        1,
        "one line on stderr, got:\n{stderr}"
    );
    assert!(stderr.starts_with("error:"), "{stderr}");
    stderr
}

/// Runs `moe-touch` with `args` and asserts that it succeeded (showing its stderr if not).
pub(crate) fn run_ok(args: &[&str]) -> Output {
    let out = run(args);
    assert!(
        out.status.success(),
        "moe-touch {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `moe-touch` with `args`, asserts success and parses stdout as one JSON object.
pub(crate) fn run_json(args: &[&str]) -> serde_json::Value {
    let out = run_ok(args);
    serde_json::from_slice(&out.stdout).expect("one JSON object on stdout")
}

/// A JSON report made comparable across runs and machines for a snapshot: every timing or rate
/// (a key ending in `_ms`, `_secs`, `_per_second` or `_per_sec`, or `secs`, `fps`) becomes
/// `"[timing]"`, paths
/// under `scratch` become `[scratch]/…`, and numbers are rounded to 6 significant digits, with
/// magnitudes below 1e-9 written as 0 (round-off of a quantity that is zero in exact arithmetic,
/// such as the centre of a sphere fitted to points around the origin): last-bit differences
/// between SIMD paths stay invisible, real changes do not.
pub(crate) fn stable(value: serde_json::Value, scratch: &Path) -> serde_json::Value {
    use serde_json::Value;
    let dir = scratch.to_string_lossy().into_owned();
    fn is_timing(key: &str) -> bool {
        key.ends_with("_ms")
            || key.ends_with("_secs")
            || key.ends_with("_per_second")
            || key.ends_with("_per_sec")
            || key == "secs"
            || key == "fps"
    }
    fn walk(v: Value, dir: &str) -> Value {
        match v {
            Value::Object(map) => Value::Object(
                map.into_iter()
                    .map(|(k, v)| {
                        let v = if is_timing(&k) && !v.is_null() {
                            Value::String("[timing]".into())
                        } else {
                            walk(v, dir)
                        };
                        (k, v)
                    })
                    .collect(),
            ),
            Value::Array(items) => Value::Array(items.into_iter().map(|v| walk(v, dir)).collect()),
            Value::String(s) => Value::String(s.replace(dir, "[scratch]")),
            Value::Number(n) if !(n.is_u64() || n.is_i64()) => {
                let x = n.as_f64().unwrap_or(f64::NAN);
                let rounded: f64 = format!("{x:.5e}").parse().unwrap_or(x);
                serde_json::json!(if rounded.abs() < 1e-9 { 0.0 } else { rounded })
            }
            other => other,
        }
    }
    walk(value, &dir)
}
