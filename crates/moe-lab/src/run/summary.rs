//! A run report as the lines `moe-touch run` and `demo` print.

use std::fmt::Write as _;
use std::path::Path;

use super::RunReport;
use crate::count;

impl RunReport {
    /// The report as text: frame rate and per-stage medians (naming `out`, the result file),
    /// the figures against the ground truth when the episode has it, and the force on every
    /// finger frame by frame when the estimator estimates force. Lines end in `\n`.
    pub fn summary(&self, out: &Path) -> String {
        let mut text = String::new();
        let r = self;
        let cut = if r.truncated.is_some() {
            " (episode cut short)"
        } else {
            ""
        };
        // Writing to a String cannot fail.
        let _ = writeln!(
            text,
            "{} frames{cut}: {:.1} frames/s (per frame: markers {:.2} ms, estimate {:.2} ms, contact points {:.2} ms, total {:.2} ms median); wrote {}",
            r.frames,
            r.frames_per_second,
            r.markers_ms.median_ms,
            r.estimate_ms.median_ms,
            r.points_ms.median_ms,
            r.total_ms.median_ms,
            out.display()
        );
        if r.failed_frames > 0 {
            let first = r.per_frame.iter().find_map(|f| {
                f.failure
                    .as_ref()
                    .map(|e| format!("at {} ns, {}", f.time_ns, e.error))
            });
            let _ = writeln!(
                text,
                "{} of {} frames not estimated (marked in the report and the result; the stream went on), the first {}",
                r.failed_frames,
                r.frames,
                first.unwrap_or_default()
            );
        }
        let s = &r.stream_ms;
        let row = |t: &super::TimingSummary| {
            format!(
                "{} frames, median {:.1}, p99 {:.1}, max {:.1} ms",
                t.frames, t.median_ms, t.p99_ms, t.max_ms
            )
        };
        let _ = writeln!(
            text,
            "whole frame: first {:.1} ms; after it {}; pressed ({}) {}; not pressed {}",
            s.first_ms,
            row(&s.after_first),
            s.press_from,
            row(&s.pressed),
            row(&s.free)
        );
        if let (Some(m), Some(bcd), Some(c)) = (&r.markers, r.shape_bcd_mm, &r.contact) {
            let _ = writeln!(
                text,
                "against the ground truth: markers {:.1} % of {} visible found (error {:.2} mm mean); shape BCD {:.3} mm; contact BCD {:.1} mm, UCD {:.1} mm, F1 {:.3}, {} of {} contact frames missed, {} false alarms",
                100.0 * m.detection_rate,
                m.visible,
                m.mean_error_mm,
                bcd,
                c.bcd_mm,
                c.ucd_mm,
                c.f1,
                c.misses,
                c.contact_frames,
                c.false_alarms
            );
        }
        text.push_str(&self.forces_table());
        text
    }

    /// The estimated force on every finger, frame by frame, and each finger's largest (empty
    /// for runs whose estimator estimates no force). Lines end in `\n`.
    pub fn forces_table(&self) -> String {
        let Some(summary) = &self.forces else {
            return String::new();
        };
        let mut text =
            String::from("estimated force on each finger (N, hand frame x, y, z; loads found):\n");
        for (k, frame) in self.per_frame.iter().enumerate() {
            let Some(fingers) = &frame.finger_forces else {
                continue;
            };
            let cells: Vec<String> = fingers
                .iter()
                .enumerate()
                .map(|(f, x)| {
                    let loads = x
                        .loads
                        .map_or(String::new(), |n| format!(", {}", count(n, "load")));
                    let failed = if x.error.is_some() {
                        ", no estimate"
                    } else if x.degraded {
                        ", search stopped at its budget"
                    } else {
                        ""
                    };
                    format!(
                        "finger {f} {:.3} ({:+.3}, {:+.3}, {:+.3}{loads}{failed})",
                        x.magnitude_n, x.force_n.x, x.force_n.y, x.force_n.z
                    )
                })
                .collect();
            let _ = writeln!(
                text,
                "  frame {k:>3} {:>8.3} s  {}",
                1e-9 * frame.time_ns as f64,
                cells.join("   ")
            );
        }
        let cells: Vec<String> = summary
            .fingers
            .iter()
            .enumerate()
            .map(|(f, s)| {
                format!(
                    "finger {f} up to {:.3} N ({} of {} frames with force)",
                    s.max_magnitude_n, s.frames_with_force, self.frames
                )
            })
            .collect();
        let _ = writeln!(text, "  {}", cells.join("; "));
        text
    }
}
