//! Drawing on RGB images: pixels, rings, lines, a small bitmap font, labels placed so that they
//! do not overlap, and finger meshes rendered with a z-buffer and coloured by contact probability
//! (the figures of `moe-touch demo` and the perception overlays).

use image::{Rgb, RgbImage};
use moe_geom::nalgebra::Rotation3;
use moe_geom::{Point3, Real, Vector3};

/// 3 × 5 pixel glyphs, one row per entry, bit 2 on the left.
fn glyph(ch: char) -> Option<[u8; 5]> {
    Some(match ch.to_ascii_uppercase() {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        ',' => [0b000, 0b000, 0b000, 0b010, 0b100],
        ':' => [0b000, 0b010, 0b000, 0b010, 0b000],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '=' => [0b000, 0b111, 0b000, 0b111, 0b000],
        '/' => [0b001, 0b001, 0b010, 0b100, 0b100],
        '(' => [0b010, 0b100, 0b100, 0b100, 0b010],
        ')' => [0b010, 0b001, 0b001, 0b001, 0b010],
        '%' => [0b101, 0b001, 0b010, 0b100, 0b101],
        ' ' => [0; 5],
        'A' => [0b010, 0b101, 0b111, 0b101, 0b101],
        'B' => [0b110, 0b101, 0b110, 0b101, 0b110],
        'C' => [0b011, 0b100, 0b100, 0b100, 0b011],
        'D' => [0b110, 0b101, 0b101, 0b101, 0b110],
        'E' => [0b111, 0b100, 0b110, 0b100, 0b111],
        'F' => [0b111, 0b100, 0b110, 0b100, 0b100],
        'G' => [0b011, 0b100, 0b101, 0b101, 0b011],
        'H' => [0b101, 0b101, 0b111, 0b101, 0b101],
        'I' => [0b111, 0b010, 0b010, 0b010, 0b111],
        'J' => [0b001, 0b001, 0b001, 0b101, 0b010],
        'K' => [0b101, 0b101, 0b110, 0b101, 0b101],
        'L' => [0b100, 0b100, 0b100, 0b100, 0b111],
        'M' => [0b101, 0b111, 0b111, 0b101, 0b101],
        'N' => [0b110, 0b101, 0b101, 0b101, 0b101],
        'O' => [0b010, 0b101, 0b101, 0b101, 0b010],
        'P' => [0b110, 0b101, 0b110, 0b100, 0b100],
        'Q' => [0b010, 0b101, 0b101, 0b110, 0b011],
        'R' => [0b110, 0b101, 0b110, 0b101, 0b101],
        'S' => [0b011, 0b100, 0b010, 0b001, 0b110],
        'T' => [0b111, 0b010, 0b010, 0b010, 0b010],
        'U' => [0b101, 0b101, 0b101, 0b101, 0b111],
        'V' => [0b101, 0b101, 0b101, 0b101, 0b010],
        'W' => [0b101, 0b101, 0b111, 0b111, 0b101],
        'X' => [0b101, 0b101, 0b010, 0b101, 0b101],
        'Y' => [0b101, 0b101, 0b010, 0b010, 0b010],
        'Z' => [0b111, 0b001, 0b010, 0b100, 0b111],
        _ => return None,
    })
}

/// Pixels per glyph cell edge at text scale 2 (glyphs are 3 × 5 cells, 4 cells apart).
const CELL: i64 = 2;

/// The size in pixels of `s` drawn by [`text`].
pub fn text_size(s: &str) -> (i64, i64) {
    let n = s.chars().count() as i64;
    (if n == 0 { 0 } else { 4 * CELL * n - CELL }, 5 * CELL)
}

/// Sets one pixel (outside the image: nothing).
pub fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && x < i64::from(img.width()) && y < i64::from(img.height()) {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// A ring of radius `r` pixels, two pixels wide.
pub fn ring(img: &mut RgbImage, u: Real, v: Real, r: Real, c: Rgb<u8>) {
    let steps = (2.0 * std::f64::consts::PI * r * 2.0).ceil() as usize;
    for s in 0..steps {
        let a = s as Real / steps as Real * std::f64::consts::TAU;
        for dr in [0.0, 1.0] {
            put(
                img,
                (u + (r + dr) * a.cos()).round() as i64,
                (v + (r + dr) * a.sin()).round() as i64,
                c,
            );
        }
    }
}

/// A diagonal cross of half-size `half` pixels.
pub fn cross(img: &mut RgbImage, u: Real, v: Real, half: i64, c: Rgb<u8>) {
    let (x, y) = (u.round() as i64, v.round() as i64);
    for d in -half..=half {
        put(img, x + d, y + d, c);
        put(img, x + d, y - d, c);
    }
}

/// A straight line from `(u0, v0)` to `(u1, v1)`, `width` pixels wide (1 or more).
pub fn line(
    img: &mut RgbImage,
    (u0, v0): (Real, Real),
    (u1, v1): (Real, Real),
    width: i64,
    c: Rgb<u8>,
) {
    if ![u0, v0, u1, v1].iter().all(|x| x.is_finite()) {
        return;
    }
    let steps = ((u1 - u0).abs().max((v1 - v0).abs()).ceil() as usize).clamp(1, 100_000);
    let lo = -(width - 1) / 2;
    for s in 0..=steps {
        let a = s as Real / steps as Real;
        let (x, y) = (
            (u0 + a * (u1 - u0)).round() as i64,
            (v0 + a * (v1 - v0)).round() as i64,
        );
        for dx in lo..lo + width {
            for dy in lo..lo + width {
                put(img, x + dx, y + dy, c);
            }
        }
    }
}

/// An arrow ending at `(u1, v1)` with a head of `head` pixels.
pub fn arrow(img: &mut RgbImage, from: (Real, Real), to: (Real, Real), head: Real, c: Rgb<u8>) {
    line(img, from, to, 2, c);
    let (dx, dy) = (to.0 - from.0, to.1 - from.1);
    let len = dx.hypot(dy);
    if len < 1e-9 {
        return;
    }
    let (ux, uy) = (dx / len, dy / len);
    for side in [-1.0, 1.0] {
        let (hx, hy) = (-ux * 0.866 - side * uy * 0.5, -uy * 0.866 + side * ux * 0.5);
        line(img, to, (to.0 + head * hx, to.1 + head * hy), 2, c);
    }
}

/// `s` at text scale 2, top-left corner at `(u, v)`; characters without a glyph are skipped.
pub fn text(img: &mut RgbImage, u: Real, v: Real, s: &str, c: Rgb<u8>) {
    let (x0, y0) = (u.round() as i64, v.round() as i64);
    for (n, ch) in s.chars().enumerate() {
        let Some(g) = glyph(ch) else { continue };
        let gx = x0 + 4 * CELL * n as i64;
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (0b100 >> col) != 0 {
                    for dx in 0..CELL {
                        for dy in 0..CELL {
                            put(img, gx + CELL * col + dx, y0 + CELL * row as i64 + dy, c);
                        }
                    }
                }
            }
        }
    }
}

/// `img` encoded as PNG.
///
/// # Errors
/// The encoder's error (none is expected for an image in memory).
pub fn png_bytes(img: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

/// A pixel rectangle `[x0, x1) × [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelBox {
    /// Left edge.
    pub x0: i64,
    /// Top edge.
    pub y0: i64,
    /// Right edge (exclusive).
    pub x1: i64,
    /// Bottom edge (exclusive).
    pub y1: i64,
}

impl PixelBox {
    /// Whether the two boxes share a pixel.
    pub fn overlaps(&self, other: &PixelBox) -> bool {
        self.x0 < other.x1 && other.x0 < self.x1 && self.y0 < other.y1 && other.y0 < self.y1
    }

    fn area_with(&self, other: &PixelBox) -> i64 {
        let w = (self.x1.min(other.x1) - self.x0.max(other.x0)).max(0);
        let h = (self.y1.min(other.y1) - self.y0.max(other.y0)).max(0);
        w * h
    }
}

/// How a label position ranks: outside the image, pixels overlapped, distance step.
type Cost = (i64, i64, i64);

/// Places one label of `size` (pixels) beside each anchor `(u, v)`, each ringed with radius
/// `ring_px`: greedily, in anchor order, at the first of a set of positions around the anchor
/// (close first, then further out, in eight directions) whose box overlaps no label placed
/// before it and no anchor's ring, inside a `width` × `height` image when it can be. When no
/// position is free, the one of least overlap. Returns the boxes' top-left corners.
pub fn place_labels(
    anchors: &[(Real, Real)],
    sizes: &[(i64, i64)],
    ring_px: Real,
    width: i64,
    height: i64,
) -> Vec<(i64, i64)> {
    let r = ring_px.ceil() as i64 + 2;
    let rings: Vec<PixelBox> = anchors
        .iter()
        .map(|&(u, v)| {
            let (x, y) = (u.round() as i64, v.round() as i64);
            PixelBox {
                x0: x - r,
                y0: y - r,
                x1: x + r + 1,
                y1: y + r + 1,
            }
        })
        .collect();
    let mut placed: Vec<PixelBox> = Vec::with_capacity(anchors.len());
    let mut corners = Vec::with_capacity(anchors.len());
    for (k, (&(u, v), &(w, h))) in anchors.iter().zip(sizes).enumerate() {
        let (x, y) = (u.round() as i64, v.round() as i64);
        // (outside, overlap, step) of the best position so far, and its corner.
        let mut best: Option<(Cost, (i64, i64))> = None;
        'search: for step in 0..8 {
            let d = r + 1 + 6 * step;
            // Right, left, above, below, then the four corners.
            let positions = [
                (x + d, y - h / 2),
                (x - d - w, y - h / 2),
                (x - w / 2, y - d - h),
                (x - w / 2, y + d),
                (x + d, y - d - h),
                (x - d - w, y - d - h),
                (x + d, y + d),
                (x - d - w, y + d),
            ];
            for (x0, y0) in positions {
                let b = PixelBox {
                    x0,
                    y0,
                    x1: x0 + w,
                    y1: y0 + h,
                };
                let overlap: i64 = placed
                    .iter()
                    .chain(
                        rings
                            .iter()
                            .enumerate()
                            .filter(|(j, _)| *j != k)
                            .map(|(_, b)| b),
                    )
                    .map(|o| b.area_with(o))
                    .sum();
                let outside = i64::from(x0 < 0 || y0 < 0 || b.x1 > width || b.y1 > height);
                let cost = (outside, overlap, step);
                if best.is_none_or(|(c, _)| cost < c) {
                    best = Some((cost, (x0, y0)));
                }
                if outside == 0 && overlap == 0 {
                    break 'search;
                }
            }
        }
        let (_, (x0, y0)) = best.unwrap_or(((0, 0, 0), (x + r + 1, y)));
        placed.push(PixelBox {
            x0,
            y0,
            x1: x0 + w,
            y1: y0 + h,
        });
        corners.push((x0, y0));
    }
    corners
}

/// A mesh to render: its vertices, faces and a contact probability per vertex (its colour,
/// blue 0 to red 1 as in the result files, [`moe_record::probability_colour`]).
#[derive(Debug, Clone, Copy)]
pub struct ShadedMesh<'a> {
    /// Vertices, any common frame.
    pub vertices: &'a [Point3],
    /// Triangles.
    pub faces: &'a [[u32; 3]],
    /// Per-vertex contact probability.
    pub probability: &'a [Real],
}

/// An orthographic view: a rotation into view coordinates (x right, y up, z toward the
/// viewer) and where the view's centre lands, with a scale in pixels per metre.
#[derive(Debug, Clone, Copy)]
pub struct OrthoView {
    /// View from the meshes' frame.
    pub view_from_frame: Rotation3<Real>,
    /// The point (view coordinates) drawn at the panel's centre.
    pub centre: Point3,
    /// Pixels per metre.
    pub px_per_m: Real,
    /// Panel width, pixels.
    pub width: u32,
    /// Panel height, pixels.
    pub height: u32,
}

impl OrthoView {
    /// The view that fits `points` (with a margin of `margin_px`) into a `width` × `height`
    /// panel, looking along `view_from_frame`.
    pub fn fitting<'a>(
        view_from_frame: Rotation3<Real>,
        points: impl IntoIterator<Item = &'a Point3>,
        width: u32,
        height: u32,
        margin_px: Real,
    ) -> Self {
        let mut lo = Vector3::repeat(Real::INFINITY);
        let mut hi = Vector3::repeat(Real::NEG_INFINITY);
        for p in points {
            let q = view_from_frame * p.coords;
            if q.iter().all(|x| x.is_finite()) {
                lo = lo.inf(&q);
                hi = hi.sup(&q);
            }
        }
        if lo.x.is_nan() || lo.x > hi.x {
            lo = Vector3::zeros();
            hi = Vector3::zeros();
        }
        let span_x = (hi.x - lo.x).max(1e-6);
        let span_y = (hi.y - lo.y).max(1e-6);
        let px_per_m = ((Real::from(width) - 2.0 * margin_px) / span_x)
            .min((Real::from(height) - 2.0 * margin_px) / span_y)
            .max(1e-3);
        Self {
            view_from_frame,
            centre: Point3::from((lo + hi) / 2.0),
            px_per_m,
            width,
            height,
        }
    }

    /// Pixel position and depth (larger: nearer the viewer) of a point.
    pub fn project(&self, p: &Point3) -> (Real, Real, Real) {
        let q = self.view_from_frame * p.coords - self.centre.coords;
        (
            Real::from(self.width) / 2.0 + self.px_per_m * q.x,
            Real::from(self.height) / 2.0 - self.px_per_m * q.y,
            q.z,
        )
    }
}

/// Renders `meshes` on a `background` panel with a z-buffer, each triangle shaded by its facing
/// the viewer and coloured by its vertices' contact probabilities (interpolated).
pub fn render_meshes(view: &OrthoView, meshes: &[ShadedMesh<'_>], background: Rgb<u8>) -> RgbImage {
    let (w, h) = (view.width as usize, view.height as usize);
    let mut img = RgbImage::from_pixel(view.width, view.height, background);
    let mut depth = vec![Real::NEG_INFINITY; w * h];
    for mesh in meshes {
        let projected: Vec<(Real, Real, Real)> =
            mesh.vertices.iter().map(|p| view.project(p)).collect();
        for face in mesh.faces {
            let Some(idx) = face
                .iter()
                .map(|&i| ((i as usize) < projected.len()).then_some(i as usize))
                .collect::<Option<Vec<usize>>>()
            else {
                continue;
            };
            let [a, b, c] = [idx[0], idx[1], idx[2]];
            let [pa, pb, pc] = [a, b, c].map(|i| mesh.vertices[i]);
            let normal = view.view_from_frame * (pb - pa).cross(&(pc - pa));
            let Some(n) = normal.try_normalize(0.0) else {
                continue;
            };
            let shade = 0.35 + 0.65 * n.z.abs();
            let colours = [a, b, c].map(|i| {
                moe_record::probability_colour(mesh.probability.get(i).copied().unwrap_or(0.0))
                    .map(|c| Real::from(c) / 255.0)
            });
            let [(xa, ya, za), (xb, yb, zb), (xc, yc, zc)] = [a, b, c].map(|i| projected[i]);
            let area = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya);
            if area.is_nan() || area.abs() <= 1e-12 {
                continue;
            }
            let x0 = xa.min(xb).min(xc).floor().max(0.0) as usize;
            let x1 = (xa.max(xb).max(xc).ceil() as i64).min(w as i64 - 1);
            let y0 = ya.min(yb).min(yc).floor().max(0.0) as usize;
            let y1 = (ya.max(yb).max(yc).ceil() as i64).min(h as i64 - 1);
            if x1 < 0 || y1 < 0 {
                continue;
            }
            for y in y0..=y1 as usize {
                for x in x0..=x1 as usize {
                    let (px, py) = (x as Real + 0.5, y as Real + 0.5);
                    let wa = ((xb - px) * (yc - py) - (xc - px) * (yb - py)) / area;
                    let wb = ((xc - px) * (ya - py) - (xa - px) * (yc - py)) / area;
                    let wc = 1.0 - wa - wb;
                    if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                        continue;
                    }
                    let z = wa * za + wb * zb + wc * zc;
                    let slot = &mut depth[y * w + x];
                    if z <= *slot {
                        continue;
                    }
                    *slot = z;
                    let rgb = [0, 1, 2].map(|i| {
                        let v = wa * colours[0][i] + wb * colours[1][i] + wc * colours[2][i];
                        (255.0 * (shade * v).clamp(0.0, 1.0)).round() as u8
                    });
                    img.put_pixel(x as u32, y as u32, Rgb(rgb));
                }
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_beside_a_dense_row_of_markers_do_not_overlap_each_other_or_the_rings() {
        // Seven markers 9 px apart down a finger, as the camera row sees them, and a second row
        // 14 px beside it: every label box clear of the others and of every ring.
        let anchors: Vec<(Real, Real)> = (0..7)
            .flat_map(|k| {
                [
                    (100.0, 40.0 + 9.0 * k as Real),
                    (114.0, 44.0 + 9.0 * k as Real),
                ]
            })
            .collect();
        let sizes: Vec<(i64, i64)> = (0..anchors.len())
            .map(|k| text_size(&format!("{}.{}", k % 2, k / 2)))
            .collect();
        let corners = place_labels(&anchors, &sizes, 7.0, 640, 480);
        let boxes: Vec<PixelBox> = corners
            .iter()
            .zip(&sizes)
            .map(|(&(x0, y0), &(w, h))| PixelBox {
                x0,
                y0,
                x1: x0 + w,
                y1: y0 + h,
            })
            .collect();
        for (i, a) in boxes.iter().enumerate() {
            assert!(
                a.x0 >= 0 && a.y0 >= 0 && a.x1 <= 640 && a.y1 <= 480,
                "{a:?}"
            );
            for b in &boxes[i + 1..] {
                assert!(!a.overlaps(b), "{a:?} overlaps {b:?}");
            }
            for &(u, v) in &anchors {
                let ring = PixelBox {
                    x0: u as i64 - 7,
                    y0: v as i64 - 7,
                    x1: u as i64 + 8,
                    y1: v as i64 + 8,
                };
                assert!(!a.overlaps(&ring), "{a:?} covers the marker at {u}, {v}");
            }
        }
    }

    #[test]
    fn a_nearer_triangle_hides_a_farther_one_and_colour_follows_the_value() {
        let far = [
            Point3::new(-1.0, -1.0, 0.0),
            Point3::new(1.0, -1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let near: Vec<Point3> = far
            .iter()
            .map(|p| p + Vector3::new(0.0, 0.0, 0.5))
            .collect();
        let view = OrthoView::fitting(Rotation3::identity(), far.iter(), 64, 64, 4.0);
        fn mesh<'a>(vertices: &'a [Point3], value: &'a [Real]) -> ShadedMesh<'a> {
            ShadedMesh {
                vertices,
                faces: &[[0, 1, 2]],
                probability: value,
            }
        }
        let (blue, red_value) = ([0.0; 3], [1.0; 3]);
        // Drawn far first, then near first: the near (red) triangle shows at the centre either
        // way, facing the viewer (shade 1), and a corner stays background.
        let red = moe_record::probability_colour(1.0);
        for order in [
            [mesh(&far, &blue), mesh(&near, &red_value)],
            [mesh(&near, &red_value), mesh(&far, &blue)],
        ] {
            let img = render_meshes(&view, &order, Rgb([0, 0, 0]));
            assert_eq!(img.get_pixel(32, 36).0, red);
            assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
        }
    }
}
