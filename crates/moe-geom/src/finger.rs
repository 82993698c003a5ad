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

use std::f64::consts::{FRAC_PI_2, PI};
use std::str::FromStr;

use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

use crate::error::GeomError;
use crate::math::{Point3, Real, is_finite_point};
use crate::mesh::TriMesh;

/// Geometry of the parametric finger. SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FingerParams {
    /// Length from the base plane to the tip apex, metres. Default 0.08.
    pub length_m: Real,
    /// Radius at the base, metres. Default 0.011.
    pub base_radius_m: Real,
    /// Radius of the hemispherical tip (and of the body where it joins), metres. Default 0.008.
    pub tip_radius_m: Real,
    /// Requested number of surface vertices. Default 1024; the mesh has this many within a few
    /// percent.
    pub vertex_budget: usize,
    /// Number of markers in each row of the [`MarkerLayout`] that does not give its own
    /// `count`: with the default layout, the markers along the camera-facing side. Default 7
    /// (paper §4.2).
    pub marker_count: usize,
    /// Distance of the tendons from the axis, as a fraction of the local body radius. Default 0.6.
    pub tendon_offset_ratio: Real,
    /// Where the markers are painted: a preset name (`"camera-row"`, `"two-rows"`, `"sides"`,
    /// `"tip-ring"`) or a table `{ rows = [{ angle_deg = 0, count = 7 }], tip_ring = 0 }`.
    /// Default: one row of `marker_count` on the camera side (left out of the serialised form
    /// when it is the default, so files written before layouts existed are unchanged).
    #[serde(skip_serializing_if = "MarkerLayout::is_default")]
    pub marker_layout: MarkerLayout,
}

impl Default for FingerParams {
    fn default() -> Self {
        Self {
            length_m: 0.08,
            base_radius_m: 0.011,
            tip_radius_m: 0.008,
            vertex_budget: 1024,
            marker_count: 7,
            tendon_offset_ratio: 0.6,
            marker_layout: MarkerLayout::default(),
        }
    }
}

impl FingerParams {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] naming the first bad one.
    pub fn validate(&self) -> Result<(), GeomError> {
        let bad = |name, value, reason| {
            Err(GeomError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        for (name, v) in [
            ("length_m", self.length_m),
            ("base_radius_m", self.base_radius_m),
            ("tip_radius_m", self.tip_radius_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "must be finite and positive");
            }
        }
        if self.length_m <= 1.5 * self.tip_radius_m {
            return bad("length_m", self.length_m, "must exceed 1.5 × tip_radius_m");
        }
        if !(16..=1_000_000).contains(&self.vertex_budget) {
            return bad(
                "vertex_budget",
                self.vertex_budget as Real,
                "must be in 16..=1000000",
            );
        }
        if !(1..=64).contains(&self.marker_count) {
            return bad(
                "marker_count",
                self.marker_count as Real,
                "must be in 1..=64",
            );
        }
        if !(self.tendon_offset_ratio > 0.0 && self.tendon_offset_ratio < 0.95) {
            return bad(
                "tendon_offset_ratio",
                self.tendon_offset_ratio,
                "must be in (0, 0.95)",
            );
        }
        self.marker_layout.validate(self.marker_count)
    }

    /// Height where the cylindrical-conical body meets the hemispherical tip.
    pub fn cap_start_z(&self) -> Real {
        self.length_m - self.tip_radius_m
    }

    /// Radius of the body surface at height `z` (0 outside `[0, length]`).
    pub fn radius_at(&self, z: Real) -> Real {
        let zc = self.cap_start_z();
        if !(0.0..=self.length_m).contains(&z) {
            0.0
        } else if z <= zc {
            self.base_radius_m + (self.tip_radius_m - self.base_radius_m) * z / zc
        } else {
            let dz = z - zc;
            (self.tip_radius_m * self.tip_radius_m - dz * dz)
                .max(0.0)
                .sqrt()
        }
    }
}

/// A tendon's path through the finger body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TendonRoute {
    /// Polyline from the base (first point) to the anchor (last point), in the finger frame.
    pub points_in_finger: Vec<Point3>,
    /// Index (within the same finger) of the antagonistic tendon.
    pub antagonist: usize,
}

impl TendonRoute {
    /// Length of the polyline.
    pub fn length(&self) -> Real {
        self.points_in_finger
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum()
    }
}

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

    /// The rest surface mesh, in the finger frame.
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// Marker vertex ids, ordered from base to tip.
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

/// Profile samples `(r, z)` from the base pole to the tip apex at spacing about `h`; the first
/// and last have `r = 0`.
fn profile(params: &FingerParams, h: Real) -> Vec<(Real, Real)> {
    let (rb, rt, zc) = (
        params.base_radius_m,
        params.tip_radius_m,
        params.cap_start_z(),
    );
    let side_len = ((rb - rt).powi(2) + zc * zc).sqrt();
    let n0 = ((rb / h).round() as usize).max(1);
    let n1 = ((side_len / h).round() as usize).max(1);
    let n2 = ((rt * FRAC_PI_2 / h).round() as usize).max(2);
    let mut out = Vec::with_capacity(n0 + n1 + n2 + 1);
    for k in 0..=n0 {
        out.push((rb * k as Real / n0 as Real, 0.0));
    }
    for k in 1..=n1 {
        let t = k as Real / n1 as Real;
        out.push((rb + (rt - rb) * t, zc * t));
    }
    for k in 1..=n2 {
        let phi = FRAC_PI_2 * k as Real / n2 as Real;
        let r = if k == n2 { 0.0 } else { rt * phi.cos() };
        out.push((r, zc + rt * phi.sin()));
    }
    out
}

fn ring_count(r: Real, h: Real) -> usize {
    if r <= 0.0 {
        1
    } else {
        ((2.0 * PI * r / h).round() as usize).max(3)
    }
}

fn vertex_count(params: &FingerParams, h: Real) -> usize {
    profile(params, h)
        .iter()
        .map(|&(r, _)| ring_count(r, h))
        .sum()
}

/// Finds the sample spacing whose vertex count is closest to the budget.
fn spacing_for_budget(params: &FingerParams) -> Real {
    let (rb, rt, zc) = (
        params.base_radius_m,
        params.tip_radius_m,
        params.cap_start_z(),
    );
    let scale = rb + zc + rt;
    let (mut lo, mut hi) = (scale * 1e-5, scale); // count(lo) > budget > count(hi)
    let target = params.vertex_budget;
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if vertex_count(params, mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let err = |h| (vertex_count(params, h) as i64 - target as i64).unsigned_abs();
    if err(lo) < err(hi) { lo } else { hi }
}

/// Builds the closed surface of revolution by stitching consecutive rings.
fn revolve_finger(params: &FingerParams) -> Result<TriMesh, GeomError> {
    let h = spacing_for_budget(params);
    let prof = profile(params, h);
    let mut vertices = Vec::new();
    let mut rings: Vec<(usize, usize, Real)> = Vec::with_capacity(prof.len()); // start, count, phase
    for (k, &(r, z)) in prof.iter().enumerate() {
        let m = ring_count(r, h);
        let phase = if k % 2 == 0 { 0.0 } else { 0.5 };
        rings.push((vertices.len(), m, phase));
        if m == 1 {
            vertices.push(Point3::new(0.0, 0.0, z));
        } else {
            for i in 0..m {
                let th = 2.0 * PI * (i as Real + phase) / m as Real;
                vertices.push(Point3::new(r * th.cos(), r * th.sin(), z));
            }
        }
    }
    let mut faces: Vec<[u32; 3]> = Vec::new();
    for w in rings.windows(2) {
        stitch(w[0], w[1], &mut faces);
    }
    let mesh = TriMesh::new(vertices, faces)?;
    Ok(if mesh.signed_volume() < 0.0 {
        mesh.flipped()
    } else {
        mesh
    })
}

/// Triangulates the band between ring `a` (lower in the profile) and ring `b` by advancing
/// along whichever ring's next vertex has the smaller angle.
fn stitch(a: (usize, usize, Real), b: (usize, usize, Real), faces: &mut Vec<[u32; 3]>) {
    let (a0, ma, pa) = a;
    let (b0, mb, pb) = b;
    let ia = |i: usize| (a0 + i % ma) as u32;
    let ib = |j: usize| (b0 + j % mb) as u32;
    if ma == 1 {
        for j in 0..mb {
            faces.push([ia(0), ib(j + 1), ib(j)]);
        }
        return;
    }
    if mb == 1 {
        for i in 0..ma {
            faces.push([ia(i), ia(i + 1), ib(0)]);
        }
        return;
    }
    let ang_a = |i: usize| (i as Real + pa) / ma as Real;
    let ang_b = |j: usize| (j as Real + pb) / mb as Real;
    let (mut i, mut j) = (0, 0);
    while i < ma || j < mb {
        let advance_a = j == mb || (i < ma && ang_a(i + 1) < ang_b(j + 1));
        if advance_a {
            faces.push([ia(i), ia(i + 1), ib(j)]);
            i += 1;
        } else {
            faces.push([ia(i), ib(j + 1), ib(j)]);
            j += 1;
        }
    }
}

/// Marker vertices: the surface vertices nearest to evenly spaced points on the +x side, from
/// 12 % of the length to where the body meets the tip cap, all distinct. Markers stay off the
/// cap: its far side faces away from a wrist camera looking along the finger.
fn place_markers(mesh: &TriMesh, params: &FingerParams) -> Result<Vec<u32>, GeomError> {
    let n = params.marker_count;
    let z_lo = 0.12 * params.length_m;
    let z_hi = params.cap_start_z();
    let mut taken = Vec::with_capacity(n);
    for k in 0..n {
        let z = if n == 1 {
            0.5 * (z_lo + z_hi)
        } else {
            z_lo + (z_hi - z_lo) * k as Real / (n - 1) as Real
        };
        let target = Point3::new(params.radius_at(z), 0.0, z);
        let best = mesh
            .vertices()
            .iter()
            .enumerate()
            .filter(|(i, _)| !taken.contains(&(*i as u32)))
            .min_by(|(_, p), (_, q)| (*p - target).norm().total_cmp(&(*q - target).norm()))
            .map(|(i, _)| i as u32)
            .ok_or(GeomError::InvalidParameter {
                name: "marker_count",
                value: n as Real,
                reason: "exceeds the number of mesh vertices (raise vertex_budget)",
            })?;
        taken.push(best);
    }
    Ok(taken)
}

/// Four straight tendon routes at `tendon_offset_ratio` of the local radius, from the base plane
/// to the start of the tip cap, in the ±x and ±y directions.
fn tendon_routes(params: &FingerParams) -> Vec<TendonRoute> {
    let dirs = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)];
    let antagonist = [1, 0, 3, 2];
    let segments = 16;
    let z_end = params.cap_start_z();
    dirs.iter()
        .zip(antagonist)
        .map(|(&(dx, dy), antagonist)| {
            let points_in_finger = (0..=segments)
                .map(|s| {
                    let z = z_end * s as Real / segments as Real;
                    let rho = params.tendon_offset_ratio * params.radius_at(z);
                    Point3::new(dx * rho, dy * rho, z)
                })
                .collect();
            TendonRoute {
                points_in_finger,
                antagonist,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Topology;

    fn min_angle_deg(mesh: &TriMesh) -> Real {
        let mut min = Real::INFINITY;
        for f in 0..mesh.num_faces() {
            let t = mesh.triangle(f);
            for k in 0..3 {
                let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let ang = (b - a).angle(&(c - a)).to_degrees();
                min = min.min(ang);
            }
        }
        min
    }

    #[test]
    fn finger_is_closed_manifold_genus_zero_at_several_budgets() {
        for budget in [128, 256, 512, 1024, 2048, 4096] {
            let params = FingerParams {
                vertex_budget: budget,
                ..FingerParams::default()
            };
            let finger = FingerModel::from_params(&params).unwrap();
            let mesh = finger.mesh();
            let topo = Topology::new(mesh);
            mesh.require_closed().unwrap();
            assert_eq!(topo.euler_characteristic(), 2, "budget {budget}");
            assert_eq!(topo.connected_components().1, 1);
            let n = mesh.num_vertices() as Real;
            let rel = (n - budget as Real).abs() / budget as Real;
            assert!(rel <= 0.03, "budget {budget}: {n} vertices");
            let min_angle = min_angle_deg(mesh);
            assert!(
                min_angle >= 20.0,
                "budget {budget}: min angle {min_angle:.1}°"
            );
            assert!(mesh.signed_volume() > 0.0);
        }
    }

    #[test]
    fn volume_and_area_approach_the_analytic_body() {
        let p = FingerParams {
            vertex_budget: 8192,
            ..FingerParams::default()
        };
        let mesh = FingerModel::from_params(&p).unwrap().mesh().clone();
        let (rb, rt, zc) = (p.base_radius_m, p.tip_radius_m, p.cap_start_z());
        let frustum = PI * zc / 3.0 * (rb * rb + rb * rt + rt * rt);
        let cap = 2.0 / 3.0 * PI * rt.powi(3);
        let rel = (mesh.signed_volume() - (frustum + cap)).abs() / (frustum + cap);
        assert!(rel < 0.01, "volume off by {:.3} %", rel * 100.0);
    }

    #[test]
    fn markers_base_and_tendons_are_where_they_belong() {
        let p = FingerParams::default();
        let f = FingerModel::from_params(&p).unwrap();
        assert_eq!(f.marker_vertices().len(), 7);
        let pos = f.marker_positions();
        for w in pos.windows(2) {
            assert!(w[1].z > w[0].z, "markers ordered base to tip");
        }
        for m in &pos {
            assert!(
                m.x > 0.0 && m.y.abs() < 0.25 * m.x,
                "camera-facing (+x) side: {m}"
            );
        }
        assert!(!f.base_vertices().is_empty());
        assert!(
            f.base_vertices()
                .iter()
                .all(|&v| f.mesh().vertices()[v as usize].z == 0.0)
        );
        assert_eq!(f.tendon_routes().len(), 4);
        for (i, t) in f.tendon_routes().iter().enumerate() {
            assert_eq!(f.tendon_routes()[t.antagonist].antagonist, i);
            for q in &t.points_in_finger {
                let r = (q.x * q.x + q.y * q.y).sqrt();
                assert!(r < p.radius_at(q.z), "tendon point {q} outside the body");
            }
        }
    }

    #[test]
    fn bad_params_are_named() {
        let p = FingerParams {
            tip_radius_m: -1.0,
            ..FingerParams::default()
        };
        assert!(matches!(
            FingerModel::from_params(&p),
            Err(GeomError::InvalidParameter {
                name: "tip_radius_m",
                ..
            })
        ));
        let p = FingerParams {
            vertex_budget: 3,
            ..FingerParams::default()
        };
        assert!(matches!(
            FingerModel::from_params(&p),
            Err(GeomError::InvalidParameter {
                name: "vertex_budget",
                ..
            })
        ));
    }

    #[test]
    fn more_markers_than_vertices_is_an_error() {
        let p = FingerParams {
            vertex_budget: 16,
            marker_count: 64,
            ..FingerParams::default()
        };
        assert!(matches!(
            FingerModel::from_params(&p),
            Err(GeomError::InvalidParameter {
                name: "marker_count",
                ..
            })
        ));
    }

    #[test]
    fn user_parts_are_checked() {
        let f = FingerModel::from_params(&FingerParams::default()).unwrap();
        let n = f.mesh().num_vertices();
        let err = FingerModel::from_parts(f.mesh().clone(), vec![0, n as u32], vec![1], vec![]);
        assert_eq!(
            err,
            Err(GeomError::VertexIdOutOfRange {
                what: "marker",
                index: n,
                len: n
            })
        );
        let err = FingerModel::from_parts(f.mesh().clone(), vec![0], vec![1, 1], vec![]);
        assert_eq!(
            err,
            Err(GeomError::DuplicateVertexId {
                what: "base",
                index: 1
            })
        );
    }
}
