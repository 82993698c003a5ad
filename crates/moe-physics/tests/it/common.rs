//! Markers of a hand whose fingers carry known point loads, simulated statically by the data
//! generator's own model (its 3.5 mm voxel mesh; the estimator models the finger with its own).

use moe_geom::{FingerParams, HandKeypoints, HandModel, HandPreset, Point3, Real, Vector3};

pub(crate) fn hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
}

pub(crate) use moe_physics::testing::PointLoad;

/// The surface vertex of finger `f` nearest `p` (finger frame).
pub(crate) fn vertex_near(hand: &HandModel, f: usize, p: Point3) -> u32 {
    let v = hand.fingers()[f].model.mesh().vertices();
    (0..v.len())
        .min_by(|&a, &b| (v[a] - p).norm().total_cmp(&(v[b] - p).norm()))
        .unwrap() as u32
}

/// The outward normal of finger `f` at vertex `v`, finger frame.
pub(crate) fn normal_at(hand: &HandModel, f: usize, v: u32) -> Vector3 {
    hand.fingers()[f].model.mesh().vertex_normals()[v as usize]
}

/// The static markers (hand frame) of every finger under `pulls` and `loads`, by the data
/// generator's model, the hand held fingers-up.
pub(crate) fn simulate(
    hand: &HandModel,
    pulls: &[Vec<Real>],
    loads: &[PointLoad],
) -> HandKeypoints {
    moe_physics::testing::static_markers(hand, pulls, &moe_geom::WorldFromHand::identity(), loads)
        .unwrap()
}

/// A press of `newtons` along the inward normal at vertex `v` of finger 0.
pub(crate) fn press(hand: &HandModel, v: u32, newtons: Real) -> PointLoad {
    PointLoad {
        finger: 0,
        vertex: v,
        force: -normal_at(hand, 0, v) * newtons,
    }
}

/// Zero pulls for every tendon of `hand`.
pub(crate) fn no_pulls(hand: &HandModel) -> Vec<Vec<Real>> {
    hand.fingers()
        .iter()
        .map(|f| vec![0.0; f.model.tendon_routes().len()])
        .collect()
}

/// Vertices of finger `f` within one ring of `v` (edge neighbours, `v` included).
pub(crate) fn ring(hand: &HandModel, f: usize, v: u32) -> Vec<u32> {
    let mut out = vec![v];
    for face in hand.fingers()[f].model.mesh().faces() {
        if face.contains(&v) {
            for &u in face {
                if !out.contains(&u) {
                    out.push(u);
                }
            }
        }
    }
    out
}
