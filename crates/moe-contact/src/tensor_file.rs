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
    safetensors::serialize(views, metadata).map_err(|e| ContactError::MalformedWeights {
        message: e.to_string(),
    })
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
