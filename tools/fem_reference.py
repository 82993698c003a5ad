#!/usr/bin/env python3
"""Reference static solutions of one finger from an independent FEM code.

The finger's own closed surface (as `moe-touch hand` writes it) is tetrahedralised with TetGen
(the `tetgen` package on PyPI) and solved with scikit-fem's quadratic tetrahedra (P2) in linear
elasticity, fixed at the base plane. The load cases are the ones the simulator's comparison test
(`crates/moe-tendon-sim/tests/it/reference.rs`) applies to its own voxel FEM:

* presses at three heights (tip, middle, base) on three sides (the marker side and 90 degrees
  either way): a constant traction over the surface triangles within `PATCH_RADIUS_M` of the
  pressed vertex, total force `PRESS_N` against the vertex's rest normal;
* bending: a constant traction over the tip cap, total force `BEND_N` across the finger (x, y);
* twisting: a traction over the tip cap that turns about the finger axis, torque `TWIST_NM`;
* gravity across the finger (x, y) and along it (-z).

Every load is given per surface triangle as a constant traction, so that both codes integrate the
same load exactly. The solve is linear (small displacement): the fixture holds the displacements
of the surface vertices for the stated loads, and the Rust test compares the simulator's response
to the same loads scaled down by 1000, where its corotational elasticity is linear.

Convergence: the same cases are solved on a second TetGen mesh with a quarter of the maximum
element volume and a refined surface; the largest change of a marker displacement between the two
meshes, relative to the case's largest marker displacement, is written to the fixture as
`mesh_change` so that the reference's own error is on record.

Usage (needs `pip install scikit-fem tetgen numpy scipy`; run by hand, never by the tests):

    cargo run --release -p moe-touch-cli -- hand --out /tmp/hand
    python tools/fem_reference.py /tmp/hand fixtures/mechanics/finger_reference.json
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla
import skfem
import tetgen
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

E_PA = 1e5
NU = 0.1
DENSITY = 1070.0
G = 9.81
PRESS_N = 0.1
BEND_N = 0.02
TWIST_NM = 2e-4
PATCH_RADIUS_M = 0.004
TIP_CAP_M = 0.005
BASE_TOL_M = 1e-9
# Coarse and fine maximum element volumes, m^3 (regular tets of edge about 3.3 mm and 2.6 mm; the fine one also splits the surface).
COARSE_VOLUME = 4e-9
FINE_VOLUME = 2e-9


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    verts, faces = [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append([float(c) for c in parts[1:4]])
        elif parts[0] == "f":
            faces.append([int(c.split("/")[0]) - 1 for c in parts[1:4]])
    return np.array(verts), np.array(faces, dtype=np.int64)


def quat_matrix(xyzw: list[float]) -> np.ndarray:
    x, y, z, w = xyzw
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def load_finger(hand_dir: Path):
    hand = json.loads((hand_dir / "hand.json").read_text())
    finger = hand["fingers"][0]
    verts_hand, faces = read_obj(hand_dir / finger["mesh"])
    rot = quat_matrix(finger["hand_from_finger_rotation_xyzw"])
    trans = np.array(finger["hand_from_finger_translation_m"])
    verts = (verts_hand - trans) @ rot  # finger frame: rot^T (p - t)
    return verts, faces, finger["marker_vertices"], finger["base_vertices"]


def face_geometry(verts: np.ndarray, faces: np.ndarray):
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / (2.0 * area[:, None])
    centroid = (a + b + c) / 3.0
    return area, normal, centroid


def vertex_normals(verts, faces, area, normal):
    vn = np.zeros_like(verts)
    for k in range(3):
        np.add.at(vn, faces[:, k], normal * area[:, None])
    return vn / np.linalg.norm(vn, axis=1)[:, None]


def load_cases(verts, faces, markers, base_z):
    """Per case: name, per-face constant tractions {face: traction}, gravity vector."""
    area, normal, centroid = face_geometry(verts, faces)
    vn = vertex_normals(verts, faces, area, normal)
    length = verts[:, 2].max() - base_z
    marker_dir = verts[markers, :2].mean(axis=0)
    marker_angle = math.atan2(marker_dir[1], marker_dir[0])
    cases = []
    for height_name, frac in (("tip", 0.85), ("middle", 0.55), ("base", 0.3)):
        h = base_z + frac * length
        for side_name, turn in (("marker_side", 0.0), ("left", 0.5 * math.pi), ("right", -0.5 * math.pi)):
            ang = marker_angle + turn
            d = np.array([math.cos(ang), math.sin(ang)])
            near = np.where(np.abs(verts[:, 2] - h) < 0.003)[0]
            radial = verts[near, :2]
            score = (radial @ d) / np.maximum(np.linalg.norm(radial, axis=1), 1e-12)
            v = int(near[np.argmax(score)])
            patch = np.where(np.linalg.norm(centroid - verts[v], axis=1) < PATCH_RADIUS_M)[0]
            t = -vn[v] * PRESS_N / area[patch].sum()
            cases.append(
                {
                    "name": f"press_{height_name}_{side_name}",
                    "pressed_vertex": v,
                    "tractions": {int(f): t for f in patch},
                    "gravity": np.zeros(3),
                }
            )
    cap = np.where(centroid[:, 2] > verts[:, 2].max() - TIP_CAP_M)[0]
    cap_area = area[cap].sum()
    for axis_name, axis in (("x", np.array([1.0, 0, 0])), ("y", np.array([0, 1.0, 0]))):
        cases.append(
            {
                "name": f"bend_{axis_name}",
                "tractions": {int(f): axis * BEND_N / cap_area for f in cap},
                "gravity": np.zeros(3),
            }
        )
    r2 = (centroid[cap, 0] ** 2 + centroid[cap, 1] ** 2) * area[cap]
    c = TWIST_NM / r2.sum()
    cases.append(
        {
            "name": "twist_z",
            "tractions": {
                int(f): c * np.array([-centroid[f, 1], centroid[f, 0], 0.0]) for f in cap
            },
            "gravity": np.zeros(3),
        }
    )
    for name, g in (
        ("gravity_x", [G, 0, 0]),
        ("gravity_y", [0, G, 0]),
        ("gravity_minus_z", [0, 0, -G]),
    ):
        cases.append({"name": name, "tractions": {}, "gravity": np.array(g, dtype=float)})
    return cases


def tetrahedralise(verts, faces, max_volume, refine_surface):
    tg = tetgen.TetGen(verts, faces.astype(np.int32))
    nodes, elems, *_ = tg.tetrahedralize(
        quality=True,
        minratio=1.5,
        mindihedral=10.0,
        fixedvolume=True,
        maxvolume=max_volume,
        nobisect=not refine_surface,
        # Keep every input triangle a facet of its own: merged coplanar triangles would be
        # re-triangulated across their shared edges, and a traction given per input triangle
        # could no longer be told apart.
        nomergefacet=True,
    )
    # TetGen keeps the input points first and in order.
    assert np.allclose(nodes[: len(verts)], verts, atol=1e-12), "surface vertices moved"
    return nodes, elems


def solve(verts, faces, cases, base_z, max_volume, refine_surface):
    nodes, elems = tetrahedralise(verts, faces, max_volume, refine_surface)
    mesh = skfem.MeshTet(nodes.T.copy(), elems.T.astype(np.int64).copy())
    elem = skfem.ElementVector(skfem.ElementTetP2())
    basis = skfem.Basis(mesh, elem, intorder=4)
    stiffness = skfem.asm(linear_elasticity(*lame_parameters(E_PA, NU)), basis)
    fixed = basis.get_dofs(lambda x: x[2] <= base_z + BASE_TOL_M).all()
    free = np.setdiff1d(np.arange(basis.N), fixed)
    # Minimum-degree ordering on the symmetric pattern: the default column ordering fills in
    # an order of magnitude more for these 3-D quadratic elements.
    lu = spla.splu(stiffness[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A")

    # Boundary facets of the tet mesh that lie on each input surface triangle: TetGen keeps each
    # input facet as a union of boundary facets (the same triangle without surface refinement).
    area, normal, centroid = face_geometry(verts, faces)
    bfacets = mesh.boundary_facets()
    fc = mesh.p[:, mesh.facets[:, bfacets]].mean(axis=1).T
    owner = np.full(len(bfacets), -1)
    for k, p in enumerate(fc):
        dist = np.abs(np.einsum("ij,ij->i", p - verts[faces[:, 0]], normal))
        cand = np.where(dist < 1e-9)[0]
        for f in cand:
            a, b, c = verts[faces[f]]
            # Barycentric test within the triangle's plane.
            m = np.column_stack([b - a, c - a])
            lam, *_ = np.linalg.lstsq(m, p - a, rcond=None)
            if lam.min() >= -1e-9 and lam.sum() <= 1 + 1e-9:
                owner[k] = f
                break
    assert (owner >= 0).all(), "a boundary facet lies on no input triangle"

    out = {}
    for case in cases:
        rhs = np.zeros(basis.N)
        if case["tractions"]:
            faces_loaded = np.array(sorted(case["tractions"]))
            sel = np.isin(owner, faces_loaded)
            fb = skfem.FacetBasis(mesh, elem, facets=bfacets[sel], intorder=2)
            t = np.zeros((3, len(bfacets)))
            for k in np.where(sel)[0]:
                t[:, k] = case["tractions"][int(owner[k])]
            tsel = t[:, sel]

            @skfem.LinearForm
            def traction(v, w):
                return dot(w["t"], v)

            tq = np.repeat(tsel[:, :, None], fb.X.shape[-1], axis=2)
            rhs += skfem.asm(traction, fb, t=tq)
        if np.any(case["gravity"]):
            g = case["gravity"] * DENSITY

            @skfem.LinearForm
            def body(v, w):
                return g[0] * v[0] + g[1] * v[1] + g[2] * v[2]

            rhs += skfem.asm(body, basis)
        u = np.zeros(basis.N)
        u[free] = lu.solve(rhs[free])
        # Nodal values of the P2 field at the mesh vertices (the first dofs per component).
        disp = u[basis.nodal_dofs].T  # (num_vertices, 3)
        out[case["name"]] = disp[: len(verts)]
    return out, {"tets": int(mesh.t.shape[1]), "dofs": int(basis.N), "free": int(len(free))}


def write_fixture(out_path: Path, doc: dict) -> None:
    """Writes `doc` as compact JSON, creating the directory."""
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(doc, separators=(",", ":")) + "\n")
    print(f"wrote {out_path} ({out_path.stat().st_size / 1e6:.2f} MB)")


def main() -> None:
    hand_dir, out_path = Path(sys.argv[1]), Path(sys.argv[2])
    verts, faces, markers, base = load_finger(hand_dir)
    base_z = verts[base, 2].max()
    cases = load_cases(verts, faces, markers, base_z)
    t0 = time.time()
    coarse, coarse_info = solve(verts, faces, cases, base_z, COARSE_VOLUME, False)
    t1 = time.time()
    fine, fine_info = solve(verts, faces, cases, base_z, FINE_VOLUME, True)
    t2 = time.time()
    print(f"coarse {coarse_info} {t1 - t0:.1f} s; fine {fine_info} {t2 - t1:.1f} s")
    doc_cases = []
    for case in cases:
        name = case["name"]
        uf, uc = fine[name], coarse[name]
        scale = np.linalg.norm(uf[markers], axis=1).max()
        change = np.linalg.norm(uf[markers] - uc[markers], axis=1).max() / scale
        print(f"{name:28s} largest marker displacement {scale * 1e3:8.4f} mm, mesh change {change * 100:.2f} %")
        doc_cases.append(
            {
                "name": name,
                "pressed_vertex": case.get("pressed_vertex"),
                "gravity_m_s2": case["gravity"].tolist(),
                "face_tractions_pa": [
                    [f, *np.round(t, 9).tolist()] for f, t in sorted(case["tractions"].items())
                ],
                "mesh_change": float(change),
                "displacement_m": np.round(uf, 10).tolist(),
            }
        )
    doc = {
        "what": "Static linear-elastic displacements of finger 0 of the default two-finger hand, "
        "scikit-fem P2 tetrahedra on a TetGen mesh of the finger's own surface, fixed at z <= base_z",
        "made_by": "tools/fem_reference.py",
        "youngs_modulus_pa": E_PA,
        "poisson_ratio": NU,
        "density_kg_m3": DENSITY,
        "base_z_m": float(base_z),
        "meshes": {"coarse": coarse_info, "fine": fine_info},
        "vertices_m": np.round(verts, 12).tolist(),
        "faces": faces.tolist(),
        "marker_vertices": list(markers),
        "cases": doc_cases,
    }
    write_fixture(out_path, doc)


if __name__ == "__main__":
    main()
