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

/// Runs the `moe-touch` binary with `args` in the working directory `dir`.
pub(crate) fn run_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_moe-touch"))
        .args(args)
        .current_dir(dir)
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

/// Keys of the JSON reports whose values are wall-clock timings or rates, or counts of the
/// work done (solves) that another machine's round-off can move by an iteration.
const TIMING_KEYS: [&str; 19] = [
    "contact_ms",
    "degraded_fingers",
    "detect_ms",
    "estimate_ms",
    "fit_secs",
    "frames_per_second",
    "markers_ms",
    "mesh_secs",
    "points_ms",
    "poisson_secs",
    "query_secs",
    "shape_ms",
    "solves",
    "steps_per_sec",
    "stream_ms",
    "total_ms",
    "total_secs",
    "variance_secs",
    "wall_secs",
];

/// Keys whose values are exact on one machine only (a hash of the state's bits).
const MACHINE_KEYS: [&str; 1] = ["state_digest"];

/// A JSON report made comparable across runs and machines for a snapshot: the wall-clock
/// timings and rates of [`TIMING_KEYS`] become `"[timing]"` and the machine-exact values of
/// [`MACHINE_KEYS`] `"[machine]"`; paths under `scratch` become `[scratch]/…` and paths into
/// the committed fixtures `[fixtures]/…`; numbers are rounded to 6 significant digits, and the
/// round-off of quantities that are zero in exact arithmetic is written 0: any magnitude below
/// 1e-15 (an ARAP energy at rest, a sine of π in a pose), and a length in metres (a key ending
/// in `_m`) below 1 nm (the centre of a sphere fitted around the origin).
/// Last-bit differences between SIMD paths stay invisible; real changes do not.
pub(crate) fn stable(value: serde_json::Value, scratch: &Path) -> serde_json::Value {
    use serde_json::Value;
    let dirs = [
        (scratch.to_string_lossy().into_owned(), "[scratch]"),
        (fixtures().to_string_lossy().into_owned(), "[fixtures]"),
    ];
    fn walk(v: Value, dirs: &[(String, &str)], metres: bool) -> Value {
        match v {
            Value::Object(map) => Value::Object(
                map.into_iter()
                    .map(|(k, v)| {
                        let v = if TIMING_KEYS.contains(&k.as_str()) && !v.is_null() {
                            Value::String("[timing]".into())
                        } else if MACHINE_KEYS.contains(&k.as_str()) {
                            Value::String("[machine]".into())
                        } else {
                            walk(v, dirs, k.ends_with("_m"))
                        };
                        (k, v)
                    })
                    .collect(),
            ),
            Value::Array(items) => {
                Value::Array(items.into_iter().map(|v| walk(v, dirs, metres)).collect())
            }
            Value::String(s) => Value::String(
                dirs.iter()
                    .fold(s, |s, (dir, name)| s.replace(dir.as_str(), name)),
            ),
            Value::Number(n) if !(n.is_u64() || n.is_i64()) => {
                let x = n.as_f64().unwrap_or(f64::NAN);
                let rounded: f64 = format!("{x:.5e}").parse().unwrap_or(x);
                let zero = rounded.abs() < 1e-15 || (metres && rounded.abs() < 1e-9);
                serde_json::json!(if zero { 0.0 } else { rounded })
            }
            other => other,
        }
    }
    walk(value, &dirs, false)
}
