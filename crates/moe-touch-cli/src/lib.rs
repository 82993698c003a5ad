//! The `moe-touch` command-line tool. Every subcommand lives in its own module under `cli/`;
//! this file only parses arguments, dispatches, and turns errors into one line on stderr and a
//! non-zero exit code.

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The subcommands, one module each.
mod cli;
/// Drawing on images: text, labels that do not overlap, meshes coloured by a value.
pub mod draw;
/// Small SVG figures written by hand.
mod figure;
/// Golden fixtures: committed reference results of the numerical stages, recomputed and
/// compared.
pub mod golden;
/// Marker detections drawn over camera frames.
pub mod overlay;

/// Shape and contact estimation for soft tendon-driven hands, from deformation alone.
#[derive(Debug, Parser)]
#[command(
    name = "moe-touch",
    version,
    about = "Shape and contact estimation for soft tendon-driven hands, from deformation alone",
    long_about = None,
    propagate_version = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The whole pipeline on the committed example episode with the shipped model: a short
    /// table, a result MCAP for Foxglove, meshes coloured by contact and a picture.
    Demo(cli::demo::DemoArgs),
    /// Generate a hand model (rest meshes, marker and base vertex ids) from a preset or a config.
    Hand(cli::hand::HandArgs),
    /// Deform any mesh with SR-ARAP so that handle vertices reach their targets.
    Arap(cli::arap::ArapArgs),
    /// Detect and track the red markers in every frame of an episode (wrist RGB-D → keypoints
    /// per finger); report detection against the ground truth when the episode has it.
    Markers(cli::markers::MarkersArgs),
    /// Run the whole pipeline (markers → SR-ARAP → contact, or markers → physics) over an
    /// episode: a result MCAP for Foxglove and a report against the ground truth.
    Run(cli::run::RunArgs),
    /// Estimate a hand's deformed finger meshes from one frame of marker keypoints (SR-ARAP).
    Shape(cli::shape::ShapeArgs),
    /// Estimate per-vertex contact with the DGCNN (on a point cloud, or on a hand shape as
    /// `moe-touch shape` writes it), or with physics from one frame of markers and tendon pulls
    /// (loads with force and uncertainty, the dented shape): meshes coloured by contact
    /// probability, contact points.
    Contact(cli::contact::ContactArgs),
    /// Fit the hand's material (Young's modulus, damping) for the physics estimator to the
    /// contact-free frames of an episode or a data set.
    Calibrate(cli::calibrate::CalibrateArgs),
    /// Run a scripted tendon-FEM scene; write surface meshes per saved frame and a summary.
    Sim(cli::sim::SimArgs),
    /// Reconstruct an occluded surface from contact points (GPIS with a prior, sphere or constant
    /// mean, or the non-probabilistic baseline); query the posterior at points.
    Surface(cli::surface::SurfaceArgs),
    /// Fit a plane to 3-D points (RANSAC with a least-squares refit): unit normal, offset,
    /// inliers and RMS distance.
    Plane(cli::plane::PlaneArgs),
    /// Generate a labelled training set with the tendon FEM simulator (sharded, resumable).
    GenData(cli::gen_data::GenDataArgs),
    /// Train the contact network on a generated data set (checkpoints every epoch, resumable).
    Train(cli::train::TrainArgs),
    /// Run an evaluation: contact (paper Tables 1–2), physics, markers, labels, patting, grasp,
    /// surface, observability.
    Eval(cli::eval::EvalArgs),
    /// Write a small data set of held-out frames (the golden regression's input).
    HeldoutShard(cli::eval::contact::HeldoutArgs),
}

/// Runs the tool on `args` (the first being the program name), as the `moe-touch` binary does:
/// errors become one line on stderr and a failing exit code.
pub fn main_with(args: impl IntoIterator<Item = impl Into<OsString> + Clone>) -> ExitCode {
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(err) => err.exit(),
    };
    let result = match cli.command {
        Command::Demo(args) => cli::demo::run(args),
        Command::Hand(args) => cli::hand::run(args),
        Command::Arap(args) => cli::arap::run(args),
        Command::Markers(args) => cli::markers::run(args),
        Command::Run(args) => cli::run::run(args),
        Command::Shape(args) => cli::shape::run(args),
        Command::Contact(args) => cli::contact::run(args),
        Command::Calibrate(args) => cli::calibrate::run(args),
        Command::Sim(args) => cli::sim::run(args),
        Command::Surface(args) => cli::surface::run(args),
        Command::Plane(args) => cli::plane::run(args),
        Command::GenData(args) => cli::gen_data::run(&args),
        Command::Train(args) => cli::train::run(&args),
        Command::Eval(args) => cli::eval::run(&args),
        Command::HeldoutShard(args) => cli::eval::contact::write_heldout(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", moe_touch::error::one_line(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// Options that size a run are refused outside their range when they are parsed, before any
    /// data is loaded.
    #[test]
    fn sizing_options_are_bounded_when_parsed() {
        let parse = |args: &[&str]| Cli::try_parse_from(["moe-touch"].iter().chain(args));
        let train = ["train", "--data", "d", "--out", "o"];
        let with = |extra: &[&'static str]| {
            let mut v: Vec<&str> = train.to_vec();
            v.extend_from_slice(extra);
            v
        };
        assert!(parse(&with(&["--epochs", "10000", "--batch-size", "4096"])).is_ok());
        assert!(parse(&with(&["--k", "256", "--edge-widths", "1,8192,3"])).is_ok());
        for bad in [
            &["--epochs", "0"][..],
            &["--epochs", "10001"],
            &["--batch-size", "0"],
            &["--batch-size", "4097"],
            &["--max-frames", "0"],
            &["--k", "0"],
            &["--k", "257"],
            &["--edge-widths", "64,0,256"],
            &["--head-widths", "512,8193"],
            &["--lr-step-epochs", "0"],
        ] {
            let err = parse(&with(bad)).unwrap_err();
            assert_eq!(
                err.kind(),
                clap::error::ErrorKind::ValueValidation,
                "{bad:?}"
            );
        }
        let heldout = |extra: &[&'static str]| {
            let mut v = vec!["heldout-shard", "--data", "d"];
            v.extend_from_slice(extra);
            parse(&v)
        };
        assert!(heldout(&["--trajectories", "1", "--frames", "1"]).is_ok());
        for (bad, arg) in [
            (
                &["--trajectories", "0"][..],
                "--trajectories <TRAJECTORIES>",
            ),
            (&["--frames", "0"], "--frames <FRAMES>"),
        ] {
            let err = heldout(bad).unwrap_err();
            assert_eq!(
                err.kind(),
                clap::error::ErrorKind::ValueValidation,
                "{bad:?}"
            );
            assert_eq!(
                err.get(clap::error::ContextKind::InvalidArg),
                Some(&clap::error::ContextValue::String(arg.into())),
                "{bad:?}: {err}"
            );
        }
    }
}

#[cfg(test)]
mod docs_commands {
    use clap::Parser;

    /// `[a | b]` becomes `[a]`: the first of alternatives that exclude each other.
    fn first_alternatives(line: &str) -> String {
        let mut out = String::new();
        let mut rest = line;
        while let Some(i) = rest.find(" | ") {
            out.push_str(&rest[..i]);
            rest = &rest[i..];
            rest = &rest[rest.find(']').unwrap_or(rest.len())..];
        }
        out.push_str(rest);
        out
    }

    /// A value for a placeholder of the docs' synopses: counts and seeds (`N`, `S`), fractions
    /// and probabilities (`P`, `Q`, `A`, `F`), metres (`M`), a weight (`W`), a hand preset, a
    /// marker layout.
    fn placeholder(word: &str) -> Option<&'static str> {
        Some(match word {
            "N" | "S" => "1",
            "P" | "Q" | "A" | "F" => "0.5",
            "M" => "0.001",
            "W" => "2",
            "PRESET" => "two-finger",
            "LAYOUT" => "two-rows",
            _ => return None,
        })
    }

    /// Every `moe-touch …` command line in the fenced shell blocks of a Markdown file
    /// (`cargo run … -p moe-touch-cli -- …` and `cargo xtask gen-data|train|eval …` included),
    /// continuation lines joined, as argument vectors.
    fn commands(markdown: &str) -> Vec<Vec<String>> {
        let mut out = Vec::new();
        let mut in_shell = false;
        let mut pending = String::new();
        for line in markdown.lines() {
            if let Some(fence) = line.trim_start().strip_prefix("```") {
                in_shell = !in_shell && matches!(fence.trim(), "sh" | "bash" | "shell" | "console");
                continue;
            }
            if !in_shell {
                continue;
            }
            let code = line.split(" #").next().unwrap_or_default().trim();
            let code = code.trim_start_matches("$ ");
            if code.starts_with('#') || code.is_empty() && pending.is_empty() {
                continue;
            }
            pending.push_str(code.trim_end_matches('\\'));
            pending.push(' ');
            if code.ends_with('\\') {
                continue;
            }
            let line = std::mem::take(&mut pending);
            // Synopsis notation: `[--opt V]` is written out, `a|b` takes `a`, `...` is dropped.
            let words: Vec<String> = first_alternatives(&line)
                .replace(['[', ']'], " ")
                .split_whitespace()
                .filter(|w| *w != "...")
                .map(|w| w.split('|').next().unwrap_or(w))
                .map(|w| placeholder(w).unwrap_or(w).to_owned())
                .collect();
            let args = if let Some(i) = words.iter().position(|w| w == "--") {
                words[..i]
                    .iter()
                    .any(|w| w == "moe-touch-cli")
                    .then(|| words[i + 1..].to_vec())
            } else if words.first().is_some_and(|w| w == "moe-touch") {
                Some(words[1..].to_vec())
            } else if words.starts_with(&["cargo".into(), "xtask".into()])
                && words.get(2).is_some_and(|c| {
                    ["gen-data", "train", "eval", "heldout-shard"].contains(&c.as_str())
                })
            {
                Some(words[2..].to_vec())
            } else {
                None
            };
            if let Some(args) = args {
                // Shell redirections and pipes end the command.
                let args = args
                    .into_iter()
                    .take_while(|w| !["|", ">", "2>", "&&", ";"].contains(&w.as_str()))
                    .collect();
                out.push(args);
            }
        }
        out
    }

    /// The commands the README and the docs give are accepted by the tool as they are written:
    /// a renamed or removed option makes this test fail, so stale docs are caught.
    #[test]
    fn the_docs_commands_parse() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut files = vec![
            root.join("README.md"),
            root.join("models/README.md"),
            root.join("fixtures/README.md"),
        ];
        let mut docs: Vec<_> = std::fs::read_dir(root.join("docs"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .collect();
        docs.sort();
        files.extend(docs);
        let mut checked = 0;
        let mut failures = Vec::new();
        for file in &files {
            let text = std::fs::read_to_string(file).unwrap();
            for args in commands(&text) {
                checked += 1;
                let argv = std::iter::once("moe-touch".to_owned()).chain(args.iter().cloned());
                match super::Cli::try_parse_from(argv) {
                    Ok(_) => {}
                    Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => {}
                    Err(e) => failures.push(format!(
                        "{}: moe-touch {}: {}",
                        file.strip_prefix(&root).unwrap_or(file).display(),
                        args.join(" "),
                        e.to_string().lines().next().unwrap_or_default()
                    )),
                }
            }
        }
        assert!(checked >= 20, "only {checked} commands found");
        assert!(
            failures.is_empty(),
            "{} of {checked} commands fail:\n{}",
            failures.len(),
            failures.join("\n")
        );
    }
}
