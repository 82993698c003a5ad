//! `moe-touch train` and `moe-touch eval contact` end to end on a tiny generated data set, and their
//! refusals of bad input: one clear error line and a non-zero exit.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

use common::PARAMS;

fn scratch(name: &str) -> PathBuf {
    common::scratch("contact", name)
}

fn tool(args: &[&str], paths: &[(&str, &Path)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_moe-touch"));
    cmd.args(args);
    for (flag, path) in paths {
        cmd.arg(flag).arg(path);
    }
    cmd.output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failure reported as exactly one `error:` line.
fn assert_one_error(o: &Output, needle: &str) {
    assert!(!o.status.success(), "expected a failure");
    let err = stderr(o);
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(errors[0].contains(needle), "expected '{needle}' in: {err}");
}

fn generate(dir: &Path, params: &Path, trajectories: &str) {
    let o = tool(
        &[
            "gen-data",
            "--trajectories",
            trajectories,
            "--seed",
            "3",
            "--trajectories-per-shard",
            "8",
        ],
        &[("--out", dir), ("--params", params)],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `train` for one epoch of a tiny network.
const TINY_TRAIN: &[&str] = &[
    "train",
    "--epochs",
    "1",
    "--batch-size",
    "4",
    "--negative-fraction",
    "0.5",
    "--k",
    "12",
    "--edge-widths",
    "16,16,32",
    "--head-widths",
    "32,16",
];

#[test]
fn train_then_evaluate_a_tiny_model_and_refuse_bad_input() {
    let root = scratch("run");
    let params = root.join("params.toml");
    std::fs::write(&params, PARAMS).unwrap();
    let data = root.join("data");
    generate(&data, &params, "24");
    let model = root.join("tiny");
    let o = tool(
        &[TINY_TRAIN, &["--features", "xyz,rest-xyz,deformation"]].concat(),
        &[("--data", &data), ("--out", &model)],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let card: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.with_extension("json")).unwrap())
            .unwrap();
    // The architecture options reach the card, which evaluation below builds the network from.
    let arch = &card["architecture"];
    assert_eq!(arch["k"], 12);
    assert_eq!(arch["edge_widths"], serde_json::json!([16, 16, 32]));
    assert_eq!(arch["head_widths"], serde_json::json!([32, 16]));
    assert_eq!(
        arch["input"]["features"],
        serde_json::json!(["xyz", "rest-xyz", "deformation"])
    );
    let epochs = card["metrics"]["epochs"].as_array().unwrap();
    assert_eq!(epochs.len(), 1);
    // Validation records the contact metrics: rates in [0, 1], a BCD (null when every contact
    // frame was missed, as JSON has no NaN).
    for key in [
        "validation_miss_rate",
        "validation_false_alarm_rate",
        "validation_f1",
    ] {
        let v = epochs[0][key].as_f64().unwrap_or(-1.0);
        assert!((0.0..=1.0).contains(&v), "{key} = {}", epochs[0][key]);
    }
    let bcd = &epochs[0]["validation_contact_bcd_mm"];
    assert!(
        bcd.is_null() || bcd.as_f64().is_some_and(|b| b >= 0.0),
        "{bcd}"
    );
    assert_eq!(card["dataset"]["sets"][0]["label_rule"], "press");
    assert!(
        card["dataset"]["sets"][0]["regenerate"]
            .as_str()
            .unwrap()
            .contains("--trajectories 24 --seed 3")
    );

    // Table 1 and one trial of each plate, with the KNN index written on the first run.
    let index = root.join("knn.safetensors");
    let out = root.join("out");
    let weights = model.with_extension("safetensors");
    let o = tool(
        &["eval", "contact", "--trials", "1", "--json"],
        &[
            ("--data", &data),
            ("--model", &weights),
            ("--knn-index", &index),
            ("--out", &out),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(index.exists());
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let methods: Vec<&str> = report["table1"]["contact"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["method"].as_str().unwrap())
        .collect();
    assert_eq!(
        methods,
        [
            "DGCNN (true shape)",
            "DGCNN (SR-ARAP)",
            "KNN[All]",
            "KNN[Sub]"
        ]
        .repeat(2),
        "scored against the press labels and the proximity labels"
    );
    let shape = report["table1"]["shape"].as_array().unwrap();
    assert_eq!(shape[0]["method"], "rest");
    assert_eq!(shape[1]["markers"], 7);
    assert_eq!(shape[2]["markers"], 4);
    assert_eq!(report["table2"]["trials"].as_array().unwrap().len(), 6);
    assert!(out.join("plate_regions.svg").exists());
    // The second run loads the index instead of rebuilding it.
    let o = tool(
        &["eval", "contact", "--trials", "0"],
        &[
            ("--data", &data),
            ("--model", &weights),
            ("--knn-index", &index),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("KNN index of"), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("Table 1"));

    // Fine-tuning with the tendon pulls added: the initial weights are widened, the channels
    // they were trained on keep their normalisation, the new ones get the data's; evaluation
    // feeds every frame's pulls (Table 1 and the plates).
    let pulled = root.join("pulled");
    let o = tool(
        &[
            TINY_TRAIN,
            &["--features", "xyz,rest-xyz,deformation,tendon-pull"],
        ]
        .concat(),
        &[("--data", &data), ("--out", &pulled), ("--init", &weights)],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // Features can only be added after the initial model's, not reordered or dropped.
    assert_one_error(
        &tool(
            &[
                TINY_TRAIN,
                &["--features", "rest-xyz,xyz,deformation,tendon-pull"],
            ]
            .concat(),
            &[
                ("--data", &data),
                ("--out", &root.join("never")),
                ("--init", &weights),
            ],
        ),
        "can only be added",
    );
    let pulled_card: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(pulled.with_extension("json")).unwrap())
            .unwrap();
    let input = &pulled_card["architecture"]["input"];
    assert_eq!(
        input["features"],
        serde_json::json!(["xyz", "rest-xyz", "deformation", "tendon-pull"])
    );
    let old = &arch["input"]["normalisation"];
    for key in ["mean", "std"] {
        let new = input["normalisation"][key].as_array().unwrap();
        assert_eq!(new.len(), 12);
        assert_eq!(&new[..9], old[key].as_array().unwrap().as_slice(), "{key}");
    }
    // The bending varies over the data set; the co-contraction is always zero there (the
    // generator pulls one tendon of a pair and pays out the other), so it is left unscaled.
    let std = |c: usize| input["normalisation"]["std"][c].as_f64().unwrap();
    assert!(std(9) > 1e-4, "{}", input["normalisation"]);
    assert_eq!(std(11), 1.0, "{}", input["normalisation"]);
    assert_eq!(input["normalisation"]["mean"][11], 0.0);
    let o = tool(
        &["eval", "contact", "--trials", "1"],
        &[
            ("--data", &data),
            ("--model", &pulled.with_extension("safetensors")),
            ("--knn-index", &index),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));

    // Bad input. An empty directory:
    let empty = root.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    assert_one_error(
        &tool(
            &["eval", "contact"],
            &[("--data", &empty), ("--model", &weights)],
        ),
        "card.json",
    );
    assert_one_error(
        &tool(
            &["train"],
            &[("--data", &empty), ("--out", &root.join("never"))],
        ),
        "card.json",
    );
    // A data set of another hand than the model's:
    let other_params = root.join("other.toml");
    std::fs::write(
        &other_params,
        PARAMS.replace("vertex_budget = 120", "vertex_budget = 200"),
    )
    .unwrap();
    let other = root.join("other");
    generate(&other, &other_params, "8");
    assert_one_error(
        &tool(
            &["eval", "contact", "--trials", "0"],
            &[("--data", &other), ("--model", &weights)],
        ),
        "trained on the hand",
    );
    // A card whose input features the weights (and so the data) cannot feed:
    let bad = root.join("bad");
    std::fs::copy(&weights, bad.with_extension("safetensors")).unwrap();
    let mut edited = card.clone();
    edited["architecture"]["input"]["features"] = serde_json::json!(["xyz"]);
    edited["architecture"]["input"]["normalisation"] = serde_json::Value::Null;
    std::fs::write(
        bad.with_extension("json"),
        serde_json::to_string(&edited).unwrap(),
    )
    .unwrap();
    assert_one_error(
        &tool(
            &["eval", "contact", "--trials", "0"],
            &[
                ("--data", &data),
                ("--model", &bad.with_extension("safetensors")),
            ],
        ),
        "architecture.input.features",
    );
    let _ = std::fs::remove_dir_all(&root);
}
