//! Foxglove message helpers shared by episodes and run files.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::Path;

use foxglove::messages as fg;
use foxglove::{Decode, Encode};
use moe_geom::math::UnitQuat;
use moe_geom::nalgebra;
use moe_geom::{Iso3, Point3, Vector3};

use super::{CameraInfo, ObstacleMesh};
use moe_io::IoError;

/// Colour of contact vertices on true meshes.
pub(crate) const CONTACT_COLOR: [f64; 4] = [0.86, 0.1, 0.1, 1.0];
/// Colour of the other vertices.
pub(crate) const FREE_COLOR: [f64; 4] = [0.75, 0.75, 0.72, 1.0];

pub(crate) fn format_err(path: &Path, message: impl Into<String>) -> IoError {
    IoError::parse(path, None, message)
}

pub(crate) fn mcap_err(path: &Path, e: mcap::McapError) -> IoError {
    IoError::parse(path, None, format!("MCAP: {e}"))
}

pub(crate) fn schema_of<T: Encode>() -> (String, String, Vec<u8>) {
    let s = T::get_schema().expect("Foxglove messages carry their schema");
    (s.name, s.encoding, s.data.into_owned())
}

pub(crate) fn timestamp(time_ns: u64) -> Option<fg::Timestamp> {
    Some(fg::Timestamp::new(
        (time_ns / 1_000_000_000) as u32,
        (time_ns % 1_000_000_000) as u32,
    ))
}

pub(crate) fn fg_point(p: &Point3) -> fg::Point3 {
    fg::Point3 {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

pub(crate) fn fg_quaternion(q: &UnitQuat) -> fg::Quaternion {
    fg::Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

/// A pose at `position` turned by `rotation`.
pub(crate) fn fg_pose(position: &Point3, rotation: &UnitQuat) -> fg::Pose {
    fg::Pose {
        position: Some(fg::Vector3 {
            x: position.x,
            y: position.y,
            z: position.z,
        }),
        orientation: Some(fg_quaternion(rotation)),
    }
}

pub(crate) fn fg_color(c: [f64; 4]) -> Option<fg::Color> {
    Some(fg::Color {
        r: c[0],
        g: c[1],
        b: c[2],
        a: c[3],
    })
}

pub(crate) fn fg_transform(
    time_ns: u64,
    parent: &str,
    child: &str,
    iso: &Iso3,
) -> fg::FrameTransform {
    let t = iso.translation.vector;
    fg::FrameTransform {
        timestamp: timestamp(time_ns),
        parent_frame_id: parent.to_owned(),
        child_frame_id: child.to_owned(),
        translation: Some(fg::Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        rotation: Some(fg_quaternion(&iso.rotation)),
    }
}

pub(crate) fn iso_from(path: &Path, t: &fg::FrameTransform) -> Result<Iso3, IoError> {
    let (Some(v), Some(q)) = (t.translation, t.rotation) else {
        return Err(format_err(
            path,
            format!(
                "transform {}→{} lacks translation or rotation",
                t.parent_frame_id, t.child_frame_id
            ),
        ));
    };
    let rotation = UnitQuat::new_unchecked(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
    Ok(Iso3::from_parts(
        Vector3::new(v.x, v.y, v.z).into(),
        rotation,
    ))
}

pub(crate) fn encode<T: Encode>(message: &T) -> Vec<u8> {
    let mut buf = Vec::new();
    message
        .encode(&mut buf)
        .expect("encoding into a Vec cannot fail");
    buf
}

/// The colour image of a frame as a Foxglove `RawImage` (`rgb8`, frame `camera`).
pub(crate) fn color_image(time_ns: u64, cam: &CameraInfo, rgb8: &[u8]) -> fg::RawImage {
    fg::RawImage {
        timestamp: timestamp(time_ns),
        frame_id: "camera".into(),
        width: cam.width,
        height: cam.height,
        encoding: "rgb8".into(),
        step: 3 * cam.width,
        data: rgb8.to_vec().into(),
    }
}

/// The pinhole calibration of the camera (no distortion).
pub(crate) fn camera_calibration(time_ns: u64, cam: &CameraInfo) -> fg::CameraCalibration {
    fg::CameraCalibration {
        timestamp: timestamp(time_ns),
        frame_id: "camera".into(),
        width: cam.width,
        height: cam.height,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: vec![cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0],
        r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: vec![
            cam.fx, 0.0, cam.cx, 0.0, 0.0, cam.fy, cam.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
    }
}

/// Spheres of diameter `size_m` at `points` (in `frame_id`), one entity.
pub(crate) fn spheres_entity(
    time_ns: u64,
    frame_id: &str,
    id: String,
    points: &[Point3],
    size_m: f64,
    color: [f64; 4],
) -> fg::SceneEntity {
    fg::SceneEntity {
        timestamp: timestamp(time_ns),
        frame_id: frame_id.to_owned(),
        id,
        spheres: points
            .iter()
            .map(|m| fg::SpherePrimitive {
                pose: Some(fg_pose(m, &UnitQuat::identity())),
                size: Some(fg::Vector3 {
                    x: size_m,
                    y: size_m,
                    z: size_m,
                }),
                color: fg_color(color),
            })
            .collect(),
        ..Default::default()
    }
}

pub(crate) fn mesh_entity(
    time_ns: u64,
    frame_id: &str,
    id: String,
    vertices: &[Point3],
    faces: &[[u32; 3]],
    colors: Option<Vec<fg::Color>>,
) -> fg::SceneEntity {
    let triangle = fg::TriangleListPrimitive {
        pose: Some(fg_pose(&Point3::origin(), &UnitQuat::identity())),
        points: vertices.iter().map(fg_point).collect(),
        color: fg_color(FREE_COLOR),
        colors: colors.unwrap_or_default(),
        indices: faces.iter().flatten().copied().collect(),
    };
    fg::SceneEntity {
        timestamp: timestamp(time_ns),
        frame_id: frame_id.to_owned(),
        id,
        triangles: vec![triangle],
        ..Default::default()
    }
}

pub(crate) fn decode<T: Decode>(path: &Path, topic: &str, data: &[u8]) -> Result<T, IoError> {
    T::decode(data).map_err(|e| format_err(path, format!("{topic}: cannot decode: {e}")))
}

pub(crate) fn points_of(tri: &fg::TriangleListPrimitive) -> Vec<Point3> {
    tri.points
        .iter()
        .map(|p| Point3::new(p.x, p.y, p.z))
        .collect()
}

pub(crate) fn faces_of(
    path: &Path,
    topic: &str,
    tri: &fg::TriangleListPrimitive,
) -> Result<Vec<[u32; 3]>, IoError> {
    if !tri.indices.len().is_multiple_of(3) {
        return Err(format_err(
            path,
            format!(
                "{topic}: triangle index count {} is not a multiple of 3",
                tri.indices.len()
            ),
        ));
    }
    Ok(tri.indices.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
}

pub(crate) fn first_triangles<'a>(
    path: &Path,
    topic: &str,
    e: &'a fg::SceneEntity,
) -> Result<&'a fg::TriangleListPrimitive, IoError> {
    e.triangles
        .first()
        .ok_or_else(|| format_err(path, format!("{topic}: entity '{}' has no triangles", e.id)))
}

/// An MCAP writer with the project's settings: one zstd chunk per frame (closed by `flush`, so no
/// size limit), compressed on the writing thread so that the bytes do not depend on the core
/// count. `profile` is the MCAP profile: empty for Foxglove files, `ros2` for rosbag2 storage
/// (which ROS 2 readers require).
pub(crate) fn mcap_writer<W: Write + Seek>(
    sink: W,
    path: &Path,
    profile: &str,
) -> Result<mcap::Writer<W>, IoError> {
    mcap::WriteOptions::new()
        .profile(profile)
        .library("moe-touch")
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .use_chunks(true)
        .chunk_size(None)
        .create(sink)
        .map_err(|e| mcap_err(path, e))
}

/// Adds a channel on `topic` with its schema (name, encoding, data) and message encoding.
pub(crate) fn add_channel<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    path: &Path,
    topic: &str,
    (name, encoding, data): (String, String, Vec<u8>),
    message_encoding: &str,
) -> Result<u16, IoError> {
    let schema = writer
        .add_schema(&name, &encoding, &data)
        .map_err(|e| mcap_err(path, e))?;
    writer
        .add_channel(schema, topic, message_encoding, &BTreeMap::new())
        .map_err(|e| mcap_err(path, e))
}

/// Writes `info` as the one JSON message of `topic` (schema `schema_name`) at time 0 and closes
/// its chunk.
pub(crate) fn write_info<W: Write + Seek, T: serde::Serialize>(
    writer: &mut mcap::Writer<W>,
    path: &Path,
    topic: &str,
    schema_name: &str,
    info: &T,
) -> Result<(), IoError> {
    let schema = (
        schema_name.to_owned(),
        "jsonschema".to_owned(),
        br#"{"type":"object"}"#.to_vec(),
    );
    let channel = add_channel(writer, path, topic, schema, "json")?;
    let body = serde_json::to_vec(info).map_err(|e| format_err(path, e.to_string()))?;
    let header = mcap::records::MessageHeader {
        channel_id: channel,
        sequence: 0,
        log_time: 0,
        publish_time: 0,
    };
    writer
        .write_to_known_channel(&header, &body)
        .map_err(|e| mcap_err(path, e))?;
    writer.flush().map_err(|e| mcap_err(path, e))
}

/// A true mesh of finger `f`: grey, its contact vertices red.
pub(crate) fn contact_mesh_entity(
    time_ns: u64,
    id: String,
    vertices: &[Point3],
    faces: &[[u32; 3]],
    contact_vertices: &[u32],
) -> fg::SceneEntity {
    let mut colors = vec![fg_color(FREE_COLOR).expect("some"); vertices.len()];
    for &v in contact_vertices {
        if let Some(c) = colors.get_mut(v as usize) {
            *c = fg_color(CONTACT_COLOR).expect("some");
        }
    }
    mesh_entity(time_ns, "hand", id, vertices, faces, Some(colors))
}

/// The obstacles' meshes as entities in the world frame.
pub(crate) fn obstacle_entities(time_ns: u64, obstacles: &[ObstacleMesh]) -> Vec<fg::SceneEntity> {
    obstacles
        .iter()
        .map(|o| {
            mesh_entity(
                time_ns,
                "world",
                o.name.clone(),
                &o.vertices_in_world,
                &o.faces,
                None,
            )
        })
        .collect()
}

/// Writes one message of a frame on `channel` and advances the sequence number.
pub(crate) fn write_message<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    path: &Path,
    channel: u16,
    sequence: &mut u32,
    time_ns: u64,
    data: &[u8],
) -> Result<(), IoError> {
    let header = mcap::records::MessageHeader {
        channel_id: channel,
        sequence: *sequence,
        log_time: time_ns,
        publish_time: time_ns,
    };
    writer
        .write_to_known_channel(&header, data)
        .map_err(|e| mcap_err(path, e))?;
    *sequence += 1;
    Ok(())
}
