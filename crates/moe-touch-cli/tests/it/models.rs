//! The committed contact models: their cards parse with the typed sections, name the finger
//! they were trained on by its rest-mesh digest, and refuse another finger.

use moe_contact::{ContactError, DgcnnEstimator};
use moe_geom::{FingerParams, HandModel, HandPreset};

fn model(name: &str) -> (Vec<u8>, String) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models");
    let weights = std::fs::read(dir.join(format!("{name}.safetensors"))).unwrap();
    let card = std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap();
    (weights, card)
}

#[test]
fn shipped_cards_name_the_two_finger_preset_finger_and_refuse_another() {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let digest = hand.fingers()[0].model.mesh().digest();
    println!("two-finger preset finger digest: {digest}");
    for name in ["contact-two-finger", "contact-two-finger-paper"] {
        let (weights, json) = model(name);
        let card = moe_contact::ModelCard::from_json(&json).unwrap();
        let trained = card.hand.as_ref().unwrap();
        assert_eq!(trained.finger_digests, vec![digest.clone(); 2], "{name}");
        assert!(card.training.is_some() && card.dataset.is_some(), "{name}");
        assert!(!card.metrics.as_ref().unwrap().epochs.is_empty(), "{name}");
        // The finger alone, from its mesh: no markers or hand needed.
        let finger = hand.fingers()[0].model.mesh();
        let alone = DgcnnEstimator::finger_from_bytes(&weights, &json, finger).unwrap();
        assert_eq!(
            alone.finger_map(finger.vertices()).unwrap().len(),
            finger.num_vertices()
        );
        // A finger of other parameters is refused, and the message says how to get a model.
        let thicker = FingerParams {
            base_radius_m: FingerParams::default().base_radius_m * 1.2,
            ..FingerParams::default()
        };
        let other = HandModel::preset(HandPreset::TwoFinger, &thicker).unwrap();
        let err = DgcnnEstimator::from_bytes(&weights, &json, &other).unwrap_err();
        assert!(
            matches!(
                err,
                ContactError::FingerMismatch { .. } | ContactError::HandMismatch { .. }
            ),
            "{name}: {err}"
        );
        assert!(err.to_string().contains("two-finger"), "{name}: {err}");
    }
}
