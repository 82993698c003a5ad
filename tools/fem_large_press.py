#!/usr/bin/env python3
"""Reference large presses of one finger from an independent FEM code.

The companion of `fem_reference.py` (same finger, TetGen mesh and scikit-fem quadratic
tetrahedra, base fixed) for presses far beyond the linear range: compressible Neo-Hookean
elasticity (the strain energy mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2, with the Lame
parameters of the same Young's modulus and Poisson ratio), solved by Newton's method in load
increments.

The finger's cables are in the model as in the project's default hand at zero pull: each
route (`tendon_routes_m` of `hand.json`) is a polyline of points that move with the body, held at
its rest length by its motor, so its tension is `k max(0, L - L0)` (`k` the project's default
1e5 N/m, `L` the path's length): it resists any bending that lengthens it and never pushes.

The press is a follower load: on each surface triangle of the patch (the triangles within
`PATCH_RADIUS_M` of the pressed vertex, as in `fem_reference.py`) a constant traction per rest
area, of magnitude `force / patch rest area`, along the inward normal of the triangle as it is
deformed (its corners' displaced positions). That is what an object pressing the finger does
(its force stays normal to the surface it presses), and the resultant's magnitude is the stated
force up to the spread of the patch's normals, which the fixture records: `resultant_n` is the
sum of the tractions at the solution. Newton's tangent includes the follower load's own
derivative (it depends on the patch triangles' corners only), so each increment converges
quadratically; the solve stops when the update of every node is below `TOLERANCE_M`.

For each press place (three heights x three sides, the places of `fem_reference.py`) the
fixture holds the surface vertices' displacements and the resultant at each force of
`FORCES_N`. A Rust test feeds the markers to the contact estimator as lone frames.

Usage (needs `pip install scikit-fem tetgen numpy scipy`; run by hand, never by the tests):

    cargo run --release -p moe-touch-cli -- hand --out /tmp/hand
    python tools/fem_large_press.py /tmp/hand fixtures/mechanics/finger_large_presses.json
"""

from __future__ import annotations

import json
import multiprocessing
import os
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem
from skfem.helpers import ddot, det, dot, grad, identity, inv, mul, trace, transpose
from skfem.models.elasticity import lame_parameters

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fem_reference as fr  # noqa: E402

FORCES_N = [0.25, 0.5, 0.75, 1.0]
# Load increments per 0.25 N.
SUBSTEPS = 2
TOLERANCE_M = 1e-7
MAX_ITERATIONS = 30
# Axial stiffness of a cable, N/m (the project's default `TendonParams`).
CABLE_STIFFNESS_N_PER_M = 1e5
# P2 tetrahedra of this maximum volume agree with `fem_reference.py`'s converged fixture within
# 0.1 % on every press (linear solve).
MAX_VOLUME = 1.6e-8

# What the worker processes of `main` share (they are forked from it).
_CONTEXT: dict = {}


def _solve_press(index: int):
    return _CONTEXT["solve"](_CONTEXT["presses"][index])


def main() -> None:
    hand_dir, out_path = Path(sys.argv[1]), Path(sys.argv[2])
    verts, faces, markers, base = fr.load_finger(hand_dir)
    base_z = verts[base, 2].max()
    presses = [
        c for c in fr.load_cases(verts, faces, markers, base_z) if c["name"].startswith("press")
    ]
    area, _, _ = fr.face_geometry(verts, faces)

    nodes, elems = fr.tetrahedralise(verts, faces, MAX_VOLUME, False)
    mesh = skfem.MeshTet(nodes.T.copy(), elems.T.astype(np.int64).copy())
    elem = skfem.ElementVector(skfem.ElementTetP2())
    # Order 3: the quadratic elements' linear part exactly, the Neo-Hookean terms to well within
    # the mesh's own error.
    basis = skfem.Basis(mesh, elem, intorder=3)
    lam, mu = lame_parameters(fr.E_PA, fr.NU)
    fixed = basis.get_dofs(lambda x: x[2] <= base_z + fr.BASE_TOL_M).all()
    free = np.setdiff1d(np.arange(basis.N), fixed)

    # The cables: each route's points (finger frame, nudged off the base plane into the body)
    # follow the body, `p = X + P u`; rows of P are component-major (x of every point, then y,
    # then z).
    hand = json.loads((hand_dir / "hand.json").read_text())
    finger0 = hand["fingers"][0]
    rot = fr.quat_matrix(finger0["hand_from_finger_rotation_xyzw"])
    trans = np.array(finger0["hand_from_finger_translation_m"])
    cables = []
    for route in finger0["tendon_routes_m"]:
        rest = (np.array(route) - trans) @ rot
        rest[:, 2] = np.maximum(rest[:, 2], base_z + 1e-6)
        probe = basis.probes(rest.T).tocsr()
        lengths = np.linalg.norm(np.diff(rest, axis=0), axis=1)
        cables.append((rest, probe, lengths.sum()))

    def cable_terms(u):
        """The held cables' nodal forces (as internal forces, `+T dL/du`) and tangent: each
        cable's tension `k max(0, L - L0)` along its path of length `L`, `L0` its rest length
        (held at rest length, as the project's default hand at zero pull)."""
        force = np.zeros(basis.N)
        stiffness = sp.csr_matrix((basis.N, basis.N))
        for rest, probe, rest_length in cables:
            n = len(rest)
            p = rest + (probe @ u).reshape(3, n).T
            d = np.diff(p, axis=0)
            ell = np.linalg.norm(d, axis=1)
            unit = d / ell[:, None]
            excess = ell.sum() - rest_length
            if excess <= 0.0:
                continue
            tension = CABLE_STIFFNESS_N_PER_M * excess
            dl_dp = np.zeros((n, 3))
            dl_dp[1:] += unit
            dl_dp[:-1] -= unit
            g = probe.T @ dl_dp.T.ravel()
            force += tension * g
            # Geometric stiffness (T / l)(I - u u^T) between consecutive points.
            rows, cols, vals = [], [], []
            for k in range(n - 1):
                block = (np.eye(3) - np.outer(unit[k], unit[k])) * (tension / ell[k])
                for a, sa in ((k, 1.0), (k + 1, -1.0)):
                    for b, sb in ((k, 1.0), (k + 1, -1.0)):
                        for i in range(3):
                            for j in range(3):
                                rows.append(i * n + a)
                                cols.append(j * n + b)
                                vals.append(sa * sb * block[i, j])
            h = sp.csr_matrix((vals, (rows, cols)), shape=(3 * n, 3 * n))
            gs = sp.csr_matrix(g)
            stiffness = stiffness + CABLE_STIFFNESS_N_PER_M * (gs.T @ gs) + probe.T @ h @ probe
        return force, stiffness

    def piola(gu):
        f = gu + identity(gu)
        finv_t = transpose(inv(f))
        return f, finv_t, mu * (f - finv_t) + lam * np.log(det(f)) * finv_t

    @skfem.LinearForm
    def internal(v, w):
        return ddot(piola(grad(w["u"]))[2], grad(v))

    @skfem.BilinearForm
    def tangent(du, v, w):
        f, finv_t, _ = piola(grad(w["u"]))
        log_j = np.log(det(f))
        d = grad(du)
        dp = (
            mu * d
            + (mu - lam * log_j) * mul(finv_t, mul(transpose(d), finv_t))
            + lam * trace(mul(transpose(finv_t), d)) * finv_t
        )
        return ddot(dp, grad(v))

    # The boundary facets on each input triangle (no surface refinement: one each).
    bfacets = mesh.boundary_facets()
    bverts = np.sort(mesh.facets[:, bfacets], axis=0)
    owner_of = {tuple(k): i for i, k in enumerate(bverts.T)}

    @skfem.LinearForm
    def traction(v, w):
        return dot(w["t"], v)

    t_start = time.time()

    def solve_one(case):
        patch = np.array(sorted(case["tractions"]))
        sel = np.array([owner_of[tuple(sorted(faces[f]))] for f in patch])
        fb = skfem.FacetBasis(mesh, elem, facets=bfacets[sel], intorder=2)
        rest_area = area[patch].sum()
        u = np.zeros(basis.N)
        states = []
        steps = SUBSTEPS * round(FORCES_N[-1] / 0.25)
        iterations = 0
        # The nodal forces are linear in the per-triangle tractions: `ext = B t`, B assembled
        # once, one column per triangle and axis.
        unit = np.zeros((3, len(patch), fb.X.shape[-1]))
        columns = []
        for j in range(len(patch)):
            for d in range(3):
                unit[:] = 0.0
                unit[d, j, :] = 1.0
                columns.append(skfem.asm(traction, fb, t=unit))
        b_mat = sp.csr_matrix(np.column_stack(columns))
        corners = faces[patch]
        corner_dofs = basis.nodal_dofs[:, corners.ravel()].T.reshape(len(patch), 3, 3)

        def skew(w):
            return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])

        def external(u, force):
            """The follower traction's nodal forces at displacement `u`, its derivative with
            respect to `u` and the triangles' deformed unit normals."""
            x = verts + u[basis.nodal_dofs].T[: len(verts)]
            a, b, c = (x[corners[:, k]] for k in range(3))
            raw = np.cross(b - a, c - a)
            length = np.linalg.norm(raw, axis=1)
            n = raw / length[:, None]
            # Traction per rest area along the deformed inward normal; the facet basis
            # integrates over the rest facet.
            scale = force / rest_area
            t = -n * scale
            rows, cols, vals = [], [], []
            for j in range(len(patch)):
                # d(raw)/d(corner): skew(c - b), skew(a - c), skew(b - a); dn = P dn_raw / |raw|.
                proj = (np.eye(3) - np.outer(n[j], n[j])) / length[j]
                for k, m in enumerate((skew(c[j] - b[j]), skew(a[j] - c[j]), skew(b[j] - a[j]))):
                    block = -scale * proj @ m
                    for d in range(3):
                        for e in range(3):
                            rows.append(3 * j + d)
                            cols.append(corner_dofs[j, k, e])
                            vals.append(block[d, e])
            dt = sp.csr_matrix((vals, (rows, cols)), shape=(3 * len(patch), basis.N))
            return b_mat @ t.ravel(), b_mat @ dt, n

        failed_at = None
        for step in range(1, steps + 1):
            force = FORCES_N[-1] * step / steps
            for it in range(MAX_ITERATIONS):
                ext, load_stiffness, _ = external(u, force)
                uw = basis.interpolate(u)
                cable_force, cable_stiffness = cable_terms(u)
                residual = skfem.asm(internal, basis, u=uw) + cable_force - ext
                k = skfem.asm(tangent, basis, u=uw) + cable_stiffness - load_stiffness
                lu = spla.splu(k[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A")
                du = -lu.solve(residual[free])
                # Halve a step that would invert an element (ln J undefined).
                alpha = 1.0
                trial = None
                for _ in range(20):
                    candidate = u.copy()
                    candidate[free] += alpha * du
                    g = basis.interpolate(candidate).grad
                    if np.all(det(g + identity(g)) > 0):
                        trial = candidate
                        break
                    alpha *= 0.5
                if trial is None:
                    # Every step inverts an element: no equilibrium on this path.
                    converged = False
                    break
                u = trial
                iterations += 1
                # Converged on a full Newton step only: a damped one is short far from
                # equilibrium.
                if alpha == 1.0 and np.abs(du).max() < TOLERANCE_M:
                    converged = True
                    break
            else:
                converged = False
            if not converged:
                # No equilibrium found (the finger folds): the press keeps the forces solved.
                failed_at = force
                print(f"{case['name']:24s} {force:5.2f} N  did not converge", flush=True)
                break
            if any(abs(force - f) < 1e-12 for f in FORCES_N):
                disp = u[basis.nodal_dofs].T[: len(verts)]
                _, _, n = external(u, force)
                resultant = -(n * area[patch][:, None]).sum(axis=0) * (force / rest_area)
                states.append(
                    {
                        "force_n": force,
                        "resultant_n": np.round(resultant, 9).tolist(),
                        "displacement_m": np.round(disp, 10).tolist(),
                    }
                )
                tip = np.linalg.norm(disp[markers], axis=1).max()
                print(
                    f"{case['name']:24s} {force:5.2f} N  |resultant| {np.linalg.norm(resultant):.4f} N"
                    f"  largest marker move {tip * 1e3:6.2f} mm  ({iterations} iterations,"
                    f" {time.time() - t_start:.0f} s)",
                    flush=True,
                )
        return (
            {
                "name": case["name"],
                "pressed_vertex": case["pressed_vertex"],
                "patch_faces": patch.tolist(),
                "states": states,
                "not_converged_at_n": failed_at,
            }
        )

    _CONTEXT["solve"] = solve_one
    _CONTEXT["presses"] = presses
    doc_presses = []
    # Presses are independent: one process each, as many at once as `FEM_PROCESSES` (2).
    processes = int(os.environ.get("FEM_PROCESSES", "2"))
    with multiprocessing.get_context("fork").Pool(processes) as pool:
        for entry in pool.imap(_solve_press, range(len(presses))):
            doc_presses.append(entry)
            # Written after every press: a long run stopped early keeps what it solved.
            doc = {
                "what": "Static Neo-Hookean displacements of finger 0 of the default two-finger hand "
                "under follower presses, scikit-fem P2 tetrahedra on a TetGen mesh of the finger's "
                "own surface, fixed at z <= base_z",
                "made_by": "tools/fem_large_press.py",
                "youngs_modulus_pa": fr.E_PA,
                "poisson_ratio": fr.NU,
                "base_z_m": float(base_z),
                "mesh": {"tets": int(mesh.t.shape[1]), "dofs": int(basis.N)},
                "cable_stiffness_n_per_m": CABLE_STIFFNESS_N_PER_M,
                "marker_vertices": list(markers),
                "presses": doc_presses,
            }
            fr.write_fixture(out_path, doc)


if __name__ == "__main__":
    main()
