//! `cargo xtask ci`: the checks CI runs, cheapest first, stopping at the first failure. The
//! golden fixtures are checked by `cargo test` (`crates/moe-touch-cli/tests/golden.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;

/// Arguments of `cargo xtask ci`.
#[derive(Debug, Args)]
pub(crate) struct CiArgs {
    /// Skip `cargo deny` (for quick local runs; CI never skips it).
    #[arg(long)]
    skip_deny: bool,
    /// The Python interpreter of a virtual environment with pip, pytest, numpy and hypothesis,
    /// in which the Python package is installed (`pip install ./python`) and tested [default:
    /// $MOE_TOUCH_PYTHON; `.ci/run` makes a fresh one].
    #[arg(long, value_name = "PYTHON")]
    python: Option<PathBuf>,
    /// Skip the Python package (for quick local runs; CI never skips it).
    #[arg(long)]
    skip_python: bool,
}

/// The workspace root (the parent of this crate's directory).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn cargo() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.current_dir(workspace_root());
    c
}

fn step(name: &str, mut cmd: Command) -> Result<()> {
    eprintln!("xtask ci: {name} ...");
    let t = Instant::now();
    let status = cmd.status().with_context(|| format!("starting {name}"))?;
    if !status.success() {
        bail!("{name} failed ({status})");
    }
    eprintln!("xtask ci: {name} ok ({:.0} s)", t.elapsed().as_secs_f64());
    Ok(())
}

/// Crates the runtime library must never depend on, whatever its features
/// (`cargo tree -p moe-touch -e normal`).
const NEVER_IN_THE_RUNTIME: [&str; 6] =
    ["moe-lab", "moe-gpis", "clap", "anyhow", "image", "foxglove"];

/// Crates the runtime takes only when a feature asks for them: the simulator's mechanics with
/// `physics`, candle with `dgcnn`.
const ONLY_BY_FEATURE: [(&str, &str); 2] =
    [("moe-tendon-sim", "physics"), ("candle-core", "dgcnn")];

/// The runtime's tree (`cargo tree -p moe-touch -e normal`) with `features`, as names.
fn runtime_tree(features: &str) -> Result<Vec<String>> {
    let mut cmd = cargo();
    cmd.args([
        "tree",
        "-p",
        "moe-touch",
        "-e",
        "normal",
        "--prefix",
        "none",
        "--locked",
    ]);
    if !features.is_empty() {
        cmd.args(["--features", features]);
    }
    let out = cmd.output().context("starting cargo tree")?;
    if !out.status.success() {
        bail!(
            "cargo tree -p moe-touch --features '{features}' failed ({})",
            out.status
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .collect())
}

/// The runtime alone, with the physics estimator, and with everything a user may ask for: its
/// tree holds no simulator scenes, command-line parser, image codec, anyhow or protobuf, never
/// the experiments or surface reconstruction, and the simulator's mechanics or candle only when
/// their feature is on.
fn runtime_tree_is_lean() -> Result<()> {
    for features in ["", "physics", "dgcnn", "physics,dgcnn"] {
        let tree = runtime_tree(features)?;
        let has = |name: &str| tree.iter().any(|n| n == name);
        let mut found: Vec<&str> = NEVER_IN_THE_RUNTIME
            .iter()
            .copied()
            .filter(|n| has(n))
            .collect();
        found.extend(
            ONLY_BY_FEATURE
                .iter()
                .filter(|(name, feature)| has(name) && !features.split(',').any(|f| f == *feature))
                .map(|(name, _)| *name),
        );
        if !found.is_empty() {
            bail!(
                "the runtime (moe-touch, features '{features}') depends on {}",
                found.join(", ")
            );
        }
        eprintln!(
            "xtask ci: moe-touch's tree (features '{features}') holds none of {}{}",
            NEVER_IN_THE_RUNTIME.join(", "),
            ONLY_BY_FEATURE
                .iter()
                .filter(|(_, feature)| !features.split(',').any(|f| f == *feature))
                .map(|(name, _)| format!(", {name}"))
                .collect::<String>()
        );
    }
    Ok(())
}

/// The Python package as a user installs it (`pip install ./python`, which builds the wheel with
/// maturin), then its pytest suite against the `moe-touch` tool of the same tree. The wheel is
/// built with the dev profile (dependencies optimised, the workspace's crates at `opt-level = 1`)
/// in the workspace's target directory: a release build of the whole tree would add minutes.
fn python_package(args: &CiArgs) -> Result<()> {
    let python = match &args.python {
        Some(p) => p.clone(),
        None => std::env::var_os("MOE_TOUCH_PYTHON")
            .map(PathBuf::from)
            .context(
                "the Python package needs a virtual environment with pytest, numpy and hypothesis: \
             --python PATH or $MOE_TOUCH_PYTHON (.ci/run makes one), or --skip-python",
            )?,
    };
    let root = workspace_root();
    let mut tool = cargo();
    tool.args([
        "build",
        "--locked",
        "-p",
        "moe-touch-cli",
        "-p",
        "moe-touch-quickstart",
    ]);
    step(
        "cargo build -p moe-touch-cli -p moe-touch-quickstart (for the Python comparisons)",
        tool,
    )?;

    let mut install = Command::new(&python);
    install
        .current_dir(&root)
        .args([
            "-m",
            "pip",
            "install",
            "--force-reinstall",
            "--no-deps",
            "./python",
        ])
        .env("MATURIN_PEP517_ARGS", "--profile dev --locked");
    step("pip install ./python", install)?;

    let mut pytest = Command::new(&python);
    pytest
        .current_dir(root.join("python"))
        .args(["-m", "pytest", "-q", "tests"])
        .env("MOE_TOUCH_BIN", target_dir(&root).join("debug/moe-touch"))
        .env(
            "MOE_TOUCH_QUICKSTART_BIN",
            target_dir(&root).join("debug/moe-touch-quickstart"),
        )
        .env("CI", "true");
    step("pytest python/tests", pytest)
}

/// Cargo's target directory: `$CARGO_TARGET_DIR`, else the workspace's `target`.
fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), PathBuf::from)
}

fn has_cargo_deny() -> bool {
    cargo()
        .args(["deny", "--version"])
        .output()
        .is_ok_and(|o| o.status.success())
}

pub(crate) fn run(args: &CiArgs) -> Result<()> {
    let mut fmt = cargo();
    fmt.args(["fmt", "--all", "--", "--check"]);
    step("cargo fmt --check", fmt)?;

    let mut clippy = cargo();
    clippy.args([
        "clippy",
        "--workspace",
        "--all-targets",
        "--locked",
        "--",
        "-D",
        "warnings",
    ]);
    step("cargo clippy -D warnings", clippy)?;

    // The runtime alone and with each feature (features resolved for it, not the workspace):
    // it must build, and its tree must hold nothing it does not ask for.
    for features in ["", "physics", "dgcnn"] {
        let mut runtime = cargo();
        runtime.args(["clippy", "-p", "moe-touch", "--locked"]);
        if !features.is_empty() {
            runtime.args(["--features", features]);
        }
        runtime.args(["--", "-D", "warnings"]);
        step(
            &format!("cargo clippy -p moe-touch --features '{features}' (the runtime alone)"),
            runtime,
        )?;
    }
    runtime_tree_is_lean()?;

    let mut test = cargo();
    test.args(["test", "--workspace", "--locked"]);
    step("cargo test --workspace", test)?;

    // The examples a newcomer runs first must keep running, not only compiling.
    for (package, example) in [("moe-arap", "deform"), ("moe-contact", "own_finger")] {
        let mut run = cargo();
        run.args(["run", "--locked", "-p", package, "--example", example]);
        step(&format!("example {package}/{example}"), run)?;
    }

    if args.skip_python {
        eprintln!("xtask ci: the Python package skipped (--skip-python)");
    } else {
        python_package(args)?;
    }

    let mut doc = cargo();
    doc.args(["doc", "--workspace", "--no-deps", "--locked"])
        .env("RUSTDOCFLAGS", "-D warnings");
    step("cargo doc", doc)?;

    if args.skip_deny {
        eprintln!("xtask ci: cargo deny skipped (--skip-deny)");
        return Ok(());
    }
    if !has_cargo_deny() {
        let mut install = cargo();
        install.args(["install", "cargo-deny", "--locked"]);
        step("cargo install cargo-deny", install)?;
    }
    let mut deny = cargo();
    deny.args(["deny", "check", "licenses", "bans", "sources"]);
    step("cargo deny check licenses bans sources", deny)?;
    eprintln!("xtask ci: all checks passed");
    Ok(())
}
