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

/// Angle of the two rows of [`MarkerLayoutPreset::TwoRows`] either side of the camera side,
/// degrees.
pub const TWO_ROWS_ANGLE_DEG: Real = 35.0;
/// Markers of the ring of [`MarkerLayoutPreset::TipRing`].
pub const TIP_RING_MARKERS: usize = 6;
/// Default height of a tip ring, as a fraction of the finger's length (where the default
/// finger's body meets its tip cap).
pub const DEFAULT_TIP_RING_HEIGHT_RATIO: Real = 0.9;
/// Height of a row's first (most proximal) marker, as a fraction of the length; its last is
/// where the body meets the tip cap.
pub const ROW_START_RATIO: Real = 0.12;
/// Most markers a layout may have.
pub const MAX_LAYOUT_MARKERS: usize = 256;

/// The marker layouts of the observability study, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MarkerLayoutPreset {
    /// One row on the camera side (0°): `marker_count` markers, 7 by default (paper §4.2). The
    /// default layout.
    CameraRow,
    /// Two rows at ±[`TWO_ROWS_ANGLE_DEG`] (+35° first), `marker_count` each: 14 by default.
    /// Both stay well inside the half the wrist camera sees.
    TwoRows,
    /// The camera row and one row on each side (+90°, then −90°), `marker_count` each: 21 by
    /// default. The side rows are seen at a grazing angle; they watch the finger's flanks.
    Sides,
    /// The camera row and a ring of [`TIP_RING_MARKERS`] around the finger at
    /// [`DEFAULT_TIP_RING_HEIGHT_RATIO`] of its length: 13 by default.
    TipRing,
}

impl MarkerLayoutPreset {
    /// All presets, in the study's order.
    pub const ALL: [MarkerLayoutPreset; 4] =
        [Self::CameraRow, Self::TwoRows, Self::Sides, Self::TipRing];

    /// The preset's config and command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::CameraRow => "camera-row",
            Self::TwoRows => "two-rows",
            Self::Sides => "sides",
            Self::TipRing => "tip-ring",
        }
    }

    /// The layout the preset names.
    pub fn layout(self) -> MarkerLayout {
        let row = |angle_deg| MarkerRow {
            angle_deg,
            count: None,
        };
        let (rows, tip_ring) = match self {
            Self::CameraRow => (vec![row(0.0)], 0),
            Self::TwoRows => (vec![row(TWO_ROWS_ANGLE_DEG), row(-TWO_ROWS_ANGLE_DEG)], 0),
            Self::Sides => (vec![row(0.0), row(90.0), row(-90.0)], 0),
            Self::TipRing => (vec![row(0.0)], TIP_RING_MARKERS),
        };
        MarkerLayout {
            rows,
            tip_ring,
            tip_ring_height_ratio: DEFAULT_TIP_RING_HEIGHT_RATIO,
        }
    }
}

impl FromStr for MarkerLayoutPreset {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown marker layout '{s}' (expected camera-row, two-rows, sides or \
                     tip-ring, or a table {{ rows = [...], tip_ring = N }})"
                )
            })
    }
}

impl std::fmt::Display for MarkerLayoutPreset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A row of markers along the finger at one angle around its axis, evenly spaced from
/// [`ROW_START_RATIO`] of the length to where the body meets the tip cap (one marker: halfway).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MarkerRow {
    /// Angle around the axis from the camera side (+x) toward +y, degrees, −180 to 180.
    /// Default 0.
    pub angle_deg: Real,
    /// Markers in the row, 1 to 64; default: the finger's `marker_count`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<usize>,
}

impl Default for MarkerRow {
    fn default() -> Self {
        Self {
            angle_deg: 0.0,
            count: None,
        }
    }
}

/// Where a parametric finger's markers are painted: rows along the finger and a ring around it
/// near the tip. Each marker is the surface vertex nearest to its target point on the finger's
/// surface; a layout whose markers would share a vertex (targets closer than the mesh spacing)
/// is refused.
///
/// Marker order (the order of [`FingerModel::marker_vertices`]): the rows in the order given,
/// each from base to tip, then the ring at angles `360° · (k + ½) / tip_ring` for
/// `k = 0, 1, …` (half a step off the camera side, so that a ring never lands on the camera
/// row).
///
/// In a config: a preset name, `marker_layout = "two-rows"`, or a table, e.g.
/// `marker_layout = { rows = [{ angle_deg = 0 }, { angle_deg = 180, count = 3 }], tip_ring = 4 }`;
/// a table's omitted fields keep the default layout's (one camera row, no ring).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerLayout {
    /// Rows along the finger. Default: one at 0° (the camera side).
    pub rows: Vec<MarkerRow>,
    /// Markers of the ring around the finger near the tip, 0 (none, the default) to 64.
    pub tip_ring: usize,
    /// Height of the ring, as a fraction of the finger's length: 0.12 to below 1. Default 0.9.
    pub tip_ring_height_ratio: Real,
}

impl Default for MarkerLayout {
    /// One row on the camera side: [`MarkerLayoutPreset::CameraRow`].
    fn default() -> Self {
        MarkerLayoutPreset::CameraRow.layout()
    }
}

impl From<MarkerLayoutPreset> for MarkerLayout {
    fn from(preset: MarkerLayoutPreset) -> Self {
        preset.layout()
    }
}

/// The table form of a layout, as a config gives it.
#[derive(Deserialize)]
#[serde(default, deny_unknown_fields)]
struct MarkerLayoutTable {
    rows: Vec<MarkerRow>,
    tip_ring: usize,
    tip_ring_height_ratio: Real,
}

impl Default for MarkerLayoutTable {
    fn default() -> Self {
        let d = MarkerLayout::default();
        Self {
            rows: d.rows,
            tip_ring: d.tip_ring,
            tip_ring_height_ratio: d.tip_ring_height_ratio,
        }
    }
}

impl<'de> Deserialize<'de> for MarkerLayout {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct LayoutVisitor;
        impl<'de> Visitor<'de> for LayoutVisitor {
            type Value = MarkerLayout;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(
                    "a marker layout: a preset name (camera-row, two-rows, sides, tip-ring) or a \
                     table { rows = [{ angle_deg = 0, count = 7 }], tip_ring = 0 }",
                )
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<MarkerLayout, E> {
                s.parse::<MarkerLayoutPreset>()
                    .map(MarkerLayoutPreset::layout)
                    .map_err(E::custom)
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<MarkerLayout, A::Error> {
                let t = MarkerLayoutTable::deserialize(de::value::MapAccessDeserializer::new(map))?;
                Ok(MarkerLayout {
                    rows: t.rows,
                    tip_ring: t.tip_ring,
                    tip_ring_height_ratio: t.tip_ring_height_ratio,
                })
            }
        }
        deserializer.deserialize_any(LayoutVisitor)
    }
}

impl MarkerLayout {
    /// True for the default layout (one camera row of `marker_count`).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The preset this layout equals, if any.
    pub fn preset(&self) -> Option<MarkerLayoutPreset> {
        MarkerLayoutPreset::ALL
            .into_iter()
            .find(|p| p.layout() == *self)
    }

    /// Number of markers, rows without a `count` having `marker_count`.
    pub fn num_markers(&self, marker_count: usize) -> usize {
        self.rows
            .iter()
            .map(|r| r.count.unwrap_or(marker_count))
            .sum::<usize>()
            + self.tip_ring
    }

    /// Checks the layout (`marker_count`: the count of rows that give none).
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] naming the bad field (`marker_layout.rows.angle_deg`,
    /// `marker_layout.rows.count`, `marker_layout.tip_ring`, ...).
    pub fn validate(&self, marker_count: usize) -> Result<(), GeomError> {
        let bad = |name, value, reason| {
            Err(GeomError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        if self.rows.len() > 16 {
            return bad(
                "marker_layout.rows",
                self.rows.len() as Real,
                "at most 16 rows",
            );
        }
        for row in &self.rows {
            if !(row.angle_deg.is_finite() && (-180.0..=180.0).contains(&row.angle_deg)) {
                return bad(
                    "marker_layout.rows.angle_deg",
                    row.angle_deg,
                    "must be finite, from -180 to 180 degrees",
                );
            }
            if let Some(c) = row.count
                && !(1..=64).contains(&c)
            {
                return bad("marker_layout.rows.count", c as Real, "must be in 1..=64");
            }
        }
        if self.tip_ring > 64 {
            return bad(
                "marker_layout.tip_ring",
                self.tip_ring as Real,
                "must be in 0..=64",
            );
        }
        let h = self.tip_ring_height_ratio;
        if !(h.is_finite() && (ROW_START_RATIO..1.0).contains(&h)) {
            return bad(
                "marker_layout.tip_ring_height_ratio",
                h,
                "must be from 0.12 to below 1",
            );
        }
        let n = self.num_markers(marker_count);
        if n == 0 {
            return bad("marker_layout", 0.0, "has no markers (no rows and no ring)");
        }
        if n > MAX_LAYOUT_MARKERS {
            return bad("marker_layout", n as Real, "has more than 256 markers");
        }
        Ok(())
    }
}

impl std::fmt::Display for MarkerLayout {
    /// The preset's name, or the rows and the ring (`rows 0°, 180°×3; tip ring 4 at 0.90 L`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(p) = self.preset() {
            return f.write_str(p.name());
        }
        let rows: Vec<String> = self
            .rows
            .iter()
            .map(|r| match r.count {
                Some(c) => format!("{}°×{c}", r.angle_deg),
                None => format!("{}°", r.angle_deg),
            })
            .collect();
        write!(f, "rows [{}]", rows.join(", "))?;
        if self.tip_ring > 0 {
            write!(
                f,
                "; tip ring {} at {:.2} L",
                self.tip_ring, self.tip_ring_height_ratio
            )?;
        }
        Ok(())
    }
}

impl FingerParams {
    /// The markers' target points on the finger's surface (finger frame), in marker order
    /// (see [`MarkerLayout`]); each marker is the vertex nearest its target.
    pub fn marker_targets(&self) -> Vec<Point3> {
        self.marker_targets_named()
            .into_iter()
            .map(|(_, p)| p)
            .collect()
    }

    /// The targets with the layout field each comes from.
    fn marker_targets_named(&self) -> Vec<(&'static str, Point3)> {
        let layout = &self.marker_layout;
        let z_lo = ROW_START_RATIO * self.length_m;
        let z_hi = self.cap_start_z();
        let mut out = Vec::with_capacity(layout.num_markers(self.marker_count));
        for row in &layout.rows {
            let n = row.count.unwrap_or(self.marker_count);
            let th = row.angle_deg.to_radians();
            let (c, s) = if row.angle_deg == 0.0 {
                (1.0, 0.0) // exactly the camera side
            } else {
                (th.cos(), th.sin())
            };
            for k in 0..n {
                let z = if n == 1 {
                    0.5 * (z_lo + z_hi)
                } else {
                    z_lo + (z_hi - z_lo) * k as Real / (n - 1) as Real
                };
                let r = self.radius_at(z);
                out.push(("marker_layout.rows", Point3::new(r * c, r * s, z)));
            }
        }
        let n = layout.tip_ring;
        let z = layout.tip_ring_height_ratio * self.length_m;
        let r = self.radius_at(z);
        for k in 0..n {
            let th = 2.0 * PI * (k as Real + 0.5) / n as Real;
            out.push((
                "marker_layout.tip_ring",
                Point3::new(r * th.cos(), r * th.sin(), z),
            ));
        }
        out
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

/// Marker vertices: for each of the layout's targets (see [`MarkerLayout`]), in order, the
/// surface vertex nearest to it (the first of equals). Two targets with the same nearest vertex
/// are refused, naming the layout field of the second — except with the default layout, which
/// keeps the placement of before layouts existed (the nearest vertex not already a marker), so
/// that every existing finger keeps its marker ids, coarse ones with crowded markers included.
fn place_markers(mesh: &TriMesh, params: &FingerParams) -> Result<Vec<u32>, GeomError> {
    let targets = params.marker_targets_named();
    let legacy = params.marker_layout.is_default();
    if targets.len() > mesh.num_vertices() {
        return Err(GeomError::InvalidParameter {
            name: if legacy {
                "marker_count"
            } else {
                "marker_layout"
            },
            value: targets.len() as Real,
            reason: "exceeds the number of mesh vertices (raise vertex_budget)",
        });
    }
    let mut taken: Vec<u32> = Vec::with_capacity(targets.len());
    for (k, (field, target)) in targets.iter().enumerate() {
        let best = mesh
            .vertices()
            .iter()
            .enumerate()
            .filter(|(i, _)| !(legacy && taken.contains(&(*i as u32))))
            .min_by(|(_, p), (_, q)| (*p - target).norm().total_cmp(&(*q - target).norm()))
            .map_or(0, |(i, _)| i as u32);
        if taken.contains(&best) {
            return Err(GeomError::InvalidParameter {
                name: field,
                value: k as Real,
                reason: "the marker of this index (marker order: rows, then the ring) falls on \
                         the surface vertex of an earlier marker: markers closer than the mesh \
                         spacing (spread them, use fewer, or raise vertex_budget)",
            });
        }
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

    /// The default layout's markers are the ones the finger always had (the ids of the code
    /// before layouts existed, at the default and two other budgets), also when the default is
    /// spelled as the `camera-row` preset.
    #[test]
    fn default_layout_keeps_the_marker_ids() {
        for (budget, ids) in [
            (1024, [215, 333, 446, 582, 710, 808, 947]),
            (512, [88, 171, 249, 288, 343, 429, 463]),
            (40, [7, 13, 18, 23, 27, 28, 36]),
        ] {
            let p = FingerParams {
                vertex_budget: budget,
                ..FingerParams::default()
            };
            assert!(p.marker_layout.is_default());
            assert_eq!(FingerModel::from_params(&p).unwrap().marker_vertices(), ids);
            let preset = FingerParams {
                marker_layout: MarkerLayoutPreset::CameraRow.layout(),
                ..p
            };
            assert_eq!(
                FingerModel::from_params(&preset).unwrap().marker_vertices(),
                ids
            );
        }
    }

    /// The longest edge of the mesh: no surface point is farther than this from a vertex.
    fn max_edge(mesh: &TriMesh) -> Real {
        Topology::new(mesh)
            .edges()
            .iter()
            .map(|&[a, b]| (mesh.vertices()[a as usize] - mesh.vertices()[b as usize]).norm())
            .fold(0.0, Real::max)
    }

    fn angle_deg(p: &Point3) -> Real {
        p.y.atan2(p.x).to_degrees()
    }

    #[test]
    fn presets_give_their_counts_on_distinct_vertices_near_their_targets() {
        for (preset, count) in [
            (MarkerLayoutPreset::CameraRow, 7),
            (MarkerLayoutPreset::TwoRows, 14),
            (MarkerLayoutPreset::Sides, 21),
            (MarkerLayoutPreset::TipRing, 13),
        ] {
            let p = FingerParams {
                marker_layout: preset.layout(),
                ..FingerParams::default()
            };
            assert_eq!(p.marker_layout.preset(), Some(preset));
            assert_eq!(p.marker_layout.to_string(), preset.name());
            assert_eq!(p.marker_layout.num_markers(p.marker_count), count);
            let f = FingerModel::from_params(&p).unwrap();
            let ids = f.marker_vertices();
            assert_eq!(ids.len(), count, "{preset}");
            let mut sorted = ids.to_vec();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), count, "{preset}: distinct vertices");
            let spacing = max_edge(f.mesh());
            let targets = p.marker_targets();
            let pos = f.marker_positions();
            for (m, t) in pos.iter().zip(&targets) {
                assert!((m - t).norm() <= spacing, "{preset}: {m} far from {t}");
                assert!(m.z > 0.1 * p.length_m, "{preset}: off the base");
            }
            // Rows: the marker_count markers of each, base to tip, at the row's angle.
            for (r, row) in p.marker_layout.rows.iter().enumerate() {
                let row_pos = &pos[r * 7..(r + 1) * 7];
                for w in row_pos.windows(2) {
                    assert!(w[1].z > w[0].z, "{preset}: row {r} runs base to tip");
                }
                for m in row_pos {
                    let radius = (m.x * m.x + m.y * m.y).sqrt();
                    let tol = (spacing / radius).to_degrees();
                    assert!(
                        (angle_deg(m) - row.angle_deg).abs() <= tol,
                        "{preset}: row at {}°, marker at {:.1}° (±{tol:.1}°)",
                        row.angle_deg,
                        angle_deg(m)
                    );
                }
            }
            // The ring: around the finger at its height, half a step off the camera side.
            let ring = &pos[7 * p.marker_layout.rows.len()..];
            assert_eq!(ring.len(), p.marker_layout.tip_ring);
            for (k, m) in ring.iter().enumerate() {
                let z = p.marker_layout.tip_ring_height_ratio * p.length_m;
                assert!(
                    (m.z - z).abs() <= spacing,
                    "{preset}: ring marker at z {}",
                    m.z
                );
                let expected = 360.0 * (k as Real + 0.5) / ring.len() as Real;
                let d = (angle_deg(m) - expected).rem_euclid(360.0);
                let d = d.min(360.0 - d);
                assert!(
                    d <= (spacing / 0.008).to_degrees(),
                    "{preset}: ring {k} at {d}° off"
                );
            }
        }
        // Two rows at ±35°: the marker pairs mirror each other across the camera side.
        let p = FingerParams {
            marker_layout: MarkerLayoutPreset::TwoRows.layout(),
            ..FingerParams::default()
        };
        let pos = FingerModel::from_params(&p).unwrap().marker_positions();
        for k in 0..7 {
            assert!(angle_deg(&pos[k]) > 20.0 && angle_deg(&pos[7 + k]) < -20.0);
            assert!((pos[k].z - pos[7 + k].z).abs() < 1e-3);
        }
    }

    #[test]
    fn custom_layouts_follow_their_rows_and_counts() {
        let p = FingerParams {
            marker_count: 5,
            marker_layout: MarkerLayout {
                rows: vec![
                    MarkerRow {
                        angle_deg: 180.0,
                        count: Some(3),
                    },
                    MarkerRow::default(),
                ],
                tip_ring: 4,
                tip_ring_height_ratio: 0.85,
            },
            ..FingerParams::default()
        };
        assert_eq!(p.marker_layout.preset(), None);
        assert_eq!(
            p.marker_layout.to_string(),
            "rows [180°×3, 0°]; tip ring 4 at 0.85 L"
        );
        let f = FingerModel::from_params(&p).unwrap();
        let pos = f.marker_positions();
        assert_eq!(pos.len(), 3 + 5 + 4);
        assert!(pos[..3].iter().all(|m| m.x < 0.0), "the back row first");
        assert!(pos[3..8].iter().all(|m| m.x > 0.0), "then the camera row");
        assert!(
            pos[8..].iter().all(|m| (m.z - 0.068).abs() < 2e-3),
            "then the ring"
        );
    }

    #[test]
    fn bad_layouts_are_refused_naming_the_field() {
        let with = |marker_layout: MarkerLayout| FingerParams {
            marker_layout,
            ..FingerParams::default()
        };
        let row = |angle_deg, count| MarkerRow { angle_deg, count };
        let name_of = |p: &FingerParams| match FingerModel::from_params(p) {
            Err(GeomError::InvalidParameter { name, .. }) => name,
            other => panic!("expected an invalid parameter, got {other:?}"),
        };
        let base = MarkerLayout::default();
        for (layout, field) in [
            (
                MarkerLayout {
                    rows: vec![row(200.0, None)],
                    ..base.clone()
                },
                "marker_layout.rows.angle_deg",
            ),
            (
                MarkerLayout {
                    rows: vec![row(Real::NAN, None)],
                    ..base.clone()
                },
                "marker_layout.rows.angle_deg",
            ),
            (
                MarkerLayout {
                    rows: vec![row(0.0, Some(0))],
                    ..base.clone()
                },
                "marker_layout.rows.count",
            ),
            (
                MarkerLayout {
                    tip_ring: 65,
                    ..base.clone()
                },
                "marker_layout.tip_ring",
            ),
            (
                MarkerLayout {
                    tip_ring: 6,
                    tip_ring_height_ratio: 1.0,
                    ..base.clone()
                },
                "marker_layout.tip_ring_height_ratio",
            ),
            (
                MarkerLayout {
                    rows: vec![],
                    tip_ring: 0,
                    ..base.clone()
                },
                "marker_layout",
            ),
            // Two rows 2° apart share vertices: refused, not silently shifted.
            (
                MarkerLayout {
                    rows: vec![row(0.0, None), row(2.0, None)],
                    ..base.clone()
                },
                "marker_layout.rows",
            ),
            // A ring of 40 at the tip is denser than the mesh.
            (
                MarkerLayout {
                    tip_ring: 40,
                    ..base.clone()
                },
                "marker_layout.tip_ring",
            ),
        ] {
            assert_eq!(name_of(&with(layout.clone())), field, "{layout:?}");
        }
        let msg = FingerModel::from_params(&with(MarkerLayout {
            rows: vec![row(0.0, None), row(2.0, None)],
            ..base
        }))
        .unwrap_err()
        .to_string();
        assert!(
            msg.contains("marker_layout.rows") && msg.contains("vertex"),
            "{msg}"
        );
    }
}
