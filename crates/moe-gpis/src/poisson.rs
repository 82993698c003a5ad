//! Screened Poisson surface reconstruction of a meshed level set (paper §6.1 / App. E).
//!
//! The paper meshes the zero level set of the GP posterior mean, then rebuilds the final mesh by
//! screened Poisson reconstruction (Kazhdan & Hoppe 2013) from the points and normals of that
//! mesh. The Poisson solve is the `poisson_reconstruction` crate's; its output is an implicit
//! function `χ` on an adaptive octree of B-splines around the samples, with `χ = 0` at the
//! (density-weighted) samples on average.
//!
//! Meshing `χ` with the crate's own marching cubes can leave cracks (marching-cubes ambiguities,
//! seams between octree levels), so the surface is extracted here instead:
//!
//! 1. **Calibration.** `χ` is evaluated at `p ± δ n` for (a stride of) the samples; the median
//!    of the finite differences along the normals gives the slope `s` of `χ` across the surface.
//!    `χ / s` then increases along the given (outward) normals — negative inside — and is close
//!    to a signed distance in metres near the samples: the crate's sign convention and scale are
//!    measured, not assumed. The same samples check that the solve converged: the slope must
//!    have the median's sign at ≥ 90 % of them and `χ / s` must vanish there to within half a
//!    finest cell (median); otherwise [`GpisError::PoissonFailed`]. The samples enter the solve
//!    mapped into the unit box, so nothing depends on the units.
//! 2. **Band.** `χ` is only fully defined where the finest octree level has all its B-splines:
//!    within one finest cell (`w = extent / 2^depth`, max norm) of a sample. Grid nodes in that
//!    band take `χ / s`; every other node takes the caller's fallback field (the GP posterior
//!    mean on the query grid, interpolated trilinearly on a refined grid), whose sign agrees with
//!    `χ / s` away from the surface. Only signs matter there.
//! 3. **Meshing** by this crate's marching tetrahedra ([`extract_surface`]), which is closed,
//!    manifold and outward oriented by construction; the result is checked again
//!    ([`moe_geom::TriMesh::require_closed`], positive enclosed volume).
//!
//! Cost: the crate's right-hand side and coarse-level corrections visit, for every node of every
//! level, all cells of the other levels within its reach (hash lookups of empty cells take most
//! of the time), so the solve grows about 8× per level of depth whatever the number of samples.
//! Its time and accuracy on the head benchmark at each depth are in docs/results.md. The conjugate-gradient iterations cost little but matter: at depth 4, 5 iterations gave a 20 mm
//! UCD and 20–100 converge; at depth 5, 20 did not converge on the sphere test and 50 does —
//! hence the default of 50. Screening multiplies the time by about 5 and did not improve the
//! sphere test, so it is off by default.
//!
//! The normals are the area-weighted vertex normals of the marching-tetrahedra mesh: outward and
//! consistent by construction, free (no extra GP queries) and, on a mesh whose triangles are a
//! fraction of a grid cell, within the gradient direction of the posterior mean up to the
//! discretisation error that Poisson smooths anyway.
//!
//! The crate's inputs are converted through plain `[f64; 3]` arrays (it uses nalgebra 0.33 and
//! parry 0.21 internally). Its assertions (one normal per point, density depth ≤ depth) and its
//! internal `unwrap`s (empty input, degenerate bounding box) are pre-empted by validation here.

use moe_geom::{Point3, Real, TriMesh, Vector3};
use poisson_reconstruction::PoissonReconstruction;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::grid::Grid3;
use crate::marching::{MeshingOptions, extract_surface};

/// Fewest samples accepted by [`PoissonField::fit`].
pub const MIN_POISSON_SAMPLES: usize = 8;

/// Fewest calibration samples whose slope along the normal has the median's sign.
const MIN_SLOPE_AGREEMENT: Real = 0.9;

/// Largest median distance (in finest cells) of the samples from the zero level set.
const MAX_SAMPLE_OFFSET_CELLS: Real = 0.5;

/// Samples used to calibrate the sign and scale of the Poisson function (a stride of all).
const CALIBRATION_SAMPLES: usize = 2000;

/// Options of the screened Poisson step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoissonOptions {
    /// Depth of the octree: the finest cell is the samples' largest extent over `2^depth`
    /// (default 4: 10 mm on a 16 cm sphere). The solve's cost grows about 8× per level.
    pub depth: usize,
    /// Octree depth at which the sample density is estimated, at most `depth` (default 4):
    /// smaller values are more robust to uneven sampling.
    pub density_depth: usize,
    /// Screening weight pulling the surface onto the samples; 0 disables screening (default 0:
    /// it multiplies the time by about 5).
    pub screening: Real,
    /// Conjugate-gradient iterations per octree level (default 50; too few leave an unconverged
    /// function, reported as [`GpisError::PoissonFailed`]).
    pub cg_iterations: usize,
    /// Meshing grid = the query grid with its spacing divided by this integer (default 1).
    pub refine: usize,
}

impl Default for PoissonOptions {
    fn default() -> Self {
        Self {
            depth: 4,
            density_depth: 4,
            screening: 0.0,
            cg_iterations: 50,
            refine: 1,
        }
    }
}

impl PoissonOptions {
    /// Checks the ranges: `1 ≤ depth ≤ 10`, `density_depth ≤ depth`, finite `screening ≥ 0`,
    /// `1 ≤ cg_iterations ≤ 1000`, `1 ≤ refine ≤ 8`.
    ///
    /// # Errors
    /// [`GpisError::InvalidParameter`] naming the first option out of range.
    pub fn validate(&self) -> Result<(), GpisError> {
        let bad = |name, value: usize, reason| {
            Err(GpisError::InvalidParameter {
                name,
                value: value as Real,
                reason,
            })
        };
        if !(1..=10).contains(&self.depth) {
            return bad("poisson_depth", self.depth, "must be in 1..=10");
        }
        if self.density_depth > self.depth {
            return bad(
                "poisson_density_depth",
                self.density_depth,
                "must not exceed poisson_depth",
            );
        }
        if !(self.screening.is_finite() && self.screening >= 0.0) {
            return Err(GpisError::InvalidParameter {
                name: "poisson_screening",
                value: self.screening,
                reason: "must be finite and >= 0",
            });
        }
        if !(1..=1000).contains(&self.cg_iterations) {
            return bad(
                "poisson_cg_iterations",
                self.cg_iterations,
                "must be in 1..=1000",
            );
        }
        if !(1..=8).contains(&self.refine) {
            return bad("poisson_refine", self.refine, "must be in 1..=8");
        }
        Ok(())
    }
}

/// A screened Poisson implicit function, calibrated to be negative inside and close to a signed
/// distance (metres) within one finest octree cell of the samples.
#[derive(Clone)]
pub struct PoissonField {
    inner: PoissonReconstruction,
    /// Multiplies the crate's value: sign convention and `1 / slope`.
    scale: Real,
    /// The samples enter the solve as `(p − center) / extent` (unit box, whatever the units).
    center: Point3,
    /// Largest extent of the samples' bounding box, metres.
    extent: Real,
    /// Finest octree cell width, metres.
    leaf: Real,
    samples: Vec<Point3>,
}

impl std::fmt::Debug for PoissonField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PoissonField")
            .field("scale", &self.scale)
            .field("leaf", &self.leaf)
            .field("samples", &self.samples.len())
            .finish_non_exhaustive()
    }
}

fn to_na(p: &Point3) -> [Real; 3] {
    [p.x, p.y, p.z]
}

impl PoissonField {
    /// Solves screened Poisson for oriented samples (`normals` point outward; they are
    /// normalised here) and calibrates the result.
    ///
    /// # Errors
    /// [`GpisError::LengthMismatch`] when `normals` and `points` differ in length,
    /// [`GpisError::TooFewObservations`] below [`MIN_POISSON_SAMPLES`] samples,
    /// [`GpisError::NonFiniteObservation`] for a non-finite point, [`GpisError::InvalidNormal`]
    /// for a non-finite or zero normal, [`GpisError::InvalidParameter`] for bad options,
    /// [`GpisError::PoissonFailed`] when the samples span no volume or the solve gives no usable
    /// function.
    pub fn fit(
        points: &[Point3],
        normals: &[Vector3],
        options: &PoissonOptions,
    ) -> Result<Self, GpisError> {
        options.validate()?;
        if normals.len() != points.len() {
            return Err(GpisError::LengthMismatch {
                what: "poisson normals (one per point)",
                expected: points.len(),
                got: normals.len(),
            });
        }
        if points.len() < MIN_POISSON_SAMPLES {
            return Err(GpisError::TooFewObservations {
                method: "poisson",
                what: "oriented points",
                needed: MIN_POISSON_SAMPLES,
                got: points.len(),
            });
        }
        crate::observations::check_finite(points, "poisson point")?;
        let mut unit = Vec::with_capacity(normals.len());
        for (index, n) in normals.iter().enumerate() {
            let len = n.norm();
            if !(len.is_finite() && len > 0.0) {
                return Err(GpisError::InvalidNormal { index });
            }
            unit.push(n / len);
        }
        let (center, extent) = moe_geom::Aabb::from_points(points)
            .map(|b| (b.center(), b.extents().max()))
            .unwrap_or((Point3::origin(), 0.0));
        if !(extent.is_finite() && extent > 0.0) {
            return Err(GpisError::PoissonFailed {
                reason: "the points span no volume (all coincide)",
            });
        }
        let leaf = extent / (1u64 << options.depth) as Real;
        let pts: Vec<_> = points
            .iter()
            .map(|p| to_na(&Point3::from((p - center) / extent)).into())
            .collect();
        let nrm: Vec<_> = unit.iter().map(|n| [n.x, n.y, n.z].into()).collect();
        let inner = PoissonReconstruction::from_points_and_normals(
            &pts,
            &nrm,
            options.screening,
            options.density_depth,
            options.depth,
            options.cg_iterations,
        );
        let mut field = Self {
            inner,
            scale: 1.0,
            center,
            extent,
            leaf,
            samples: points.to_vec(),
        };
        field.scale = 1.0 / field.calibrate_slope(&unit)?;
        Ok(field)
    }

    /// Median slope of the raw function along the normals at a stride of the samples, checked
    /// for a converged solve: the slope has the median's sign at nearly every sample, and the
    /// calibrated function nearly vanishes there.
    fn calibrate_slope(&self, normals: &[Vector3]) -> Result<Real, GpisError> {
        let delta = 0.25 * self.leaf;
        let stride = self.samples.len().div_ceil(CALIBRATION_SAMPLES).max(1);
        let picked: Vec<usize> = (0..self.samples.len()).step_by(stride).collect();
        let mut slopes: Vec<Real> = picked
            .iter()
            .map(|&i| {
                let (p, n) = (self.samples[i], normals[i]);
                (self.raw(&(p + n * delta)) - self.raw(&(p - n * delta))) / (2.0 * delta)
            })
            .collect();
        if slopes.iter().any(|s| !s.is_finite()) {
            return Err(GpisError::PoissonFailed {
                reason: "the solve gave a non-finite function at the samples",
            });
        }
        slopes.sort_by(Real::total_cmp);
        let median = slopes[slopes.len() / 2];
        let max = slopes.iter().fold(0.0, |m: Real, s| m.max(s.abs()));
        if median.abs() <= 1e-9 * max || median == 0.0 {
            return Err(GpisError::PoissonFailed {
                reason: "the function is flat across the samples (inconsistent normals?)",
            });
        }
        let agree = slopes
            .iter()
            .filter(|s| s.signum() == median.signum())
            .count() as Real
            / slopes.len() as Real;
        let mut offsets: Vec<Real> = picked
            .iter()
            .map(|&i| (self.raw(&self.samples[i]) / median).abs() / self.leaf)
            .collect();
        offsets.sort_by(Real::total_cmp);
        let offset = offsets[offsets.len() / 2];
        // Converged solves measured at 100 % agreement and 0.01–0.04 cells; unconverged ones
        // (too few conjugate-gradient iterations) at 54–84 % and 3–20 cells.
        if agree < MIN_SLOPE_AGREEMENT || offset > MAX_SAMPLE_OFFSET_CELLS {
            return Err(GpisError::PoissonFailed {
                reason: "the solve did not converge: the function does not vanish at the samples \
                         or changes sign inconsistently (raise cg_iterations or lower depth)",
            });
        }
        Ok(median)
    }

    /// The crate's value, uncalibrated.
    fn raw(&self, p: &Point3) -> Real {
        let q = Point3::from((p - self.center) / self.extent);
        self.inner.eval(&to_na(&q).into())
    }

    /// The calibrated value at `p`: negative inside, ≈ signed distance near the samples.
    /// Meaningful within [`PoissonField::leaf_width`] (max norm) of a sample.
    pub fn value(&self, p: &Point3) -> Real {
        self.scale * self.raw(p)
    }

    /// The finest octree cell width, metres.
    pub fn leaf_width(&self) -> Real {
        self.leaf
    }

    /// Values on `grid` for meshing: the calibrated function at nodes within one finest cell
    /// (max norm) of a sample, `fallback` (one value per node, negative inside) elsewhere.
    ///
    /// # Errors
    /// [`GpisError::LengthMismatch`] for a wrong fallback length, [`GpisError::PoissonFailed`]
    /// when the function is not finite at a band node.
    pub fn grid_values(&self, grid: &Grid3, fallback: &[Real]) -> Result<Vec<Real>, GpisError> {
        if fallback.len() != grid.num_nodes() {
            return Err(GpisError::LengthMismatch {
                what: "poisson fallback grid values",
                expected: grid.num_nodes(),
                got: fallback.len(),
            });
        }
        let band = self.band(grid);
        let [nx, ny, _] = grid.dims;
        let evaluated: Vec<(usize, Real)> = band
            .par_iter()
            .map(|&idx| {
                let p = grid.point(idx % nx, (idx / nx) % ny, idx / (nx * ny));
                (idx, self.value(&p))
            })
            .collect();
        let mut values = fallback.to_vec();
        for (idx, v) in evaluated {
            if !v.is_finite() {
                return Err(GpisError::PoissonFailed {
                    reason: "the function is not finite near the samples",
                });
            }
            values[idx] = v;
        }
        Ok(values)
    }

    /// Indices of the grid nodes strictly within one finest cell (max norm) of a sample.
    fn band(&self, grid: &Grid3) -> Vec<usize> {
        let r = self.leaf * (1.0 - 1e-9);
        let h = grid.spacing;
        let mut mark = vec![false; grid.num_nodes()];
        for p in &self.samples {
            let d = p - grid.origin;
            let range = |axis: usize| {
                let lo = ((d[axis] - r) / h).ceil().max(0.0) as usize;
                let hi = ((d[axis] + r) / h).floor();
                let hi = if hi < 0.0 {
                    None
                } else {
                    Some((hi as usize).min(grid.dims[axis] - 1))
                };
                hi.filter(|&hi| lo <= hi).map(|hi| lo..=hi)
            };
            let (Some(ri), Some(rj), Some(rk)) = (range(0), range(1), range(2)) else {
                continue;
            };
            for k in rk {
                for j in rj.clone() {
                    for i in ri.clone() {
                        mark[grid.index(i, j, k)] = true;
                    }
                }
            }
        }
        (0..mark.len()).filter(|&i| mark[i]).collect()
    }
}

/// `grid` with its spacing divided by `factor` (same origin and extent) and `values` (one per
/// node of `grid`) interpolated trilinearly onto it.
///
/// # Errors
/// [`GpisError::LengthMismatch`] for a wrong number of values, [`GpisError::InvalidParameter`]
/// for `factor == 0`.
pub(crate) fn refine_grid(
    grid: &Grid3,
    values: &[Real],
    factor: usize,
) -> Result<(Grid3, Vec<Real>), GpisError> {
    if values.len() != grid.num_nodes() {
        return Err(GpisError::LengthMismatch {
            what: "grid values",
            expected: grid.num_nodes(),
            got: values.len(),
        });
    }
    if factor == 0 {
        return Err(GpisError::InvalidParameter {
            name: "refine_factor",
            value: 0.0,
            reason: "must be >= 1",
        });
    }
    if factor == 1 {
        return Ok((*grid, values.to_vec()));
    }
    let fine = Grid3::new(
        grid.origin,
        grid.spacing / factor as Real,
        grid.dims.map(|n| (n - 1) * factor + 1),
    )?;
    let [fx, fy, _] = fine.dims;
    // Coarse cell and weight along one axis for fine index `i`.
    let split = |i: usize, n: usize| {
        let c = (i / factor).min(n - 2);
        (c, (i - c * factor) as Real / factor as Real)
    };
    let mut out = vec![0.0; fine.num_nodes()];
    out.par_chunks_mut(fx * fy)
        .enumerate()
        .for_each(|(k, slab)| {
            let (ck, tz) = split(k, grid.dims[2]);
            for j in 0..fy {
                let (cj, ty) = split(j, grid.dims[1]);
                for i in 0..fx {
                    let (ci, tx) = split(i, grid.dims[0]);
                    let mut v = 0.0;
                    for (dk, wz) in [(0, 1.0 - tz), (1, tz)] {
                        for (dj, wy) in [(0, 1.0 - ty), (1, ty)] {
                            for (di, wx) in [(0, 1.0 - tx), (1, tx)] {
                                let w = wx * wy * wz;
                                if w != 0.0 {
                                    v += w * values[grid.index(ci + di, cj + dj, ck + dk)];
                                }
                            }
                        }
                    }
                    slab[i + fx * j] = v;
                }
            }
        });
    Ok((fine, out))
}

/// Rebuilds a closed surface by screened Poisson from the vertices and vertex normals of `mesh`
/// (an outward-oriented level-set mesh), meshed on `grid` refined by [`PoissonOptions::refine`]
/// with `values` (the level-set field on `grid`, negative inside) away from the surface.
///
/// # Errors
/// As [`PoissonField::fit`] and [`PoissonField::grid_values`]; [`GpisError::EmptySurface`] when
/// the field has no zero crossing; [`GpisError::Geom`] / [`GpisError::PoissonFailed`] if the
/// result were not closed or not outward oriented (guarded, not expected).
pub fn poisson_surface(
    mesh: &TriMesh,
    grid: &Grid3,
    values: &[Real],
    options: &PoissonOptions,
    meshing: &MeshingOptions,
) -> Result<TriMesh, GpisError> {
    options.validate()?;
    let field = PoissonField::fit(mesh.vertices(), &mesh.vertex_normals(), options)?;

    let (fine, fallback) = refine_grid(grid, values, options.refine)?;
    let fine_values = field.grid_values(&fine, &fallback)?;

    let out = extract_surface(&fine, &fine_values, meshing)?;
    out.require_closed()?;
    if out.signed_volume() <= 0.0 {
        return Err(GpisError::PoissonFailed {
            reason: "the extracted surface is not outward oriented",
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{Aabb, Topology};

    const R: Real = 0.08;

    /// The marching-tetrahedra mesh of a sphere SDF of radius `R` on a 48³ grid (spacing
    /// ≈ 4.1 mm, like the head benchmark's 64³ grid), with the grid and its values.
    fn sphere_level_set(center: Point3) -> (TriMesh, Grid3, Vec<Real>) {
        let b = Aabb {
            min: center - Vector3::repeat(R),
            max: center + Vector3::repeat(R),
        };
        let grid = Grid3::covering(&b, 0.02, 48 * 48 * 48).unwrap();
        let values: Vec<Real> = grid
            .points()
            .iter()
            .map(|p| (p - center).norm() - R)
            .collect();
        let mesh = extract_surface(&grid, &values, &MeshingOptions::default()).unwrap();
        (mesh, grid, values)
    }

    /// Measured with the defaults (depth 4, finest cell 10 mm): 0.30 mm worst, 0.07 mm mean
    /// radial deviation, volume −0.16 %, on a 48³ grid (4.1 mm spacing).
    #[test]
    fn poisson_of_a_sphere_level_set_is_a_closed_sphere() {
        let c = Point3::new(0.011, -0.007, 0.004);
        let (mt, grid, values) = sphere_level_set(c);
        let options = PoissonOptions::default();
        let mesh =
            poisson_surface(&mt, &grid, &values, &options, &MeshingOptions::default()).unwrap();
        mesh.require_closed().unwrap();
        let topo = Topology::new(&mesh);
        assert_eq!(topo.euler_characteristic(), 2);
        assert_eq!(topo.connected_components().1, 1);
        let dev: Vec<Real> = mesh
            .vertices()
            .iter()
            .map(|p| ((p - c).norm() - R).abs())
            .collect();
        let worst = dev.iter().fold(0.0, |m: Real, d| m.max(*d));
        let mean = dev.iter().sum::<Real>() / dev.len() as Real;
        let v0 = 4.0 / 3.0 * std::f64::consts::PI * R.powi(3);
        let vol = mesh.signed_volume() / v0 - 1.0;
        assert!(worst < 5e-4, "worst deviation {worst} m");
        assert!(mean < 1.5e-4, "mean deviation {mean} m");
        assert!(vol.abs() < 0.01, "volume error {vol}");
    }

    #[test]
    fn an_unconverged_solve_is_reported_not_meshed() {
        let (mt, grid, values) = sphere_level_set(Point3::origin());
        let options = PoissonOptions {
            cg_iterations: 2,
            ..PoissonOptions::default()
        };
        let r = poisson_surface(&mt, &grid, &values, &options, &MeshingOptions::default());
        assert!(matches!(r, Err(GpisError::PoissonFailed { .. })), "{r:?}");
    }

    #[test]
    fn calibrated_function_increases_along_the_normals_like_a_distance() {
        // An icosphere's vertices with outward, then inward normals: the calibrated function
        // increases along the given normals with about unit slope (the crate's own sign
        // convention does not leak out).
        let sphere = moe_geom::shapes::icosphere(3, R);
        let outward = sphere.vertex_normals();
        let inward: Vec<Vector3> = outward.iter().map(|n| -n).collect();
        let options = PoissonOptions {
            depth: 3,
            density_depth: 3,
            ..PoissonOptions::default()
        };
        for (normals, sign) in [(&outward, 1.0), (&inward, -1.0)] {
            let f = PoissonField::fit(sphere.vertices(), normals, &options).unwrap();
            let w = f.leaf_width();
            let dir = Vector3::new(0.3, -0.5, 0.8).normalize();
            let inside = sign * f.value(&Point3::from(dir * (R - 0.5 * w)));
            let outside = sign * f.value(&Point3::from(dir * (R + 0.5 * w)));
            assert!(inside < 0.0 && outside > 0.0, "{inside} {outside}");
            let slope = (outside - inside) / w;
            assert!((0.5..2.0).contains(&slope), "{slope}");
        }
    }

    #[test]
    fn bad_input_gives_typed_errors() {
        let sphere = moe_geom::shapes::icosphere(1, R);
        let p = sphere.vertices().to_vec();
        let n = sphere.vertex_normals();
        let o = PoissonOptions::default();
        assert!(matches!(
            PoissonField::fit(&[], &[], &o),
            Err(GpisError::TooFewObservations { got: 0, .. })
        ));
        assert!(matches!(
            PoissonField::fit(&p, &n[1..], &o),
            Err(GpisError::LengthMismatch { .. })
        ));
        let mut nan_n = n.clone();
        nan_n[5].y = Real::NAN;
        assert!(matches!(
            PoissonField::fit(&p, &nan_n, &o),
            Err(GpisError::InvalidNormal { index: 5 })
        ));
        let mut zero_n = n.clone();
        zero_n[2] = Vector3::zeros();
        assert!(matches!(
            PoissonField::fit(&p, &zero_n, &o),
            Err(GpisError::InvalidNormal { index: 2 })
        ));
        let mut nan_p = p.clone();
        nan_p[7].x = Real::INFINITY;
        assert!(matches!(
            PoissonField::fit(&nan_p, &n, &o),
            Err(GpisError::NonFiniteObservation { index: 7, .. })
        ));
        let same = vec![Point3::new(0.1, 0.2, 0.3); p.len()];
        assert!(matches!(
            PoissonField::fit(&same, &n, &o),
            Err(GpisError::PoissonFailed { .. })
        ));
        let deep = PoissonOptions {
            density_depth: 5,
            ..o
        };
        assert!(matches!(
            PoissonField::fit(&p, &n, &deep),
            Err(GpisError::InvalidParameter {
                name: "poisson_density_depth",
                ..
            })
        ));
        for bad in [
            PoissonOptions { depth: 0, ..o },
            PoissonOptions {
                screening: Real::NAN,
                ..o
            },
            PoissonOptions {
                cg_iterations: 0,
                ..o
            },
            PoissonOptions { refine: 0, ..o },
        ] {
            assert!(matches!(
                bad.validate(),
                Err(GpisError::InvalidParameter { .. })
            ));
        }
        // A fallback field of the wrong size.
        let (mt, grid, values) = sphere_level_set(Point3::origin());
        assert!(matches!(
            poisson_surface(
                &mt,
                &grid,
                &values[1..],
                &PoissonOptions {
                    depth: 2,
                    density_depth: 2,
                    ..o
                },
                &MeshingOptions::default()
            ),
            Err(GpisError::LengthMismatch { .. })
        ));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
        /// Arbitrary small oriented point sets — random, flattened to a plane or a line, far from
        /// the origin — give a field or a typed error, never a panic; a field's values at the
        /// samples are finite.
        #[test]
        fn arbitrary_small_inputs_give_a_field_or_a_typed_error(
            seed in 0u64..1000,
            n in 8usize..60,
            flatten in 0usize..3,
            offset in -1e3f64..1e3,
            depth in 1usize..4,
        ) {
            let mut rng = moe_geom::SeededRng::new(seed);
            let mut g = || rng.normal();
            let points: Vec<Point3> = (0..n)
                .map(|_| {
                    let (x, y, z) = (g(), g(), g());
                    let (y, z) = match flatten {
                        0 => (y, z),
                        1 => (y, 0.0),
                        _ => (0.0, 0.0),
                    };
                    Point3::new(offset + 0.01 * x, 0.01 * y, 0.01 * z)
                })
                .collect();
            let normals: Vec<Vector3> = (0..n).map(|_| Vector3::new(g(), g(), g())).collect();
            let options = PoissonOptions { depth, density_depth: depth, ..PoissonOptions::default() };
            match PoissonField::fit(&points, &normals, &options) {
                Ok(f) => {
                    for p in &points {
                        proptest::prop_assert!(f.value(p).is_finite());
                    }
                }
                Err(e) => {
                    let typed = matches!(e, GpisError::PoissonFailed { .. });
                    proptest::prop_assert!(typed, "{}", e);
                }
            }
        }
    }

    #[test]
    fn refined_grid_interpolates_linear_fields_exactly() {
        let grid = Grid3::new(Point3::new(-0.1, 0.0, 0.2), 0.05, [4, 3, 5]).unwrap();
        let f = |p: &Point3| 2.0 * p.x - 3.0 * p.y + 0.5 * p.z + 0.1;
        let values: Vec<Real> = grid.points().iter().map(f).collect();
        let (fine, fv) = refine_grid(&grid, &values, 3).unwrap();
        assert_eq!(fine.dims, [10, 7, 13]);
        assert!((fine.bounds().max - grid.bounds().max).norm() < 1e-12);
        for (p, v) in fine.points().iter().zip(&fv) {
            assert!((f(p) - v).abs() < 1e-12);
        }
        assert!(matches!(
            refine_grid(&grid, &values, 0),
            Err(GpisError::InvalidParameter { .. })
        ));
        assert!(matches!(
            refine_grid(&grid, &values[1..], 2),
            Err(GpisError::LengthMismatch {
                what: "grid values",
                ..
            })
        ));
        // A refined grid is bounded like any other: 129³ nodes refined by 3 would be 385³.
        let big = Grid3::new(Point3::origin(), 0.01, [129, 129, 129]).unwrap();
        let zeros = vec![0.0; big.num_nodes()];
        assert!(matches!(
            refine_grid(&big, &zeros, 3),
            Err(GpisError::InvalidParameter {
                name: "grid_nodes",
                ..
            })
        ));
    }
}
