//! The contact study as text: the tables `moe-touch eval contact` prints and its progress
//! messages.

use std::fmt::Write as _;
use std::path::Path;

use super::{ContactStudyProgress, ContactStudyReport, ContactTable, KnnIndexSource, PlateTable};

impl ContactStudyReport {
    /// The report as the tables `moe-touch eval contact` prints: Table 1, Table 2 when plates
    /// were run, and the physics estimator's tables when asked for.
    pub fn tables(&self) -> String {
        let mut s = self.table1.table();
        if !self.table2.trials.is_empty() {
            s.push_str(&self.table2.table());
        }
        if let Some(p) = &self.physics {
            s.push_str("\nContact from physics on the same frames:\n");
            s.push_str(&p.table1.table());
            if !p.table2.trials.is_empty() {
                s.push_str(&p.table2.regions.table());
            }
        }
        s
    }
}

impl ContactTable {
    /// Table 1 as the text `moe-touch eval contact` prints: the shape rows (BCD and per-vertex
    /// error), then the contact rows for every label rule (the paper's metrics, time per frame).
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Table 1 — {} held-out frames of {} trajectories (DGCNN threshold {:.2})",
            self.frames, self.trajectories, self.threshold
        );
        let _ = writeln!(
            s,
            "{:<12} {:>7} {:>10} {:>10} {:>13} {:>12} {:>9}",
            "shape", "markers", "BCD mm", "sd", "vertex mean", "vertex max", "ms/frame"
        );
        for r in &self.shape {
            let _ = writeln!(
                s,
                "{:<12} {:>7} {:>10.3} {:>10.3} {:>13.3} {:>12.3} {:>9.2}",
                r.method,
                r.markers,
                r.bcd_mm,
                r.bcd_sd_mm,
                r.vertex_mean_mm,
                r.vertex_max_mm,
                r.ms_per_frame
            );
        }
        let _ = writeln!(
            s,
            "{:<20} {:<10} {:>8} {:>8} {:>7} {:>7} {:>6} {:>6} {:>6} {:>6} {:>9}",
            "contact",
            "labels",
            "BCD mm",
            "UCD mm",
            "missed",
            "f.alarm",
            "P",
            "R",
            "F1",
            "IoU",
            "ms/frame"
        );
        for r in &self.contact {
            let p = &r.report;
            let _ = writeln!(
                s,
                "{:<20} {:<10} {:>8.3} {:>8.3} {:>6.1}% {:>6.1}% {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>9.2}",
                r.method,
                r.labels,
                p.bcd_mm,
                p.ucd_mm,
                100.0 * p.miss_rate,
                100.0 * p.false_alarm_rate,
                p.precision,
                p.recall,
                p.f1,
                p.iou,
                r.ms_per_frame
            );
        }
        s
    }
}

impl PlateTable {
    /// Table 2 as the text `moe-touch eval contact` prints: every trial's UCD and missed frames
    /// for the DGCNN and `KNN[All]`, then the mean ± sd per region.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Table 2 — plate scenes, UCD predicted → true contact points, mm"
        );
        let _ = writeln!(
            s,
            "{:<20} {:>5} {:>9} {:>8} {:>10} {:>8} {:>10} {:>8}",
            "scene", "trial", "contact", "DGCNN", "missed", "KNN[All]", "missed", "tilt°"
        );
        for t in &self.trials {
            let _ = writeln!(
                s,
                "{:<20} {:>5} {:>9} {:>8.2} {:>9.0}% {:>8.2} {:>9.0}% {:>8.2}",
                t.scene,
                t.trial,
                t.contact_frames,
                t.dgcnn.ucd_mm,
                100.0 * t.dgcnn.miss_rate,
                t.knn_all.ucd_mm,
                100.0 * t.knn_all.miss_rate,
                t.tilt_deg
            );
        }
        for (region, r) in self.regions.in_order() {
            let _ = writeln!(
                s,
                "{region:<8} DGCNN {:.2} ± {:.2} mm   KNN[All] {:.2} ± {:.2} mm",
                r.dgcnn.mean_mm, r.dgcnn.sd_mm, r.knn_all.mean_mm, r.knn_all.sd_mm,
            );
        }
        s
    }
}

impl ContactStudyProgress<'_> {
    /// What the study is about to do, as the line `moe-touch eval contact` shows on stderr
    /// (without its `eval contact: ` prefix); `None` for what it does not report (an index built
    /// and kept in memory only).
    pub fn message(&self) -> Option<String> {
        let shown =
            |path: Option<&Path>| path.map_or_else(String::new, |p| p.display().to_string());
        match *self {
            Self::KnnIndex {
                frames,
                source: KnnIndexSource::Read,
                path,
            } => Some(format!("KNN index of {frames} frames from {}", shown(path))),
            Self::KnnIndex {
                frames,
                source: KnnIndexSource::BuiltAndWritten,
                path,
            } => Some(format!(
                "built the KNN index of {frames} training frames, wrote {}",
                shown(path)
            )),
            Self::KnnIndex {
                source: KnnIndexSource::Built,
                ..
            } => None,
            Self::Table1 {
                frames,
                knn_all,
                knn_sub,
            } => Some(format!(
                "{frames} frames; SR-ARAP, DGCNN, KNN[All] ({knn_all} frames), KNN[Sub] ({knn_sub})"
            )),
            Self::Plates { scenes, trials } => {
                Some(format!("{scenes} plate scenes × {trials} trials"))
            }
            Self::Physics { frames } => Some(format!("the physics estimator on {frames} frames")),
        }
    }
}
