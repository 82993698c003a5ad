//! The DGCNN behind the contact-estimator seam ([`moe_geom::ContactEstimator`]), and the
//! features it turns an observation into.

use candle_core::{DType, Device, Tensor};
use moe_geom::{
    ContactEstimate, ContactEstimator, ContactInput, ContactMap, HandModel, HandShape, Iso3,
    Point3, TriMesh,
};

use crate::card::{CardHand, ModelCard};
use crate::config::{FeatureFrame, InputFeature, InputSpec, PointSet};
use crate::deformation::DeformationFeatures;
use crate::error::ContactError;
use crate::network::{Dgcnn, ForwardTimings, Mode, contact_probability};

/// Where one point set's rows come from: its fingers in order, and its length.
#[derive(Debug, Clone)]
struct SetPlan {
    fingers: Vec<usize>,
    len: usize,
}

/// Per finger and tendon, the unit direction of the tendon's route base from the finger axis
/// (finger frame, x and y).
///
/// # Errors
/// [`ContactError::InvalidConfig`] naming the finger and tendon, when the spec takes
/// [`InputFeature::TendonPull`] and a route starts on the axis (no bending direction).
fn tendon_directions(
    hand: &HandModel,
    spec: &InputSpec,
) -> Result<Vec<Vec<[f64; 2]>>, ContactError> {
    let needed = spec.features.contains(&InputFeature::TendonPull);
    hand.fingers()
        .iter()
        .enumerate()
        .map(|(f, finger)| {
            finger
                .model
                .tendon_routes()
                .iter()
                .enumerate()
                .map(|(t, r)| {
                    let base = r.points_in_finger.first().map_or([0.0; 2], |p| [p.x, p.y]);
                    let norm = base[0].hypot(base[1]);
                    if norm > 1e-9 {
                        Ok([base[0] / norm, base[1] / norm])
                    } else if needed {
                        Err(ContactError::InvalidConfig {
                            field: "input.features",
                            message: format!(
                                "tendon-pull: finger {f}'s tendon {t} starts on the finger axis, \
                                 so its pull has no bending direction"
                            ),
                        })
                    } else {
                        Ok([0.0; 2])
                    }
                })
                .collect()
        })
        .collect()
}

/// Turns a hand shape into the network's input as an [`InputSpec`] says: which features, in
/// which frame, grouped into which point sets. Shared by inference and training.
#[derive(Debug, Clone)]
pub struct FeatureBuilder {
    spec: InputSpec,
    finger_from_hand: Vec<Iso3>,
    rest_in_hand: Vec<Vec<Point3>>,
    plans: Vec<SetPlan>,
    /// Per finger, when the spec asks for [`InputFeature::Deformation`].
    deformation: Vec<DeformationFeatures>,
    /// Per finger and tendon, the unit direction of the tendon from the finger axis (finger
    /// frame, x and y, at the route's base).
    tendon_directions: Vec<Vec<[f64; 2]>>,
}

impl FeatureBuilder {
    /// Features of `spec` for the shapes of `hand`.
    ///
    /// # Errors
    /// An invalid spec.
    pub fn new(spec: &InputSpec, hand: &HandModel) -> Result<Self, ContactError> {
        spec.validate()?;
        let counts: Vec<usize> = hand
            .fingers()
            .iter()
            .map(|f| f.model.mesh().num_vertices())
            .collect();
        let plans = match spec.point_set {
            PointSet::WholeHand => vec![SetPlan {
                fingers: (0..counts.len()).collect(),
                len: counts.iter().sum(),
            }],
            PointSet::PerFinger => counts
                .iter()
                .enumerate()
                .map(|(f, &len)| SetPlan {
                    fingers: vec![f],
                    len,
                })
                .collect(),
        };
        Ok(Self {
            spec: spec.clone(),
            finger_from_hand: hand
                .fingers()
                .iter()
                .map(|f| f.hand_from_finger.iso().inverse())
                .collect(),
            rest_in_hand: (0..hand.num_fingers())
                .map(|f| hand.rest_vertices_in_hand(f))
                .collect(),
            plans,
            deformation: if spec.features.contains(&InputFeature::Deformation) {
                hand.fingers()
                    .iter()
                    .map(|f| DeformationFeatures::new(f.model.mesh()))
                    .collect()
            } else {
                Vec::new()
            },
            tendon_directions: tendon_directions(hand, spec)?,
        })
    }

    /// Features of `spec` for one finger alone, given by its rest mesh in its own frame: what a
    /// per-finger model needs, without a hand model (no markers, base or tendons). The finger's
    /// shapes are then one-finger [`HandShape`]s in that frame.
    ///
    /// # Errors
    /// An invalid spec, or one whose features take tendon pulls (they need the hand's tendons).
    pub fn for_finger(spec: &InputSpec, rest: &TriMesh) -> Result<Self, ContactError> {
        spec.validate()?;
        if spec.features.contains(&InputFeature::TendonPull) {
            return Err(ContactError::InvalidConfig {
                field: "input.features",
                message: "tendon-pull needs the hand's tendon routes: build the estimator for a \
                          hand (DgcnnEstimator::new)"
                    .into(),
            });
        }
        let len = rest.num_vertices();
        Ok(Self {
            spec: spec.clone(),
            finger_from_hand: vec![Iso3::identity()],
            rest_in_hand: vec![rest.vertices().to_vec()],
            plans: vec![SetPlan {
                fingers: vec![0],
                len,
            }],
            deformation: if spec.features.contains(&InputFeature::Deformation) {
                vec![DeformationFeatures::new(rest)]
            } else {
                Vec::new()
            },
            tendon_directions: vec![Vec::new()],
        })
    }

    /// Whether the features need the tendon pulls of each observation.
    pub fn needs_tendon_pulls(&self) -> bool {
        self.spec.features.contains(&InputFeature::TendonPull)
    }

    /// The [`InputFeature::TendonPull`] channels of finger `f` (pulls checked beforehand).
    fn pull_channels(&self, pulls: Option<&[Vec<f64>]>, f: usize) -> [f64; 3] {
        let Some(p) = pulls.and_then(|p| p.get(f)) else {
            return [0.0; 3];
        };
        let mut out = [0.0; 3];
        for (pull, dir) in p.iter().zip(&self.tendon_directions[f]) {
            out[0] += pull * dir[0];
            out[1] += pull * dir[1];
            out[2] += pull;
        }
        out
    }

    /// The input spec.
    pub fn spec(&self) -> &InputSpec {
        &self.spec
    }

    /// Channels per point.
    pub fn channels(&self) -> usize {
        self.spec.channels()
    }

    /// The point sets of one shape, in order: the fingers of each set and its number of points.
    pub fn point_sets(&self) -> Vec<(Vec<usize>, usize)> {
        self.plans
            .iter()
            .map(|p| (p.fingers.clone(), p.len))
            .collect()
    }

    /// The input features of one finger's vertices, row after row (shape and pulls checked
    /// beforehand).
    fn finger_features(
        &self,
        shape: &HandShape,
        pulls: Option<&[Vec<f64>]>,
        f: usize,
        out: &mut Vec<f64>,
    ) {
        let to_frame = |p: &Point3| match self.spec.frame {
            FeatureFrame::Hand => *p,
            FeatureFrame::Finger => self.finger_from_hand[f] * p,
        };
        let start = out.len();
        // The measures are frame-free: the hand frame's positions give the finger frame's values.
        // Empty unless the spec asks for the feature (and then `new` built one per finger).
        let deformation = self
            .deformation
            .get(f)
            .map(|d| d.compute(&shape.fingers[f]))
            .unwrap_or_default();
        let pull = self.pull_channels(pulls, f);
        for (v, p) in shape.fingers[f].iter().enumerate() {
            for feature in &self.spec.features {
                let row = match feature {
                    InputFeature::Xyz => to_frame(p).coords.into(),
                    InputFeature::RestXyz => to_frame(&self.rest_in_hand[f][v]).coords.into(),
                    InputFeature::Deformation => deformation[v],
                    InputFeature::TendonPull => pull,
                };
                out.extend(row);
            }
        }
        self.spec.normalise(&mut out[start..]);
    }

    /// The features of one shape, one row-major `(points, channels)` block per point set (see
    /// [`FeatureBuilder::point_sets`]).
    ///
    /// # Errors
    /// A shape that does not fit the hand, naming the finger and vertex;
    /// [`ContactError::UnavailableFeatures`] for features that need tendon pulls.
    pub fn input_sets(&self, shape: &HandShape) -> Result<Vec<Vec<f64>>, ContactError> {
        self.input_sets_with(shape, None)
    }

    /// As [`FeatureBuilder::input_sets`], with the observation's tendon pulls (needed by
    /// [`InputFeature::TendonPull`], ignored otherwise).
    ///
    /// # Errors
    /// As [`FeatureBuilder::input_sets`], and pulls that do not fit the hand (naming the finger)
    /// or are not finite.
    pub fn input_sets_with(
        &self,
        shape: &HandShape,
        pulls: Option<&[Vec<f64>]>,
    ) -> Result<Vec<Vec<f64>>, ContactError> {
        self.check_shape(shape)?;
        self.check_pulls(pulls)?;
        Ok(self
            .plans
            .iter()
            .map(|plan| {
                let mut v = Vec::with_capacity(plan.len * self.channels());
                for &f in &plan.fingers {
                    self.finger_features(shape, pulls, f, &mut v);
                }
                v
            })
            .collect())
    }

    /// Checks the pulls of one observation when the features need them: given, one list per
    /// finger of the finger's tendon count, finite. Without [`InputFeature::TendonPull`] any
    /// pulls (or none) are accepted and ignored.
    ///
    /// # Errors
    /// [`ContactError::UnavailableFeatures`] when they are needed and missing,
    /// [`moe_geom::GeomError`] naming the finger otherwise.
    pub fn check_pulls(&self, pulls: Option<&[Vec<f64>]>) -> Result<(), ContactError> {
        if !self.needs_tendon_pulls() {
            return Ok(());
        }
        let Some(pulls) = pulls else {
            return Err(ContactError::UnavailableFeatures {
                features: self.spec.describe(),
                given: "an observation without tendon pulls",
            });
        };
        if pulls.len() != self.tendon_directions.len() {
            return Err(moe_geom::GeomError::LengthMismatch {
                what: "fingers of the tendon pulls",
                expected: self.tendon_directions.len(),
                got: pulls.len(),
            }
            .into());
        }
        for (finger, (p, dirs)) in pulls.iter().zip(&self.tendon_directions).enumerate() {
            if p.len() != dirs.len() {
                return Err(moe_geom::GeomError::FingerLengthMismatch {
                    what: "tendon pulls",
                    finger,
                    expected: dirs.len(),
                    got: p.len(),
                }
                .into());
            }
            if !p.iter().all(|v| v.is_finite()) {
                return Err(moe_geom::GeomError::NonFinitePoint {
                    what: "tendon pulls of the finger",
                    index: finger,
                }
                .into());
            }
        }
        Ok(())
    }

    /// Per-vertex values of every finger (labels, for instance) arranged like
    /// [`FeatureBuilder::input_sets`]: one vector per point set.
    pub fn arrange<T: Copy>(&self, per_finger: &[Vec<T>]) -> Vec<Vec<T>> {
        self.plans
            .iter()
            .map(|plan| {
                plan.fingers
                    .iter()
                    .flat_map(|&f| per_finger[f].iter().copied())
                    .collect()
            })
            .collect()
    }

    /// The inverse of [`FeatureBuilder::arrange`]: the values of one shape's point sets, set
    /// after set as the network returns them, back per finger and vertex.
    ///
    /// # Errors
    /// [`ContactError::InvalidBatch`] when `values` is not as long as the shape's point sets.
    pub fn per_finger<T: Copy + Default>(&self, values: &[T]) -> Result<Vec<Vec<T>>, ContactError> {
        let total: usize = self.plans.iter().map(|p| p.len).sum();
        if values.len() != total {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "{} values for point sets of {total} points in all",
                    values.len()
                ),
            });
        }
        let mut out: Vec<Vec<T>> = self
            .rest_in_hand
            .iter()
            .map(|r| vec![T::default(); r.len()])
            .collect();
        let mut start = 0;
        for plan in &self.plans {
            for &f in &plan.fingers {
                let n = out[f].len();
                out[f].copy_from_slice(&values[start..start + n]);
                start += n;
            }
        }
        Ok(out)
    }

    /// Checks that `shape` fits the hand and is finite.
    ///
    /// # Errors
    /// [`moe_geom::GeomError`] naming the finger and vertex.
    pub fn check_shape(&self, shape: &HandShape) -> Result<(), ContactError> {
        let num_fingers = self.finger_from_hand.len();
        if shape.fingers.len() != num_fingers {
            return Err(moe_geom::GeomError::LengthMismatch {
                what: "fingers of the hand shape",
                expected: num_fingers,
                got: shape.fingers.len(),
            }
            .into());
        }
        for (f, rest) in self.rest_in_hand.iter().enumerate() {
            if shape.fingers[f].len() != rest.len() {
                return Err(moe_geom::GeomError::FingerLengthMismatch {
                    what: "vertices",
                    finger: f,
                    expected: rest.len(),
                    got: shape.fingers[f].len(),
                }
                .into());
            }
        }
        Ok(shape.check_finite()?)
    }
}

/// The DGCNN as a [`ContactEstimator`] for one hand: turns a hand shape (and the tendon pulls,
/// when the card's features take them) into the network's input features and the logits back
/// into a contact map.
///
/// The network keeps no state between observations, so its estimates need only `&self`:
/// [`DgcnnEstimator::estimate_map`] and the batched [`DgcnnEstimator::estimate_batch`] serve
/// several threads at once, and a shared reference is a [`ContactEstimator`] too (one model
/// serves several pipelines without a copy).
#[derive(Debug, Clone)]
pub struct DgcnnEstimator {
    net: Dgcnn,
    card: ModelCard,
    features: FeatureBuilder,
}

impl DgcnnEstimator {
    /// An estimator for `hand` running `net`, with the card's input spec and threshold.
    ///
    /// # Errors
    /// [`ContactError::CardMismatch`] when the card's input features do not give the network's
    /// input width, [`ContactError::HandMismatch`] when the card's hand is not `hand` (for a
    /// per-finger model: a finger of another vertex count), [`ContactError::TooFewPoints`] when a
    /// point set of the hand has fewer points than `k`.
    pub fn new(net: Dgcnn, card: ModelCard, hand: &HandModel) -> Result<Self, ContactError> {
        card.validate()?;
        let spec = &card.architecture.input;
        if spec.channels() != net.in_channels() {
            return Err(ContactError::CardMismatch {
                field: "architecture.input.features",
                card: format!("{} ({} channels)", spec.describe(), spec.channels()),
                weights: format!("{} input channels", net.in_channels()),
            });
        }
        if let Some(trained) = &card.hand {
            let counts: Vec<usize> = hand
                .fingers()
                .iter()
                .map(|f| f.model.mesh().num_vertices())
                .collect();
            // A per-finger model sees one finger at a time in its own frame: it runs on any
            // number of fingers of the trained finger's mesh. A whole-hand model needs the hand.
            let (fits, rule) = match spec.point_set {
                PointSet::PerFinger => (
                    counts
                        .iter()
                        .all(|n| trained.finger_num_vertices.contains(n)),
                    " (a per-finger model runs on fingers of the trained size)",
                ),
                PointSet::WholeHand => (
                    counts == trained.finger_num_vertices,
                    " (a whole-hand model runs on the trained hand only)",
                ),
            };
            if !fits {
                return Err(ContactError::HandMismatch {
                    card_hand: trained.name.clone(),
                    card_vertices: trained.finger_num_vertices.clone(),
                    hand_vertices: counts,
                    rule,
                });
            }
        }
        if let Some(trained) = &card.hand {
            let meshes: Vec<&TriMesh> = hand.fingers().iter().map(|f| f.model.mesh()).collect();
            check_finger_digests(trained, &meshes)?;
        }
        let features = FeatureBuilder::new(spec, hand)?;
        Self::with_features(net, card, features)
    }

    /// An estimator for one finger given by its rest mesh alone (finger frame, metres): no hand
    /// model, markers or base needed. The card must be a per-finger model with finger-frame
    /// features that do not take tendon pulls; when it records its finger's digest, `rest` must be that finger.
    /// Shapes are one-finger [`HandShape`]s in the finger frame; [`DgcnnEstimator::finger_map`]
    /// takes the deformed vertices directly.
    ///
    /// # Errors
    /// As [`DgcnnEstimator::new`]; [`ContactError::FingerMismatch`] for another finger's mesh,
    /// [`ContactError::InvalidConfig`] for a whole-hand model or one that takes tendon pulls.
    pub fn for_finger(net: Dgcnn, card: ModelCard, rest: &TriMesh) -> Result<Self, ContactError> {
        card.validate()?;
        let input = &card.architecture.input;
        if input.point_set != PointSet::PerFinger || input.frame != FeatureFrame::Finger {
            return Err(ContactError::InvalidConfig {
                field: "architecture.input",
                message: "a whole-hand model, or one with hand-frame features, runs on the hand \
                          it was trained on: build it with DgcnnEstimator::new"
                    .into(),
            });
        }
        if let Some(trained) = &card.hand {
            if trained.finger_digests.is_empty()
                && !trained.finger_num_vertices.contains(&rest.num_vertices())
            {
                return Err(ContactError::HandMismatch {
                    card_hand: trained.name.clone(),
                    card_vertices: trained.finger_num_vertices.clone(),
                    hand_vertices: vec![rest.num_vertices()],
                    rule: " (a per-finger model runs on fingers of the trained size)",
                });
            }
            check_finger_digests(trained, &[rest])?;
        }
        let features = FeatureBuilder::for_finger(&card.architecture.input, rest)?;
        Self::with_features(net, card, features)
    }

    /// [`DgcnnEstimator::for_finger`] from the bytes of a model file and its card, in f32 on
    /// the CPU.
    ///
    /// ```
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// use moe_contact::{DgcnnConfig, DgcnnEstimator, FeatureFrame, ModelCard, ModelWeights, PointSet};
    /// use moe_geom::shapes::icosphere;
    ///
    /// // A seeded, untrained per-finger network stands in for a trained model's files here.
    /// let mut card = ModelCard::new(DgcnnConfig { k: 8, ..DgcnnConfig::default() });
    /// card.architecture.input.point_set = PointSet::PerFinger;
    /// card.architecture.input.frame = FeatureFrame::Finger;
    /// let channels = card.architecture.input.channels();
    /// let weights = ModelWeights::seeded(&card.architecture, channels, 7)?.to_bytes()?;
    /// let finger = icosphere(2, 0.01); // the finger's rest mesh, metres
    /// let model = DgcnnEstimator::finger_from_bytes(&weights, &card.to_json()?, &finger)?;
    /// let p = model.finger_map(finger.vertices())?; // the deformed vertices
    /// assert_eq!(p.len(), finger.num_vertices());
    /// # Ok(())
    /// # }
    /// ```
    ///
    /// # Errors
    /// Malformed weights or card, and as [`DgcnnEstimator::for_finger`].
    pub fn finger_from_bytes(
        weights: &[u8],
        card_json: &str,
        rest: &TriMesh,
    ) -> Result<Self, ContactError> {
        let card = ModelCard::from_json(card_json)?;
        let net = Dgcnn::from_safetensors(weights, Some(&card), DType::F32, &Device::Cpu)?;
        Self::for_finger(net, card, rest)
    }

    /// [`DgcnnEstimator::new`] from the bytes of a model file and its card, in f32 on the CPU.
    ///
    /// # Errors
    /// Malformed weights or card, and as [`DgcnnEstimator::new`].
    pub fn from_bytes(
        weights: &[u8],
        card_json: &str,
        hand: &HandModel,
    ) -> Result<Self, ContactError> {
        let card = ModelCard::from_json(card_json)?;
        let net = Dgcnn::from_safetensors(weights, Some(&card), DType::F32, &Device::Cpu)?;
        Self::new(net, card, hand)
    }

    /// Contact probability of every vertex of the finger of an estimator built with
    /// [`DgcnnEstimator::for_finger`], from its deformed vertices (finger frame).
    ///
    /// # Errors
    /// Vertices that do not fit the finger, or a failing tensor operation.
    pub fn finger_map(&self, deformed: &[Point3]) -> Result<Vec<f64>, ContactError> {
        let shape = HandShape {
            fingers: vec![deformed.to_vec()],
        };
        let mut map = self.estimate_map(&ContactInput::shape(&shape))?;
        Ok(map.fingers.swap_remove(0))
    }

    /// The estimator once its features are built: checks the point sets against `k`.
    fn with_features(
        net: Dgcnn,
        card: ModelCard,
        features: FeatureBuilder,
    ) -> Result<Self, ContactError> {
        let k = net.config().k;
        if let Some((set, p)) = features.plans.iter().enumerate().find(|(_, p)| p.len < k) {
            return Err(ContactError::TooFewPoints {
                set,
                points: p.len,
                k,
            });
        }
        Ok(Self {
            net,
            card,
            features,
        })
    }

    /// The network.
    pub fn network(&self) -> &Dgcnn {
        &self.net
    }

    /// The model card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// The card's contact threshold.
    pub fn threshold(&self) -> f64 {
        self.card.threshold
    }

    /// How shapes become the network's input.
    pub fn features(&self) -> &FeatureBuilder {
        &self.features
    }

    /// The contact map of one observation: its shape, and its tendon pulls when the card's
    /// features take them (its keypoints, pose and time are not used).
    ///
    /// # Errors
    /// A shape that does not fit the hand (naming the finger and vertex), missing or misfitting
    /// tendon pulls for a model that takes them, or a failing tensor operation.
    pub fn estimate_map(&self, input: &ContactInput<'_>) -> Result<ContactMap, ContactError> {
        let (mut maps, _) = self.estimate_inputs(std::slice::from_ref(input))?;
        maps.pop().ok_or_else(|| ContactError::InvalidBatch {
            message: "no contact map returned".into(),
        })
    }

    /// The contact maps of several observations, in order, through the network together: equal
    /// to [`DgcnnEstimator::estimate_map`] on each.
    ///
    /// # Errors
    /// As [`DgcnnEstimator::estimate_inputs`].
    pub fn estimate_batch(
        &self,
        inputs: &[ContactInput<'_>],
    ) -> Result<Vec<ContactMap>, ContactError> {
        Ok(self.estimate_inputs(inputs)?.0)
    }

    /// Contact maps of several shapes, and the network's stage timings summed over its passes.
    ///
    /// # Errors
    /// A shape that does not fit the hand (naming the finger and vertex), a model that needs
    /// tendon pulls ([`DgcnnEstimator::estimate_inputs`] takes them), or a failing tensor
    /// operation.
    pub fn estimate_shapes(
        &self,
        shapes: &[&HandShape],
    ) -> Result<(Vec<ContactMap>, ForwardTimings), ContactError> {
        let inputs: Vec<ContactInput<'_>> = shapes.iter().map(|s| ContactInput::shape(s)).collect();
        self.estimate_inputs(&inputs)
    }

    /// Contact maps of several observations, and the network's stage timings summed over its
    /// passes.
    ///
    /// # Errors
    /// A shape that does not fit the hand (naming the finger and vertex), missing or misfitting
    /// tendon pulls for a model that takes them, or a failing tensor operation.
    pub fn estimate_inputs(
        &self,
        inputs: &[ContactInput<'_>],
    ) -> Result<(Vec<ContactMap>, ForwardTimings), ContactError> {
        if inputs.is_empty() {
            return Ok((Vec::new(), ForwardTimings::default()));
        }
        for input in inputs {
            self.features.check_shape(input.shape)?;
            self.features.check_pulls(input.observation.tendon_pull_m)?;
        }
        let mut maps: Vec<ContactMap> = inputs
            .iter()
            .map(|i| ContactMap {
                fingers: i.shape.fingers.iter().map(|f| vec![0.0; f.len()]).collect(),
            })
            .collect();
        let mut timings = ForwardTimings::default();
        let channels = self.net.in_channels();
        // Point sets of equal length go through the network together.
        let plans_all = &self.features.plans;
        let mut lengths: Vec<usize> = plans_all.iter().map(|p| p.len).collect();
        lengths.sort_unstable();
        lengths.dedup();
        for len in lengths {
            let plans: Vec<&SetPlan> = plans_all.iter().filter(|p| p.len == len).collect();
            let mut values = Vec::with_capacity(inputs.len() * plans.len() * len * channels);
            for input in inputs {
                for plan in &plans {
                    for &f in &plan.fingers {
                        self.features.finger_features(
                            input.shape,
                            input.observation.tendon_pull_m,
                            f,
                            &mut values,
                        );
                    }
                }
            }
            let sets = inputs.len() * plans.len();
            let x = Tensor::from_vec(values, (sets, len, channels), &Device::Cpu)?;
            let out = self.net.forward_with(&x, Mode::Eval)?;
            let t = out.timings;
            timings.knn_s += t.knn_s;
            timings.edgeconv_s += t.edgeconv_s;
            timings.head_s += t.head_s;
            let p = contact_probability(&out.logits)?
                .to_dtype(DType::F64)?
                .to_device(&Device::Cpu)?
                .flatten_all()?
                .to_vec1::<f64>()?;
            let mut rows = p.chunks_exact(len);
            for map in &mut maps {
                for plan in &plans {
                    let Some(row) = rows.next() else {
                        return Err(ContactError::InvalidBatch {
                            message: "the network returned fewer point sets than it was given"
                                .into(),
                        });
                    };
                    let mut start = 0;
                    for &f in &plan.fingers {
                        let n = map.fingers[f].len();
                        map.fingers[f].copy_from_slice(&row[start..start + n]);
                        start += n;
                    }
                }
            }
        }
        Ok((maps, timings))
    }
}

/// Every finger mesh must be one of the card's trained fingers, when the card records them.
fn check_finger_digests(trained: &CardHand, meshes: &[&TriMesh]) -> Result<(), ContactError> {
    if trained.finger_digests.is_empty() {
        return Ok(());
    }
    for (finger, mesh) in meshes.iter().enumerate() {
        let digest = mesh.digest();
        if !trained.finger_digests.contains(&digest) {
            return Err(ContactError::FingerMismatch {
                card_hand: trained.name.clone(),
                card_digests: trained.finger_digests.clone(),
                finger,
                digest,
            });
        }
    }
    Ok(())
}

impl ContactEstimator for DgcnnEstimator {
    type Error = ContactError;

    /// [`DgcnnEstimator::estimate_map`], without forces.
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, ContactError> {
        self.estimate_map(input).map(ContactEstimate::from_map)
    }
}

/// A shared model estimates as the model does: the network keeps no state between observations.
impl ContactEstimator for &DgcnnEstimator {
    type Error = ContactError;

    /// [`DgcnnEstimator::estimate_map`], without forces.
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, ContactError> {
        self.estimate_map(input).map(ContactEstimate::from_map)
    }
}
