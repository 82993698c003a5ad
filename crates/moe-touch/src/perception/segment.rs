//! Red segmentation, back-projection and the voxel cells that DBSCAN clusters.

use std::collections::HashMap;

use moe_geom::CameraIntrinsics;
use moe_geom::{Point3, Real};

use super::DetectorConfig;

/// The integer form of the HSV threshold, so that the per-pixel test needs no division.
#[derive(Debug, Clone, Copy)]
pub(super) struct RedTest {
    /// Saturation threshold, per mille.
    saturation_milli: u32,
    /// Value threshold, 8-bit levels.
    value: u8,
    /// Hue window.
    hue_center_deg: Real,
    hue_tolerance_deg: Real,
}

impl RedTest {
    pub(super) fn new(config: &DetectorConfig) -> Self {
        Self {
            saturation_milli: (config.min_saturation * 1000.0).round() as u32,
            value: (config.min_value * 255.0).round().clamp(0.0, 255.0) as u8,
            hue_center_deg: config.hue_center_deg,
            hue_tolerance_deg: config.hue_tolerance_deg,
        }
    }

    /// Whether an RGB8 pixel is marker-coloured: saturation and value first (integers, which
    /// reject the grey silicone and the background at once), then the hue of what remains.
    #[inline]
    pub(super) fn is_marker(&self, r: u8, g: u8, b: u8) -> bool {
        let max = r.max(g).max(b);
        let min = r.min(g).min(b);
        if max < self.value || max == 0 {
            return false;
        }
        let chroma = u32::from(max - min);
        if chroma == 0 || chroma * 1000 < self.saturation_milli * u32::from(max) {
            return false;
        }
        let hue = hue_deg(r, g, b, max, chroma);
        let mut diff = (hue - self.hue_center_deg).rem_euclid(360.0);
        if diff > 180.0 {
            diff = 360.0 - diff;
        }
        diff <= self.hue_tolerance_deg
    }
}

/// HSV hue in degrees, `[0, 360)`.
fn hue_deg(r: u8, g: u8, b: u8, max: u8, chroma: u32) -> Real {
    let c = Real::from(chroma);
    let (rf, gf, bf) = (Real::from(r), Real::from(g), Real::from(b));
    let h = if max == r {
        ((gf - bf) / c).rem_euclid(6.0)
    } else if max == g {
        (bf - rf) / c + 2.0
    } else {
        (rf - gf) / c + 4.0
    };
    60.0 * h
}

/// The marker-coloured pixels of a frame that have depth, lifted into the camera frame, grouped
/// into cells.
#[derive(Debug, Default)]
pub(super) struct Segmentation {
    /// Marker-coloured pixels, with or without depth.
    pub(super) red_pixels: usize,
    /// Camera-frame points of the red pixels with valid depth.
    pub(super) points: Vec<Point3>,
    /// Pixel `(column, row)` of each point.
    pub(super) pixels: Vec<[u32; 2]>,

    /// Cell of each point.
    pub(super) cell_of: Vec<u32>,
    /// Mean point of each cell (what DBSCAN clusters).
    pub(super) cell_points: Vec<Point3>,
    /// Points per cell.
    pub(super) cell_counts: Vec<u32>,
}

/// Finds the marker-coloured pixels with valid depth (finite and positive; NaN, zero, negative
/// and infinite depth count as missing), back-projects them into the camera frame and groups
/// them into cubic voxels of side `voxel_m` in the camera frame, each represented by the mean
/// point of its pixels. Voxels are metric, so a marker yields about as many cells near the
/// camera as far from it, at any image resolution, and a cell never mixes two surfaces at
/// different ranges.
pub(super) fn segment(
    voxel_m: Real,
    test: &RedTest,
    k: &CameraIntrinsics,
    color_rgb8: &[u8],
    depth_m: &[f32],
) -> Segmentation {
    let (w, h) = (k.width as usize, k.height as usize);
    let inv_voxel = 1.0 / voxel_m.max(1e-6);
    let (inv_fx, inv_fy) = (1.0 / k.fx, 1.0 / k.fy);
    let mut out = Segmentation::default();
    let mut cells: HashMap<[i64; 3], u32> = HashMap::new();
    let mut sums: Vec<[Real; 3]> = Vec::new();
    for j in 0..h {
        let row = &color_rgb8[3 * j * w..3 * (j + 1) * w];
        let depth_row = &depth_m[j * w..(j + 1) * w];
        for (i, (rgb, &d)) in row.chunks_exact(3).zip(depth_row).enumerate() {
            if !test.is_marker(rgb[0], rgb[1], rgb[2]) {
                continue;
            }
            out.red_pixels += 1;
            let z = Real::from(d);
            if !(z.is_finite() && z > 0.0) {
                continue;
            }
            let p = Point3::new(
                (i as Real - k.cx) * z * inv_fx,
                (j as Real - k.cy) * z * inv_fy,
                z,
            );
            let key = [p.x, p.y, p.z].map(|c| (c * inv_voxel).floor() as i64);
            let next = sums.len() as u32;
            let c = *cells.entry(key).or_insert(next);
            if c == next {
                sums.push([0.0; 3]);
                out.cell_counts.push(0);
            }
            let s = &mut sums[c as usize];
            s[0] += p.x;
            s[1] += p.y;
            s[2] += p.z;
            out.cell_counts[c as usize] += 1;
            out.points.push(p);
            out.pixels.push([i as u32, j as u32]);
            out.cell_of.push(c);
        }
    }
    out.cell_points = sums
        .iter()
        .zip(&out.cell_counts)
        .map(|(s, &n)| {
            let n = Real::from(n);
            Point3::new(s[0] / n, s[1] / n, s[2] / n)
        })
        .collect();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hsv_to_rgb(h: Real, s: Real, v: Real) -> (u8, u8, u8) {
        let c = v * s;
        let hp = (h / 60.0).rem_euclid(6.0);
        let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
        let (r, g, b) = match hp as u32 {
            0 => (c, x, 0.0),
            1 => (x, c, 0.0),
            2 => (0.0, c, x),
            3 => (0.0, x, c),
            4 => (x, 0.0, c),
            _ => (c, 0.0, x),
        };
        let m = v - c;
        let q = |t: Real| ((t + m) * 255.0).round() as u8;
        (q(r), q(g), q(b))
    }

    #[test]
    fn the_integer_test_is_the_hsv_threshold() {
        let config = DetectorConfig::default();
        let test = RedTest::new(&config);
        // Marker red, shaded from full to half light, is red; the silicone, the background and
        // the obstacle colours of the recorder are not.
        for shade in [1.0, 0.75, 0.5] {
            let c = moe_tendon_sim::camera::MARKER_RED.map(|c| (Real::from(c) * shade) as u8);
            assert!(test.is_marker(c[0], c[1], c[2]), "{c:?}");
        }
        for c in [
            moe_tendon_sim::camera::FINGER_ALBEDO,
            moe_tendon_sim::camera::OBSTACLE_ALBEDO,
            moe_tendon_sim::camera::BACKGROUND,
            [0, 0, 0],
            [255, 255, 255],
        ] {
            assert!(!test.is_marker(c[0], c[1], c[2]), "{c:?}");
        }
        // Away from the thresholds' edges the test agrees with the HSV definition.
        for h in (0..360).step_by(7) {
            for s in [0.2, 0.45, 0.55, 0.9] {
                for v in [0.1, 0.2, 0.6, 1.0] {
                    let (r, g, b) = hsv_to_rgb(Real::from(h), s, v);
                    let hue_diff = (Real::from(h) + 180.0).rem_euclid(360.0) - 180.0;
                    let expected = hue_diff.abs() <= config.hue_tolerance_deg
                        && s >= config.min_saturation
                        && v >= config.min_value;
                    let near_edge = (hue_diff.abs() - config.hue_tolerance_deg).abs() < 3.0
                        || (s - config.min_saturation).abs() < 0.03
                        || (v - config.min_value).abs() < 0.03;
                    if !near_edge {
                        assert_eq!(test.is_marker(r, g, b), expected, "h {h} s {s} v {v}");
                    }
                }
            }
        }
    }

    #[test]
    fn bad_depth_is_missing_and_cells_split_by_range() {
        let config = DetectorConfig::default();
        let test = RedTest::new(&config);
        let k = CameraIntrinsics {
            width: 4,
            height: 2,
            fx: 100.0,
            fy: 100.0,
            cx: 3.5,
            cy: 1.5,
        };
        let red = moe_tendon_sim::camera::MARKER_RED;
        let color: Vec<u8> = (0..8).flat_map(|_| red).collect();
        let depth = [0.05, f32::NAN, 0.0, -1.0, f32::INFINITY, 0.05, 0.05, 0.08];
        let s = segment(0.01, &test, &k, &color, &depth);
        assert_eq!(s.red_pixels, 8);
        assert_eq!(s.pixels, vec![[0, 0], [1, 1], [2, 1], [3, 1]]);
        // Pixels (0,0), (1,1), (2,1) are within 1 mm of each other at 5 cm and share a 1 cm
        // voxel; (3,1) is 3 cm farther.
        assert_eq!(s.cell_points.len(), 2);
        assert_eq!(s.cell_counts, vec![3, 1]);
        let p = s.points[1];
        assert!((p.x - (1.0 - 3.5) * 0.05 / 100.0).abs() < 1e-9);
        assert!((p.y - (1.0 - 1.5) * 0.05 / 100.0).abs() < 1e-9);
        assert!((p.z - 0.05).abs() < 1e-9);
    }
}
