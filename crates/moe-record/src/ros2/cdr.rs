//! The ROS 2 messages a wrist-camera recording carries, decoded from CDR, the serialisation of
//! ROS 2 (DDS) messages and of rosbag2's MCAP storage.
//!
//! A message is a 4-byte encapsulation header (`00 01`: little-endian plain CDR, `00 00`:
//! big-endian; two option bytes) and then its fields in declaration order, each primitive
//! aligned to its own size counted from the end of the header; strings are a `u32` length that
//! counts a terminating NUL, then the bytes; sequences are a `u32` count, then the elements.
//! XCDR2 and parameter-list encodings are refused by name (ROS 2 does not write them).
//!
//! The decoder is written for these message types (the four a recording carries, and the two
//! results `moe-touch run --ros-out` writes) rather than generic: every declared
//! length is checked against the bytes that remain before anything is allocated (a corrupt
//! count cannot make it reserve gigabytes), image data is borrowed, not copied, and every error
//! names the field and the byte offset.

use std::fmt;

/// A message that does not decode: which field, where, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CdrError {
    /// The field being read (`header.frame_id`, `data`, ...).
    pub field: &'static str,
    /// Byte offset in the message (header included).
    pub offset: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for CdrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} at byte {}: {}",
            self.field, self.offset, self.message
        )
    }
}

impl std::error::Error for CdrError {}

/// Reads the fields of one CDR message in order.
#[derive(Debug)]
pub struct CdrReader<'a> {
    bytes: &'a [u8],
    at: usize,
    little: bool,
}

/// Size of the encapsulation header; alignment counts from its end.
const HEADER: usize = 4;

impl<'a> CdrReader<'a> {
    /// A reader after the encapsulation header of `bytes`.
    ///
    /// # Errors
    /// A message shorter than its header, or an encapsulation other than plain CDR.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let Some(head) = bytes.get(..HEADER) else {
            return Err(CdrError {
                field: "encapsulation header",
                offset: 0,
                message: format!("{} bytes, a message has at least 4", bytes.len()),
            });
        };
        let little = match [head[0], head[1]] {
            [0, 1] => true,
            [0, 0] => false,
            [0, 2 | 3] => return Err(encapsulation("parameter-list CDR")),
            [0, 6..=11] => return Err(encapsulation("XCDR2")),
            other => return Err(encapsulation(&format!("unknown identifier {other:02x?}"))),
        };
        Ok(Self {
            bytes,
            at: HEADER,
            little,
        })
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }

    fn error(&self, field: &'static str, message: impl Into<String>) -> CdrError {
        CdrError {
            field,
            offset: self.at,
            message: message.into(),
        }
    }

    fn align(&mut self, n: usize) {
        let pad = (n - (self.at - HEADER) % n) % n;
        self.at = (self.at + pad).min(self.bytes.len());
    }

    fn take<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        self.align(N);
        let b = self.bytes.get(self.at..self.at + N).ok_or_else(|| {
            self.error(
                field,
                format!("needs {N} bytes, {} remain", self.remaining()),
            )
        })?;
        self.at += N;
        let mut out = [0; N];
        out.copy_from_slice(b);
        if !self.little {
            out.reverse();
        }
        Ok(out)
    }

    /// A `uint8` (or `bool`, `char`).
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take::<1>(field)?[0])
    }

    /// A `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.take(field)?))
    }

    /// An `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.take(field)?))
    }

    /// A `float32`.
    pub fn f32(&mut self, field: &'static str) -> Result<f32, CdrError> {
        Ok(f32::from_le_bytes(self.take(field)?))
    }

    /// A `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.take(field)?))
    }

    /// A count of `element_bytes`-byte elements that must fit in what remains.
    fn count(&mut self, field: &'static str, element_bytes: usize) -> Result<usize, CdrError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(element_bytes.max(1)) > self.remaining() {
            return Err(self.error(
                field,
                format!(
                    "declares {n} elements of {element_bytes} bytes, {} bytes remain",
                    self.remaining()
                ),
            ));
        }
        Ok(n)
    }

    /// A `string`: UTF-8, NUL-terminated in the message.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.count(field, 1)?;
        let bytes = &self.bytes[self.at..self.at + n];
        let text = match bytes.split_last() {
            Some((0, text)) => text,
            _ => return Err(self.error(field, "a string without its terminating NUL")),
        };
        let s = std::str::from_utf8(text)
            .map_err(|e| self.error(field, format!("not UTF-8: {e}")))?
            .to_owned();
        self.at += n;
        Ok(s)
    }

    /// A `uint8[]`, borrowed.
    pub fn bytes(&mut self, field: &'static str) -> Result<&'a [u8], CdrError> {
        let n = self.count(field, 1)?;
        let out = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(out)
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, field: &'static str) -> Result<Vec<f64>, CdrError> {
        let n = self.count(field, 8)?;
        (0..n).map(|_| self.f64(field)).collect()
    }

    /// A `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// A `string[]`.
    pub fn string_seq(&mut self, field: &'static str) -> Result<Vec<String>, CdrError> {
        // Every string takes at least its 4-byte length and its NUL.
        let n = self.count(field, 5)?;
        (0..n).map(|_| self.string(field)).collect()
    }
}

fn encapsulation(what: &str) -> CdrError {
    CdrError {
        field: "encapsulation header",
        offset: 0,
        message: format!("{what} is not read (ROS 2 writes plain CDR)"),
    }
}

/// `builtin_interfaces/Time` as nanoseconds since the epoch.
fn time(r: &mut CdrReader<'_>) -> Result<i64, CdrError> {
    let sec = r.i32("header.stamp.sec")?;
    let nanosec = r.u32("header.stamp.nanosec")?;
    if nanosec >= 1_000_000_000 {
        return Err(r.error(
            "header.stamp.nanosec",
            format!("{nanosec} is not below 10^9"),
        ));
    }
    Ok(i64::from(sec) * 1_000_000_000 + i64::from(nanosec))
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    /// Stamp, nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// The frame the data is in.
    pub frame_id: String,
}

impl Header {
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            stamp_ns: time(r)?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

/// `sensor_msgs/Image`, its pixels borrowed from the message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image<'a> {
    /// Header.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `rgb8`, `bgr8`, `16UC1`, `32FC1`, ...
    pub encoding: String,
    /// Whether multi-byte pixels are big-endian.
    pub is_bigendian: bool,
    /// Bytes per row.
    pub step: u32,
    /// `step × height` bytes.
    pub data: &'a [u8],
}

/// Decodes a `sensor_msgs/msg/Image`.
///
/// # Errors
/// A field that does not decode, or data of another size than `step × height`.
pub fn image(bytes: &[u8]) -> Result<Image<'_>, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    let header = Header::read(&mut r)?;
    let height = r.u32("height")?;
    let width = r.u32("width")?;
    let encoding = r.string("encoding")?;
    let is_bigendian = r.u8("is_bigendian")? != 0;
    let step = r.u32("step")?;
    let data = r.bytes("data")?;
    if data.len() as u64 != u64::from(step) * u64::from(height) {
        return Err(r.error(
            "data",
            format!("{} bytes for {height} rows of {step}", data.len()),
        ));
    }
    Ok(Image {
        header,
        height,
        width,
        encoding,
        is_bigendian,
        step,
        data,
    })
}

/// `sensor_msgs/CameraInfo`: what the pipeline uses of it.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    /// Header.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `plumb_bob`, `rational_polynomial`, ... (empty: none).
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Intrinsic matrix, row-major: `[fx 0 cx; 0 fy cy; 0 0 1]`.
    pub k: [f64; 9],
}

/// Decodes a `sensor_msgs/msg/CameraInfo` (the rectification, projection, binning and region of
/// interest are read and checked, not kept).
///
/// # Errors
/// A field that does not decode.
pub fn camera_info(bytes: &[u8]) -> Result<CameraInfo, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    let header = Header::read(&mut r)?;
    let height = r.u32("height")?;
    let width = r.u32("width")?;
    let distortion_model = r.string("distortion_model")?;
    let d = r.f64_seq("d")?;
    let k = r.f64_array::<9>("k")?;
    r.f64_array::<9>("r")?;
    r.f64_array::<12>("p")?;
    r.u32("binning_x")?;
    r.u32("binning_y")?;
    for field in ["roi.x_offset", "roi.y_offset", "roi.height", "roi.width"] {
        r.u32(field)?;
    }
    r.u8("roi.do_rectify")?;
    Ok(CameraInfo {
        header,
        height,
        width,
        distortion_model,
        d,
        k,
    })
}

/// One `geometry_msgs/TransformStamped`: `header.frame_id` from `child_frame_id`.
#[derive(Debug, Clone, PartialEq)]
pub struct TransformStamped {
    /// Header (`frame_id`: the parent frame).
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Rotation quaternion `x, y, z, w`.
    pub rotation_xyzw: [f64; 4],
}

/// Decodes a `tf2_msgs/msg/TFMessage`.
///
/// # Errors
/// A field that does not decode.
pub fn tf_message(bytes: &[u8]) -> Result<Vec<TransformStamped>, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    // A transform takes at least 8 (stamp) + 2 × 5 (strings) + 7 × 8 bytes.
    let n = r.count("transforms", 74)?;
    (0..n)
        .map(|_| {
            Ok(TransformStamped {
                header: Header::read(&mut r)?,
                child_frame_id: r.string("child_frame_id")?,
                translation: r.f64_array::<3>("transform.translation")?,
                rotation_xyzw: r.f64_array::<4>("transform.rotation")?,
            })
        })
        .collect()
}

/// `sensor_msgs/JointState`.
#[derive(Debug, Clone, PartialEq)]
pub struct JointState {
    /// Header.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (for a tendon: its pulled length, metres).
    pub position: Vec<f64>,
    /// Velocities.
    pub velocity: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
}

/// Decodes a `sensor_msgs/msg/JointState`.
///
/// # Errors
/// A field that does not decode.
pub fn joint_state(bytes: &[u8]) -> Result<JointState, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    Ok(JointState {
        header: Header::read(&mut r)?,
        name: r.string_seq("name")?,
        position: r.f64_seq("position")?,
        velocity: r.f64_seq("velocity")?,
        effort: r.f64_seq("effort")?,
    })
}

/// `geometry_msgs/WrenchStamped`.
#[derive(Debug, Clone, PartialEq)]
pub struct WrenchStamped {
    /// Header.
    pub header: Header,
    /// Force, newtons.
    pub force: [f64; 3],
    /// Torque, newton-metres.
    pub torque: [f64; 3],
}

/// Decodes a `geometry_msgs/msg/WrenchStamped` (what `moe-touch run --ros-out` writes per
/// finger).
///
/// # Errors
/// A field that does not decode.
pub fn wrench_stamped(bytes: &[u8]) -> Result<WrenchStamped, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    Ok(WrenchStamped {
        header: Header::read(&mut r)?,
        force: r.f64_array::<3>("wrench.force")?,
        torque: r.f64_array::<3>("wrench.torque")?,
    })
}

/// A `visualization_msgs/Marker` (ROS 2 Jazzy's definition), the fields a result uses; the
/// texture, UV coordinates, text and mesh fields are read past.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Header (the frame the points are in).
    pub header: Header,
    /// Namespace.
    pub ns: String,
    /// Id within the namespace.
    pub id: i32,
    /// Type (`ARROW` 0, `SPHERE_LIST` 7, `POINTS` 8, ...).
    pub kind: i32,
    /// Action (`ADD` 0, `DELETE` 2, `DELETEALL` 3).
    pub action: i32,
    /// Pose: position then orientation `x, y, z, w`.
    pub pose: [f64; 7],
    /// Scale.
    pub scale: [f64; 3],
    /// Colour, RGBA in `[0, 1]`.
    pub color: [f32; 4],
    /// Points.
    pub points: Vec<[f64; 3]>,
    /// Per-point colours.
    pub colors: Vec<[f32; 4]>,
}

impl Marker {
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read(r)?;
        let ns = r.string("ns")?;
        let id = r.i32("id")?;
        let kind = r.i32("type")?;
        let action = r.i32("action")?;
        let pose = r.f64_array::<7>("pose")?;
        let scale = r.f64_array::<3>("scale")?;
        let mut color = [0.0; 4];
        for c in &mut color {
            *c = r.f32("color")?;
        }
        r.i32("lifetime.sec")?;
        r.u32("lifetime.nanosec")?;
        r.u8("frame_locked")?;
        let n = r.count("points", 24)?;
        let points = (0..n)
            .map(|_| r.f64_array::<3>("points"))
            .collect::<Result<_, _>>()?;
        let n = r.count("colors", 16)?;
        let colors = (0..n)
            .map(|_| {
                let mut c = [0.0; 4];
                for v in &mut c {
                    *v = r.f32("colors")?;
                }
                Ok(c)
            })
            .collect::<Result<_, _>>()?;
        r.string("texture_resource")?;
        Header::read(r)?;
        r.string("texture.format")?;
        r.bytes("texture.data")?;
        let n = r.count("uv_coordinates", 8)?;
        for _ in 0..n {
            r.f32("uv_coordinates")?;
            r.f32("uv_coordinates")?;
        }
        r.string("text")?;
        r.string("mesh_resource")?;
        r.string("mesh_file.filename")?;
        r.bytes("mesh_file.data")?;
        r.u8("mesh_use_embedded_materials")?;
        Ok(Self {
            header,
            ns,
            id,
            kind,
            action,
            pose,
            scale,
            color,
            points,
            colors,
        })
    }
}

/// Decodes a `visualization_msgs/msg/MarkerArray` (ROS 2 Jazzy's `Marker`).
///
/// # Errors
/// A field that does not decode.
pub fn marker_array(bytes: &[u8]) -> Result<Vec<Marker>, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    // A marker takes well over 100 bytes; 100 bounds the count.
    let n = r.count("markers", 100)?;
    (0..n).map(|_| Marker::read(&mut r)).collect()
}

/// Writes CDR messages (little-endian): episodes and results written as ROS 2 recordings, and
/// test messages.
#[derive(Debug, Default)]
pub struct CdrWriter {
    bytes: Vec<u8>,
}

impl CdrWriter {
    /// A message with the little-endian plain-CDR header.
    pub fn new() -> Self {
        Self {
            bytes: vec![0, 1, 0, 0],
        }
    }

    fn align(&mut self, n: usize) {
        while !(self.bytes.len() - HEADER).is_multiple_of(n) {
            self.bytes.push(0);
        }
    }

    /// A primitive of `N` bytes, aligned to its size (the reader's `take::<N>` backwards).
    fn put<const N: usize>(&mut self, bytes: [u8; N]) -> &mut Self {
        self.align(N);
        self.bytes.extend_from_slice(&bytes);
        self
    }

    /// A `uint8`.
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// A `float32`.
    pub fn f32(&mut self, v: f32) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(0);
        self
    }

    /// A `uint8[]`.
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u32(b.len() as u32);
        self.bytes.extend_from_slice(b);
        self
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, v: &[f64]) -> &mut Self {
        self.u32(v.len() as u32);
        for &x in v {
            self.f64(x);
        }
        self
    }

    /// A `std_msgs/Header`.
    pub fn header(&mut self, stamp_ns: i64, frame_id: &str) -> &mut Self {
        self.i32(stamp_ns.div_euclid(1_000_000_000) as i32);
        self.u32(stamp_ns.rem_euclid(1_000_000_000) as u32);
        self.string(frame_id)
    }

    /// The message.
    pub fn finish(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image_bytes(data: &[u8]) -> Vec<u8> {
        CdrWriter::new()
            .header(1_500_000_123, "camera_color_optical_frame")
            .u32(2)
            .u32(3)
            .string("rgb8")
            .u8(0)
            .u32(9)
            .bytes(data)
            .finish()
    }

    #[test]
    fn an_image_round_trips_and_borrows_its_pixels() {
        let data: Vec<u8> = (0..18).collect();
        let bytes = image_bytes(&data);
        let im = image(&bytes).unwrap();
        assert_eq!(im.header.stamp_ns, 1_500_000_123);
        assert_eq!(im.header.frame_id, "camera_color_optical_frame");
        assert_eq!((im.height, im.width, im.step), (2, 3, 9));
        assert_eq!(im.encoding, "rgb8");
        assert_eq!(im.data, &data[..]);
        assert!(std::ptr::eq(im.data.as_ptr(), &bytes[bytes.len() - 18]));
    }

    #[test]
    fn camera_info_tf_and_joint_states_round_trip() {
        let mut w = CdrWriter::new();
        w.header(7, "cam").u32(240).u32(320).string("plumb_bob");
        w.f64_seq(&[0.1, -0.2, 0.0, 0.0, 0.0]);
        let k = [190.0, 0.0, 159.5, 0.0, 190.0, 119.5, 0.0, 0.0, 1.0];
        for v in k.iter().chain(&[0.0; 9]).chain(&[0.0; 12]) {
            w.f64(*v);
        }
        w.u32(0).u32(0).u32(0).u32(0).u32(0).u32(0).u8(0);
        let info = camera_info(&w.finish()).unwrap();
        assert_eq!((info.width, info.height), (320, 240));
        assert_eq!(info.k, k);
        assert_eq!(info.d.len(), 5);

        let mut w = CdrWriter::new();
        w.u32(2);
        for (parent, child, x) in [("world", "hand", 0.5), ("hand", "camera", -0.25)] {
            w.header(-1, parent).string(child);
            for v in [x, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] {
                w.f64(v);
            }
        }
        let tf = tf_message(&w.finish()).unwrap();
        assert_eq!(tf.len(), 2);
        assert_eq!(tf[0].header.stamp_ns, -1);
        assert_eq!(
            (
                tf[1].header.frame_id.as_str(),
                tf[1].child_frame_id.as_str()
            ),
            ("hand", "camera")
        );
        assert_eq!(tf[1].translation, [-0.25, 0.0, 1.0]);
        assert_eq!(tf[1].rotation_xyzw, [0.0, 0.0, 0.0, 1.0]);

        let mut w = CdrWriter::new();
        w.header(3, "").u32(2).string("f0_t0").string("f0_t1");
        w.f64_seq(&[0.002, -0.002]).f64_seq(&[]).f64_seq(&[]);
        let js = joint_state(&w.finish()).unwrap();
        assert_eq!(js.name, ["f0_t0", "f0_t1"]);
        assert_eq!(js.position, [0.002, -0.002]);
    }

    #[test]
    fn big_endian_messages_decode_the_same() {
        let mut be = vec![0, 0, 0, 0];
        be.extend_from_slice(&5i32.to_be_bytes());
        be.extend_from_slice(&6u32.to_be_bytes());
        be.extend_from_slice(&2u32.to_be_bytes());
        be.extend_from_slice(b"a\0");
        let mut r = CdrReader::new(&be).unwrap();
        assert_eq!(Header::read(&mut r).unwrap().stamp_ns, 5_000_000_006);
    }

    /// Every truncation, every flipped byte and huge declared lengths give a typed error or a
    /// message, never a panic, and nothing is allocated for a count the bytes cannot hold.
    #[test]
    fn damaged_messages_are_errors_never_panics() {
        let bytes = image_bytes(&[7; 18]);
        for cut in 0..bytes.len() {
            assert!(image(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        for at in 0..bytes.len() {
            for flip in [0x01, 0x80, 0xff] {
                let mut b = bytes.clone();
                b[at] ^= flip;
                let _ = image(&b);
                let _ = camera_info(&b);
                let _ = tf_message(&b);
                let _ = joint_state(&b);
            }
        }
        let mut huge = CdrWriter::new();
        huge.u32(u32::MAX);
        let err = tf_message(&huge.finish()).unwrap_err();
        assert_eq!(err.field, "transforms");
        assert!(err.message.contains("4294967295 elements"), "{err}");
        let mut w = CdrWriter::new();
        w.header(0, "x")
            .u32(1)
            .u32(1)
            .string("mono8")
            .u8(0)
            .u32(1)
            .u32(1 << 30);
        let err = image(&w.finish()).unwrap_err();
        assert_eq!(err.field, "data");
        for (head, name) in [
            ([0u8, 7], "XCDR2"),
            ([0, 3], "parameter-list"),
            ([1, 0], "unknown"),
        ] {
            let err = CdrReader::new(&[head[0], head[1], 0, 0]).unwrap_err();
            assert!(err.message.contains(name), "{err}");
        }
        let mut w = CdrWriter::new();
        w.u32(3);
        w.bytes.extend_from_slice(b"ab!");
        assert!(
            CdrReader::new(&w.finish())
                .unwrap()
                .string("s")
                .unwrap_err()
                .message
                .contains("NUL")
        );
    }
}
