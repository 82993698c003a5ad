//! The network's architecture, its input features, and the model card that records them.

use serde::{Deserialize, Serialize};

use crate::error::ContactError;

/// How an EdgeConv layer reduces its edges to a point feature.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Aggregation {
    /// Maximum over the neighbours (DGCNN's choice; the default).
    #[default]
    Max,
    /// Sum over the neighbours (the paper's equation as written).
    Sum,
}

impl std::str::FromStr for Aggregation {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "max" => Ok(Self::Max),
            "sum" => Ok(Self::Sum),
            other => Err(format!("unknown aggregation '{other}' (max or sum)")),
        }
    }
}

impl std::fmt::Display for Aggregation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Max => "max",
            Self::Sum => "sum",
        })
    }
}

/// One group of per-vertex input channels (three channels each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InputFeature {
    /// The deformed vertex position.
    Xyz,
    /// The same vertex's rest-pose position (vertex `i` of a shape estimate is vertex `i` of the
    /// rest mesh), so that the network sees how each vertex moved.
    RestXyz,
    /// Local measures of deformation, zero at rest and unchanged by rigid motion: the change in
    /// normal curvature at the vertex, the same averaged over its one-ring, and the one-ring's
    /// areal strain (see the `deformation` module).
    Deformation,
    /// What the robot pulled, the same on every vertex of a finger: the finger's tendon pulls
    /// `p_t` weighted by the direction `u_t` of each tendon from the finger axis (in the finger's
    /// frame whatever [`InputSpec::frame`] says, at the route's base), `Σ p_t u_t.x`, `Σ p_t u_t.y`, and their sum `Σ p_t`. For antagonistic
    /// pairs the first two are the bending the pulls ask for and the third the co-contraction;
    /// beside the shape, they say how the finger would bend if nothing touched it. Needs the pulls
    /// with every observation ([`moe_geom::ContactInput::tendon_pull_m`]).
    TendonPull,
}

impl InputFeature {
    /// Name as in the card.
    pub fn name(self) -> &'static str {
        match self {
            Self::Xyz => "xyz",
            Self::RestXyz => "rest-xyz",
            Self::Deformation => "deformation",
            Self::TendonPull => "tendon-pull",
        }
    }
}

/// The coordinate frame the input positions are expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FeatureFrame {
    /// The hand (palm) frame: every finger at its place on the palm.
    #[default]
    Hand,
    /// Each finger's own frame (base at the origin, z along the finger): every finger looks the
    /// same at rest, whatever hand it is mounted on.
    Finger,
}

/// Which vertices form one point set (one graph) for the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PointSet {
    /// All vertices of the hand in one set (the paper's 2048 points for two fingers).
    #[default]
    WholeHand,
    /// One set per finger: neighbourhoods and the global max-pool stay within a finger.
    PerFinger,
}

/// Per-channel affine normalisation of the input: `(x − mean) / std`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Normalisation {
    /// Subtracted from each channel.
    pub mean: Vec<f64>,
    /// Each channel is divided by this (positive).
    pub std: Vec<f64>,
}

/// What the network is fed: which features, in which frame, grouped into which point sets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// Feature groups in channel order (three channels each).
    pub features: Vec<InputFeature>,
    /// Frame of the positions.
    #[serde(default)]
    pub frame: FeatureFrame,
    /// How vertices are grouped into point sets.
    #[serde(default)]
    pub point_set: PointSet,
    /// Optional normalisation, one entry per channel.
    #[serde(default)]
    pub normalisation: Option<Normalisation>,
}

impl Default for InputSpec {
    /// The defaults of a weights file without a card: xyz in the hand frame, the whole hand as
    /// one set, no normalisation.
    fn default() -> Self {
        Self {
            features: vec![InputFeature::Xyz],
            frame: FeatureFrame::Hand,
            point_set: PointSet::WholeHand,
            normalisation: None,
        }
    }
}

impl InputSpec {
    /// Number of input channels per point.
    pub fn channels(&self) -> usize {
        3 * self.features.len()
    }

    /// Applies the normalisation (if any) to rows of [`InputSpec::channels`] values, in place.
    pub fn normalise(&self, rows: &mut [f64]) {
        if let Some(n) = &self.normalisation {
            for row in rows.chunks_exact_mut(self.channels()) {
                for ((x, m), s) in row.iter_mut().zip(&n.mean).zip(&n.std) {
                    *x = (*x - m) / s;
                }
            }
        }
    }

    /// The features as text, e.g. `"xyz + rest-xyz"`.
    pub fn describe(&self) -> String {
        self.features
            .iter()
            .map(|f| f.name())
            .collect::<Vec<_>>()
            .join(" + ")
    }

    /// Checks the spec: at least one feature, no repeats, a normalisation of the right width
    /// with finite means and positive finite deviations.
    ///
    /// # Errors
    /// [`ContactError::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<(), ContactError> {
        if self.features.is_empty() {
            return Err(ContactError::InvalidConfig {
                field: "input.features",
                message: "at least one input feature is needed".into(),
            });
        }
        for (i, f) in self.features.iter().enumerate() {
            if self.features[..i].contains(f) {
                return Err(ContactError::InvalidConfig {
                    field: "input.features",
                    message: format!("'{}' is listed twice", f.name()),
                });
            }
        }
        if let Some(n) = &self.normalisation {
            let c = self.channels();
            if n.mean.len() != c || n.std.len() != c {
                return Err(ContactError::InvalidConfig {
                    field: "input.normalisation",
                    message: format!(
                        "{} means and {} deviations for {c} input channels",
                        n.mean.len(),
                        n.std.len()
                    ),
                });
            }
            if let Some(i) = n.mean.iter().position(|m| !m.is_finite()) {
                return Err(ContactError::InvalidConfig {
                    field: "input.normalisation.mean",
                    message: format!("channel {i} is not finite"),
                });
            }
            if let Some(i) = n.std.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
                return Err(ContactError::InvalidConfig {
                    field: "input.normalisation.std",
                    message: format!("channel {i} must be finite and positive"),
                });
            }
        }
        Ok(())
    }
}

/// The DGCNN's architecture (paper §4.3.2, App. D).
///
/// Three EdgeConv layers `h'_i = AGG_{j ∈ kNN(i)} ReLU(Θ(h_i − h_j) + Φ h_i)` with the kNN
/// recomputed in each layer's input space, then a shared per-point MLP on `[loc | glob]` (the
/// three layers' features and their max over the point set): `head.0` → ReLU → dropout →
/// `head.1` → ReLU → dropout → `head.2` (two logits: no contact, contact).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DgcnnConfig {
    /// Neighbourhood size, the point itself included. Default 30.
    pub k: usize,
    /// Output widths of the three EdgeConv layers. Default `[64, 128, 256]`.
    pub edge_widths: [usize; 3],
    /// Output widths of `head.0` and `head.1` (`head.2` gives 2 logits). Default `[512, 256]`.
    pub head_widths: [usize; 2],
    /// Edge aggregation. Default max.
    #[serde(default)]
    pub aggregation: Aggregation,
    /// Dropout probability after `head.0` and `head.1`, in training only. Default 0.5.
    pub dropout: f64,
    /// What the network is fed.
    #[serde(default)]
    pub input: InputSpec,
}

impl Default for DgcnnConfig {
    fn default() -> Self {
        Self {
            k: 30,
            edge_widths: [64, 128, 256],
            head_widths: [512, 256],
            aggregation: Aggregation::Max,
            dropout: 0.5,
            input: InputSpec::default(),
        }
    }
}

/// Largest neighbourhood size accepted (memory and time grow linearly with it).
pub const MAX_K: usize = 256;
/// Largest layer width accepted.
pub const MAX_WIDTH: usize = 8192;

impl DgcnnConfig {
    /// Width of the per-point features of the three layers together (448 by default).
    pub fn local_width(&self) -> usize {
        self.edge_widths.iter().sum()
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`ContactError::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<(), ContactError> {
        if self.k == 0 || self.k > MAX_K {
            return Err(ContactError::InvalidConfig {
                field: "k",
                message: format!("{} is not in 1..={MAX_K}", self.k),
            });
        }
        for (field, widths) in [
            ("edge_widths", &self.edge_widths[..]),
            ("head_widths", &self.head_widths[..]),
        ] {
            if let Some(w) = widths.iter().find(|&&w| w == 0 || w > MAX_WIDTH) {
                return Err(ContactError::InvalidConfig {
                    field,
                    message: format!("width {w} is not in 1..={MAX_WIDTH}"),
                });
            }
        }
        if !(0.0..1.0).contains(&self.dropout) {
            return Err(ContactError::InvalidConfig {
                field: "dropout",
                message: format!("{} is not in [0, 1)", self.dropout),
            });
        }
        self.input.validate()
    }
}

/// Format version of the model card written by this crate.
pub const CARD_FORMAT_VERSION: u32 = 1;

/// The hand a model was trained for: its layout, so that a model is not run on another hand by
/// mistake.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardHand {
    /// A name for the hand (a preset name or the config's file name).
    pub name: String,
    /// Surface vertices of each finger.
    pub finger_num_vertices: Vec<usize>,
}

/// `NAME.json` beside `NAME.safetensors`: what the weights are and how they were made.
///
/// Only `architecture` is needed to run the network; a weights file without a card runs with
/// [`DgcnnConfig::default`] widened to the weights' layer widths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCard {
    /// Card format version ([`CARD_FORMAT_VERSION`]).
    pub format_version: u32,
    /// The network.
    pub architecture: DgcnnConfig,
    /// Probability at or above which a vertex is reported as in contact (chosen on validation
    /// data by training; 0.5 when not given).
    #[serde(default = "default_threshold")]
    pub threshold: f64,
    /// The hand the model was trained for, if recorded.
    #[serde(default)]
    pub hand: Option<CardHand>,
    /// How the weights were trained (optimiser, schedule, loss, seed, wall time, the command that
    /// reproduces them), as written by the training code.
    #[serde(default)]
    pub training: Option<serde_json::Value>,
    /// The data set the model was trained on (card digest, seed, counts).
    #[serde(default)]
    pub dataset: Option<serde_json::Value>,
    /// Metrics per epoch and on held-out data.
    #[serde(default)]
    pub metrics: Option<serde_json::Value>,
}

fn default_threshold() -> f64 {
    0.5
}

impl ModelCard {
    /// A card for `architecture` with nothing else recorded.
    pub fn new(architecture: DgcnnConfig) -> Self {
        Self {
            format_version: CARD_FORMAT_VERSION,
            architecture,
            threshold: default_threshold(),
            hand: None,
            training: None,
            dataset: None,
            metrics: None,
        }
    }

    /// Parses a card from JSON and validates it.
    ///
    /// # Errors
    /// [`ContactError::MalformedCard`] for JSON that is not a card, [`ContactError::InvalidConfig`]
    /// for out-of-range values.
    pub fn from_json(text: &str) -> Result<Self, ContactError> {
        let card: Self = serde_json::from_str(text).map_err(|e| ContactError::MalformedCard {
            message: e.to_string(),
        })?;
        card.validate()?;
        Ok(card)
    }

    /// The card as pretty-printed JSON.
    ///
    /// # Errors
    /// Never in practice (every field serialises); kept fallible for the JSON writer.
    pub fn to_json(&self) -> Result<String, ContactError> {
        serde_json::to_string_pretty(self).map_err(|e| ContactError::MalformedCard {
            message: e.to_string(),
        })
    }

    /// Checks the version, the architecture and the threshold.
    ///
    /// # Errors
    /// [`ContactError::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<(), ContactError> {
        if self.format_version != CARD_FORMAT_VERSION {
            return Err(ContactError::InvalidConfig {
                field: "format_version",
                message: format!(
                    "{} is not supported (this version reads {CARD_FORMAT_VERSION})",
                    self.format_version
                ),
            });
        }
        if !(self.threshold > 0.0 && self.threshold < 1.0) {
            return Err(ContactError::InvalidConfig {
                field: "threshold",
                message: format!("{} is not in (0, 1)", self.threshold),
            });
        }
        self.architecture.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_card_round_trips_through_json() {
        let mut card = ModelCard::new(DgcnnConfig::default());
        card.architecture.input.features.push(InputFeature::RestXyz);
        card.architecture.input.point_set = PointSet::PerFinger;
        card.threshold = 0.3;
        let back = ModelCard::from_json(&card.to_json().unwrap()).unwrap();
        assert_eq!(back, card);
    }

    #[test]
    fn out_of_range_fields_are_named() {
        let check = |edit: fn(&mut ModelCard), field: &str| {
            let mut card = ModelCard::new(DgcnnConfig::default());
            edit(&mut card);
            match card.validate() {
                Err(ContactError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        };
        check(|c| c.architecture.k = 0, "k");
        check(|c| c.architecture.edge_widths[1] = 0, "edge_widths");
        check(|c| c.architecture.dropout = 1.0, "dropout");
        check(|c| c.threshold = 1.5, "threshold");
        check(|c| c.architecture.input.features.clear(), "input.features");
        check(
            |c| {
                c.architecture.input.normalisation = Some(Normalisation {
                    mean: vec![0.0; 3],
                    std: vec![1.0, 0.0, 1.0],
                })
            },
            "input.normalisation.std",
        );
        check(|c| c.format_version = 7, "format_version");
    }

    #[test]
    fn unknown_card_fields_are_refused() {
        let mut v = serde_json::to_value(ModelCard::new(DgcnnConfig::default())).unwrap();
        v["architecture"]["kk"] = serde_json::json!(3);
        assert!(matches!(
            ModelCard::from_json(&v.to_string()),
            Err(ContactError::MalformedCard { .. })
        ));
    }
}
