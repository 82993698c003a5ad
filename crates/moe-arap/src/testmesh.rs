//! Closed test meshes with seeded jitter.

use moe_geom::{Point3, Real, TriMesh};

/// SplitMix64: a tiny deterministic generator for test data.
pub(crate) struct SplitMix64(pub(crate) u64);

impl SplitMix64 {
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[-1, 1)`.
    pub(crate) fn signed(&mut self) -> Real {
        (self.next_u64() >> 11) as Real / (1u64 << 52) as Real - 1.0
    }
}

/// A latitude–longitude sphere of radius ~1 with `rings` interior rings of `segments` vertices and
/// two poles; each vertex's radius is scaled by `1 + jitter · u`, `u ∈ [-1, 1)`.
pub(crate) fn jittered_sphere(rings: usize, segments: usize, jitter: Real, seed: u64) -> TriMesh {
    let mut rng = SplitMix64(seed);
    let mut v = vec![Point3::new(0.0, 0.0, 1.0)];
    for r in 0..rings {
        let theta = std::f64::consts::PI * (r + 1) as Real / (rings + 1) as Real;
        for s in 0..segments {
            let phi =
                2.0 * std::f64::consts::PI * (s as Real + 0.5 * (r % 2) as Real) / segments as Real;
            let scale = 1.0 + jitter * rng.signed();
            v.push(Point3::new(
                scale * theta.sin() * phi.cos(),
                scale * theta.sin() * phi.sin(),
                scale * theta.cos(),
            ));
        }
    }
    v.push(Point3::new(0.0, 0.0, -1.0));
    let south = (v.len() - 1) as u32;
    let id = |r: usize, s: usize| (1 + r * segments + s % segments) as u32;
    let mut f = Vec::new();
    for s in 0..segments {
        f.push([0, id(0, s), id(0, s + 1)]);
        f.push([south, id(rings - 1, s + 1), id(rings - 1, s)]);
    }
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (id(r, s), id(r, s + 1), id(r + 1, s), id(r + 1, s + 1));
            if r % 2 == 0 {
                f.push([a, c, b]);
                f.push([b, c, d]);
            } else {
                f.push([a, c, d]);
                f.push([a, d, b]);
            }
        }
    }
    TriMesh::new(v, f).expect("valid sphere")
}

#[test]
fn jittered_sphere_is_closed_and_outward() {
    let m = jittered_sphere(6, 10, 0.1, 3);
    m.require_closed().unwrap();
    assert!(m.signed_volume() > 3.0);
}
