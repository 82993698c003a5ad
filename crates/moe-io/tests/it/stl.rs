//! STL (ascii and binary) read and welded into the indexed mesh it was exported from.

use std::collections::HashMap;

use moe_geom::{Point3, TriMesh};
use moe_io::{read_mesh, read_stl, read_stl_from};

use crate::{finger_mesh, scratch};

/// The mesh an STL export of `mesh` must weld back to: vertices rounded to `f32`, numbered by
/// first appearance in face order.
fn expected_after_stl(mesh: &TriMesh) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let mut map = HashMap::new();
    let mut vertices = Vec::new();
    let faces = mesh
        .faces()
        .iter()
        .map(|f| {
            f.map(|i| {
                *map.entry(i).or_insert_with(|| {
                    let p = mesh.vertices()[i as usize];
                    vertices.push(Point3::new(
                        f64::from(p.x as f32),
                        f64::from(p.y as f32),
                        f64::from(p.z as f32),
                    ));
                    (vertices.len() - 1) as u32
                })
            })
        })
        .collect();
    (vertices, faces)
}

fn triangles(mesh: &TriMesh) -> Vec<stl_io::Triangle> {
    let normals = mesh.face_normals();
    mesh.faces()
        .iter()
        .zip(normals)
        .map(|(f, n)| stl_io::Triangle {
            normal: stl_io::Normal::new([n.x as f32, n.y as f32, n.z as f32]),
            vertices: f.map(|i| {
                let p = mesh.vertices()[i as usize];
                stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32])
            }),
        })
        .collect()
}

fn ascii_stl(mesh: &TriMesh) -> String {
    let mut s = String::from("solid finger\n");
    for t in triangles(mesh) {
        s += &format!(
            "  facet normal {:e} {:e} {:e}\n    outer loop\n",
            t.normal[0], t.normal[1], t.normal[2]
        );
        for v in t.vertices {
            s += &format!("      vertex {:?} {:?} {:?}\n", v[0], v[1], v[2]);
        }
        s += "    endloop\n  endfacet\n";
    }
    s + "endsolid finger\n"
}

#[test]
fn binary_and_ascii_stl_weld_back_to_the_indexed_mesh() {
    let mesh = finger_mesh(400);
    let (v, f) = expected_after_stl(&mesh);
    let dir = scratch("stl");

    let mut binary = Vec::new();
    stl_io::write_stl(&mut binary, triangles(&mesh).iter()).unwrap();
    std::fs::write(dir.join("b.stl"), &binary).unwrap();
    std::fs::write(dir.join("a.STL"), ascii_stl(&mesh)).unwrap();
    for name in ["b.stl", "a.STL"] {
        let m = read_mesh(&dir.join(name)).unwrap();
        assert_eq!(m.num_vertices(), mesh.num_vertices(), "{name}");
        assert_eq!(m.vertices(), v.as_slice(), "{name}");
        assert_eq!(m.faces(), f.as_slice(), "{name}");
        m.require_closed().unwrap();
        let rel = (m.signed_volume() - mesh.signed_volume()).abs() / mesh.signed_volume();
        assert!(rel < 1e-5, "{name}: volume differs by {rel:e}");
    }
    assert_eq!(
        read_stl(&dir.join("b.stl")).unwrap(),
        read_stl_from(binary.as_slice()).unwrap()
    );
}

#[test]
fn corners_one_ulp_apart_are_welded() {
    // A tetrahedron whose last facet writes vertex (1, 0, 0) one f32 ulp off.
    let off = f32::from_bits(1.0f32.to_bits() + 1);
    let text = format!(
        "solid t\n\
         facet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\n\
         facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n\
         facet normal -1 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\n\
         facet normal 1 1 1\nouter loop\nvertex {off:?} 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\n\
         endsolid t\n"
    );
    let m = read_stl_from(text.as_bytes()).unwrap();
    assert_eq!(m.num_vertices(), 4);
    m.require_closed().unwrap();
}
