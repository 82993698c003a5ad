//! Small held-out sets: a few test frames with contact cut from a data set (what the workspace
//! commits in `fixtures/contact/heldout` for its golden fixtures), and the committed one's
//! `KNN[All]` index, built into this crate.

use std::path::Path;

use moe_contact::KnnIndex;
use moe_io::dataset::{
    CARD_FILE, DatasetCard, ShardEntry, parse_shard, shard_file_name, shard_stats, write_shard,
};
use moe_io::{DatasetFrame, DatasetReader, IoError, Split, SplitFractions};

use crate::error::LabError;

/// Of each of the first `trajectories` test trajectories of `reader` with contact, `frames`
/// frames: every other frame from the one before the first contact. Empty when no test
/// trajectory has contact.
///
/// # Errors
/// An unreadable shard.
pub fn select_heldout_frames(
    reader: &DatasetReader,
    trajectories: usize,
    frames: usize,
) -> Result<Vec<DatasetFrame>, LabError> {
    let mut by_trajectory: Vec<(u64, Vec<DatasetFrame>)> = Vec::new();
    for f in reader.frames(Some(Split::Test), SplitFractions::default()) {
        let f = f?;
        match by_trajectory.last_mut() {
            Some((t, v)) if *t == f.trajectory_id => v.push(f),
            _ => by_trajectory.push((f.trajectory_id, vec![f])),
        }
    }
    let mut selected = Vec::new();
    for (_, traj) in by_trajectory
        .iter()
        .filter(|(_, v)| v.iter().any(|f| f.contact_count() > 0))
        .take(trajectories)
    {
        let first = traj.iter().position(|f| f.contact_count() > 0).unwrap_or(0);
        selected.extend(
            traj.iter()
                .skip(first.saturating_sub(1))
                .step_by(2)
                .take(frames)
                .cloned(),
        );
    }
    Ok(selected)
}

/// Writes `frames` (of `reader`'s data set) to the directory `out` as a data set of one shard,
/// with a card of `reader`'s layout, seed and generator.
///
/// # Errors
/// A directory or file that cannot be written.
pub fn write_heldout_set(
    reader: &DatasetReader,
    frames: &[DatasetFrame],
    out: &Path,
) -> Result<(), LabError> {
    let layout = reader.card().layout.clone();
    std::fs::create_dir_all(out).map_err(|source| IoError::Io {
        path: out.to_owned(),
        source,
    })?;
    let file = shard_file_name(0, 1);
    write_shard(&out.join(&file), &layout, frames)?;
    let (stats, families) = shard_stats(&layout, frames);
    let card = DatasetCard::new(
        layout,
        reader.card().seed,
        reader.card().generator.clone(),
        vec![(ShardEntry { file, stats }, families)],
    );
    moe_io::write_json(&out.join(CARD_FILE), &card)?;
    Ok(())
}

/// The one shard of the committed held-out set (`fixtures/contact/heldout`), built in so that a
/// study finds it wherever it runs.
const HELDOUT_SHARD: &[u8] =
    include_bytes!("../../../../fixtures/contact/heldout/shard-00000-of-00001.safetensors");
/// Its name in messages.
const HELDOUT_SHARD_NAME: &str =
    "fixtures/contact/heldout/shard-00000-of-00001.safetensors (built in)";

/// The `KNN[All]` index of every frame of the committed held-out set (two-finger hand, no
/// shapes kept): a small stand-in for an index of a data set's training frames, built in.
///
/// # Errors
/// A built-in shard that does not parse (a build from an edited checkout).
pub fn heldout_knn_index() -> Result<KnnIndex, LabError> {
    let (layout, frames) = parse_shard(Path::new(HELDOUT_SHARD_NAME), HELDOUT_SHARD)?;
    let frames = frames
        .iter()
        .map(|f| f.to_labelled(&layout))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(KnnIndex::new(&frames, false)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact_eval::build_knn_index;

    /// The built-in index is the one built from the committed directory.
    #[test]
    fn the_built_in_index_is_the_committed_sets() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/contact/heldout");
        let reader = DatasetReader::open(&dir).unwrap();
        let from_dir = build_knn_index(&reader, None, false).unwrap();
        let built_in = heldout_knn_index().unwrap();
        assert!(!built_in.is_empty());
        assert!(
            built_in == from_dir,
            "the built-in index differs from {}",
            dir.display()
        );
    }
}
