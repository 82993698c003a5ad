//! `moe-touch hand`: write a hand model's rest meshes and vertex ids; with `--bound`, the
//! Cramér–Rao bound of a press's place on finger 0 for its marker layout.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::{FingerParams, HandModel, HandPreset, MarkerLayoutPreset, Real, TriMesh, Vector3};
use moe_physics::{
    BoundOptions, HandMaterial, PhysicsConfig, PhysicsEstimator, PlaceBound, RegionBound, Spread,
    region_bounds,
};
use serde::Serialize;

/// Arguments of `moe-touch hand`.
#[derive(Debug, Args)]
pub(crate) struct HandArgs {
    /// Built-in layout: two-finger (facing each other), three-finger (120°) or five-finger.
    #[arg(long, default_value = "two-finger", conflicts_with = "config")]
    preset: HandPreset,
    /// Hand config (TOML or JSON) describing a preset with custom finger parameters, or your own
    /// finger meshes with marker and base vertex ids.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Vertices per parametric finger (preset hands only).
    #[arg(long, default_value_t = FingerParams::default().vertex_budget, conflicts_with = "config")]
    vertex_budget: usize,
    /// Marker layout of every finger (preset hands only; a config sets `marker_layout`):
    /// camera-row (7 on the camera side), two-rows (7 at ±35°), sides (the camera row and 7 at
    /// ±90°) or tip-ring (the camera row and 6 around the finger at 90 % of its length).
    #[arg(long, default_value = "camera-row", conflicts_with = "config")]
    marker_layout: MarkerLayoutPreset,
    /// Also report the Cramér–Rao bound of a press's place along and around finger 0 and of its
    /// force, for its markers (physics model with the default material, zero pulls, gravity
    /// along the hand's −z), per region (tip, middle, base), and write the per-vertex map
    /// `bound_finger_0.ply`.
    #[arg(long)]
    bound: bool,
    /// Force of the press the bound assumes, newtons.
    #[arg(long, value_name = "N", default_value_t = BoundOptions::default().force_n, requires = "bound")]
    bound_force: Real,
    /// Independent frames of a held press (the bound shrinks as one over their square root).
    #[arg(long, value_name = "N", default_value_t = BoundOptions::default().frames as u64,
          value_parser = clap::value_parser!(u64).range(1..=1_000_000), requires = "bound")]
    bound_frames: u64,
    /// Noise of a marker coordinate, metres (default: the perception stage's, 0.16 mm).
    #[arg(long, value_name = "M", default_value_t = BoundOptions::default().marker_sigma_m, requires = "bound")]
    bound_sigma: Real,
    /// Output directory: finger_<i>.obj (rest mesh in the hand frame, metres) and hand.json.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// What `hand.json` holds for one finger.
#[derive(Debug, Serialize)]
struct FingerRecord {
    mesh: String,
    frame: &'static str,
    num_vertices: usize,
    num_faces: usize,
    marker_vertices: Vec<u32>,
    base_vertices: Vec<u32>,
    hand_from_finger_translation_m: [f64; 3],
    hand_from_finger_rotation_xyzw: [f64; 4],
    surface_area_m2: f64,
    volume_m3: f64,
    min_edge_length_m: f64,
    max_edge_length_m: f64,
}

/// `hand.json`, also the `--json` summary.
#[derive(Debug, Serialize)]
struct HandRecord {
    source: String,
    num_fingers: usize,
    total_vertices: usize,
    fingers: Vec<FingerRecord>,
    /// With `--bound`.
    #[serde(skip_serializing_if = "Option::is_none")]
    bound: Option<BoundRecord>,
}

/// `--bound`'s report.
#[derive(Debug, Serialize)]
struct BoundRecord {
    finger: usize,
    marker_layout: String,
    markers: usize,
    force_n: Real,
    frames: usize,
    marker_sigma_m: Real,
    gravity_in_hand_m_s2: [Real; 3],
    pulls: &'static str,
    regions: Vec<RegionBound>,
    map: String,
}

/// Bounds above this (and infinite ones) are written to the map as this many millimetres.
const MAP_CAP_MM: Real = 1000.0;

pub(crate) fn run(args: HandArgs) -> Result<()> {
    let (hand, source, layout) = match &args.config {
        Some(path) => {
            let config: moe_io::HandConfig = moe_io::read_config(path)?;
            let hand = config.build(path)?;
            // Finger 0's layout, as the config gives it.
            let layout = match (&config.finger, config.fingers.first()) {
                (Some(p), _) => p.marker_layout.to_string(),
                (None, Some(f)) => f.params.as_ref().map_or_else(
                    || "the mesh's marker ids".to_owned(),
                    |p| p.marker_layout.to_string(),
                ),
                (None, None) => MarkerLayoutPreset::CameraRow.to_string(),
            };
            (hand, path.display().to_string(), layout)
        }
        None => {
            let params = FingerParams {
                vertex_budget: args.vertex_budget,
                marker_layout: args.marker_layout.layout(),
                ..FingerParams::default()
            };
            let hand = HandModel::preset(args.preset, &params).with_context(|| {
                format!(
                    "building the {} preset with the {} marker layout",
                    args.preset, args.marker_layout
                )
            })?;
            (
                hand,
                args.preset.to_string(),
                args.marker_layout.to_string(),
            )
        }
    };
    // Build every output in memory first, so a failure leaves nothing half-written.
    let mut meshes = Vec::with_capacity(hand.num_fingers());
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for (i, f) in hand.fingers().iter().enumerate() {
        let mesh = f
            .model
            .mesh()
            .with_vertices(hand.rest_vertices_in_hand(i))?;
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
        });
        meshes.push(mesh);
    }
    let (bound, bound_map) = if args.bound {
        let options = BoundOptions {
            force_n: args.bound_force,
            marker_sigma_m: args.bound_sigma,
            frames: args.bound_frames as usize,
        };
        let (record, ply) = finger_bound(&hand, &meshes[0], &options, layout)?;
        (Some(record), Some(ply))
    } else {
        (None, None)
    };
    let record = HandRecord {
        source,
        num_fingers: hand.num_fingers(),
        total_vertices: hand.num_vertices(),
        fingers,
        bound,
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output directory {}", args.out.display()))?;
    for (mesh, f) in meshes.iter().zip(&record.fingers) {
        moe_io::write_mesh(&args.out.join(&f.mesh), mesh)?;
    }
    if let (Some(b), Some(ply)) = (&record.bound, &bound_map) {
        moe_io::write_ply(&args.out.join(&b.map), ply)?;
    }
    moe_io::write_json(&args.out.join("hand.json"), &record)?;
    if args.json {
        super::print_json(&record)?;
    } else {
        super::outln!(
            "hand '{}': {} fingers, {} vertices in total",
            record.source,
            record.num_fingers,
            record.total_vertices
        );
        for (i, f) in record.fingers.iter().enumerate() {
            super::outln!(
                "  finger {i}: {} vertices, {} faces, {} markers, {} base vertices, area {:.1} cm², \
                 volume {:.2} cm³, edges {:.2}–{:.2} mm",
                f.num_vertices,
                f.num_faces,
                f.marker_vertices.len(),
                f.base_vertices.len(),
                f.surface_area_m2 * 1e4,
                f.volume_m3 * 1e6,
                f.min_edge_length_m * 1e3,
                f.max_edge_length_m * 1e3
            );
        }
        if let Some(b) = &record.bound {
            print_bound(b);
        }
        super::outln!(
            "wrote {} meshes{} and hand.json to {}",
            record.num_fingers,
            record
                .bound
                .as_ref()
                .map_or(String::new(), |b| format!(", {}", b.map)),
            args.out.display()
        );
    }
    Ok(())
}

fn print_bound(b: &BoundRecord) {
    super::outln!(
        "Cramér–Rao bound of a press on finger {} ({} markers, layout {}): {:.2} N along the \
         inward normal, {} frame(s), marker noise {:.3} mm per coordinate, zero pulls, gravity \
         along the hand's −z",
        b.finger,
        b.markers,
        b.marker_layout,
        b.force_n,
        b.frames,
        b.marker_sigma_m * 1e3
    );
    super::outln!(
        "  {:<20} {:>8} {:>22} {:>22} {:>22}",
        "region (z / length)",
        "vertices",
        "along mm (med / p90)",
        "around mm (med / p90)",
        "force sd N (med / p90)"
    );
    for r in &b.regions {
        let pair = |s: Spread, digits: usize| format!("{:.digits$} / {:.digits$}", s.median, s.p90);
        super::outln!(
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
        );
    }
}

/// The bound of finger 0 of `hand` (whose rest mesh in the hand frame is `mesh`): the report
/// and the per-vertex map.
fn finger_bound(
    hand: &HandModel,
    mesh: &TriMesh,
    options: &BoundOptions,
    marker_layout: String,
) -> Result<(BoundRecord, moe_io::PlyData)> {
    let finger = hand.fingers()[0].clone();
    let model = finger.model.clone();
    // The bound needs finger 0's model only.
    let one = HandModel::new(vec![finger])?;
    let config = PhysicsConfig::default();
    let mut estimator = PhysicsEstimator::new(&one, &HandMaterial::default(), &config)
        .context("building finger 0's physics model")?;
    let g = Vector3::from(config.gravity_m_s2).norm();
    let gravity = Vector3::new(0.0, 0.0, -g);
    let pulls = vec![0.0; model.tendon_routes().len()];
    let bounds = estimator
        .location_bounds(0, &pulls, gravity, options)
        .context("the Cramér–Rao bound of finger 0")?;
    let rest = model.mesh().vertices();
    let length = rest.iter().map(|p| p.z).fold(Real::MIN, Real::max);
    let regions = region_bounds(&bounds, length);
    let map = "bound_finger_0.ply".to_owned();
    let ply = bound_map(mesh, model.marker_vertices(), &bounds);
    let record = BoundRecord {
        finger: 0,
        marker_layout,
        markers: model.marker_vertices().len(),
        force_n: options.force_n,
        frames: options.frames,
        marker_sigma_m: options.marker_sigma_m,
        gravity_in_hand_m_s2: gravity.into(),
        pulls: "zero",
        regions,
        map,
    };
    Ok((record, ply))
}

/// Finger 0's rest mesh (hand frame) with the bound per vertex: scalars `bound_along_mm`,
/// `bound_around_mm`, `bound_force_sd_n` (0 on the vertices fixed to the palm, which no press
/// moves; infinite bounds written as [`MAP_CAP_MM`] mm, or as many newtons), `movable` (1 or
/// 0) and `marker` (1 on marker vertices), and colours: the along bound on a log ramp from
/// 0.5 mm (dark blue) to 50 mm and beyond (yellow) (a fixed range, unlike `moe-touch eval
/// observability`'s figure, whose range follows the data), markers black, fixed vertices grey.
fn bound_map(mesh: &TriMesh, markers: &[u32], bounds: &[PlaceBound]) -> moe_io::PlyData {
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
    let mut ply = moe_io::PlyData::from_mesh(mesh)
        .with_scalar("bound_along_mm", along)
        .with_scalar("bound_around_mm", around)
        .with_scalar("bound_force_sd_n", force)
        .with_scalar("movable", movable)
        .with_scalar("marker", is_marker);
    ply.colors = Some(colors);
    ply
}

fn edge_length_range(mesh: &TriMesh) -> (f64, f64) {
    let topo = moe_geom::Topology::new(mesh);
    topo.edges()
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &[a, b]| {
            let l = (mesh.vertices()[a as usize] - mesh.vertices()[b as usize]).norm();
            (lo.min(l), hi.max(l))
        })
}
