//! Tests of data set generation: shard specs, plans, resumed and split runs, cards.

use super::*;
use moe_geom::SeededRng;
use moe_tendon_sim::randomize::RandomSceneParams;

#[test]
fn shard_specs_take_the_index_from_the_scheduler() {
    let env = |vars: &'static [(&'static str, &'static str)]| {
        move |k: &str| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    };
    let none = env(&[]);
    assert_eq!(parse_shard_spec("2/4", &none).unwrap(), (2, 4));
    assert_eq!(
        parse_shard_spec("auto/4", &env(&[("SLURM_ARRAY_TASK_ID", "3")])).unwrap(),
        (3, 4)
    );
    assert_eq!(
        parse_shard_spec(
            "auto/4",
            &env(&[("SLURM_ARRAY_TASK_ID", "0"), ("SLURM_ARRAY_TASK_MIN", "0")])
        )
        .unwrap(),
        (1, 4)
    );
    assert_eq!(
        parse_shard_spec("auto/4", &env(&[("JOB_COMPLETION_INDEX", "3")])).unwrap(),
        (4, 4)
    );
    for (spec, vars, needle) in [
        ("auto/4", &[][..], "none of SLURM_ARRAY_TASK_ID"),
        (
            "auto/4",
            &[("JOB_COMPLETION_INDEX", "4")][..],
            "machine 5 of 4",
        ),
        (
            "auto/4",
            &[("SLURM_ARRAY_TASK_ID", "x")][..],
            "SLURM_ARRAY_TASK_ID=x",
        ),
        ("0/4", &[][..], "machine 0 of 4"),
        ("3", &[][..], "expected I/N"),
        ("1/0", &[][..], "not in 1..=0"),
    ] {
        let vars: &'static [(&'static str, &'static str)] =
            Box::leak(vars.to_vec().into_boxed_slice());
        let err = parse_shard_spec(spec, &env(vars)).unwrap_err().to_string();
        assert!(err.contains(needle), "{spec} {vars:?}: {err}");
    }
}

fn layout() -> DatasetLayout {
    DatasetLayout {
        finger_num_vertices: vec![4],
        markers_per_finger: vec![1],
        tendons_per_finger: 1,
        object_param_len: 1,
        object_families: vec!["a".into(), "b".into()],
    }
}

/// A stand-in generator: frames that are a pure function of (seed, trajectory).
fn synthetic(seed: u64) -> impl Fn(u64) -> Result<Vec<DatasetFrame>, LabError> + Sync {
    move |t| {
        let mut rng = SeededRng::new(seed).split(t);
        let n = 1 + rng.below(3) as u32;
        Ok((0..n)
            .map(|k| DatasetFrame {
                trajectory_id: t,
                frame_index: k,
                vertices: (0..4).map(|_| [rng.uniform() as f32; 3]).collect(),
                contact: (0..4).map(|_| u8::from(rng.uniform() < 0.3)).collect(),
                contact_force_n: (0..4).map(|_| rng.uniform() as f32).collect(),
                obstacle_distance_m: vec![f32::INFINITY; 4],
                finger_force_n: Some(vec![[0.0, 0.0, 0.1 * k as f32]]),
                markers: vec![[0.0, 0.0, rng.uniform() as f32]],
                world_from_hand: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
                tendon_pull_m: vec![rng.uniform() as f32],
                object_family: (t % 2) as u8,
                object_params: vec![t as f32],
            })
            .collect())
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("moe-datagen-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `generate` with the test layout, the synthetic generator of `seed` and no progress.
fn run(
    plan: &GenPlan,
    dir: &Path,
    generator: serde_json::Value,
    seed: u64,
) -> Result<GenReport, LabError> {
    generate(
        plan,
        dir,
        &layout(),
        generator,
        &synthetic(seed),
        &|_, _| {},
    )
}

fn plan(machine: u32, machines: u32) -> GenPlan {
    GenPlan {
        trajectories: 23,
        trajectories_per_shard: 4,
        seed: 9,
        machine,
        machines,
    }
}

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

#[test]
fn split_runs_equal_one_run_byte_for_byte() {
    let whole = scratch("whole");
    let report = run(&plan(1, 1), &whole, serde_json::json!({}), 9).unwrap();
    assert_eq!(report.shards_written.len(), 6);
    let card = report.card.expect("complete");
    assert_eq!(card.totals.trajectories, 23);
    let split = scratch("split");
    let first = run(&plan(1, 2), &split, serde_json::json!({}), 9).unwrap();
    assert!(first.card.is_none(), "half the shards are missing");
    let second = run(&plan(2, 2), &split, serde_json::json!({}), 9).unwrap();
    assert!(second.card.is_some());
    assert_eq!(files(&whole), files(&split));
    // Rerunning skips every shard and rewrites the same card.
    let again = run(&plan(1, 1), &whole, serde_json::json!({}), 9).unwrap();
    assert!(again.shards_written.is_empty());
    assert_eq!(again.shards_skipped.len(), 6);
    assert_eq!(files(&whole), files(&split));
    std::fs::remove_dir_all(&whole).unwrap();
    std::fs::remove_dir_all(&split).unwrap();
}

#[test]
fn a_failing_trajectory_keeps_finished_shards_and_is_named() {
    let dir = scratch("fail");
    let good = synthetic(9);
    let failing = move |t: u64| {
        if t == 13 {
            Err(LabError::Trajectory {
                trajectory: t,
                draws: MAX_DRAWS,
                source: moe_tendon_sim::SimError::NonFinite {
                    step: 7,
                    finger: 0,
                    node: 3,
                },
            })
        } else {
            good(t)
        }
    };
    let err = generate(
        &plan(1, 1),
        &dir,
        &layout(),
        serde_json::json!({}),
        &failing,
        &|_, _| {},
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            LabError::Trajectory {
                trajectory: 13,
                source: moe_tendon_sim::SimError::NonFinite { step: 7, .. },
                ..
            }
        ),
        "{err:?}"
    );
    // Shards 0..=2 (trajectories 0..12) finished; shard 3 holds trajectory 13 and is absent.
    let names: Vec<String> = files(&dir)
        .into_keys()
        .filter(|n| n.ends_with(".safetensors"))
        .collect();
    assert_eq!(names.len(), 3, "{names:?}");
    assert!(!names.iter().any(|n| n.contains("00003")));
    // A rerun with a working generator completes only what is missing.
    let report = run(&plan(1, 1), &dir, serde_json::json!({}), 9).unwrap();
    assert_eq!(report.shards_written, vec![3, 4, 5]);
    assert!(report.card.is_some());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_directory_refuses_a_different_data_set() {
    let dir = scratch("settings");
    run(&plan(1, 2), &dir, serde_json::json!({"a": 1}), 9).unwrap();
    let other_seed = GenPlan {
        seed: 10,
        ..plan(2, 2)
    };
    let err = run(&other_seed, &dir, serde_json::json!({"a": 1}), 10).unwrap_err();
    assert!(
        matches!(&err, LabError::SettingsMismatch { dir: d } if *d == dir),
        "{err:?}"
    );
    let err = run(&plan(2, 2), &dir, serde_json::json!({"a": 2}), 9).unwrap_err();
    assert!(
        matches!(&err, LabError::SettingsMismatch { dir: d } if *d == dir),
        "{err:?}"
    );
    run(&plan(2, 2), &dir, serde_json::json!({"a": 1}), 9).unwrap();
    // A directory of a writer before format version 2 (no finger forces; its plan.json does
    // not record the format) takes no shard of this one.
    let settings = dir.join(SETTINGS_FILE);
    let mut old: serde_json::Value = moe_io::read_json(&settings).unwrap();
    assert_eq!(old["format_version"], FORMAT_VERSION);
    old.as_object_mut().unwrap().remove("format_version");
    moe_io::write_json(&settings, &old).unwrap();
    let err = run(&plan(2, 2), &dir, serde_json::json!({"a": 1}), 9).unwrap_err();
    assert!(
        matches!(&err, LabError::SettingsMismatch { dir: d } if *d == dir),
        "{err:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn plans_are_checked() {
    let refused = |p: GenPlan, what: &str| match p.validate() {
        Err(LabError::InvalidPlan { reason }) => assert!(reason.contains(what), "{reason}"),
        other => panic!("{what}: {other:?}"),
    };
    refused(plan(0, 2), "shard 0/2");
    refused(plan(3, 2), "shard 3/2");
    for (trajectories, what) in [(0, "0 trajectories"), (MAX_TRAJECTORIES + 1, "between 1")] {
        refused(
            GenPlan {
                trajectories,
                ..plan(1, 1)
            },
            what,
        );
    }
    for per_shard in [0, MAX_TRAJECTORIES_PER_SHARD + 1] {
        refused(
            GenPlan {
                trajectories_per_shard: per_shard,
                ..plan(1, 1)
            },
            "trajectories per shard",
        );
    }
    assert!(
        GenPlan {
            trajectories: MAX_TRAJECTORIES,
            trajectories_per_shard: MAX_TRAJECTORIES_PER_SHARD,
            ..plan(1, 1)
        }
        .validate()
        .is_ok()
    );
    assert_eq!(plan(2, 3).shards_for_machine(), vec![1, 4]);
    assert_eq!(plan(1, 1).trajectories_of(5), 20..23);
}

#[test]
fn simulated_frames_fit_their_layout_and_are_deterministic() {
    let params = RandomSceneParams {
        press_secs: 0.25,
        hold_secs: 0.0,
        retract_secs: 0.05,
        save_every_steps: 5,
        ..RandomSceneParams::default()
    };
    let layout = simulated_layout(&params).unwrap();
    // A bad parameter is refused before anything is simulated, naming it.
    let soft = RandomSceneParams {
        material: moe_tendon_sim::Material {
            youngs_modulus_pa: 0.0,
            ..moe_tendon_sim::Material::default()
        },
        ..params.clone()
    };
    let err = simulated_layout(&soft).unwrap_err();
    assert!(
        matches!(
            err,
            LabError::Simulation(moe_tendon_sim::SimError::InvalidParameter {
                name: "youngs_modulus_pa",
                ..
            })
        ),
        "{err:?}"
    );
    let dir = scratch("simulated");
    let plan = GenPlan {
        trajectories: 2,
        trajectories_per_shard: 2,
        seed: 4,
        machine: 1,
        machines: 1,
    };
    let frames_of = |t| simulated_frames(&params, 4, t);
    let report = generate(
        &plan,
        &dir,
        &layout,
        serde_json::json!({}),
        &frames_of,
        &|_, _| {},
    )
    .unwrap();
    let card = report.card.unwrap();
    assert_eq!(card.totals.trajectories, 2);
    let (l, frames) = moe_io::read_shard(&dir.join(plan.shard_file(0))).unwrap();
    assert_eq!(l, layout);
    assert_eq!(
        frames,
        [frames_of(0).unwrap(), frames_of(1).unwrap()].concat()
    );
    // Every frame carries each finger's net contact force, no longer than the sum of its
    // vertices' force magnitudes, and the presses show in some.
    assert!(card.has_finger_force());
    let mut pressed = 0;
    for f in &frames {
        let forces = f.finger_force_n.as_ref().unwrap();
        let magnitudes = layout.per_finger(&f.contact_force_n, |&v| f64::from(v));
        assert_eq!(forces.len(), magnitudes.len());
        for (force, m) in forces.iter().zip(&magnitudes) {
            let net = force
                .iter()
                .map(|&c| f64::from(c).powi(2))
                .sum::<f64>()
                .sqrt();
            let total: f64 = m.iter().sum();
            assert!(net <= total * (1.0 + 1e-5) + 1e-9, "{net} > {total}");
            pressed += usize::from(net > 1e-2);
        }
    }
    assert!(pressed > 0, "no frame presses a finger");
    // Frame 0 is the hand settled under gravity, fingers up: every marker within 0.3 mm of
    // its rest place (the free sag), and none exactly there.
    let hand = moe_geom::HandModel::preset(params.preset, &params.finger).unwrap();
    let rest = hand.rest_keypoints();
    for (k, m) in rest.fingers[0].iter().enumerate() {
        let m = m.unwrap();
        let got = frames[0].markers[k];
        let d = (0..3)
            .map(|i| (f64::from(got[i]) - m[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(d > 0.0 && d < 3e-4, "marker {k}: {d} m from rest");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
