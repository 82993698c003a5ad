//! Material and damping parameters of the silicone body (paper §4.3.1).

use moe_geom::Real;
use serde::{Deserialize, Serialize};

use crate::error::{SimError, require_non_negative, require_positive};

/// Linear-elastic isotropic material with Rayleigh damping.
///
/// Defaults are the paper's SOFA setup: E = 100 kPa, ν = 0.1, Rayleigh mass 0.1 and stiffness
/// 0.1, and silicone's density 1070 kg/m³.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Material {
    /// Young's modulus E, pascals. Default 1e5.
    pub youngs_modulus_pa: Real,
    /// Poisson's ratio ν, in (−1, 0.5). Default 0.1.
    pub poisson_ratio: Real,
    /// Density, kg/m³. Default 1070.
    pub density_kg_m3: Real,
    /// Rayleigh mass coefficient α_M (damping matrix α_M·M + β_K·K), 1/s. Default 0.1.
    pub rayleigh_mass: Real,
    /// Rayleigh stiffness coefficient β_K, seconds. Default 0.1.
    pub rayleigh_stiffness: Real,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            youngs_modulus_pa: 1e5,
            poisson_ratio: 0.1,
            density_kg_m3: 1070.0,
            rayleigh_mass: 0.1,
            rayleigh_stiffness: 0.1,
        }
    }
}

impl Material {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first bad one: E ≤ 0, ν ∉ (−1, 0.5), density
    /// ≤ 0, negative damping, or a non-finite value.
    pub fn validate(&self) -> Result<(), SimError> {
        require_positive("youngs_modulus_pa", self.youngs_modulus_pa)?;
        let nu = self.poisson_ratio;
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(SimError::InvalidParameter {
                name: "poisson_ratio",
                value: nu,
                reason: "must be in (-1, 0.5)",
            });
        }
        require_positive("density_kg_m3", self.density_kg_m3)?;
        require_non_negative("rayleigh_mass", self.rayleigh_mass)?;
        require_non_negative("rayleigh_stiffness", self.rayleigh_stiffness)?;
        Ok(())
    }

    /// Lamé parameters `(λ, μ)`, pascals.
    pub fn lame(&self) -> (Real, Real) {
        let (e, nu) = (self.youngs_modulus_pa, self.poisson_ratio);
        let mu = e / (2.0 * (1.0 + nu));
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        (lambda, mu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_parameters_match_the_textbook_relations() {
        let m = Material::default();
        let (l, mu) = m.lame();
        // E = μ(3λ + 2μ)/(λ + μ), ν = λ / (2(λ + μ)).
        let e = mu * (3.0 * l + 2.0 * mu) / (l + mu);
        let nu = l / (2.0 * (l + mu));
        assert!((e - 1e5).abs() < 1e-6);
        assert!((nu - 0.1).abs() < 1e-12);
    }

    #[test]
    fn out_of_range_parameters_are_named() {
        let cases = [
            (
                Material {
                    youngs_modulus_pa: 0.0,
                    ..Material::default()
                },
                "youngs_modulus_pa",
            ),
            (
                Material {
                    youngs_modulus_pa: -5.0,
                    ..Material::default()
                },
                "youngs_modulus_pa",
            ),
            (
                Material {
                    poisson_ratio: 0.5,
                    ..Material::default()
                },
                "poisson_ratio",
            ),
            (
                Material {
                    poisson_ratio: -1.0,
                    ..Material::default()
                },
                "poisson_ratio",
            ),
            (
                Material {
                    density_kg_m3: Real::NAN,
                    ..Material::default()
                },
                "density_kg_m3",
            ),
            (
                Material {
                    rayleigh_mass: -0.1,
                    ..Material::default()
                },
                "rayleigh_mass",
            ),
        ];
        for (m, name) in cases {
            match m.validate() {
                Err(SimError::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{name}: expected an error, got {other:?}"),
            }
        }
        Material::default().validate().unwrap();
    }
}
