//! The parametric MOE finger: a tapered, round-tipped body of revolution with a flat base,
//! marker vertices painted where its [`MarkerLayout`] says (by default seven in a row on its
//! camera-facing side, paper §4.2), a fixed base and four tendon routes.
//!
//! Finger frame: the base disk lies in the plane z = 0 centred at the origin, the finger extends
//! along +z, and +x points toward the hand's central axis — the side the wrist camera sees, where
//! the markers sit. The four tendons run parallel to the axis in the ±x and ±y directions: two
//! antagonistic pairs in two bending planes (paper §4.1), so pulling the +x tendon bends the
//! finger toward +x.
//!
//! Angles around the finger's axis are measured from +x (the camera side, 0°) toward +y, in
//! degrees from −180 to 180; the back of the finger is at ±180°.

mod layout;
mod params;
mod revolve;
mod tendons;
#[cfg(test)]
mod tests;

pub use layout::{
    DEFAULT_TIP_RING_HEIGHT_RATIO, MAX_LAYOUT_MARKERS, MarkerLayout, MarkerLayoutPreset, MarkerRow,
    ROW_START_RATIO, TIP_RING_MARKERS, TWO_ROWS_ANGLE_DEG,
};
pub use params::FingerParams;
pub use tendons::TendonRoute;

use crate::error::GeomError;
use crate::math::{Point3, Real, is_finite_point};
use crate::mesh::TriMesh;
use layout::place_markers;
use revolve::revolve_finger;
use tendons::tendon_routes;

/// A finger's rest surface mesh with the vertices that matter to the pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerModel {
    mesh: TriMesh,
    marker_vertices: Vec<u32>,
    base_vertices: Vec<u32>,
    tendon_routes: Vec<TendonRoute>,
}

impl FingerModel {
    /// Generates the parametric finger.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] for bad parameters.
    pub fn from_params(params: &FingerParams) -> Result<Self, GeomError> {
        params.validate()?;
        let mesh = revolve_finger(params)?;
        let base_vertices: Vec<u32> = mesh
            .vertices()
            .iter()
            .enumerate()
            .filter(|(_, p)| p.z == 0.0)
            .map(|(i, _)| i as u32)
            .collect();
        let marker_vertices = place_markers(&mesh, params)?;
        let tendon_routes = tendon_routes(params);
        Self::from_parts(mesh, marker_vertices, base_vertices, tendon_routes)
    }

    /// Assembles a finger from a user's own mesh (finger frame, metres) and vertex ids.
    ///
    /// # Errors
    /// An open mesh, out-of-range or repeated ids, an empty base, a tendon route with fewer than
    /// two points, non-finite points or an antagonist index out of range.
    pub fn from_parts(
        mesh: TriMesh,
        marker_vertices: Vec<u32>,
        base_vertices: Vec<u32>,
        tendon_routes: Vec<TendonRoute>,
    ) -> Result<Self, GeomError> {
        mesh.require_closed()?;
        let n = mesh.num_vertices();
        check_ids("marker", &marker_vertices, n)?;
        check_ids("base", &base_vertices, n)?;
        if marker_vertices.is_empty() {
            return Err(GeomError::EmptyPointSet {
                what: "marker vertices",
            });
        }
        if base_vertices.is_empty() {
            return Err(GeomError::EmptyPointSet {
                what: "base vertices",
            });
        }
        for route in &tendon_routes {
            if route.points_in_finger.len() < 2 {
                return Err(GeomError::LengthMismatch {
                    what: "tendon route points (at least)",
                    expected: 2,
                    got: route.points_in_finger.len(),
                });
            }
            if let Some(index) = route
                .points_in_finger
                .iter()
                .position(|p| !is_finite_point(p))
            {
                return Err(GeomError::NonFinitePoint {
                    what: "tendon route",
                    index,
                });
            }
            if route.antagonist >= tendon_routes.len() {
                return Err(GeomError::InvalidParameter {
                    name: "tendon antagonist",
                    value: route.antagonist as Real,
                    reason: "must index a tendon of the same finger",
                });
            }
        }
        Ok(Self {
            mesh,
            marker_vertices,
            base_vertices,
            tendon_routes,
        })
    }

    /// The marker indices from the most distal (farthest along the finger's axis, the finger
    /// frame's z, from its base) to the most proximal; ties keep their index order. The one
    /// definition of "the most distal marker".
    pub fn distal_marker_order(&self) -> Vec<usize> {
        let z: Vec<Real> = self.marker_positions().iter().map(|p| p.z).collect();
        let mut order: Vec<usize> = (0..z.len()).collect();
        order.sort_by(|&a, &b| z[b].total_cmp(&z[a]));
        order
    }

    /// The rest surface mesh, in the finger frame.
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// Marker vertex ids. A parametric finger's are in its [`MarkerLayout`]'s marker order: the
    /// rows in turn, each from base to tip, then the tip ring (the default layout: one row, base
    /// to tip). A user's mesh finger's are in the order its config gives.
    pub fn marker_vertices(&self) -> &[u32] {
        &self.marker_vertices
    }

    /// Vertex ids fixed to the palm, sorted.
    pub fn base_vertices(&self) -> &[u32] {
        &self.base_vertices
    }

    /// Tendon routes (four for the parametric finger: +x, −x, +y, −y).
    pub fn tendon_routes(&self) -> &[TendonRoute] {
        &self.tendon_routes
    }

    /// Rest positions of the markers, in the finger frame.
    pub fn marker_positions(&self) -> Vec<Point3> {
        self.marker_vertices
            .iter()
            .map(|&v| self.mesh.vertices()[v as usize])
            .collect()
    }
}

fn check_ids(what: &'static str, ids: &[u32], len: usize) -> Result<(), GeomError> {
    let mut seen = std::collections::HashSet::with_capacity(ids.len());
    for &id in ids {
        if id as usize >= len {
            return Err(GeomError::VertexIdOutOfRange {
                what,
                index: id as usize,
                len,
            });
        }
        if !seen.insert(id) {
            return Err(GeomError::DuplicateVertexId {
                what,
                index: id as usize,
            });
        }
    }
    Ok(())
}
