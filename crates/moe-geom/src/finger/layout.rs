//! Marker layouts: where a parametric finger's markers are painted (presets, rows, a tip ring),
//! their config forms, and the mesh vertices they fall on.

use std::f64::consts::PI;
use std::str::FromStr;

use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

#[cfg(doc)]
use super::FingerModel;
use super::params::FingerParams;
use crate::error::GeomError;
use crate::math::{Point3, Real};
use crate::mesh::TriMesh;

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

/// Marker vertices: for each of the layout's targets (see [`MarkerLayout`]), in order, the
/// surface vertex nearest to it (the first of equals). Two targets with the same nearest vertex
/// are refused, naming the layout field of the second — except with the default layout, which
/// keeps the placement of before layouts existed (the nearest vertex not already a marker), so
/// that every existing finger keeps its marker ids, coarse ones with crowded markers included.
pub(super) fn place_markers(mesh: &TriMesh, params: &FingerParams) -> Result<Vec<u32>, GeomError> {
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
