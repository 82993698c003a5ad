//! Model files: bit-exact round trips, PyTorch files load unchanged, and bad files and inputs
//! are refused with errors that name the item.

use std::collections::BTreeMap;

use moe_contact::candle_core::{DType, Device, Tensor};
use moe_contact::{
    ContactError, Dgcnn, DgcnnConfig, InputFeature, Mode, ModelCard, ModelWeights, tensor_names,
};
use safetensors::tensor::{Dtype, TensorView};

use crate::common::{random_points, small_config, tensor, values};

fn reference_weights() -> Vec<u8> {
    std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/contact/reference_weights.safetensors"),
    )
    .unwrap()
}

fn load(bytes: &[u8], card: Option<&ModelCard>) -> Result<Dgcnn, ContactError> {
    Dgcnn::from_safetensors(bytes, card, DType::F32, &Device::Cpu)
}

/// Safetensors bytes from (name, dtype, shape, raw little-endian data).
fn file(tensors: &[(String, Dtype, Vec<usize>, Vec<u8>)]) -> Vec<u8> {
    let views: Vec<(String, TensorView<'_>)> = tensors
        .iter()
        .map(|(n, d, s, b)| (n.clone(), TensorView::new(*d, s.clone(), b).unwrap()))
        .collect();
    safetensors::serialize(views, None).unwrap()
}

/// The tensors of a seeded small network, as raw entries to edit.
fn entries() -> Vec<(String, Dtype, Vec<usize>, Vec<u8>)> {
    let w = ModelWeights::seeded(&small_config(Default::default()), 3, 1).unwrap();
    tensor_names()
        .into_iter()
        .map(|n| {
            let (shape, v) = w.get(&n).unwrap();
            let bytes = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            (n, Dtype::F32, shape.to_vec(), bytes)
        })
        .collect()
}

fn small_card() -> ModelCard {
    ModelCard::new(small_config(Default::default()))
}

#[test]
fn save_load_forward_is_bit_identical() {
    let config = small_config(Default::default());
    let bytes = ModelWeights::seeded(&config, 3, 9)
        .unwrap()
        .to_bytes()
        .unwrap();
    let x = tensor(&random_points(1, 80, 3, 1), 1, 80, 3);
    let a = load(&bytes, Some(&small_card())).unwrap();
    let saved = a.to_safetensors().unwrap();
    assert_eq!(
        saved, bytes,
        "saving the loaded weights gives the same bytes"
    );
    let b = load(&saved, Some(&small_card())).unwrap();
    let la = values(&a.forward_with(&x, Mode::Eval).unwrap().logits);
    let lb = values(&b.forward_with(&x, Mode::Eval).unwrap().logits);
    assert_eq!(
        la.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        lb.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    // Through f64 and back, the float32 weights are unchanged.
    let wide = Dgcnn::from_safetensors(&bytes, None, DType::F64, &Device::Cpu).unwrap();
    assert_eq!(wide.to_safetensors().unwrap(), bytes);
}

#[test]
fn weights_written_by_pytorch_load_unchanged() {
    let bytes = reference_weights();
    let original = ModelWeights::parse(&bytes).unwrap();
    let net = load(&bytes, None).unwrap();
    assert_eq!(
        net.config(),
        &DgcnnConfig::default(),
        "k = 30, max, 64/128/256, 512/256"
    );
    assert_eq!(net.in_channels(), 3);
    let again = ModelWeights::parse(&net.to_safetensors().unwrap()).unwrap();
    for name in tensor_names() {
        let (sa, va) = original.get(&name).unwrap();
        let (sb, vb) = again.get(&name).unwrap();
        assert_eq!(sa, sb, "{name}");
        assert!(
            va.iter().zip(vb).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{name}"
        );
    }
}

#[test]
fn a_missing_tensor_is_named() {
    let mut e = entries();
    e.retain(|t| t.0 != "edge2.phi.bias");
    match load(&file(&e), None) {
        Err(ContactError::MissingTensor { name }) => assert_eq!(name, "edge2.phi.bias"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_tensor_of_the_wrong_shape_is_named() {
    let mut e = entries();
    let t = e.iter_mut().find(|t| t.0 == "head.1.weight").unwrap();
    t.2 = vec![16, 31];
    t.3.truncate(16 * 31 * 4);
    match load(&file(&e), None) {
        Err(ContactError::TensorShape {
            name,
            expected,
            got,
        }) => {
            assert_eq!(name, "head.1.weight");
            assert_eq!((expected, got), (vec![16, 32], vec![16, 31]));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_tensor_of_the_wrong_dtype_is_named() {
    let mut e = entries();
    let t = e.iter_mut().find(|t| t.0 == "edge1.theta").unwrap();
    t.1 = Dtype::F64;
    t.3 =
        t.3.chunks_exact(4)
            .flat_map(|b| f64::from(f32::from_le_bytes(b.try_into().unwrap())).to_le_bytes())
            .collect();
    match load(&file(&e), None) {
        Err(ContactError::TensorDtype { name, got }) => {
            assert_eq!((name.as_str(), got.as_str()), ("edge1.theta", "f64"));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_extra_tensor_and_a_non_finite_weight_are_named() {
    let mut e = entries();
    e.push((
        "edge4.theta".into(),
        Dtype::F32,
        vec![1],
        1f32.to_le_bytes().to_vec(),
    ));
    assert!(matches!(
        load(&file(&e), None),
        Err(ContactError::UnexpectedTensor { name }) if name == "edge4.theta"
    ));
    let mut e = entries();
    let t = e.iter_mut().find(|t| t.0 == "head.2.bias").unwrap();
    t.3[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(matches!(
        load(&file(&e), None),
        Err(ContactError::NonFiniteWeight { name, index: 1 }) if name == "head.2.bias"
    ));
}

#[test]
fn a_card_that_contradicts_the_weights_is_refused() {
    let bytes = file(&entries());
    let mut card = small_card();
    card.architecture.edge_widths = [8, 16, 64];
    assert!(matches!(
        load(&bytes, Some(&card)),
        Err(ContactError::CardMismatch {
            field: "architecture.edge_widths",
            ..
        })
    ));
    let mut card = small_card();
    card.architecture.head_widths = [32, 8];
    assert!(matches!(
        load(&bytes, Some(&card)),
        Err(ContactError::CardMismatch {
            field: "architecture.head_widths",
            ..
        })
    ));
    let mut card = small_card();
    card.architecture.input.features.push(InputFeature::RestXyz);
    let err = load(&bytes, Some(&card)).unwrap_err();
    assert!(
        matches!(
            err,
            ContactError::CardMismatch {
                field: "architecture.input.features",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("xyz + rest-xyz"), "{err}");
}

#[test]
fn garbled_files_give_errors_never_panics() {
    let bytes = file(&entries());
    let mut checked = 0;
    for cut in (0..bytes.len())
        .step_by(97)
        .chain([1, 7, 8, 9, bytes.len() - 1])
    {
        moe_geom::assert_err!(
            load(&bytes[..cut], None),
            ContactError::MalformedWeights { message } if message.starts_with("model file: "),
            "cut at {cut}"
        );
        checked += 1;
    }
    for at in (0..bytes.len().min(4000)).step_by(13) {
        let mut b = bytes.clone();
        b[at] ^= 0x5a;
        // A flip inside the data is a valid file with another weight; inside the header it
        // must be an error. Either way, no panic.
        let _ = load(&b, None);
        checked += 1;
    }
    assert!(checked > 100);
    assert!(matches!(
        load(b"not a model", None),
        Err(ContactError::MalformedWeights { .. })
    ));
}

#[test]
fn bad_inputs_name_the_point_set_and_point() {
    let net = load(&file(&entries()), None).unwrap();
    let few = tensor(&random_points(1, 5, 3, 1), 1, 5, 3);
    assert!(matches!(
        net.forward_with(&few, Mode::Eval),
        Err(ContactError::TooFewPoints {
            points: 5,
            k: 30,
            ..
        })
    ));
    let mut v = random_points(2, 40, 3, 1);
    v[(40 + 17) * 3 + 1] = f64::NAN;
    assert!(matches!(
        net.forward_with(&tensor(&v, 2, 40, 3), Mode::Eval),
        Err(ContactError::NonFinitePoint { set: 1, index: 17 })
    ));
    let wide = Tensor::zeros((1, 40, 6), DType::F64, &Device::Cpu).unwrap();
    assert!(matches!(
        net.forward_with(&wide, Mode::Eval),
        Err(ContactError::InputWidth {
            expected: 3,
            got: 6
        })
    ));
    let flat = Tensor::zeros((40, 3), DType::F64, &Device::Cpu).unwrap();
    assert!(matches!(
        net.forward_with(&flat, Mode::Eval),
        Err(ContactError::InvalidBatch { .. })
    ));
}

#[test]
fn seeded_weights_depend_on_the_seed_only() {
    let config = small_config(Default::default());
    let a = ModelWeights::seeded(&config, 3, 4).unwrap();
    assert_eq!(a, ModelWeights::seeded(&config, 3, 4).unwrap());
    assert_ne!(a, ModelWeights::seeded(&config, 3, 5).unwrap());
    let names: BTreeMap<&str, ()> = a.names().map(|n| (n, ())).collect();
    assert_eq!(names.len(), 15);
}
