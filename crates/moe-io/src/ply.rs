//! Stanford PLY: meshes and point clouds with per-vertex colour and scalar properties, parsed and
//! written by `ply-rs-bw`.
//!
//! Reading accepts ascii, binary little- and big-endian files. The `vertex` element must have
//! scalar `x`, `y`, `z` (any numeric type; `float` and `double` are exact in `f64`); optional
//! `red`, `green`, `blue` become colours (integers in 0..=255, or floats in 0..=1 scaled to
//! 0..=255); every other scalar vertex property (e.g. `contact_probability`, `nx`) becomes a named
//! `f32` scalar, in header order (`double` scalars are rounded to `f32`). Vertex list properties
//! and other elements are ignored. The optional `face` element's `vertex_indices` (or
//! `vertex_index`) lists are fan-triangulated. A file without faces is a point cloud.
//!
//! Writing always produces binary little-endian PLY with `double` x/y/z, `uchar` colours,
//! `float` scalars and `uchar`/`uint` index lists, so a write → read round trip is bit-exact.

use std::io::Read;
use std::path::Path;

use moe_geom::{GeomError, Point3, TriMesh};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{
    DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use crate::atomic::write_atomic;
use crate::error::IoError;
use crate::files::{MEMORY, guarded, read_bytes, read_to_end};

/// The contents of a PLY file: points, optional triangles, optional colours and named scalars.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlyData {
    /// Vertex positions (metres, in the frame the file was written in).
    pub points: Vec<Point3>,
    /// Triangles (empty for a point cloud).
    pub faces: Vec<[u32; 3]>,
    /// Per-vertex colours, if present.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Named per-vertex scalars (e.g. `contact_probability`), each with one value per point.
    pub scalars: Vec<(String, Vec<f32>)>,
}

const COLOR_NAMES: [&str; 3] = ["red", "green", "blue"];

impl PlyData {
    /// A mesh's vertices and faces, without colours or scalars.
    pub fn from_mesh(mesh: &TriMesh) -> Self {
        Self {
            points: mesh.vertices().to_vec(),
            faces: mesh.faces().to_vec(),
            colors: None,
            scalars: Vec::new(),
        }
    }

    /// Adds a named per-vertex scalar (stored as f32, one value per point).
    #[must_use]
    pub fn with_scalar(mut self, name: &str, values: impl IntoIterator<Item = f64>) -> Self {
        self.scalars.push((
            name.to_owned(),
            values.into_iter().map(|v| v as f32).collect(),
        ));
        self
    }

    /// A surface with its GP posterior `variance` (m²) and standard deviation `std` (m) per
    /// vertex, as the `surface` command and the surface benchmark write it; without a variance
    /// (an empty slice: the prior, the non-probabilistic baseline), the bare mesh.
    pub fn with_variance(mesh: &TriMesh, variance: &[f64]) -> Self {
        if variance.is_empty() {
            return Self::from_mesh(mesh);
        }
        Self::from_mesh(mesh)
            .with_scalar("variance", variance.iter().copied())
            .with_scalar("std", variance.iter().map(|v| v.sqrt()))
    }

    /// A point cloud (no faces, colours or scalars).
    pub fn from_points(points: &[Point3]) -> Self {
        Self {
            points: points.to_vec(),
            faces: Vec::new(),
            colors: None,
            scalars: Vec::new(),
        }
    }

    /// The validated triangle mesh (colours and scalars are dropped).
    ///
    /// # Errors
    /// As [`TriMesh::new`]; a point cloud gives [`GeomError::EmptyMesh`].
    pub fn into_mesh(self) -> Result<TriMesh, GeomError> {
        TriMesh::new(self.points, self.faces)
    }

    /// The scalar named `name`, if present.
    pub fn scalar(&self, name: &str) -> Option<&[f32]> {
        self.scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    /// Checks that the data can be written: finite points and scalars, sizes that match, face
    /// indices in range, scalar names that are PLY identifiers and distinct from the fixed
    /// properties.
    ///
    /// # Errors
    /// [`IoError::InvalidData`] naming the offending item (errors name `path`).
    pub fn validate(&self, path: &Path) -> Result<(), IoError> {
        let n = self.points.len();
        if let Some(i) = self
            .points
            .iter()
            .position(|p| !moe_geom::math::is_finite_point(p))
        {
            return Err(IoError::invalid(
                path,
                format!("vertex {i}"),
                "non-finite coordinate",
            ));
        }
        for (f, face) in self.faces.iter().enumerate() {
            if let Some(&k) = face.iter().find(|&&k| k as usize >= n) {
                return Err(IoError::invalid(
                    path,
                    format!("face {f}"),
                    format!("vertex index {k} out of range ({n} vertices)"),
                ));
            }
        }
        if let Some(colors) = &self.colors
            && colors.len() != n
        {
            return Err(IoError::invalid(
                path,
                "colors",
                format!("{} colours for {n} vertices", colors.len()),
            ));
        }
        for (s, (name, values)) in self.scalars.iter().enumerate() {
            let valid_name = !name.is_empty()
                && name.chars().all(|c| c.is_ascii_graphic())
                && !["x", "y", "z"].contains(&name.as_str())
                && !COLOR_NAMES.contains(&name.as_str())
                && !self.scalars[..s].iter().any(|(m, _)| m == name);
            if !valid_name {
                return Err(IoError::invalid(
                    path,
                    format!("scalar '{name}'"),
                    "name must be a unique, non-empty PLY identifier other than x, y, z, red, \
                     green, blue",
                ));
            }
            if values.len() != n {
                return Err(IoError::invalid(
                    path,
                    format!("scalar '{name}'"),
                    format!("{} values for {n} vertices", values.len()),
                ));
            }
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(IoError::invalid(
                    path,
                    format!("vertex {i} property '{name}'"),
                    "non-finite value",
                ));
            }
        }
        Ok(())
    }
}

/// Reads a PLY file (mesh or point cloud).
///
/// # Errors
/// [`IoError::Io`] if unreadable, [`IoError::Parse`] (with the line for header and ascii errors)
/// for malformed or truncated files, [`IoError::InvalidData`] naming the vertex, face or
/// property at fault.
pub fn read_ply(path: &Path) -> Result<PlyData, IoError> {
    parse_ply(&read_bytes(path)?, path)
}

/// Reads PLY from any reader (errors name the path `<memory>`).
///
/// # Errors
/// As [`read_ply`].
pub fn read_ply_from(reader: impl Read) -> Result<PlyData, IoError> {
    let path = Path::new(MEMORY);
    parse_ply(&read_to_end(reader, path)?, path)
}

/// Writes PLY (binary little-endian, double coordinates), atomically.
///
/// # Errors
/// [`PlyData::validate`]'s errors; otherwise as [`write_atomic`].
pub fn write_ply(path: &Path, data: &PlyData) -> Result<(), IoError> {
    write_atomic(path, &ply_bytes(data, path)?)
}

/// The bytes of a binary little-endian PLY file; `path` only names errors.
///
/// # Errors
/// [`PlyData::validate`]'s errors.
pub fn ply_bytes(data: &PlyData, path: &Path) -> Result<Vec<u8>, IoError> {
    data.validate(path)?;
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = Encoding::BinaryLittleEndian;
    ply.header.comments.push("moe-touch; units: metres".into());

    let mut vertex = ElementDef::new("vertex".into());
    let add = |def: &mut ElementDef, name: &str, t: PropertyType| {
        def.properties
            .insert(name.to_string(), PropertyDef::new(name.to_string(), t));
    };
    for axis in ["x", "y", "z"] {
        add(&mut vertex, axis, PropertyType::Scalar(ScalarType::Double));
    }
    if data.colors.is_some() {
        for c in COLOR_NAMES {
            add(&mut vertex, c, PropertyType::Scalar(ScalarType::UChar));
        }
    }
    for (name, _) in &data.scalars {
        add(&mut vertex, name, PropertyType::Scalar(ScalarType::Float));
    }
    ply.header.elements.insert("vertex".into(), vertex);
    let mut face = ElementDef::new("face".into());
    add(
        &mut face,
        "vertex_indices",
        PropertyType::List(ScalarType::UChar, ScalarType::UInt),
    );
    ply.header.elements.insert("face".into(), face);

    let vertices: Vec<DefaultElement> = (0..data.points.len())
        .map(|i| {
            let mut e = DefaultElement::new();
            let p = data.points[i];
            e.insert("x".into(), Property::Double(p.x));
            e.insert("y".into(), Property::Double(p.y));
            e.insert("z".into(), Property::Double(p.z));
            if let Some(colors) = &data.colors {
                for (k, c) in COLOR_NAMES.iter().enumerate() {
                    e.insert((*c).into(), Property::UChar(colors[i][k]));
                }
            }
            for (name, values) in &data.scalars {
                e.insert(name.clone(), Property::Float(values[i]));
            }
            e
        })
        .collect();
    let faces: Vec<DefaultElement> = data
        .faces
        .iter()
        .map(|f| {
            let mut e = DefaultElement::new();
            e.insert("vertex_indices".into(), Property::ListUInt(f.to_vec()));
            e
        })
        .collect();
    ply.payload.insert("vertex".into(), vertices);
    ply.payload.insert("face".into(), faces);

    let mut out = Vec::new();
    Writer::<DefaultElement>::new()
        .write_ply(&mut out, &mut ply)
        .map_err(|e| IoError::Serialize {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    Ok(out)
}

/// Parses PLY bytes; `path` only names the source in errors.
pub(crate) fn parse_ply(bytes: &[u8], path: &Path) -> Result<PlyData, IoError> {
    let mut cursor = std::io::Cursor::new(bytes);
    let ply = guarded(path, "ply-rs-bw", || {
        Parser::<DefaultElement>::new()
            .read_ply(&mut cursor)
            .map_err(|e| IoError::parse(path, e.line(), e.to_string()))
    })?;
    let Some(vertex_def) = ply.header.elements.get("vertex") else {
        return Err(IoError::parse(path, None, "no 'vertex' element"));
    };
    let empty = Vec::new();
    let vertices = ply.payload.get("vertex").unwrap_or(&empty);
    let (has_colors, scalar_names) = check_vertex_def(path, vertex_def)?;
    let mut data = read_vertices(path, vertices, has_colors, &scalar_names)?;
    if let Some(face_list) = ply.payload.get("face") {
        data.faces = read_faces(path, face_list, data.points.len())?;
    }
    Ok(data)
}

/// Checks the `vertex` element's header: scalar `x`, `y`, `z` and all or none of the colours;
/// returns whether it has colours and the names of its other scalar properties.
fn check_vertex_def(path: &Path, vertex_def: &ElementDef) -> Result<(bool, Vec<String>), IoError> {
    let scalar_def = |name: &str| {
        matches!(
            vertex_def.properties.get(name).map(|d| &d.data_type),
            Some(PropertyType::Scalar(_))
        )
    };
    for axis in ["x", "y", "z"] {
        if !scalar_def(axis) {
            return Err(IoError::invalid(
                path,
                "element 'vertex'",
                format!("needs a scalar property '{axis}'"),
            ));
        }
    }
    let color_count = COLOR_NAMES.iter().filter(|c| scalar_def(c)).count();
    if color_count % 3 != 0 {
        return Err(IoError::invalid(
            path,
            "element 'vertex'",
            "has some but not all of the colour properties red, green, blue",
        ));
    }
    let has_colors = color_count == 3;
    let scalar_names: Vec<String> = vertex_def
        .properties
        .values()
        .filter(|d| matches!(d.data_type, PropertyType::Scalar(_)))
        .map(|d| d.name.clone())
        .filter(|n| !["x", "y", "z"].contains(&n.as_str()))
        .filter(|n| !(has_colors && COLOR_NAMES.contains(&n.as_str())))
        .collect();
    Ok((has_colors, scalar_names))
}

/// Reads every vertex's point, colour (when `has_colors`) and the scalars `scalar_names`;
/// the result has no faces.
fn read_vertices(
    path: &Path,
    vertices: &[DefaultElement],
    has_colors: bool,
    scalar_names: &[String],
) -> Result<PlyData, IoError> {
    let mut points = Vec::with_capacity(vertices.len());
    let mut colors = has_colors.then(|| Vec::with_capacity(vertices.len()));
    let mut scalars: Vec<(String, Vec<f32>)> = scalar_names
        .iter()
        .map(|n| (n.clone(), Vec::with_capacity(vertices.len())))
        .collect();
    for (i, v) in vertices.iter().enumerate() {
        let get = |name: &str| -> Result<&Property, IoError> {
            v.get(name).ok_or_else(|| {
                IoError::invalid(
                    path,
                    format!("vertex {i}"),
                    format!("missing property '{name}'"),
                )
            })
        };
        let mut xyz = [0.0; 3];
        for (k, axis) in ["x", "y", "z"].into_iter().enumerate() {
            xyz[k] = scalar_f64(get(axis)?).ok_or_else(|| {
                IoError::invalid(
                    path,
                    format!("vertex {i} property '{axis}'"),
                    "not a number",
                )
            })?;
            if !xyz[k].is_finite() {
                return Err(IoError::invalid(
                    path,
                    format!("vertex {i} property '{axis}'"),
                    "non-finite coordinate",
                ));
            }
        }
        points.push(Point3::new(xyz[0], xyz[1], xyz[2]));
        if let Some(colors) = colors.as_mut() {
            let mut rgb = [0u8; 3];
            for (k, c) in COLOR_NAMES.iter().enumerate() {
                rgb[k] = color_u8(get(c)?).ok_or_else(|| {
                    IoError::invalid(
                        path,
                        format!("vertex {i} property '{c}'"),
                        "colour must be an integer in 0..=255 or a float in 0..=1",
                    )
                })?;
            }
            colors.push(rgb);
        }
        for (name, values) in scalars.iter_mut() {
            let value = scalar_f64(get(name)?).map(|x| x as f32);
            match value {
                Some(x) if x.is_finite() => values.push(x),
                _ => {
                    return Err(IoError::invalid(
                        path,
                        format!("vertex {i} property '{name}'"),
                        "not a finite number",
                    ));
                }
            }
        }
    }
    Ok(PlyData {
        points,
        faces: Vec::new(),
        colors,
        scalars,
    })
}

/// Reads the `face` element's index lists over `n` vertices, fan-triangulated.
fn read_faces(
    path: &Path,
    face_list: &[DefaultElement],
    n: usize,
) -> Result<Vec<[u32; 3]>, IoError> {
    let mut faces = Vec::new();
    for (f, e) in face_list.iter().enumerate() {
        let Some(list) = e.get("vertex_indices").or_else(|| e.get("vertex_index")) else {
            return Err(IoError::invalid(
                path,
                format!("face {f}"),
                "has no 'vertex_indices' list",
            ));
        };
        let Some(ids) = list.to_u32_list() else {
            return Err(IoError::invalid(
                path,
                format!("face {f}"),
                "'vertex_indices' must be a list of non-negative integers",
            ));
        };
        if ids.len() < 3 {
            return Err(IoError::invalid(
                path,
                format!("face {f}"),
                format!("has {} vertices; a face needs at least 3", ids.len()),
            ));
        }
        if let Some(&k) = ids.iter().find(|&&k| k as usize >= n) {
            return Err(IoError::invalid(
                path,
                format!("face {f}"),
                format!("vertex index {k} out of range ({n} vertices)"),
            ));
        }
        for k in 1..ids.len() - 1 {
            faces.push([ids[0], ids[k], ids[k + 1]]);
        }
    }
    Ok(faces)
}

fn scalar_f64(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        _ => return None,
    })
}

fn color_u8(p: &Property) -> Option<u8> {
    match *p {
        Property::Float(_) | Property::Double(_) => {
            let x = scalar_f64(p)?;
            (0.0..=1.0).contains(&x).then(|| (x * 255.0).round() as u8)
        }
        _ => {
            let x = scalar_f64(p)?;
            (0.0..=255.0).contains(&x).then_some(x as u8)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &[u8]) -> Result<PlyData, IoError> {
        parse_ply(s, Path::new("t.ply"))
    }

    const ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n\
        property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n\
        property uchar blue\nproperty float contact_probability\nelement face 1\n\
        property list uchar int vertex_indices\nend_header\n\
        0 0 0 255 0 0 0.5\n1 0 0 0 255 0 0.25\n1 1 0 0 0 255 1\n0 1 0 9 9 9 0\n4 0 1 2 3\n";

    #[test]
    fn ascii_with_colours_scalars_and_a_quad() {
        let d = parse(ASCII.as_bytes()).unwrap();
        assert_eq!(d.points.len(), 4);
        assert_eq!(d.faces, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(d.colors.as_ref().unwrap()[1], [0, 255, 0]);
        assert_eq!(
            d.scalar("contact_probability").unwrap(),
            &[0.5, 0.25, 1.0, 0.0]
        );
        assert_eq!(d.into_mesh().unwrap().num_faces(), 2);
    }

    #[test]
    fn variance_and_its_square_root_round_trip() {
        let mesh = TriMesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
        .unwrap();
        let dir = std::env::temp_dir().join(format!("moe-io-ply-var-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("v.ply");
        write_ply(
            &path,
            &PlyData::with_variance(&mesh, &[0.25, 4e-6, 0.0, 1.0]),
        )
        .unwrap();
        let back = read_ply(&path).unwrap();
        assert_eq!(back.scalar("variance").unwrap(), &[0.25, 4e-6, 0.0, 1.0]);
        assert_eq!(back.scalar("std").unwrap(), &[0.5, 2e-3, 0.0, 1.0]);
        assert_eq!(back.into_mesh().unwrap(), mesh);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn binary_round_trip_is_exact() {
        let d = PlyData {
            points: vec![
                Point3::new(0.1, 1.0 / 3.0, -0.0),
                Point3::new(1e-310, 2.0, 3.0),
                Point3::new(-7.25, 0.3, 1e200),
            ],
            faces: vec![[0, 1, 2]],
            colors: Some(vec![[1, 2, 3], [4, 5, 6], [255, 0, 128]]),
            scalars: vec![
                ("contact_probability".into(), vec![0.0, 0.5, 1.0]),
                ("noise".into(), vec![1e-20, -3.5, f32::MAX]),
            ],
        };
        let bytes = ply_bytes(&d, Path::new("t.ply")).unwrap();
        let back = parse(&bytes).unwrap();
        assert_eq!(back, d);
        for (a, b) in d.points.iter().zip(&back.points) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits());
            }
        }
    }

    #[test]
    fn big_endian_point_cloud() {
        let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\n\
            property double y\nproperty double z\nend_header\n"
            .to_vec();
        for x in [1.5f64, -2.0, 0.125, 3.0, 4.0, 5.0] {
            bytes.extend_from_slice(&x.to_be_bytes());
        }
        let d = parse(&bytes).unwrap();
        assert_eq!(
            d.points,
            vec![Point3::new(1.5, -2.0, 0.125), Point3::new(3.0, 4.0, 5.0)]
        );
        assert!(d.faces.is_empty());
        assert!(matches!(d.into_mesh(), Err(GeomError::EmptyMesh { .. })));
    }

    #[test]
    fn bad_files_and_bad_data_give_typed_errors() {
        assert!(matches!(parse(b"not a ply"), Err(IoError::Parse { .. })));
        let truncated = &ASCII.as_bytes()[..ASCII.len() - 12];
        assert!(matches!(parse(truncated), Err(IoError::Parse { .. })));
        let bad_index = ASCII.replace("4 0 1 2 3", "3 0 1 7");
        let e = parse(bad_index.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("face 0"), "{e}");
        let nan = ASCII.replace("1 1 0 0 0 255 1", "1 nan 0 0 0 255 1");
        // ply-rs reads no "nan": the line of vertex 2 is a syntax error.
        moe_geom::assert_err!(
            parse(nan.as_bytes()),
            IoError::Parse {
                path,
                line: Some(16),
                ..
            } if path == Path::new("t.ply")
        );
        // A float property that overflows f32 reads as infinity.
        let inf = ASCII.replace("1 1 0 0 0 255 1", "1 1e99 0 0 0 255 1");
        moe_geom::assert_err!(
            parse(inf.as_bytes()),
            IoError::InvalidData { path, item, message }
                if path == Path::new("t.ply")
                    && item == "vertex 2 property 'y'"
                    && message == "non-finite coordinate"
        );
        let partial_colour = ASCII.replace("property uchar blue", "property uchar blur");
        let e = parse(partial_colour.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("colour"), "{e}");
        let d = PlyData {
            points: vec![Point3::origin()],
            scalars: vec![("x".into(), vec![1.0])],
            ..PlyData::default()
        };
        assert!(matches!(
            ply_bytes(&d, Path::new("t.ply")),
            Err(IoError::InvalidData { .. })
        ));
    }
}
