//! `moe-touch gen-data`: a thin command over `moe_lab::datagen` and the simulator's
//! randomised scenes.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use moe_geom::HandPreset;
use moe_lab::datagen::{
    GenPlan, generate, merge_card, parse_shard_spec, simulated_frames_with, simulated_layout,
};
use moe_tendon_sim::randomize::RandomSceneParams;

/// Arguments of `moe-touch gen-data`.
#[derive(Debug, Args)]
pub(crate) struct GenDataArgs {
    /// Output directory (created if missing): shards, their statistics and card.json.
    #[arg(long)]
    out: PathBuf,
    /// Trajectories in the whole data set.
    #[arg(long)]
    trajectories: u64,
    /// Seed of the whole data set.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Fingers of the hand: 2, 3 or 5.
    #[arg(long, default_value_t = 2)]
    fingers: u32,
    /// This machine's part of an array job, `I/N` (1-based): shards k with k mod N = I − 1.
    /// `auto/N` takes I from the scheduler: `SLURM_ARRAY_TASK_ID` (minus
    /// `SLURM_ARRAY_TASK_MIN` − 1 when set) or `JOB_COMPLETION_INDEX` + 1 (Kubernetes).
    #[arg(long, default_value = "1/1")]
    shard: String,
    /// Generate nothing: check that every shard of the plan exists in `--out` and write the
    /// data set card (the last step of an array job).
    #[arg(long)]
    merge: bool,
    /// Trajectories per output shard.
    #[arg(long, default_value_t = 32)]
    trajectories_per_shard: u64,
    /// Randomisation ranges as a TOML or JSON file (RandomSceneParams; defaults otherwise).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Print the run report as one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &GenDataArgs) -> Result<()> {
    let (machine, machines) = parse_shard_spec(&args.shard, &|k| std::env::var(k).ok())?;
    let mut params: RandomSceneParams = match &args.params {
        Some(p) => moe_io::read_config(p)?,
        None => RandomSceneParams::default(),
    };
    params.preset = match args.fingers {
        2 => HandPreset::TwoFinger,
        3 => HandPreset::ThreeFinger,
        5 => HandPreset::FiveFinger,
        n => bail!("--fingers {n}: expected 2, 3 or 5"),
    };
    let plan = GenPlan {
        trajectories: args.trajectories,
        trajectories_per_shard: args.trajectories_per_shard,
        seed: args.seed,
        machine,
        machines,
    };
    plan.validate()?;
    let layout = simulated_layout(&params)?;
    // Everything but the machine split: every machine of an array job records the same.
    let generator = serde_json::json!({ "simulator": "moe-tendon-sim", "params": params });
    if args.merge {
        let card = merge_card(&plan, &args.out, &layout, generator)?;
        eprintln!(
            "gen-data: merged {} shards: {} frames, {} trajectories, contact ratio {:.4}",
            card.shards.len(),
            card.totals.frames,
            card.totals.trajectories,
            card.totals.contact_ratio()
        );
        return Ok(());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} trajectories  {per_sec}  ETA {eta}",
        )
        .context("progress template")?,
    );
    bar.enable_steady_tick(Duration::from_millis(250));
    let started = Instant::now();
    // The fingers are voxelised once for every trajectory (the data set shares its hand,
    // material and resolution).
    let bodies =
        moe_tendon_sim::randomize::hand_bodies(&params).context("the data set's finger bodies")?;
    let frames_of = |t| simulated_frames_with(&params, Some(&bodies), args.seed, t);
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let report = generate(&plan, &args.out, &layout, generator, &frames_of, &progress)?;
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    let rate = report.frames_written as f64 / secs.max(1e-9);
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "shards_written": report.shards_written,
                "shards_skipped": report.shards_skipped,
                "frames_written": report.frames_written,
                "seconds": secs,
                "frames_per_second": rate,
                "card_written": report.card.is_some(),
            })
        );
    } else {
        eprintln!(
            "gen-data: {} shards written, {} skipped, {} frames in {secs:.1} s ({rate:.1} frames/s)",
            report.shards_written.len(),
            report.shards_skipped.len(),
            report.frames_written
        );
        match &report.card {
            Some(card) => eprintln!(
                "gen-data: data set complete: {} frames, {} trajectories, contact ratio {:.4}",
                card.totals.frames,
                card.totals.trajectories,
                card.totals.contact_ratio()
            ),
            None => eprintln!("gen-data: other shards of the plan are still missing; no card yet"),
        }
    }
    Ok(())
}
