//! Observations of the signed distance: contacts (SDF 0), points offset along contact normals
//! (`±d`), free-space points (positive SDF) and interior points (negative SDF).

use moe_geom::{Point3, PointIndex, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::mean::MeanFunction;

/// What an observation is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObservationKind {
    /// A contact point: on the surface, SDF 0.
    Contact,
    /// A point offset from a contact along its normal: SDF `±d`, pins the gradient.
    NormalOffset,
    /// A point known to be outside (e.g. on the non-contact finger surface): SDF > 0.
    FreeSpace,
    /// A point known to be inside: SDF < 0.
    Interior,
    /// A point with a user-given SDF value (e.g. an `x,y,z,sdf` CSV row).
    Valued,
}

/// A set of SDF observations `(x_i, y_i)`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Observations {
    points: Vec<Point3>,
    values: Vec<Real>,
    kinds: Vec<ObservationKind>,
}

/// [`GpisError::NonFiniteObservation`] naming the first non-finite point of `points` as `what`.
pub(crate) fn check_finite(points: &[Point3], what: &'static str) -> Result<(), GpisError> {
    match points
        .iter()
        .position(|p| !moe_geom::math::is_finite_point(p))
    {
        Some(index) => Err(GpisError::NonFiniteObservation { what, index }),
        None => Ok(()),
    }
}

impl Observations {
    /// No observations.
    pub fn new() -> Self {
        Self::default()
    }

    /// Contacts only.
    ///
    /// # Errors
    /// [`GpisError::NonFiniteObservation`] naming the first bad contact.
    pub fn from_contacts(contacts: &[Point3]) -> Result<Self, GpisError> {
        let mut o = Self::new();
        o.add_contacts(contacts)?;
        Ok(o)
    }

    fn push(&mut self, p: Point3, v: Real, k: ObservationKind) {
        self.points.push(p);
        self.values.push(v);
        self.kinds.push(k);
    }

    /// Adds contact points (SDF 0).
    ///
    /// # Errors
    /// [`GpisError::NonFiniteObservation`].
    pub fn add_contacts(&mut self, contacts: &[Point3]) -> Result<(), GpisError> {
        check_finite(contacts, "contact")?;
        for p in contacts {
            self.push(*p, 0.0, ObservationKind::Contact);
        }
        Ok(())
    }

    /// Adds points with given SDF values.
    ///
    /// # Errors
    /// Length mismatch or non-finite points or values.
    pub fn add_valued(&mut self, points: &[Point3], values: &[Real]) -> Result<(), GpisError> {
        if points.len() != values.len() {
            return Err(GpisError::LengthMismatch {
                what: "observation values",
                expected: points.len(),
                got: values.len(),
            });
        }
        check_finite(points, "valued point")?;
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(GpisError::NonFiniteObservation {
                what: "valued point",
                index,
            });
        }
        for (p, v) in points.iter().zip(values) {
            let kind = if *v == 0.0 {
                ObservationKind::Contact
            } else {
                ObservationKind::Valued
            };
            self.push(*p, *v, kind);
        }
        Ok(())
    }

    /// For each contact `c` with outward normal `n`, adds `c + d·n` (SDF `+d`) and `c − d·n`
    /// (SDF `−d`). Normals are normalised.
    ///
    /// # Errors
    /// Length mismatch, a non-finite contact, `offset_m ≤ 0`, or a zero or non-finite normal
    /// ([`GpisError::InvalidNormal`], which names its index).
    pub fn add_normal_offsets(
        &mut self,
        contacts: &[Point3],
        normals: &[Vector3],
        offset_m: Real,
    ) -> Result<(), GpisError> {
        if contacts.len() != normals.len() {
            return Err(GpisError::LengthMismatch {
                what: "contact normals",
                expected: contacts.len(),
                got: normals.len(),
            });
        }
        if !(offset_m.is_finite() && offset_m > 0.0) {
            return Err(GpisError::InvalidParameter {
                name: "normal_offset_m",
                value: offset_m,
                reason: "must be finite and > 0",
            });
        }
        check_finite(contacts, "contact")?;
        for (index, (c, n)) in contacts.iter().zip(normals).enumerate() {
            let len = n.norm();
            if !(len.is_finite() && len > 0.0) {
                return Err(GpisError::InvalidNormal { index });
            }
            let n = n / len;
            self.push(c + n * offset_m, offset_m, ObservationKind::NormalOffset);
            self.push(c - n * offset_m, -offset_m, ObservationKind::NormalOffset);
        }
        Ok(())
    }

    /// Adds `±d` offsets along the normals that the mean function gives at the contacts
    /// (`∇m / ‖∇m‖`): the prior's (or fitted sphere's) outward normal. Contacts where the mean
    /// has no gradient (a constant mean) are skipped; returns how many contacts got offsets.
    ///
    /// With contacts alone, the residual `y − m(x)` of noisy contacts is explained equally well
    /// by a field that cancels the mean's slope (`r ≈ −m` near the contacts), which flattens the
    /// posterior SDF into a slab with an ill-defined zero level set. The offsets pin the slope.
    ///
    /// # Errors
    /// `offset_m ≤ 0` or non-finite.
    pub fn add_mean_normal_offsets<M: MeanFunction + ?Sized>(
        &mut self,
        mean: &M,
        offset_m: Real,
    ) -> Result<usize, GpisError> {
        let contacts = self.contacts();
        let (mut pts, mut normals) = (Vec::new(), Vec::new());
        for c in contacts {
            let g = mean.gradient(&c);
            if g.norm() > 1e-6 && g.iter().all(|v| v.is_finite()) {
                pts.push(c);
                normals.push(g);
            }
        }
        self.add_normal_offsets(&pts, &normals, offset_m)?;
        Ok(pts.len())
    }

    /// Adds free-space points (outside the surface). Their SDF value is `clearances[i]` if
    /// given; otherwise the distance to the nearest contact already added — an upper bound of
    /// the true SDF, since contacts lie on the surface.
    ///
    /// # Errors
    /// Non-finite input, non-positive clearances, a length mismatch, or no contacts to measure
    /// the clearance from.
    pub fn add_free_space(
        &mut self,
        points: &[Point3],
        clearances: Option<&[Real]>,
    ) -> Result<(), GpisError> {
        check_finite(points, "free-space point")?;
        let values: Vec<Real> = match clearances {
            Some(c) => {
                if c.len() != points.len() {
                    return Err(GpisError::LengthMismatch {
                        what: "free-space clearances",
                        expected: points.len(),
                        got: c.len(),
                    });
                }
                if let Some(index) = c.iter().position(|v| !v.is_finite()) {
                    return Err(GpisError::NonFiniteObservation {
                        what: "free-space clearance",
                        index,
                    });
                }
                if let Some(&value) = c.iter().find(|&&v| v <= 0.0) {
                    return Err(GpisError::InvalidParameter {
                        name: "free-space clearance",
                        value,
                        reason: "must be > 0 (a free-space point lies outside the surface)",
                    });
                }
                c.to_vec()
            }
            None => {
                let contacts = self.contacts();
                if contacts.is_empty() {
                    return Err(GpisError::TooFewObservations {
                        method: "free-space clearance",
                        what: "contacts",
                        needed: 1,
                        got: 0,
                    });
                }
                PointIndex::new(&contacts, "contacts")?.nearest_distances(points)
            }
        };
        for (p, v) in points.iter().zip(values) {
            self.push(*p, v, ObservationKind::FreeSpace);
        }
        Ok(())
    }

    /// Adds one interior point with SDF `value < 0`.
    ///
    /// # Errors
    /// Non-finite input or a non-negative value.
    pub fn add_interior(&mut self, point: Point3, value: Real) -> Result<(), GpisError> {
        check_finite(&[point], "interior point")?;
        if !(value.is_finite() && value < 0.0) {
            return Err(GpisError::InvalidParameter {
                name: "interior_sdf_m",
                value,
                reason: "an interior point needs a negative SDF",
            });
        }
        self.push(point, value, ObservationKind::Interior);
        Ok(())
    }

    /// Adds the contacts' centroid as an interior point, with SDF minus the mean distance from
    /// the centroid to the contacts — the usual way to give a constant-mean GPIS an inside.
    ///
    /// # Errors
    /// [`GpisError::TooFewObservations`] without contacts.
    pub fn add_centroid_interior(&mut self) -> Result<(), GpisError> {
        let contacts = self.contacts();
        if contacts.is_empty() {
            return Err(GpisError::TooFewObservations {
                method: "centroid interior point",
                what: "contacts",
                needed: 1,
                got: 0,
            });
        }
        let n = contacts.len() as Real;
        let c = Point3::from(contacts.iter().map(|p| p.coords).sum::<Vector3>() / n);
        let r = contacts.iter().map(|p| (p - c).norm()).sum::<Real>() / n;
        self.add_interior(c, -r.max(1e-6))
    }

    /// All observation points.
    pub fn points(&self) -> &[Point3] {
        &self.points
    }

    /// All observed SDF values.
    pub fn values(&self) -> &[Real] {
        &self.values
    }

    /// The kind of every observation.
    pub fn kinds(&self) -> &[ObservationKind] {
        &self.kinds
    }

    /// Number of observations.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The contact points (SDF 0 observations).
    pub fn contacts(&self) -> Vec<Point3> {
        self.points
            .iter()
            .zip(&self.kinds)
            .filter(|(_, k)| **k == ObservationKind::Contact)
            .map(|(p, _)| *p)
            .collect()
    }

    /// Drops the contacts for which `keep` is false (other observations stay); returns how many
    /// were dropped.
    pub fn retain_contacts(&mut self, keep: impl Fn(&Point3) -> bool) -> usize {
        let before = self.points.len();
        let mut k = 0;
        for i in 0..before {
            if self.kinds[i] != ObservationKind::Contact || keep(&self.points[i]) {
                self.points.swap(k, i);
                self.values.swap(k, i);
                self.kinds.swap(k, i);
                k += 1;
            }
        }
        self.points.truncate(k);
        self.values.truncate(k);
        self.kinds.truncate(k);
        before - k
    }

    /// Number of observations with a negative SDF value (inside).
    pub fn num_interior(&self) -> usize {
        self.values.iter().filter(|v| **v < 0.0).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retain_contacts_keeps_other_observations_and_the_order() {
        let c = [
            Point3::new(0.0, 0.0, 1.0),
            Point3::new(5.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let mut o = Observations::from_contacts(&c).unwrap();
        o.add_interior(Point3::new(9.0, 0.0, 0.0), -1.0).unwrap();
        let dropped = o.retain_contacts(|p| p.x < 1.0);
        assert_eq!(dropped, 1);
        assert_eq!(o.contacts(), vec![c[0], c[2]]);
        assert_eq!(o.len(), 3);
        assert_eq!(o.kinds()[2], ObservationKind::Interior);
        assert_eq!(o.values(), &[0.0, 0.0, -1.0]);
        assert_eq!(o.retain_contacts(|_| false), 2);
        assert_eq!(o.len(), 1);
    }

    #[test]
    fn builders_set_values_and_kinds() {
        let c = [Point3::new(0.0, 0.0, 1.0), Point3::new(1.0, 0.0, 0.0)];
        let mut o = Observations::from_contacts(&c).unwrap();
        o.add_normal_offsets(&c, &[Vector3::z() * 2.0, Vector3::x()], 0.01)
            .unwrap();
        assert_eq!(o.len(), 6);
        assert_eq!(o.points()[2], Point3::new(0.0, 0.0, 1.01));
        assert_eq!(&o.values()[2..6], &[0.01, -0.01, 0.01, -0.01]);
        o.add_free_space(&[Point3::new(0.0, 0.0, 3.0)], None)
            .unwrap();
        assert!((o.values()[6] - 2.0).abs() < 1e-12);
        o.add_centroid_interior().unwrap();
        assert_eq!(o.num_interior(), 3);
        assert_eq!(o.contacts().len(), 2);
    }

    #[test]
    fn bad_input_is_named() {
        let mut c = vec![Point3::origin(); 3];
        c[1].z = Real::INFINITY;
        assert_eq!(
            Observations::from_contacts(&c),
            Err(GpisError::NonFiniteObservation {
                what: "contact",
                index: 1
            })
        );
        let mut o = Observations::new();
        moe_geom::assert_err!(
            o.add_free_space(&[Point3::origin()], Some(&[f64::NAN])),
            GpisError::NonFiniteObservation {
                what: "free-space clearance",
                index: 0
            }
        );
        moe_geom::assert_err!(
            o.add_free_space(&[Point3::origin()], Some(&[-0.01])),
            GpisError::InvalidParameter {
                name: "free-space clearance",
                value,
                ..
            } if *value == -0.01
        );
        moe_geom::assert_err!(
            o.add_free_space(&[Point3::origin()], None),
            GpisError::TooFewObservations {
                method: "free-space clearance",
                what: "contacts",
                needed: 1,
                got: 0
            }
        );
        moe_geom::assert_err!(
            o.add_normal_offsets(
                &[Point3::origin(); 2],
                &[Vector3::z(), Vector3::zeros()],
                0.01
            ),
            GpisError::InvalidNormal { index: 1 }
        );
    }
}
