//! Safetensors bytes for the crate's three files (model weights, training checkpoints, KNN
//! indexes): one writer, one guarded reader, and the little-endian conversions they share.

use std::collections::HashMap;

use safetensors::SafeTensors;
use safetensors::tensor::{Dtype, TensorView};

use crate::error::ContactError;

/// One tensor to write: name, dtype, shape and little-endian bytes.
pub(crate) struct Entry {
    pub(crate) name: String,
    pub(crate) dtype: Dtype,
    pub(crate) shape: Vec<usize>,
    pub(crate) bytes: Vec<u8>,
}

impl Entry {
    pub(crate) fn f32(name: impl Into<String>, shape: Vec<usize>, values: &[f32]) -> Self {
        Self {
            name: name.into(),
            dtype: Dtype::F32,
            shape,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    pub(crate) fn f64(name: impl Into<String>, shape: Vec<usize>, values: &[f64]) -> Self {
        Self {
            name: name.into(),
            dtype: Dtype::F64,
            shape,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    pub(crate) fn u32(name: impl Into<String>, shape: Vec<usize>, values: &[u32]) -> Self {
        Self {
            name: name.into(),
            dtype: Dtype::U32,
            shape,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }
}

/// Safetensors bytes of `entries` (the serialiser sorts them) with optional metadata.
///
/// The same entries and metadata give the same bytes: the serialiser writes the metadata map in
/// its hash order, which differs from map to map, so the header is rewritten with its keys
/// sorted (same keys and values, so the same length, and the data offsets stay valid).
pub(crate) fn serialize(
    entries: &[Entry],
    metadata: Option<HashMap<String, String>>,
) -> Result<Vec<u8>, ContactError> {
    let views = entries
        .iter()
        .map(|e| {
            TensorView::new(e.dtype, e.shape.clone(), &e.bytes)
                .map(|v| (e.name.clone(), v))
                .map_err(|err| ContactError::MalformedWeights {
                    message: format!("{}: {err}", e.name),
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let bytes =
        safetensors::serialize(views, metadata).map_err(|e| ContactError::MalformedWeights {
            message: e.to_string(),
        })?;
    sorted_header(bytes)
}

/// `bytes` with the JSON header's object keys in sorted order, padded as before.
fn sorted_header(mut bytes: Vec<u8>) -> Result<Vec<u8>, ContactError> {
    let malformed = |message: String| ContactError::MalformedWeights { message };
    let len = bytes
        .get(..8)
        .and_then(|b| b.try_into().ok())
        .map(u64::from_le_bytes)
        .ok_or_else(|| malformed("serialised tensors without a header".into()))?;
    let end = usize::try_from(len)
        .ok()
        .and_then(|n| n.checked_add(8))
        .filter(|&end| end <= bytes.len())
        .ok_or_else(|| malformed("serialised header longer than the file".into()))?;
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..end]).map_err(|e| malformed(e.to_string()))?;
    let mut sorted =
        serde_json::to_vec(&sort_keys(header)).map_err(|e| malformed(e.to_string()))?;
    let padded = end - 8;
    if sorted.len() > padded {
        return Err(malformed("sorted header grew".into()));
    }
    sorted.resize(padded, b' ');
    bytes[8..end].copy_from_slice(&sorted);
    Ok(bytes)
}

/// `value` with every object's keys in sorted order, whatever map type serde_json was built
/// with.
fn sort_keys(value: serde_json::Value) -> serde_json::Value {
    match value {
        serde_json::Value::Object(map) => {
            let sorted: std::collections::BTreeMap<String, serde_json::Value> =
                map.into_iter().map(|(k, v)| (k, sort_keys(v))).collect();
            serde_json::Value::Object(sorted.into_iter().collect())
        }
        other => other,
    }
}

/// Parses safetensors bytes and their metadata; `what` names the file in errors. The parser is
/// a dependency: a panic inside it on hostile bytes is reported, not raised.
pub(crate) fn parse<'a>(
    bytes: &'a [u8],
    what: &str,
) -> Result<(SafeTensors<'a>, HashMap<String, String>), ContactError> {
    let bad = |message: String| ContactError::MalformedWeights {
        message: format!("{what}: {message}"),
    };
    let st = std::panic::catch_unwind(|| SafeTensors::deserialize(bytes))
        .map_err(|_| bad("the safetensors parser failed on these bytes".into()))?
        .map_err(|e| bad(e.to_string()))?;
    let (_, meta) = SafeTensors::read_metadata(bytes).map_err(|e| bad(e.to_string()))?;
    Ok((st, meta.metadata().clone().unwrap_or_default()))
}

pub(crate) fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

pub(crate) fn f64s(bytes: &[u8]) -> Vec<f64> {
    bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
        .collect()
}

pub(crate) fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The serialiser writes metadata in hash order, which differs between maps: without the
    /// sorted header, two writes of the same index differ in almost every run of this test.
    #[test]
    fn the_same_tensors_and_metadata_give_the_same_bytes() {
        let entries = [
            Entry::f64("b", vec![2], &[1.0, 2.0]),
            Entry::u32("a", vec![3], &[1, 2, 3]),
        ];
        let meta = || {
            (0..12)
                .map(|k| (format!("key{k}"), format!("value {k}")))
                .collect::<HashMap<_, _>>()
        };
        let first = serialize(&entries, Some(meta())).unwrap();
        for _ in 0..16 {
            assert_eq!(serialize(&entries, Some(meta())).unwrap(), first);
        }
        let (st, read) = parse(&first, "test").unwrap();
        assert_eq!(read, meta());
        assert_eq!(f64s(st.tensor("b").unwrap().data()), [1.0, 2.0]);
    }
}
