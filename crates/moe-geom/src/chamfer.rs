//! Nearest-neighbour queries over point sets and Chamfer distances.
//!
//! Convention (docs/design.md): mean Euclidean (not squared) nearest-neighbour distance.
//! `UCD(A→B)` averages, over every point of `A`, the distance to its nearest point of `B`;
//! `BCD(A, B) = (UCD(A→B) + UCD(B→A)) / 2`. Values are in the points' units (metres); reports
//! convert to millimetres.

use std::num::NonZero;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::error::GeomError;
use crate::math::{Point3, Real, is_finite_point};

/// A k-d tree over a fixed point set.
pub struct PointIndex {
    tree: ImmutableKdTree<Real, 3>,
    len: usize,
}

impl std::fmt::Debug for PointIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointIndex")
            .field("len", &self.len)
            .finish_non_exhaustive()
    }
}

/// A neighbour found by a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbor {
    /// Index of the point in the indexed set.
    pub index: usize,
    /// Euclidean distance to the query.
    pub distance: Real,
}

impl PointIndex {
    /// Indexes `points`; `what` names the set in errors.
    ///
    /// # Errors
    /// [`GeomError::EmptyPointSet`] and [`GeomError::NonFinitePoint`].
    pub fn new(points: &[Point3], what: &'static str) -> Result<Self, GeomError> {
        check_points(points, what)?;
        let coords: Vec<[Real; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree =
            ImmutableKdTree::new_from_slice(&coords).map_err(|_| GeomError::LengthMismatch {
                what: "k-d tree construction (too many points)",
                expected: u32::MAX as usize,
                got: points.len(),
            })?;
        Ok(Self {
            tree,
            len: points.len(),
        })
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false: an index holds at least one point.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest indexed point to `q`.
    pub fn nearest(&self, q: &Point3) -> Neighbor {
        let r = self
            .tree
            .query(&[q.x, q.y, q.z])
            .nearest_one::<SquaredEuclidean<Real>>()
            .execute();
        Neighbor {
            index: r.item as usize,
            distance: r.distance.sqrt(),
        }
    }

    /// The `k` nearest indexed points to `q`, nearest first (fewer if the set is smaller).
    pub fn k_nearest(&self, q: &Point3, k: usize) -> Vec<Neighbor> {
        let Some(k) = NonZero::new(k.min(self.len)) else {
            return Vec::new();
        };
        sorted(
            self.tree
                .query(&[q.x, q.y, q.z])
                .nearest_n::<SquaredEuclidean<Real>>(k)
                .execute()
                .into_iter()
                .map(|r| (r.item, r.distance)),
        )
    }

    /// Every indexed point within `radius` of `q`, nearest first.
    pub fn within(&self, q: &Point3, radius: Real) -> Vec<Neighbor> {
        sorted(
            self.tree
                .query(&[q.x, q.y, q.z])
                .within::<SquaredEuclidean<Real>>(radius * radius)
                .execute()
                .into_iter()
                .map(|r| (r.item, r.distance)),
        )
    }

    /// Distance from every query point to its nearest indexed point (parallel, order kept).
    pub fn nearest_distances(&self, queries: &[Point3]) -> Vec<Real> {
        queries
            .par_iter()
            .map(|q| self.nearest(q).distance)
            .collect()
    }
}

/// Neighbours from `(index, squared distance)` pairs, nearest first (ties by index).
fn sorted(pairs: impl Iterator<Item = (u32, Real)>) -> Vec<Neighbor> {
    let mut out: Vec<Neighbor> = pairs
        .map(|(index, d2)| Neighbor {
            index: index as usize,
            distance: d2.sqrt(),
        })
        .collect();
    out.sort_by(|a, b| {
        a.distance
            .total_cmp(&b.distance)
            .then(a.index.cmp(&b.index))
    });
    out
}

fn check_points(points: &[Point3], what: &'static str) -> Result<(), GeomError> {
    if points.is_empty() {
        return Err(GeomError::EmptyPointSet { what });
    }
    if let Some(index) = points.iter().position(|p| !is_finite_point(p)) {
        return Err(GeomError::NonFinitePoint { what, index });
    }
    Ok(())
}

/// Unidirectional Chamfer distance `UCD(from → to)`: mean distance from each point of `from` to
/// its nearest point of `to`.
///
/// # Errors
/// Empty or non-finite point sets.
pub fn ucd(from: &[Point3], to: &[Point3]) -> Result<Real, GeomError> {
    check_points(from, "from")?;
    let index = PointIndex::new(to, "to")?;
    Ok(mean(&index.nearest_distances(from)))
}

/// Bidirectional Chamfer distance `BCD(a, b) = (UCD(a → b) + UCD(b → a)) / 2`.
///
/// # Errors
/// Empty or non-finite point sets.
pub fn bcd(a: &[Point3], b: &[Point3]) -> Result<Real, GeomError> {
    Ok(0.5 * (ucd(a, b)? + ucd(b, a)?))
}

/// Mean with a fixed (pairwise) summation order, so that results do not depend on thread count.
fn mean(values: &[Real]) -> Real {
    fn pairwise(v: &[Real]) -> Real {
        if v.len() <= 64 {
            v.iter().sum()
        } else {
            let (a, b) = v.split_at(v.len() / 2);
            pairwise(a) + pairwise(b)
        }
    }
    pairwise(values) / values.len() as Real
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vector3;
    use proptest::prelude::*;

    fn brute_ucd(a: &[Point3], b: &[Point3]) -> Real {
        a.iter()
            .map(|p| {
                b.iter()
                    .map(|q| (p - q).norm())
                    .fold(Real::INFINITY, Real::min)
            })
            .sum::<Real>()
            / a.len() as Real
    }

    fn grid(n: usize, spacing: Real) -> Vec<Point3> {
        let mut v = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    v.push(Point3::new(i as Real, j as Real, k as Real) * spacing);
                }
            }
        }
        v
    }

    #[test]
    fn ucd_of_a_set_to_itself_is_zero() {
        let g = grid(5, 0.01);
        assert_eq!(ucd(&g, &g).unwrap(), 0.0);
        assert_eq!(bcd(&g, &g).unwrap(), 0.0);
    }

    #[test]
    fn ucd_of_a_point_is_its_distance_to_the_nearest_member() {
        let g = grid(4, 1.0);
        let p = [Point3::new(1.2, 0.9, -0.5)];
        let expected = (p[0] - Point3::new(1.0, 1.0, 0.0)).norm();
        assert!((ucd(&p, &g).unwrap() - expected).abs() < 1e-15);
    }

    #[test]
    fn shift_below_half_spacing_gives_exactly_the_shift() {
        let spacing = 0.004;
        let g = grid(6, spacing);
        let d = 0.45 * spacing;
        let dir = Vector3::new(1.0, 2.0, -2.0).normalize();
        let shifted: Vec<Point3> = g.iter().map(|p| p + dir * d).collect();
        assert!((ucd(&g, &shifted).unwrap() - d).abs() < 1e-15);
        assert!((bcd(&g, &shifted).unwrap() - d).abs() < 1e-15);
    }

    #[test]
    fn errors_name_the_set() {
        let g = grid(2, 1.0);
        assert_eq!(ucd(&[], &g), Err(GeomError::EmptyPointSet { what: "from" }));
        let bad = vec![Point3::new(0.0, Real::NAN, 0.0)];
        assert_eq!(
            ucd(&g, &bad),
            Err(GeomError::NonFinitePoint {
                what: "to",
                index: 0
            })
        );
    }

    #[test]
    fn k_nearest_and_within_are_sorted_and_exact() {
        let g = grid(5, 1.0);
        let index = PointIndex::new(&g, "grid").unwrap();
        let q = Point3::new(2.1, 2.0, 2.0);
        let knn = index.k_nearest(&q, 7);
        assert_eq!(knn.len(), 7);
        assert_eq!(g[knn[0].index], Point3::new(2.0, 2.0, 2.0));
        assert!(knn.windows(2).all(|w| w[0].distance <= w[1].distance));
        let within = index.within(&q, 1.0);
        let brute = g.iter().filter(|p| (*p - q).norm() <= 1.0).count();
        assert_eq!(within.len(), brute);
    }

    proptest! {
        #[test]
        fn chamfer_matches_brute_force(
            a in prop::collection::vec((-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64), 1..80),
            b in prop::collection::vec((-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64), 1..80),
        ) {
            let a: Vec<Point3> = a.into_iter().map(|(x, y, z)| Point3::new(x, y, z)).collect();
            let b: Vec<Point3> = b.into_iter().map(|(x, y, z)| Point3::new(x, y, z)).collect();
            prop_assert!((ucd(&a, &b).unwrap() - brute_ucd(&a, &b)).abs() < 1e-12);
            let both = 0.5 * (brute_ucd(&a, &b) + brute_ucd(&b, &a));
            prop_assert!((bcd(&a, &b).unwrap() - both).abs() < 1e-12);
        }
    }
}
