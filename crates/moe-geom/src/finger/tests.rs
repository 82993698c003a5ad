//! Tests of the parametric finger: its mesh, markers, tendons and layouts.

use std::f64::consts::PI;

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
