//! The physics evaluation as text: the Markdown tables `moe-touch eval physics` prints.

use std::fmt::Write as _;

use moe_geom::Real;

use super::PhysicsEvaluation;

impl PhysicsEvaluation {
    /// The evaluation as the Markdown tables `moe-touch eval physics` prints: the paper's
    /// per-vertex metrics per estimator, the shape BCD, the force table by the true force, the
    /// false alarms and how presses are followed through the streams.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} frames of {} trajectories, markers: {}; physics estimator {:.1} ms per frame \
             (median; p90 {:.1}); {} finger-frames failed; solves per finger-frame {} \
             (median; p99 {}, max {}), {} finger-frames stopped at the budget",
            self.frames,
            self.trajectories,
            self.markers,
            self.physics_ms_median,
            self.physics_ms_p90,
            self.failed_fingers,
            self.solves.median,
            self.solves.p99,
            self.solves.max,
            self.degraded_fingers
        );
        let _ = writeln!(
            s,
            "\n| contact estimation | BCD mm | UCD mm | missed frames | false-alarm frames | P | R | F1 | IoU |\n|---|---|---|---|---|---|---|---|---|"
        );
        let mut row = |name: &str, r: &moe_contact::ContactReport| {
            let _ = writeln!(
                s,
                "| {name} | {:.2} | {:.2} | {:.1} % | {:.1} % | {:.3} | {:.3} | {:.3} | {:.3} |",
                r.bcd_mm,
                r.ucd_mm,
                100.0 * r.miss_rate,
                100.0 * r.false_alarm_rate,
                r.precision,
                r.recall,
                r.f1,
                r.iou
            );
        };
        row("physics estimator", &self.physics);
        if let Some(r) = &self.dgcnn_on_physics {
            row("DGCNN on the physics shape", r);
        }
        if let Some(r) = &self.dgcnn_on_sr_arap {
            row("DGCNN on the SR-ARAP shape", r);
        }
        if let Some(r) = &self.dgcnn_on_sr_arap_depth {
            row("DGCNN on the SR-ARAP shape from markers and depth", r);
        }
        if let Some(r) = &self.dgcnn_on_true_shape {
            row("DGCNN on the true shape", r);
        }
        if let Some(r) = &self.physics_placed_by_dgcnn {
            row("physics, placed by the DGCNN on its shape", r);
        }
        let _ = writeln!(
            s,
            "\nshape BCD: physics {:.3} mm{}",
            self.physics_shape_bcd_mm,
            if self.sr_arap_shape_bcd_mm.is_finite() {
                format!(", SR-ARAP {:.3} mm", self.sr_arap_shape_bcd_mm)
            } else {
                String::new()
            } + &self
                .sr_arap_depth_shape_bcd_mm
                .map_or_else(String::new, |b| {
                    format!(", SR-ARAP from markers and depth {b:.3} mm")
                })
        );
        let f = &self.forces;
        let _ = writeln!(
            s,
            "\n| true force (N) | fingers | detected | location median mm (along) | force error median N (%) |\n|---|---|---|---|---|"
        );
        for b in &f.bins {
            let _ = writeln!(
                s,
                "| {:.2}–{} | {} | {:.1} % | {:.2} ({:.2}) | {:.3} ({:.0} %) |",
                b.lo_n,
                if b.hi_n.is_finite() {
                    format!("{:.2}", b.hi_n)
                } else {
                    "∞".into()
                },
                b.fingers,
                100.0 * b.detection_rate,
                b.location_median_mm,
                b.along_median_mm,
                b.force_error_median_n,
                b.force_error_median_pct
            );
        }
        let _ = writeln!(
            s,
            "\nfalse alarms: {} of {} unpressed finger-frames ({:.1} %); smallest force detected 90 % of the time: {:.3} N; truth: {}",
            f.false_alarm_fingers,
            f.unpressed_fingers,
            100.0 * f.false_alarm_fingers as Real / f.unpressed_fingers.max(1) as Real,
            f.force_detected_90pct_n,
            if f.net_force_truth {
                "net force vectors"
            } else {
                "summed magnitudes (an old data set)"
            }
        );
        let t = &self.stream;
        let _ = writeln!(
            s,
            "presses (runs of contact frames of a finger): {}; detected in their first frame: {} \
             ({:.1} %), after {:.2} frames on average; held frames after detection dropped: {} of {} \
             ({:.1} %, {} presses flicker); releases still reported: {} of {} ({:.1} %)",
            t.presses,
            t.onset_detected,
            100.0 * t.onset_detected as Real / t.presses.max(1) as Real,
            t.onset_delay_frames_mean,
            t.held_frames_dropped,
            t.held_frames,
            100.0 * t.held_frames_dropped as Real / t.held_frames.max(1) as Real,
            t.presses_with_flicker,
            t.release_false_alarms,
            t.releases,
            100.0 * t.release_false_alarms as Real / t.releases.max(1) as Real,
        );
        s
    }
}
