//! Solver configuration: the energy variant, the smoothing weight and the iteration count.

use moe_geom::Real;
use serde::{Deserialize, Serialize};

use crate::error::ArapError;

/// Which ARAP energy the solver minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ArapEnergy {
    /// One-ring spokes cells plus the rotation-smoothing term weighted by `alpha` (SR-ARAP, the
    /// default; with `alpha = 0` it is plain ARAP).
    #[default]
    Smoothed,
    /// Plain ARAP with one-ring spokes cells (`alpha` is ignored).
    Spokes,
    /// Spokes-and-rims cells (each cell also holds the edges opposite its vertex), with the
    /// smoothing term weighted by `alpha`.
    SpokesAndRims,
}

impl ArapEnergy {
    /// All variants.
    pub const ALL: [ArapEnergy; 3] = [Self::Smoothed, Self::Spokes, Self::SpokesAndRims];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Smoothed => "smoothed",
            Self::Spokes => "spokes",
            Self::SpokesAndRims => "spokes-and-rims",
        }
    }
}

impl std::str::FromStr for ArapEnergy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| {
                format!("unknown ARAP energy '{s}' (expected smoothed, spokes or spokes-and-rims)")
            })
    }
}

impl std::fmt::Display for ArapEnergy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Configuration of an [`crate::ArapSolver`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ArapConfig {
    /// Energy variant. Default [`ArapEnergy::Smoothed`].
    pub energy: ArapEnergy,
    /// Rotation-smoothing weight α (the paper's λ), dimensionless; multiplied by the rest surface
    /// area. Default 0.01. Zero gives plain ARAP. Ignored by [`ArapEnergy::Spokes`].
    pub alpha: Real,
    /// Local/global iterations per solve. Default 50 (the paper's setting).
    pub iterations: usize,
    /// Run the per-vertex local step on the rayon pool. Default `true`; it only pays for meshes of
    /// several thousand vertices, and the multi-finger estimator turns it off because it already
    /// runs one finger per thread.
    pub parallel: bool,
}

impl Default for ArapConfig {
    fn default() -> Self {
        Self {
            energy: ArapEnergy::Smoothed,
            alpha: 0.01,
            iterations: 50,
            parallel: true,
        }
    }
}

impl ArapConfig {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`ArapError::InvalidConfig`] for a negative or non-finite `alpha` or more than a million
    /// iterations.
    pub fn validate(&self) -> Result<(), ArapError> {
        if !(self.alpha.is_finite() && self.alpha >= 0.0) {
            return Err(ArapError::InvalidConfig {
                name: "alpha",
                value: self.alpha,
                reason: "must be finite and non-negative",
            });
        }
        if self.iterations > 1_000_000 {
            return Err(ArapError::InvalidConfig {
                name: "iterations",
                value: self.iterations as Real,
                reason: "must be at most 1000000",
            });
        }
        Ok(())
    }

    /// The smoothing weight actually used: `alpha`, or 0 for [`ArapEnergy::Spokes`].
    pub fn effective_alpha(&self) -> Real {
        match self.energy {
            ArapEnergy::Spokes => 0.0,
            ArapEnergy::Smoothed | ArapEnergy::SpokesAndRims => self.alpha,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_settings_and_valid() {
        let c = ArapConfig::default();
        assert_eq!(
            (c.energy, c.alpha, c.iterations),
            (ArapEnergy::Smoothed, 0.01, 50)
        );
        c.validate().unwrap();
    }

    #[test]
    fn bad_alpha_is_rejected_by_name() {
        for alpha in [-1.0, Real::NAN, Real::INFINITY] {
            let c = ArapConfig {
                alpha,
                ..Default::default()
            };
            assert!(matches!(
                c.validate(),
                Err(ArapError::InvalidConfig { name: "alpha", .. })
            ));
        }
    }

    #[test]
    fn energy_names_round_trip() {
        for e in ArapEnergy::ALL {
            assert_eq!(e.name().parse::<ArapEnergy>().unwrap(), e);
        }
        let e = "rims".parse::<ArapEnergy>().unwrap_err();
        assert!(e.contains("'rims'"), "{e}");
        let spokes = ArapConfig {
            energy: ArapEnergy::Spokes,
            ..Default::default()
        };
        assert_eq!(spokes.effective_alpha(), 0.0);
    }
}
