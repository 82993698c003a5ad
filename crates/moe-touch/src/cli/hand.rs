//! `moe-touch hand`: write a hand model's rest meshes and vertex ids.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::{FingerParams, HandModel, HandPreset, TriMesh};
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
}

pub(crate) fn run(args: HandArgs) -> Result<()> {
    let (hand, source) = match &args.config {
        Some(path) => (moe_io::load_hand_config(path)?, path.display().to_string()),
        None => {
            let params = FingerParams {
                vertex_budget: args.vertex_budget,
                ..FingerParams::default()
            };
            let hand = HandModel::preset(args.preset, &params)
                .with_context(|| format!("building the {} preset", args.preset))?;
            (hand, args.preset.to_string())
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
    let record = HandRecord {
        source,
        num_fingers: hand.num_fingers(),
        total_vertices: hand.num_vertices(),
        fingers,
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output directory {}", args.out.display()))?;
    for (mesh, f) in meshes.iter().zip(&record.fingers) {
        moe_io::write_mesh(&args.out.join(&f.mesh), mesh)?;
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
        super::outln!(
            "wrote {} meshes and hand.json to {}",
            record.num_fingers,
            args.out.display()
        );
    }
    Ok(())
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
