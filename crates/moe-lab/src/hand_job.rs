//! A hand model's files, as `moe-touch hand` writes them: every finger's rest mesh in the hand
//! frame with its vertex ids and measures (`hand.json`), and on request the Cramér–Rao bound of
//! a press's place on finger 0 for its marker layout, per region and per vertex
//! (`bound_finger_0.ply`).

use std::path::Path;

use moe_geom::{HandModel, MarkerLayoutPreset, Real, Topology, TriMesh};
use moe_io::PlyData;
use moe_physics::{BoundOptions, PlaceBound, RegionBound, Spread, region_bounds};
use serde::Serialize;

use crate::error::LabError;
use crate::output_files::OutputFiles;

/// The name of the bound's per-vertex map.
const BOUND_MAP: &str = "bound_finger_0.ply";

/// Bounds above this (and infinite ones) are written to the map as this many millimetres.
const MAP_CAP_MM: Real = 1000.0;

/// What `hand.json` holds for one finger.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FingerRecord {
    /// The rest mesh's file.
    pub mesh: String,
    /// The frame of its vertices.
    pub frame: &'static str,
    /// Its vertices.
    pub num_vertices: usize,
    /// Its faces.
    pub num_faces: usize,
    /// Marker vertex ids, base to tip.
    pub marker_vertices: Vec<u32>,
    /// Vertex ids fixed to the palm.
    pub base_vertices: Vec<u32>,
    /// Translation of the finger frame in the hand frame, metres.
    pub hand_from_finger_translation_m: [Real; 3],
    /// Rotation of the finger frame in the hand frame, a unit quaternion `x, y, z, w`.
    pub hand_from_finger_rotation_xyzw: [Real; 4],
    /// Surface area, m².
    pub surface_area_m2: Real,
    /// Enclosed volume, m³.
    pub volume_m3: Real,
    /// Shortest edge, metres.
    pub min_edge_length_m: Real,
    /// Longest edge, metres.
    pub max_edge_length_m: Real,
    /// Each tendon's route through the body, from the base to its anchor, hand frame, metres
    /// (a cable in displacement mode holds this path's length at zero pull).
    pub tendon_routes_m: Vec<Vec<[Real; 3]>>,
}

/// `hand.json`, also the `moe-touch hand --json` summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HandRecord {
    /// Where the hand comes from: a preset's name or a config file.
    pub source: String,
    /// Its fingers.
    pub num_fingers: usize,
    /// Vertices of all fingers.
    pub total_vertices: usize,
    /// Every finger.
    pub fingers: Vec<FingerRecord>,
    /// The bound, when asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bound: Option<BoundRecord>,
}

/// The Cramér–Rao bound of a press on finger 0.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoundRecord {
    /// The finger (0).
    pub finger: usize,
    /// Its marker layout's name.
    pub marker_layout: String,
    /// Its markers.
    pub markers: usize,
    /// Force of the press, newtons.
    pub force_n: Real,
    /// Independent frames of the held press.
    pub frames: usize,
    /// Noise of a marker coordinate, metres.
    pub marker_sigma_m: Real,
    /// Gravity in the hand frame, m/s².
    pub gravity_in_hand_m_s2: [Real; 3],
    /// The tendon pulls assumed (`zero`).
    pub pulls: &'static str,
    /// Median and 90th percentile per region (tip, middle, base).
    pub regions: Vec<RegionBound>,
    /// The per-vertex map's file.
    pub map: String,
    /// What is observed: `markers`, `depth` or `markers and depth`.
    pub observed: &'static str,
    /// The depth image's model, when depth is observed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub depth: Option<moe_physics::DepthBoundModel>,
    /// What that camera sees of the finger, when depth is observed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub depth_coverage: Option<moe_physics::DepthCoverage>,
}

/// The bound of finger 0 with its per-vertex map.
#[derive(Debug, Clone)]
pub struct FingerBound {
    /// The report.
    pub record: BoundRecord,
    /// Finger 0's rest mesh (hand frame) with the bound per vertex.
    pub map: PlyData,
}

/// A hand's record and files (`finger_<i>.obj`, the bound's map, `hand.json`).
#[derive(Debug)]
pub struct HandOutput {
    /// The record.
    pub record: HandRecord,
    /// The files to write.
    pub files: OutputFiles,
}

/// Reads a hand config and builds its hand; also finger 0's marker layout, as the config gives
/// it (the camera row when it names none).
///
/// # Errors
/// A missing, unreadable or malformed config, or one whose hand cannot be built, naming the
/// file and the field.
pub fn read_hand_config(path: &Path) -> Result<(HandModel, String), LabError> {
    let config: moe_io::HandConfig = moe_io::read_config(path)?;
    let hand = config.build(path)?;
    let layout = match (&config.finger, config.fingers.first()) {
        (Some(p), _) => p.marker_layout.to_string(),
        (None, Some(f)) => f.params.as_ref().map_or_else(
            || "the mesh's marker ids".to_owned(),
            |p| p.marker_layout.to_string(),
        ),
        (None, None) => MarkerLayoutPreset::CameraRow.to_string(),
    };
    Ok((hand, layout))
}

/// Every finger's rest mesh in the hand frame and its record; with `bound`, its map too.
///
/// # Errors
/// A finger whose rest vertices in the hand frame are not finite.
pub fn hand_output(
    hand: &HandModel,
    source: String,
    bound: Option<FingerBound>,
) -> Result<HandOutput, LabError> {
    let mut files = OutputFiles::new();
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for (i, f) in hand.fingers().iter().enumerate() {
        let mesh = rest_mesh_in_hand(hand, i)?;
        let (min_edge, max_edge) = edge_length_range(&mesh);
        let iso = f.hand_from_finger.iso();
        let q = iso.rotation.quaternion();
        fingers.push(FingerRecord {
            mesh: format!("finger_{i}.obj"),
            frame: "hand",
            num_vertices: mesh.num_vertices(),
            num_faces: mesh.num_faces(),
            marker_vertices: f.model.marker_vertices().to_vec(),
            base_vertices: f.model.base_vertices().to_vec(),
            hand_from_finger_translation_m: iso.translation.vector.into(),
            hand_from_finger_rotation_xyzw: [q.i, q.j, q.k, q.w],
            surface_area_m2: mesh.surface_area(),
            volume_m3: mesh.signed_volume(),
            min_edge_length_m: min_edge,
            max_edge_length_m: max_edge,
            tendon_routes_m: f
                .model
                .tendon_routes()
                .iter()
                .map(|r| {
                    r.points_in_finger
                        .iter()
                        .map(|p| f.hand_from_finger.transform_point(p).coords.into())
                        .collect()
                })
                .collect(),
        });
        files.add_mesh(format!("finger_{i}.obj"), mesh);
    }
    let bound = bound.map(|b| {
        files.add_ply(b.record.map.clone(), b.map);
        b.record
    });
    let record = HandRecord {
        source,
        num_fingers: hand.num_fingers(),
        total_vertices: hand.num_vertices(),
        fingers,
        bound,
    };
    files.add_json("hand.json", record.clone());
    Ok(HandOutput { record, files })
}

/// Finger `i`'s rest mesh with its vertices in the hand frame.
fn rest_mesh_in_hand(hand: &HandModel, i: usize) -> Result<TriMesh, LabError> {
    let mesh = hand.fingers()[i].model.mesh();
    Ok(mesh.with_vertices(hand.rest_vertices_in_hand(i))?)
}

/// The Cramér–Rao bound of a press on finger 0 of `hand`, whose markers are laid out as
/// `marker_layout` says: the physics model with the default material and settings, zero pulls,
/// gravity along the hand's −z.
///
/// # Errors
/// A finger the physics model cannot be built for, `options` out of range, a failing solve.
pub fn finger_bound(
    hand: &HandModel,
    options: &BoundOptions,
    marker_layout: String,
) -> Result<FingerBound, LabError> {
    let model = hand.fingers()[0].model.clone();
    // The bound needs finger 0's model only.
    let mut alone = crate::observability::FingerAlone::of(hand)?;
    let gravity = alone.gravity();
    let bounds = alone.location_bounds(options)?;
    let depth_coverage = match &options.depth {
        Some(depth) => Some(alone.depth_coverage(depth)?),
        None => None,
    };
    let length = model
        .mesh()
        .vertices()
        .iter()
        .map(|p| p.z)
        .fold(Real::MIN, Real::max);
    let map = bound_map(
        &rest_mesh_in_hand(hand, 0)?,
        model.marker_vertices(),
        &bounds,
    );
    let record = BoundRecord {
        finger: 0,
        marker_layout,
        markers: model.marker_vertices().len(),
        force_n: options.force_n,
        frames: options.frames,
        marker_sigma_m: options.marker_sigma_m,
        gravity_in_hand_m_s2: gravity.into(),
        pulls: "zero",
        regions: region_bounds(&bounds, length),
        map: BOUND_MAP.to_owned(),
        observed: options.observed(),
        depth: options.depth.clone(),
        depth_coverage,
    };
    Ok(FingerBound { record, map })
}

/// Finger 0's rest mesh (hand frame) with the bound per vertex: scalars `bound_along_mm`,
/// `bound_around_mm`, `bound_force_sd_n` (0 on the vertices fixed to the palm, which no press
/// moves; infinite bounds written as [`MAP_CAP_MM`] mm, or as many newtons), `movable` (1 or
/// 0) and `marker` (1 on marker vertices), and colours: the along bound on a log ramp from
/// 0.5 mm (dark blue) to 50 mm and beyond (yellow) (a fixed range, unlike `moe-touch eval
/// observability`'s figure, whose range follows the data), markers black, fixed vertices grey.
fn bound_map(mesh: &TriMesh, markers: &[u32], bounds: &[PlaceBound]) -> PlyData {
    let n = mesh.num_vertices();
    let cap = |v: Real| {
        if v.is_finite() {
            v.min(MAP_CAP_MM)
        } else {
            MAP_CAP_MM
        }
    };
    let (mut along, mut around, mut force, mut movable) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for b in bounds {
        let v = b.vertex as usize;
        along[v] = cap(b.along_m * 1e3);
        around[v] = cap(b.around_m * 1e3);
        force[v] = cap(b.force_sd_n);
        movable[v] = 1.0;
    }
    let mut is_marker = vec![0.0; n];
    for &m in markers {
        is_marker[m as usize] = 1.0;
    }
    let colors = (0..n)
        .map(|v| {
            if is_marker[v] > 0.0 {
                [0, 0, 0]
            } else if movable[v] == 0.0 {
                [160, 160, 160]
            } else {
                moe_record::viridis_colour(((along[v] / 0.5).log10() / 2.0).clamp(0.0, 1.0))
            }
        })
        .collect();
    let mut ply = PlyData::from_mesh(mesh)
        .with_scalar("bound_along_mm", along)
        .with_scalar("bound_around_mm", around)
        .with_scalar("bound_force_sd_n", force)
        .with_scalar("movable", movable)
        .with_scalar("marker", is_marker);
    ply.colors = Some(colors);
    ply
}

/// The shortest and the longest edge of `mesh`.
fn edge_length_range(mesh: &TriMesh) -> (Real, Real) {
    let topo = Topology::new(mesh);
    topo.edges()
        .iter()
        .fold((Real::INFINITY, 0.0), |(lo, hi), &[a, b]| {
            let l = (mesh.vertices()[a as usize] - mesh.vertices()[b as usize]).norm();
            (lo.min(l), hi.max(l))
        })
}

impl HandRecord {
    /// The lines `moe-touch hand` prints: the hand, each finger, the bound's table when there is
    /// one, and what was written to `out`.
    pub fn summary(&self, out: &Path) -> String {
        let mut lines = vec![format!(
            "hand '{}': {} fingers, {} vertices in total",
            self.source, self.num_fingers, self.total_vertices
        )];
        for (i, f) in self.fingers.iter().enumerate() {
            lines.push(format!(
                "  finger {i}: {} vertices, {} faces, {} markers, {} base vertices, area {:.1} \
                 cm², volume {:.2} cm³, edges {:.2}–{:.2} mm",
                f.num_vertices,
                f.num_faces,
                f.marker_vertices.len(),
                f.base_vertices.len(),
                f.surface_area_m2 * 1e4,
                f.volume_m3 * 1e6,
                f.min_edge_length_m * 1e3,
                f.max_edge_length_m * 1e3
            ));
        }
        if let Some(b) = &self.bound {
            lines.push(b.table());
        }
        lines.push(format!(
            "wrote {} meshes{} and hand.json to {}",
            self.num_fingers,
            self.bound
                .as_ref()
                .map_or(String::new(), |b| format!(", {}", b.map)),
            out.display()
        ));
        lines.join("\n")
    }
}

impl BoundRecord {
    /// The bound as a heading line and a table of the regions.
    pub fn table(&self) -> String {
        let depth = self.depth.as_ref().map_or(String::new(), |d| {
            format!(
                "; depth seen from the wrist camera ({} × {}, σ = {:.2} mm + {:.4} m⁻¹·z², \
                 correlated {:.2} mm, unit {:.1} mm)",
                d.intrinsics.width,
                d.intrinsics.height,
                d.noise.sigma_base_m * 1e3,
                d.noise.sigma_per_m2,
                d.noise.correlated_sigma_m * 1e3,
                d.noise.quantum_m * 1e3
            )
        });
        let seen = self.depth_coverage.as_ref().map_or(String::new(), |c| {
            format!(
                "; it sees {} of the finger's {} surface vertices, {:.0} depth pixels, at {:.1} \
                 mm (median; 90 % within {:.1} mm)",
                c.vertices,
                c.surface_vertices,
                c.pixels,
                c.depth_m.median * 1e3,
                c.depth_m.p90 * 1e3
            )
        });
        let mut lines = vec![
            format!(
                "Cramér–Rao bound of a press on finger {} ({} markers, layout {}): {:.2} N along \
                 the inward normal, {} frame(s), marker noise {:.3} mm per coordinate, zero \
                 pulls, gravity along the hand's −z; observed: {}{depth}{seen}",
                self.finger,
                self.markers,
                self.marker_layout,
                self.force_n,
                self.frames,
                self.marker_sigma_m * 1e3,
                self.observed
            ),
            format!(
                "  {:<20} {:>8} {:>22} {:>22} {:>22}",
                "region (z / length)",
                "vertices",
                "along mm (med / p90)",
                "around mm (med / p90)",
                "force sd N (med / p90)"
            ),
        ];
        let pair = |s: Spread, digits: usize| format!("{:.digits$} / {:.digits$}", s.median, s.p90);
        for r in &self.regions {
            lines.push(format!(
                "  {:<20} {:>8} {:>22} {:>22} {:>22}{}",
                format!("{} ({:.2}–{:.2})", r.region, r.z_from, r.z_to),
                r.vertices,
                pair(r.along_mm, 2),
                pair(r.around_mm, 2),
                pair(r.force_sd_n, 3),
                if r.unobservable > 0 {
                    format!("  ({} unobservable)", r.unobservable)
                } else {
                    String::new()
                }
            ));
        }
        lines.join("\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerParams, HandPreset};

    #[test]
    fn every_finger_has_its_mesh_and_record_and_the_summary_names_the_files() {
        let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
        let out = hand_output(&hand, "three-finger".into(), None).unwrap();
        assert_eq!(out.record.num_fingers, 3);
        assert_eq!(
            out.files.names().collect::<Vec<_>>(),
            ["finger_0.obj", "finger_1.obj", "finger_2.obj", "hand.json"]
        );
        let f = &out.record.fingers[0];
        assert!(f.min_edge_length_m > 0.0 && f.min_edge_length_m <= f.max_edge_length_m);
        assert!(f.volume_m3 > 0.0);
        let text = out.record.summary(Path::new("dir"));
        assert!(
            text.ends_with("wrote 3 meshes and hand.json to dir"),
            "{text}"
        );
        assert_eq!(text.lines().count(), 5);
    }
}
