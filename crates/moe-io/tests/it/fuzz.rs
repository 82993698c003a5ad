//! Fuzz-style robustness: every reader gets every prefix of valid files, byte-flipped copies and
//! random bytes, and must return an error or a valid value — never panic. A panic inside a
//! parser crate would surface as `IoError::ParserPanic` (the readers catch it); that is counted
//! as a failure too, so the crate doc's claim that the parsers did not panic stays checked.

use std::path::Path;

use moe_geom::{Point3, TriMesh};
use moe_io::dataset::{DatasetFrame, DatasetLayout};
use moe_io::{HandConfig, PlyData};

use crate::harness::{Outcome, Reader, from_result, fuzz_readers, run_case};
use crate::{fixture_configs, octahedron};

fn mesh_check(m: &TriMesh) -> Option<String> {
    TriMesh::new(m.vertices().to_vec(), m.faces().to_vec())
        .err()
        .map(|e| format!("invalid mesh returned: {e}"))
}

fn read_obj(b: &[u8]) -> Outcome {
    from_result(moe_io::read_obj_from(b), mesh_check)
}

fn read_stl(b: &[u8]) -> Outcome {
    from_result(moe_io::read_stl_from(b), mesh_check)
}

fn read_ply(b: &[u8]) -> Outcome {
    from_result(moe_io::read_ply_from(b), |d: &PlyData| {
        d.validate(Path::new("fuzz.ply"))
            .err()
            .map(|e| format!("invalid PLY data returned: {e}"))
    })
}

fn read_csv(b: &[u8]) -> Outcome {
    from_result(
        moe_io::csv::read_points_csv_from(b),
        |rows: &Vec<Vec<f64>>| {
            let w = rows.first().map_or(3, Vec::len);
            let ok = (w == 3 || w == 4)
                && rows
                    .iter()
                    .all(|r| r.len() == w && r.iter().all(|x| x.is_finite()));
            (!ok).then(|| "invalid rows returned".to_string())
        },
    )
}

fn read_shard(b: &[u8]) -> Outcome {
    let path = Path::new("fuzz.safetensors");
    from_result(
        moe_io::dataset::parse_shard(path, b),
        |(layout, frames): &(DatasetLayout, Vec<DatasetFrame>)| {
            moe_io::dataset::shard_bytes(path, layout, frames)
                .err()
                .map(|e| format!("a shard that does not re-serialise was returned: {e}"))
        },
    )
}

/// A valid shard of three frames of a small layout.
fn shard_sample() -> Vec<u8> {
    let layout = DatasetLayout {
        finger_num_vertices: vec![3, 2],
        markers_per_finger: vec![1, 1],
        tendons_per_finger: 1,
        object_param_len: 2,
        object_families: vec!["sphere".into(), "plate".into()],
    };
    let frames: Vec<DatasetFrame> = (0..3u32)
        .map(|k| {
            let s = k as f32 * 0.01;
            DatasetFrame {
                trajectory_id: 7,
                frame_index: k,
                vertices: (0..5).map(|i| [i as f32 * 0.01, s, 0.0]).collect(),
                contact: vec![0, 1, 0, 0, u8::from(k == 1)],
                contact_force_n: vec![0.0, 0.02, 0.0, 0.0, 0.5 * s],
                obstacle_distance_m: vec![0.01, -1e-5, 2e-3, f32::INFINITY, 0.0],
                finger_force_n: Some(vec![[0.0, -0.02, 0.0], [0.1 * s, 0.0, -0.5 * s]]),
                markers: vec![[0.0, 0.0, s], [0.01, 0.0, s]],
                world_from_hand: [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0],
                tendon_pull_m: vec![0.001 * k as f32, 0.0],
                object_family: 1,
                object_params: vec![0.02, 0.003],
            }
        })
        .collect();
    moe_io::dataset::shard_bytes(Path::new("s.safetensors"), &layout, &frames).unwrap()
}

fn config_path() -> std::path::PathBuf {
    // Not a real file: only its directory matters, to resolve the finger mesh.
    fixture_configs().join("fuzz-input.toml")
}

fn read_hand_toml(b: &[u8]) -> Outcome {
    let path = config_path();
    let r = moe_io::parse_toml::<HandConfig>(b, &path).and_then(|c| c.build(&path));
    from_result(r, |h| (h.num_fingers() == 0).then(|| "empty hand".into()))
}

fn read_hand_json(b: &[u8]) -> Outcome {
    let path = config_path();
    let r = moe_io::parse_json::<HandConfig>(b, &path).and_then(|c| c.build(&path));
    from_result(r, |h| (h.num_fingers() == 0).then(|| "empty hand".into()))
}

const HAND_TOML: &str = "[[fingers]]\nmesh = \"tiny-finger.obj\"\nmarker_vertices = [7, 13, 19]\n\
    base_vertices = [0, 1, 2, 3, 4, 5, 6]\n\
    tendons = [{ points_in_finger = [[0.005, 0.0, 0.0], [0.005, 0.0, 0.04]], antagonist = 0 }]\n\
    position_m = [0.025, 0.0, 0.0]\nrotation_axis_angle_rad = [0.0, 0.0, 3.14]\n\n\
    [[fingers]]\nparams = { length_m = 0.05, vertex_budget = 40 }\n";

const PRESET_TOML: &str =
    "preset = \"two-finger\"\n[finger]\nlength_m = 0.07\nvertex_budget = 48\n";

fn samples() -> Vec<(&'static str, Reader, Vec<u8>)> {
    let oct = octahedron(0.01);
    let mut colored = PlyData::from_mesh(&oct);
    colored.colors = Some(vec![[10, 20, 30]; 6]);
    colored.scalars = vec![(
        "contact_probability".into(),
        vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0],
    )];
    let ply_le = moe_io::ply_bytes(&colored, Path::new("s.ply")).unwrap();
    let mut ply_be = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\nproperty list uchar uint vertex_indices\n\
        end_header\n"
        .to_vec();
    for x in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        ply_be.extend_from_slice(&x.to_be_bytes());
    }
    ply_be.push(3);
    for i in [0u32, 1, 2] {
        ply_be.extend_from_slice(&i.to_be_bytes());
    }
    let ply_ascii = b"ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty double x\n\
        property double y\nproperty double z\nproperty uchar red\nproperty uchar green\n\
        property uchar blue\nproperty float p\nelement face 2\nproperty list uchar int vertex_indices\n\
        end_header\n0 0 0 1 2 3 0.5\n1 0 0 4 5 6 0.25\n1 1 0 7 8 9 1\n0 1 0 0 0 0 0\n3 0 1 2\n3 0 2 3\n"
        .to_vec();
    let obj_rich = b"# comment\nmtllib x.mtl\no a\nv 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0\n\
        vt 0 0\nvn 0 0 1\ng b\nusemtl m\ns 1\nf 1/1/1 2/1/1 3/1/1 4/1/1\nl 1 2\nv 2 0.5 0\nf -4 -1 -3\n"
        .to_vec();
    let tris: Vec<stl_io::Triangle> = oct
        .faces()
        .iter()
        .map(|f| stl_io::Triangle {
            normal: stl_io::Normal::new([0.0, 0.0, 1.0]),
            vertices: f.map(|i| {
                let p: Point3 = oct.vertices()[i as usize];
                stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32])
            }),
        })
        .collect();
    let mut stl_bin = Vec::new();
    stl_io::write_stl(&mut stl_bin, tris.iter()).unwrap();
    let stl_ascii = b"solid t\nfacet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\n\
        vertex 1 0 0\nendloop\nendfacet\nfacet normal 0 -1 0\nouter loop\nvertex 0 0 0\n\
        vertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\nfacet normal -1 0 0\nouter loop\n\
        vertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\nfacet normal 1 1 1\n\
        outer loop\nvertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid t\n"
        .to_vec();
    let hand: HandConfig = moe_io::parse_toml(HAND_TOML.as_bytes(), Path::new("h.toml")).unwrap();
    let hand_json = serde_json::to_vec_pretty(&hand).unwrap();
    let csv = b"x,y,z,p\n0.1,0.2,0.3,0.5\n-1e-3,2.5e2,0,1\n4,5,6,7\n".to_vec();
    vec![
        ("obj", read_obj as Reader, moe_io::obj_bytes(&oct)),
        ("obj-rich", read_obj, obj_rich),
        ("ply-le", read_ply, ply_le),
        ("ply-be", read_ply, ply_be),
        ("ply-ascii", read_ply, ply_ascii),
        ("stl-binary", read_stl, stl_bin),
        ("stl-ascii", read_stl, stl_ascii),
        ("hand-toml", read_hand_toml, HAND_TOML.as_bytes().to_vec()),
        (
            "preset-toml",
            read_hand_toml,
            PRESET_TOML.as_bytes().to_vec(),
        ),
        ("hand-json", read_hand_json, hand_json),
        ("csv", read_csv, csv),
        ("shard", read_shard, shard_sample()),
    ]
}

#[test]
fn every_reader_survives_truncation_flips_and_garbage() {
    fuzz_readers(0x005E_ED0F_F022, samples());
}

#[test]
fn adversarial_sizes_and_nesting_are_errors() {
    let mut failures = Vec::new();
    let huge_ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n\
        property double x\nproperty double y\nproperty double z\nend_header\n\x00\x01"
        .to_vec();
    let huge_list = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\nproperty list uint uint vertex_indices\n\
        end_header\n\xff\xff\xff\xff"
        .to_vec();
    let mut huge_stl = vec![0u8; 80];
    huge_stl.extend_from_slice(&u32::MAX.to_le_bytes());
    huge_stl.extend_from_slice(&[0u8; 50]);
    let huge_index =
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 18446744073709551615\nf 1 2 -9223372036854775807\n"
            .to_vec();
    let deep_toml = format!("a = {}{}", "[".repeat(100_000), "]".repeat(100_000)).into_bytes();
    let deep_inline = format!("a = {}{}", "{ b = ".repeat(50_000), "}".repeat(50_000)).into_bytes();
    let deep_json = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000)).into_bytes();
    // A safetensors header that declares 2^63 bytes of JSON, and one whose tensor claims a
    // shape of 2^40 frames over the few bytes that follow.
    let mut huge_header = (1u64 << 63).to_le_bytes().to_vec();
    huge_header.extend_from_slice(b"{}");
    let json = r#"{"trajectory_id":{"dtype":"U64","shape":[1099511627776],"data_offsets":[0,8]}}"#;
    let mut huge_shape = (json.len() as u64).to_le_bytes().to_vec();
    huge_shape.extend_from_slice(json.as_bytes());
    huge_shape.extend_from_slice(&[0u8; 8]);
    let cases: Vec<(&str, Reader, Vec<u8>)> = vec![
        ("shard 2^63 header", read_shard, huge_header),
        ("shard 2^40 frames", read_shard, huge_shape),
        ("ply 1e12 vertices", read_ply, huge_ply),
        ("ply 2^32-1 list", read_ply, huge_list),
        ("stl 2^32-1 facets", read_stl, huge_stl),
        ("obj huge index", read_obj, huge_index),
        ("toml deep arrays", read_hand_toml, deep_toml),
        ("toml deep tables", read_hand_toml, deep_inline),
        ("json deep arrays", read_hand_json, deep_json),
    ];
    for (name, reader, input) in cases {
        let accepted = run_case(name, reader, &input, "adversarial", &mut failures);
        assert!(!accepted, "{name} was accepted");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
