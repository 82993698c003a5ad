//! Long runs: the pipeline on a stream of many frames, an episode looped with advancing time
//! stamps and with what hours of use bring mixed in — gaps beyond the memory horizon, resets,
//! and refused frames — to show that its memory, its frame times and its stream state stay
//! bounded (`moe-touch eval soak`).

use moe_geom::{HandEstimator, Real};
use moe_record::EpisodeFrame;
use serde::Serialize;

use crate::LabError;
use crate::run::TimingSummary;
use moe_touch::{Pipeline, StreamEvent};

/// What a soak run does.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SoakOptions {
    /// Frames to run.
    pub frames: usize,
    /// Frames per reported window (the figures are compared window by window).
    pub window: usize,
    /// Every this many frames, a gap of `gap_secs` before the frame (the stream restarts).
    pub gap_every: usize,
    /// The gap, seconds (beyond the pipeline's memory horizon).
    pub gap_secs: Real,
    /// Every this many frames, `Pipeline::reset` before the frame.
    pub reset_every: usize,
    /// Every this many frames, a frame whose time repeats the previous one's: the pipeline
    /// refuses it, and the stream must go on.
    pub refuse_every: usize,
}

impl Default for SoakOptions {
    /// 20,000 frames in windows of 1,000; a 2 s gap every 350 frames, a reset every 1,001, a
    /// refused frame every 997 (periods that do not divide one another).
    fn default() -> Self {
        Self {
            frames: 20_000,
            window: 1_000,
            gap_every: 350,
            gap_secs: 2.0,
            reset_every: 1_001,
            refuse_every: 997,
        }
    }
}

impl SoakOptions {
    /// Checks the options.
    ///
    /// # Errors
    /// [`LabError::InvalidEvaluation`] for no frames, a zero window or period, or a gap that
    /// is not finite and positive.
    pub fn validate(&self) -> Result<(), LabError> {
        let bad = |reason: String| Err(LabError::InvalidEvaluation { reason });
        if self.frames == 0 || self.window == 0 {
            return bad("a soak needs frames and a window of at least one frame".into());
        }
        for (name, every) in [
            ("gap_every", self.gap_every),
            ("reset_every", self.reset_every),
            ("refuse_every", self.refuse_every),
        ] {
            if every == 0 {
                return bad(format!("{name} must be at least 1 frame"));
            }
        }
        if !(self.gap_secs.is_finite() && self.gap_secs > 0.0) {
            return bad(format!(
                "gap_secs = {}: must be finite and positive",
                self.gap_secs
            ));
        }
        Ok(())
    }
}

/// The figures of one window of a soak run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SoakWindow {
    /// Its first frame.
    pub first_frame: usize,
    /// Whole-frame times of its estimated frames, milliseconds.
    pub frame_ms: TimingSummary,
    /// Frames the pipeline refused or could not estimate (the refused ones injected among
    /// them).
    pub failed_frames: usize,
    /// Frames that restarted the stream (after a gap) or started it (after a reset).
    pub restarts: usize,
    /// The process's resident memory at the window's end, MiB (Linux; `None` elsewhere).
    pub resident_mib: Option<Real>,
}

/// The report of a soak run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SoakReport {
    /// What was run.
    pub options: SoakOptions,
    /// Frames run.
    pub frames: usize,
    /// Frames refused on purpose (a repeated time).
    pub refused_on_purpose: usize,
    /// Frames that failed otherwise (0 for a pipeline that does not fail on its own).
    pub unexpected_failures: usize,
    /// The first unexpected failure, if any.
    pub first_unexpected_failure: Option<String>,
    /// Window by window.
    pub windows: Vec<SoakWindow>,
    /// The resident memory at the end over that at the end of the first window, less one
    /// (`None` without a reading, or with one window).
    pub resident_growth: Option<Real>,
    /// The last full window's 99th-percentile frame time over the first's, less one.
    pub p99_drift: Option<Real>,
    /// The same of the median.
    pub median_drift: Option<Real>,
}

/// The process's resident memory, MiB, from `/proc/self/status` (`None` where there is none).
pub fn resident_mib() -> Option<Real> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kib: Real = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Runs `pipeline` on `episode` looped to `options.frames` frames: frame `k` is episode frame
/// `k mod n` at time `k` frame spacings (the episode's first spacing) after the start, plus
/// every gap so far; gaps, resets and refused frames mixed in as `options` says. A frame that
/// fails does not end the run: it is counted. `progress(k, n)` after every window.
///
/// # Errors
/// Invalid options, or an episode of fewer than two frames (no spacing to loop with).
pub fn soak<E: HandEstimator>(
    pipeline: &mut Pipeline<E>,
    episode: &[EpisodeFrame],
    options: &SoakOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<SoakReport, LabError> {
    options.validate()?;
    let spacing_ns = match episode {
        [a, b, ..] if b.time_ns > a.time_ns => b.time_ns - a.time_ns,
        _ => {
            return Err(LabError::InvalidEvaluation {
                reason: "a soak loops an episode of at least two frames in time order".into(),
            });
        }
    };
    let gap_ns = (options.gap_secs * 1e9).round() as u64;
    pipeline.reset();
    let mut windows = Vec::new();
    let (mut refused, mut unexpected) = (0, 0);
    let mut first_unexpected = None;
    let mut offset_ns = 0u64;
    let mut previous_ns = None;
    for start in (0..options.frames).step_by(options.window) {
        let end = (start + options.window).min(options.frames);
        let mut times = Vec::with_capacity(end - start);
        let (mut failed, mut restarts) = (0, 0);
        for k in start..end {
            if k > 0 && k % options.gap_every == 0 {
                offset_ns += gap_ns;
            }
            if k > 0 && k % options.reset_every == 0 {
                pipeline.reset();
            }
            let frame = &episode[k % episode.len()];
            let refuse = k > 0 && k % options.refuse_every == 0;
            let time_ns = match (refuse, previous_ns) {
                (true, Some(t)) => t,
                _ => episode[0].time_ns + k as u64 * spacing_ns + offset_ns,
            };
            // The frame's own images, at the looped time: no copy of them per frame.
            let observation = frame.observation().with_time(1e-9 * time_ns as Real);
            match pipeline.process(frame.rgbd(), &observation) {
                Ok(est) => {
                    previous_ns = Some(time_ns);
                    times.push(est.timings.total_ms);
                    restarts += usize::from(matches!(
                        est.stream,
                        StreamEvent::Started | StreamEvent::Restarted { .. }
                    ));
                }
                Err(failure) => {
                    failed += 1;
                    if refuse {
                        refused += 1;
                    } else {
                        unexpected += 1;
                        first_unexpected.get_or_insert_with(|| format!("frame {k}: {failure}"));
                        previous_ns = Some(time_ns);
                    }
                }
            }
        }
        windows.push(SoakWindow {
            first_frame: start,
            frame_ms: TimingSummary::of(times),
            failed_frames: failed,
            restarts,
            resident_mib: resident_mib(),
        });
        progress(end, options.frames);
    }
    // The last window counts only when full (a short tail's percentiles are not comparable).
    let full: Vec<&SoakWindow> = windows
        .iter()
        .filter(|w| w.frame_ms.frames + w.failed_frames == options.window)
        .collect();
    let drift = |f: fn(&TimingSummary) -> Real| match (full.first(), full.last()) {
        (Some(a), Some(b)) if full.len() > 1 && f(&a.frame_ms) > 0.0 => {
            Some(f(&b.frame_ms) / f(&a.frame_ms) - 1.0)
        }
        _ => None,
    };
    let resident_growth = match (windows.first(), windows.last()) {
        (Some(a), Some(b)) if windows.len() > 1 => match (a.resident_mib, b.resident_mib) {
            (Some(a), Some(b)) if a > 0.0 => Some(b / a - 1.0),
            _ => None,
        },
        _ => None,
    };
    Ok(SoakReport {
        options: options.clone(),
        frames: options.frames,
        refused_on_purpose: refused,
        unexpected_failures: unexpected,
        first_unexpected_failure: first_unexpected,
        p99_drift: drift(|t| t.p99_ms),
        median_drift: drift(|t| t.median_ms),
        windows,
        resident_growth,
    })
}

impl SoakReport {
    /// The report in a few lines: the counts, then one line per window.
    pub fn summary(&self) -> String {
        let pct = |x: Option<Real>| {
            x.map_or_else(|| "n/a".to_owned(), |x| format!("{:+.1} %", 100.0 * x))
        };
        let mut s = format!(
            "{} frames: {} refused on purpose, {} other failures; resident memory {} from the first window's end to the last's; p99 frame time {} and median {} from the first full window to the last\n",
            self.frames,
            self.refused_on_purpose,
            self.unexpected_failures,
            pct(self.resident_growth),
            pct(self.p99_drift),
            pct(self.median_drift),
        );
        for w in &self.windows {
            s.push_str(&format!(
                "  frames {:>6}..: median {:.1} ms, p99 {:.1}, max {:.1}; {} failed, {} restarts; {}\n",
                w.first_frame,
                w.frame_ms.median_ms,
                w.frame_ms.p99_ms,
                w.frame_ms.max_ms,
                w.failed_frames,
                w.restarts,
                w.resident_mib
                    .map_or_else(|| "memory n/a".to_owned(), |m| format!("{m:.1} MiB resident")),
            ));
        }
        s
    }
}
