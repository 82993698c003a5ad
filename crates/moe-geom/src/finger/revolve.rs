//! Mesh generation: the finger's closed surface of revolution, sampled to a vertex budget.

use std::f64::consts::{FRAC_PI_2, PI};

use super::params::FingerParams;
use crate::error::GeomError;
use crate::math::{Point3, Real};
use crate::mesh::TriMesh;

/// Profile samples `(r, z)` from the base pole to the tip apex at spacing about `h`; the first
/// and last have `r = 0`.
fn profile(params: &FingerParams, h: Real) -> Vec<(Real, Real)> {
    let (rb, rt, zc) = (
        params.base_radius_m,
        params.tip_radius_m,
        params.cap_start_z(),
    );
    let side_len = ((rb - rt).powi(2) + zc * zc).sqrt();
    let n0 = ((rb / h).round() as usize).max(1);
    let n1 = ((side_len / h).round() as usize).max(1);
    let n2 = ((rt * FRAC_PI_2 / h).round() as usize).max(2);
    let mut out = Vec::with_capacity(n0 + n1 + n2 + 1);
    for k in 0..=n0 {
        out.push((rb * k as Real / n0 as Real, 0.0));
    }
    for k in 1..=n1 {
        let t = k as Real / n1 as Real;
        out.push((rb + (rt - rb) * t, zc * t));
    }
    for k in 1..=n2 {
        let phi = FRAC_PI_2 * k as Real / n2 as Real;
        let r = if k == n2 { 0.0 } else { rt * phi.cos() };
        out.push((r, zc + rt * phi.sin()));
    }
    out
}

fn ring_count(r: Real, h: Real) -> usize {
    if r <= 0.0 {
        1
    } else {
        ((2.0 * PI * r / h).round() as usize).max(3)
    }
}

fn vertex_count(params: &FingerParams, h: Real) -> usize {
    profile(params, h)
        .iter()
        .map(|&(r, _)| ring_count(r, h))
        .sum()
}

/// Finds the sample spacing whose vertex count is closest to the budget.
fn spacing_for_budget(params: &FingerParams) -> Real {
    let (rb, rt, zc) = (
        params.base_radius_m,
        params.tip_radius_m,
        params.cap_start_z(),
    );
    let scale = rb + zc + rt;
    let (mut lo, mut hi) = (scale * 1e-5, scale); // count(lo) > budget > count(hi)
    let target = params.vertex_budget;
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if vertex_count(params, mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let err = |h| (vertex_count(params, h) as i64 - target as i64).unsigned_abs();
    if err(lo) < err(hi) { lo } else { hi }
}

/// Builds the closed surface of revolution by stitching consecutive rings.
pub(super) fn revolve_finger(params: &FingerParams) -> Result<TriMesh, GeomError> {
    let h = spacing_for_budget(params);
    let prof = profile(params, h);
    let mut vertices = Vec::new();
    let mut rings: Vec<(usize, usize, Real)> = Vec::with_capacity(prof.len()); // start, count, phase
    for (k, &(r, z)) in prof.iter().enumerate() {
        let m = ring_count(r, h);
        let phase = if k % 2 == 0 { 0.0 } else { 0.5 };
        rings.push((vertices.len(), m, phase));
        if m == 1 {
            vertices.push(Point3::new(0.0, 0.0, z));
        } else {
            for i in 0..m {
                let th = 2.0 * PI * (i as Real + phase) / m as Real;
                vertices.push(Point3::new(r * th.cos(), r * th.sin(), z));
            }
        }
    }
    let mut faces: Vec<[u32; 3]> = Vec::new();
    for w in rings.windows(2) {
        stitch(w[0], w[1], &mut faces);
    }
    let mesh = TriMesh::new(vertices, faces)?;
    Ok(if mesh.signed_volume() < 0.0 {
        mesh.flipped()
    } else {
        mesh
    })
}

/// Triangulates the band between ring `a` (lower in the profile) and ring `b` by advancing
/// along whichever ring's next vertex has the smaller angle.
fn stitch(a: (usize, usize, Real), b: (usize, usize, Real), faces: &mut Vec<[u32; 3]>) {
    let (a0, ma, pa) = a;
    let (b0, mb, pb) = b;
    let ia = |i: usize| (a0 + i % ma) as u32;
    let ib = |j: usize| (b0 + j % mb) as u32;
    if ma == 1 {
        for j in 0..mb {
            faces.push([ia(0), ib(j + 1), ib(j)]);
        }
        return;
    }
    if mb == 1 {
        for i in 0..ma {
            faces.push([ia(i), ia(i + 1), ib(0)]);
        }
        return;
    }
    let ang_a = |i: usize| (i as Real + pa) / ma as Real;
    let ang_b = |j: usize| (j as Real + pb) / mb as Real;
    let (mut i, mut j) = (0, 0);
    while i < ma || j < mb {
        let advance_a = j == mb || (i < ma && ang_a(i + 1) < ang_b(j + 1));
        if advance_a {
            faces.push([ia(i), ia(i + 1), ib(j)]);
            i += 1;
        } else {
            faces.push([ia(i), ib(j + 1), ib(j)]);
            j += 1;
        }
    }
}
