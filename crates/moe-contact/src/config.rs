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
    /// with every observation ([`moe_geom::Observation::tendon_pull_m`]).
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
