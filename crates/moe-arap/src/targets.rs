//! Handle lists given as `(vertex, target)` pairs, as in a constraints file.

use moe_geom::math::is_finite_point;
use moe_geom::{Point3, Real};
use serde::{Deserialize, Serialize};

use crate::error::ArapError;

/// Distinct handle vertices with one target each, checked against a mesh size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandleTargets {
    /// Vertex ids, in first-appearance order.
    pub vertices: Vec<u32>,
    /// Target of every vertex.
    pub targets: Vec<Point3>,
}

impl HandleTargets {
    /// Collects `(vertex, target)` pairs. A vertex repeated with the same target is kept once.
    ///
    /// # Errors
    /// [`ArapError::VertexOutOfRange`], [`ArapError::NonFiniteTarget`] (index of the pair), or
    /// [`ArapError::ConflictingTargets`] for a vertex given two different targets.
    pub fn from_pairs(pairs: &[(u32, Point3)], num_vertices: usize) -> Result<Self, ArapError> {
        let mut slot: std::collections::HashMap<u32, usize> =
            std::collections::HashMap::with_capacity(pairs.len());
        let mut out = Self {
            vertices: Vec::with_capacity(pairs.len()),
            targets: Vec::with_capacity(pairs.len()),
        };
        for (index, &(v, t)) in pairs.iter().enumerate() {
            if v as usize >= num_vertices {
                return Err(ArapError::VertexOutOfRange {
                    what: "handle",
                    index: v as usize,
                    len: num_vertices,
                });
            }
            if !is_finite_point(&t) {
                return Err(ArapError::NonFiniteTarget {
                    what: "handle target",
                    index,
                });
            }
            match slot.get(&v) {
                Some(&k) if out.targets[k] == t => {}
                Some(&k) => {
                    let xyz = |p: &Point3| -> [Real; 3] { [p.x, p.y, p.z] };
                    return Err(ArapError::ConflictingTargets {
                        vertex: v as usize,
                        first: xyz(&out.targets[k]),
                        second: xyz(&t),
                    });
                }
                None => {
                    slot.insert(v, out.vertices.len());
                    out.vertices.push(v);
                    out.targets.push(t);
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_pairs_are_merged_and_conflicts_named() {
        let p = Point3::new(1.0, 2.0, 3.0);
        let q = Point3::new(1.0, 2.0, 3.5);
        let h = HandleTargets::from_pairs(&[(4, p), (1, q), (4, p)], 10).unwrap();
        assert_eq!(h.vertices, vec![4, 1]);
        assert_eq!(
            HandleTargets::from_pairs(&[(4, p), (4, q)], 10),
            Err(ArapError::ConflictingTargets {
                vertex: 4,
                first: [1.0, 2.0, 3.0],
                second: [1.0, 2.0, 3.5]
            })
        );
        assert_eq!(
            HandleTargets::from_pairs(&[(10, p)], 10),
            Err(ArapError::VertexOutOfRange {
                what: "handle",
                index: 10,
                len: 10
            })
        );
        let nan = Point3::new(Real::NAN, 0.0, 0.0);
        assert_eq!(
            HandleTargets::from_pairs(&[(1, p), (2, nan)], 10),
            Err(ArapError::NonFiniteTarget {
                what: "handle target",
                index: 1
            })
        );
    }
}
