//! The data set card: layout, shard list and frame statistics, written beside the shards.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::frame::{DatasetFrame, DatasetLayout};

/// File name of the data set card.
pub const CARD_FILE: &str = "card.json";

/// Counts over a set of frames.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameStats {
    /// Frames.
    pub frames: u64,
    /// Distinct trajectories.
    pub trajectories: u64,
    /// Frames with at least one contact vertex.
    pub contact_frames: u64,
    /// Vertices labelled in contact, over all frames.
    pub contact_vertices: u64,
    /// Vertices, over all frames.
    pub vertices: u64,
    /// Frames that carry the fingers' net contact forces (`finger_force_n`; 0 in cards of
    /// format version 1, whose shards lack the tensor).
    #[serde(default)]
    pub force_frames: u64,
}

impl FrameStats {
    /// Fraction of all vertices that are labelled in contact.
    pub fn contact_ratio(&self) -> f64 {
        if self.vertices == 0 {
            0.0
        } else {
            self.contact_vertices as f64 / self.vertices as f64
        }
    }

    fn add(&mut self, other: &FrameStats) {
        self.frames += other.frames;
        self.trajectories += other.trajectories;
        self.contact_frames += other.contact_frames;
        self.contact_vertices += other.contact_vertices;
        self.vertices += other.vertices;
        self.force_frames += other.force_frames;
    }
}

/// One shard as listed in the card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardEntry {
    /// File name within the data set directory.
    pub file: String,
    /// Its statistics.
    pub stats: FrameStats,
}

/// The data set card: what a data set holds, written beside its shards.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetCard {
    /// Format version of the shards.
    pub format_version: u32,
    /// The frame layout.
    pub layout: DatasetLayout,
    /// Seed of the generator that produced the data.
    pub seed: u64,
    /// Free-form description of how the data were generated.
    pub generator: serde_json::Value,
    /// Every shard, in order.
    pub shards: Vec<ShardEntry>,
    /// Totals over all shards.
    pub totals: FrameStats,
    /// Totals per object family.
    pub families: BTreeMap<String, FrameStats>,
}

/// The shard format version this crate writes. Version 2 added the optional `finger_force_n`
/// tensor (and the card's [`FrameStats::force_frames`]); cards and shards of version 1 read as
/// before, their frames without finger forces.
pub const FORMAT_VERSION: u32 = 2;

/// Statistics of a shard's frames, overall and per family.
pub fn shard_stats(
    layout: &DatasetLayout,
    frames: &[DatasetFrame],
) -> (FrameStats, BTreeMap<String, FrameStats>) {
    let mut total = FrameStats::default();
    let mut per_family: BTreeMap<String, FrameStats> = BTreeMap::new();
    let mut seen: BTreeMap<String, std::collections::BTreeSet<u64>> = BTreeMap::new();
    for f in frames {
        let name = layout
            .object_families
            .get(usize::from(f.object_family))
            .cloned()
            .unwrap_or_default();
        let contacts = f.contact_count() as u64;
        let one = FrameStats {
            frames: 1,
            trajectories: 0,
            contact_frames: u64::from(contacts > 0),
            contact_vertices: contacts,
            vertices: f.contact.len() as u64,
            force_frames: u64::from(f.finger_force_n.is_some()),
        };
        total.add(&one);
        per_family.entry(name.clone()).or_default().add(&one);
        seen.entry(name).or_default().insert(f.trajectory_id);
    }
    let all: std::collections::BTreeSet<u64> = frames.iter().map(|f| f.trajectory_id).collect();
    total.trajectories = all.len() as u64;
    for (name, ids) in seen {
        per_family.entry(name).or_default().trajectories = ids.len() as u64;
    }
    (total, per_family)
}

impl DatasetCard {
    /// Whether every frame of the data set carries the fingers' net contact forces
    /// ([`DatasetFrame::finger_force_n`]): false for an empty data set and for one written
    /// before format version 2.
    pub fn has_finger_force(&self) -> bool {
        self.totals.frames > 0 && self.totals.force_frames == self.totals.frames
    }

    /// A card for shards whose statistics are given (trajectories never span shards).
    pub fn new(
        layout: DatasetLayout,
        seed: u64,
        generator: serde_json::Value,
        shards: Vec<(ShardEntry, BTreeMap<String, FrameStats>)>,
    ) -> Self {
        let mut totals = FrameStats::default();
        let mut families: BTreeMap<String, FrameStats> = BTreeMap::new();
        for (entry, fam) in &shards {
            totals.add(&entry.stats);
            for (name, s) in fam {
                families.entry(name.clone()).or_default().add(s);
            }
        }
        Self {
            format_version: FORMAT_VERSION,
            layout,
            seed,
            generator,
            shards: shards.into_iter().map(|(e, _)| e).collect(),
            totals,
            families,
        }
    }
}
