//! The command line as parsed, without running a command: options bounded when parsed, and
//! every command the README and the docs give accepted as written.

/// Options that size a run are refused outside their range when they are parsed, before any
/// data is loaded.
#[test]
fn sizing_options_are_bounded_when_parsed() {
    let parse = |args: &[&str]| moe_touch_cli::check_args(["moe-touch"].iter().chain(args));
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
            match moe_touch_cli::check_args(argv) {
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
