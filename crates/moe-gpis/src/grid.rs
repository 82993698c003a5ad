//! Regular query grids: isotropic spacing, nodes indexed x-fastest.

use moe_geom::{Aabb, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;

/// The most nodes a query grid may have: 256³ (the values alone take 128 MiB; the meshing
/// buffers several times that).
pub const MAX_GRID_NODES: usize = 256 * 256 * 256;

/// A regular grid of `nx × ny × nz` nodes with isotropic spacing `h`:
/// node `(i, j, k)` is at `origin + h·(i, j, k)` and has linear index `i + nx·(j + ny·k)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Grid3 {
    /// Position of node `(0, 0, 0)`.
    pub origin: Point3,
    /// Node spacing `h`, metres.
    pub spacing: Real,
    /// Nodes along x, y, z (each at least 2).
    pub dims: [usize; 3],
}

impl Grid3 {
    /// A grid from its origin, spacing and node counts.
    ///
    /// # Errors
    /// [`GpisError::InvalidParameter`] for a non-positive spacing, a non-finite origin, fewer
    /// than 2 nodes along an axis or more than [`MAX_GRID_NODES`] in all.
    pub fn new(origin: Point3, spacing: Real, dims: [usize; 3]) -> Result<Self, GpisError> {
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(GpisError::InvalidParameter {
                name: "grid_spacing_m",
                value: spacing,
                reason: "must be finite and > 0",
            });
        }
        if !moe_geom::math::is_finite_point(&origin) {
            return Err(GpisError::InvalidParameter {
                name: "grid_origin_m",
                value: Real::NAN,
                reason: "must be finite",
            });
        }
        if let Some(&d) = dims.iter().find(|&&d| d < 2) {
            return Err(GpisError::InvalidParameter {
                name: "grid_nodes_per_axis",
                value: d as Real,
                reason: "need at least 2 nodes per axis",
            });
        }
        let nodes = dims
            .iter()
            .try_fold(1usize, |n, &d| n.checked_mul(d))
            .unwrap_or(usize::MAX);
        if nodes > MAX_GRID_NODES {
            return Err(GpisError::InvalidParameter {
                name: "grid_nodes",
                value: nodes as Real,
                reason: "at most 256³ = 16,777,216 nodes (the query and meshing buffers grow with it)",
            });
        }
        Ok(Self {
            origin,
            spacing,
            dims,
        })
    }

    /// The isotropic grid with at most `max_nodes` nodes that covers `bounds` grown by `padding`
    /// on every side, centred on it. Elongated boxes (the arm's 2:20:1) get proportionally more
    /// nodes along their long axis, not a coarser spacing everywhere.
    ///
    /// # Errors
    /// [`GpisError::InvalidParameter`] for a non-finite box or padding, `max_nodes < 8`, or
    /// `max_nodes` above [`MAX_GRID_NODES`].
    pub fn covering(bounds: &Aabb, padding: Real, max_nodes: usize) -> Result<Self, GpisError> {
        if !(padding.is_finite() && padding >= 0.0) {
            return Err(GpisError::InvalidParameter {
                name: "grid_padding_m",
                value: padding,
                reason: "must be finite and >= 0",
            });
        }
        if max_nodes < 8 {
            return Err(GpisError::InvalidParameter {
                name: "grid_max_nodes",
                value: max_nodes as Real,
                reason: "need at least 8 nodes",
            });
        }
        if max_nodes > MAX_GRID_NODES {
            return Err(GpisError::InvalidParameter {
                name: "grid_max_nodes",
                value: max_nodes as Real,
                reason: "at most 256³ = 16,777,216 nodes (the query and meshing buffers grow with it)",
            });
        }
        let e = bounds.extents() + Vector3::repeat(2.0 * padding);
        let e = e.map(|v| v.max(1e-9));
        if !e.iter().all(|v| v.is_finite()) {
            return Err(GpisError::InvalidParameter {
                name: "grid_bounds_m",
                value: Real::NAN,
                reason: "must be finite",
            });
        }
        let count = |h: Real| e.map(|v| ((v / h).ceil() as usize + 1).max(2));
        let mut h = (e.x * e.y * e.z / max_nodes as Real).cbrt();
        while {
            let c = count(h);
            c.x * c.y * c.z > max_nodes
        } {
            h *= 1.01;
        }
        let c = count(h);
        let dims = [c.x, c.y, c.z];
        let half = Vector3::new(
            (dims[0] - 1) as Real,
            (dims[1] - 1) as Real,
            (dims[2] - 1) as Real,
        ) * (0.5 * h);
        Self::new(bounds.center() - half, h, dims)
    }

    /// Total number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Linear index of node `(i, j, k)`.
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Position of node `(i, j, k)`.
    #[inline]
    pub fn point(&self, i: usize, j: usize, k: usize) -> Point3 {
        self.origin + Vector3::new(i as Real, j as Real, k as Real) * self.spacing
    }

    /// Every node position in index order.
    pub fn points(&self) -> Vec<Point3> {
        let [nx, ny, nz] = self.dims;
        let mut out = Vec::with_capacity(self.num_nodes());
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    out.push(self.point(i, j, k));
                }
            }
        }
        out
    }

    /// The box spanned by the nodes.
    pub fn bounds(&self) -> Aabb {
        let [nx, ny, nz] = self.dims;
        Aabb {
            min: self.origin,
            max: self.point(nx - 1, ny - 1, nz - 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_grid_respects_budget_and_covers_the_box() {
        let b = Aabb {
            min: Point3::new(-0.1, -1.0, -0.05),
            max: Point3::new(0.1, 1.0, 0.05),
        };
        let g = Grid3::covering(&b, 0.02, 64 * 64 * 64).unwrap();
        assert!(g.num_nodes() <= 64 * 64 * 64);
        assert!(g.num_nodes() > 60 * 60 * 60, "{g:?}");
        let gb = g.bounds();
        assert!(
            gb.min.x <= -0.12 && gb.max.y >= 1.02 && gb.max.z >= 0.07,
            "{gb:?}"
        );
        assert!(
            g.dims[1] > 5 * g.dims[0],
            "elongated axis gets more nodes: {g:?}"
        );
        let p = g.points();
        assert_eq!(p[g.index(3, 2, 1)], g.point(3, 2, 1));
        moe_geom::assert_err!(
            Grid3::new(Point3::origin(), 0.0, [2, 2, 2]),
            GpisError::InvalidParameter {
                name: "grid_spacing_m",
                value: 0.0,
                ..
            }
        );
        moe_geom::assert_err!(
            Grid3::new(Point3::origin(), 1.0, [2, 1, 2]),
            GpisError::InvalidParameter {
                name: "grid_nodes_per_axis",
                value: 1.0,
                ..
            }
        );
    }

    #[test]
    fn a_budget_beyond_the_limit_is_refused_before_allocating() {
        let b = Aabb {
            min: Point3::origin(),
            max: Point3::new(0.1, 0.1, 0.1),
        };
        assert!(Grid3::covering(&b, 0.0, MAX_GRID_NODES).is_ok());
        for too_many in [MAX_GRID_NODES + 1, usize::MAX] {
            assert!(matches!(
                Grid3::covering(&b, 0.0, too_many),
                Err(GpisError::InvalidParameter {
                    name: "grid_max_nodes",
                    ..
                })
            ));
        }
    }

    #[test]
    fn explicit_grids_beyond_the_limit_are_refused() {
        let o = Point3::origin();
        assert!(Grid3::new(o, 0.01, [256, 256, 256]).is_ok());
        for dims in [[256, 256, 257], [usize::MAX, 2, 2], [1 << 40, 1 << 40, 2]] {
            assert!(
                matches!(
                    Grid3::new(o, 0.01, dims),
                    Err(GpisError::InvalidParameter {
                        name: "grid_nodes",
                        ..
                    })
                ),
                "{dims:?}"
            );
        }
    }
}
