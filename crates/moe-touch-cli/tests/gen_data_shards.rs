//! An array job in practice: `gen-data --shard auto/N` run once per task with the scheduler's
//! index variable set (Slurm's and Kubernetes'), then `--merge`, gives the shards and card of
//! one unsplit run, byte for byte.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

use common::PARAMS;

fn scratch(name: &str) -> PathBuf {
    common::scratch("shards", name)
}

fn gen_data(
    out: &Path,
    params: &Path,
    shard: &str,
    env: &[(&str, &str)],
    merge: bool,
) -> std::process::Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_moe-touch"));
    cmd.args([
        "gen-data",
        "--trajectories",
        "3",
        "--trajectories-per-shard",
        "1",
    ])
    .args(["--seed", "5", "--shard", shard])
    .arg("--out")
    .arg(out)
    .arg("--params")
    .arg(params)
    .env_remove("SLURM_ARRAY_TASK_ID")
    .env_remove("SLURM_ARRAY_TASK_MIN")
    .env_remove("JOB_COMPLETION_INDEX");
    if merge {
        cmd.arg("--merge");
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().unwrap()
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    out.sort();
    out
}

#[test]
fn array_tasks_from_the_scheduler_s_environment_equal_one_unsplit_run() {
    let root = scratch("array");
    let params = root.join("params.toml");
    std::fs::write(&params, PARAMS).unwrap();
    let whole = root.join("whole");
    let out = gen_data(&whole, &params, "1/1", &[], false);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    for (name, tasks) in [
        // Slurm, --array=0-2: the minimum is subtracted.
        (
            "slurm",
            vec![
                vec![("SLURM_ARRAY_TASK_ID", "0"), ("SLURM_ARRAY_TASK_MIN", "0")],
                vec![("SLURM_ARRAY_TASK_ID", "1"), ("SLURM_ARRAY_TASK_MIN", "0")],
                vec![("SLURM_ARRAY_TASK_ID", "2"), ("SLURM_ARRAY_TASK_MIN", "0")],
            ],
        ),
        // Kubernetes Indexed Job: 0-based completion indexes.
        (
            "k8s",
            vec![
                vec![("JOB_COMPLETION_INDEX", "2")],
                vec![("JOB_COMPLETION_INDEX", "0")],
                vec![("JOB_COMPLETION_INDEX", "1")],
            ],
        ),
    ] {
        let dir = root.join(name);
        // After the first task, merging names what is missing.
        for (k, env) in tasks.iter().enumerate() {
            let out = gen_data(&dir, &params, "auto/3", env, false);
            assert!(
                out.status.success(),
                "{name} task {k}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            if k == 0 {
                let early = gen_data(&dir, &params, "1/3", &[], true);
                assert!(!early.status.success());
                let err = String::from_utf8_lossy(&early.stderr);
                assert!(err.contains("2 of 3 shards are missing"), "{err}");
            }
        }
        let merged = gen_data(&dir, &params, "1/3", &[], true);
        assert!(
            merged.status.success(),
            "{}",
            String::from_utf8_lossy(&merged.stderr)
        );
        assert_eq!(
            files(&dir),
            files(&whole),
            "{name}: the union differs from one run"
        );
    }
    // Without any scheduler variable, `auto` is one clear error line.
    let out = gen_data(&root.join("none"), &params, "auto/3", &[], false);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("none of SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    let _ = std::fs::remove_dir_all(&root);
}
