//! Exact write → read round trips through real files.

use moe_geom::{GeomError, Point3, TriMesh};
use moe_io::{PlyData, read_mesh, read_obj, read_ply, write_mesh, write_obj, write_ply};
use proptest::prelude::*;

use crate::{assert_bit_exact, finger_mesh, octahedron, scratch};

#[test]
fn finger_mesh_round_trips_exactly_through_obj_and_ply() {
    let dir = scratch("finger-round-trip");
    let mesh = finger_mesh(500);
    for name in ["f.obj", "f.ply", "F.OBJ"] {
        let path = dir.join(name);
        write_mesh(&path, &mesh).unwrap();
        let back = read_mesh(&path).unwrap();
        assert_bit_exact(mesh.vertices(), back.vertices());
        assert_eq!(mesh.faces(), back.faces(), "{name}");
    }
    // Rotated vertex coordinates have full 53-bit mantissas: still exact.
    let rot = moe_geom::Iso3::new(
        moe_geom::Vector3::new(0.01, -0.02, 0.3),
        moe_geom::Vector3::new(0.3, -1.1, 0.7),
    );
    let moved = mesh
        .with_vertices(mesh.vertices().iter().map(|p| rot * p).collect())
        .unwrap();
    write_obj(&dir.join("m.obj"), &moved).unwrap();
    assert_bit_exact(
        moved.vertices(),
        read_obj(&dir.join("m.obj")).unwrap().vertices(),
    );
}

#[test]
fn ply_colours_scalars_and_point_clouds_round_trip() {
    let dir = scratch("ply-round-trip");
    let mesh = finger_mesh(300);
    let n = mesh.num_vertices();
    let mut data = PlyData::from_mesh(&mesh);
    data.colors = Some(
        (0..n)
            .map(|i| [i as u8, (i * 7) as u8, 255 - i as u8])
            .collect(),
    );
    data.scalars = vec![
        (
            "contact_probability".into(),
            (0..n).map(|i| i as f32 / n as f32).collect(),
        ),
        (
            "signed_distance".into(),
            (0..n).map(|i| (i as f32).sin() * 1e-3).collect(),
        ),
    ];
    write_ply(&dir.join("c.ply"), &data).unwrap();
    let back = read_ply(&dir.join("c.ply")).unwrap();
    assert_eq!(back, data);
    assert_bit_exact(&data.points, &back.points);
    assert_eq!(back.into_mesh().unwrap(), mesh);

    // Contact points: no faces.
    let cloud = PlyData {
        points: vec![Point3::new(0.01, 0.02, 0.03), Point3::new(-1e-9, 0.5, 2.0)],
        scalars: vec![("contact_probability".into(), vec![0.9, 0.1])],
        ..PlyData::default()
    };
    write_ply(&dir.join("p.ply"), &cloud).unwrap();
    assert_eq!(read_ply(&dir.join("p.ply")).unwrap(), cloud);
    moe_geom::assert_err!(
        read_mesh(&dir.join("p.ply")),
        moe_io::IoError::Geometry {
            path,
            source: GeomError::EmptyMesh {
                vertices: 2,
                faces: 0
            }
        } if *path == dir.join("p.ply"),
        "a point cloud is not a mesh"
    );
}

#[test]
fn csv_tables_round_trip_exactly_through_files() {
    let dir = scratch("csv");
    let rows: Vec<Vec<f64>> = (0..50)
        .map(|i| {
            let t = f64::from(i) * 0.37;
            vec![t.sin() * 0.01, t.cos() / 3.0, -t * 1e-5, (t * 7.0).fract()]
        })
        .collect();
    moe_io::write_csv(&dir.join("p.csv"), &["x", "y", "z", "p"], &rows).unwrap();
    assert_eq!(moe_io::read_points_csv(&dir.join("p.csv")).unwrap(), rows);
    let table = moe_io::read_csv(&dir.join("p.csv")).unwrap();
    assert_eq!(table.header.unwrap(), vec!["x", "y", "z", "p"]);
    // Two columns are not points.
    moe_io::write_csv(&dir.join("t.csv"), &[], &[vec![1.0, 2.0]]).unwrap();
    let e = moe_io::read_points_csv(&dir.join("t.csv")).unwrap_err();
    assert!(e.to_string().contains("t.csv"), "{e}");
}

#[test]
fn unsupported_extensions_are_rejected_naming_the_path() {
    let dir = scratch("extensions");
    let mesh = octahedron(1.0);
    let e = write_mesh(&dir.join("m.stl"), &mesh).unwrap_err();
    assert!(
        matches!(e, moe_io::IoError::UnsupportedExtension { .. }),
        "{e}"
    );
    assert!(e.to_string().contains("m.stl"), "{e}");
    moe_geom::assert_err!(
        read_mesh(&dir.join("m.off")),
        moe_io::IoError::UnsupportedExtension { path, ext, .. }
            if *path == dir.join("m.off") && ext == "off"
    );
    moe_geom::assert_err!(
        read_mesh(&dir.join("missing.obj")),
        moe_io::IoError::Io { path, source }
            if *path == dir.join("missing.obj") && source.kind() == std::io::ErrorKind::NotFound
    );
    assert!(crate::entries(&dir).is_empty());
}

/// A mesh with arbitrary coordinates: the octahedron scaled by 10^exp, each coordinate
/// perturbed by a relative amount so every mantissa bit is exercised.
fn arbitrary_mesh() -> impl Strategy<Value = TriMesh> {
    (
        -8i32..8,
        proptest::collection::vec(-1e-3f64..1e-3, 18),
        proptest::bool::ANY,
    )
        .prop_map(|(exp, noise, flip)| {
            let base = octahedron(10f64.powi(exp));
            let v: Vec<Point3> = base
                .vertices()
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let s = 10f64.powi(exp);
                    Point3::new(
                        p.x + s * noise[3 * i],
                        p.y + s * noise[3 * i + 1],
                        p.z + s * noise[3 * i + 2],
                    )
                })
                .collect();
            let m = TriMesh::new(v, base.faces().to_vec()).expect("perturbed octahedron");
            if flip { m.flipped() } else { m }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn obj_and_ply_round_trips_are_bit_exact(mesh in arbitrary_mesh()) {
        let obj = moe_io::obj_bytes(&mesh);
        let back = moe_io::read_obj_from(obj.as_slice()).unwrap();
        assert_bit_exact(mesh.vertices(), back.vertices());
        prop_assert_eq!(mesh.faces(), back.faces());

        let ply = moe_io::ply_bytes(&PlyData::from_mesh(&mesh), std::path::Path::new("m.ply")).unwrap();
        let back = moe_io::read_ply_from(ply.as_slice()).unwrap();
        assert_bit_exact(mesh.vertices(), &back.points);
        prop_assert_eq!(mesh.faces(), back.faces.as_slice());
    }
}
