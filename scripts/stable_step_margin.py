#!/usr/bin/python3
"""How far the solver's time step sits below the central-difference stability limit, at rest.

Usage: stable_step_margin.py RESULT.h5 [RESULT.h5 ...]

For the mesh and material stored in each result file (mesh/nodes, mesh/triangles, the spec in
attrs['spec']) this assembles the linear volumetric stiffness at rest -- plain P1, where each
element carries kappa (dJ_e)^2 / 2 per area, and the average nodal pressure element, where each
node does with its patch-averaged J_a, plus beta kappa times the P1 term as a bound on its
stabilisation -- with lumped masses rho A_e / 3, finds the largest eigenvalue omega_max^2 of
M^-1 K (scipy's Lanczos), and prints the critical step 2 / omega_max beside the solver's element
estimate h / c (smallest altitude over the longitudinal speed) and the step it takes, cfl h / c.
The shear modulus (kappa / mu ~ 4e5) and the viscosity are left out.

tests/solver/test_element_kernels.cpp (StableStep.LiesWithinTheCentralDifferenceLimitOfThe-
AssembledOperator) checks the same on a 300-element disk from the kernel's own forces, at rest and
compressed; this script gives the figures for full-size meshes (docs/verification.md).
"""
import json
import sys

import h5py
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla


def largest_eigenvalue(k, inv_sqrt_mass):
    a = sp.diags(inv_sqrt_mass) @ k @ sp.diags(inv_sqrt_mass)
    return sla.eigsh(a, k=1, which="LA", return_eigenvectors=False)[0]


def margins(path):
    try:
        with h5py.File(path, "r") as f:
            xy = f["mesh/nodes"][:]
            tri = f["mesh/triangles"][:]
            spec = json.loads(f.attrs["spec"])
    except (OSError, KeyError) as e:
        sys.exit(f"{path}: not a softshock result file with mesh/nodes, mesh/triangles and a spec "
                 f"attribute ({e})")
    material, element = spec.get("material", {}), spec.get("element", {})
    kappa = float(material.get("bulk_modulus", 2e9))
    mu = float(material.get("shear_modulus", 5e3))
    rho = float(material.get("density", 1000.0))
    beta = float(element.get("stabilization", 0.0))
    cfl = float(spec.get("run", {}).get("cfl", 0.5))

    x, y = xy[:, 0], xy[:, 1]
    nn, ne = len(x), len(tri)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    area = 0.5 * ((x[b] - x[a]) * (y[c] - y[a]) - (x[c] - x[a]) * (y[b] - y[a]))
    # d(area)/d(node coordinates), three corners in turn: 0.5 (y_j - y_k, x_k - x_j).
    grad = np.zeros((ne, 6))
    dof = np.zeros((ne, 6), dtype=int)
    for corner, (i, j, k) in enumerate([(a, b, c), (b, c, a), (c, a, b)]):
        grad[:, 2 * corner], grad[:, 2 * corner + 1] = 0.5 * (y[j] - y[k]), 0.5 * (x[k] - x[j])
        dof[:, 2 * corner], dof[:, 2 * corner + 1] = 2 * i, 2 * i + 1
    rows = np.repeat(np.arange(ne), 6)
    d_area = sp.csr_matrix((grad.ravel(), (rows, dof.ravel())), shape=(ne, 2 * nn))
    d_j_element = sp.diags(1.0 / area) @ d_area
    k_p1 = d_j_element.T @ sp.diags(kappa * area) @ d_j_element

    nodal_area = np.zeros(nn)
    for corner in (a, b, c):
        np.add.at(nodal_area, corner, area / 3.0)
    owner = sp.csr_matrix((np.ones(3 * ne), (np.concatenate([a, b, c]), np.tile(np.arange(ne), 3))),
                          shape=(nn, ne))
    d_j_nodal = sp.diags(1.0 / nodal_area) @ owner @ (d_area / 3.0)
    k_nodal = d_j_nodal.T @ sp.diags(kappa * nodal_area) @ d_j_nodal + beta * k_p1

    inv_sqrt_mass = np.repeat(1.0 / np.sqrt(rho * nodal_area), 2)
    edges_sq = np.maximum.reduce([(x[b] - x[a]) ** 2 + (y[b] - y[a]) ** 2,
                                  (x[c] - x[a]) ** 2 + (y[c] - y[a]) ** 2,
                                  (x[c] - x[b]) ** 2 + (y[c] - y[b]) ** 2])
    smallest_altitude = np.min(2.0 * np.abs(area) / np.sqrt(edges_sq))
    estimate = smallest_altitude / np.sqrt((kappa + 4.0 / 3.0 * mu) / rho)
    print(f"{path}: {ne} elements, element estimate h/c = {estimate * 1e12:.1f} ps, "
          f"step taken (cfl {cfl}) {cfl * estimate * 1e12:.1f} ps")
    for name, k in (("plain P1", k_p1), (f"average nodal pressure (beta {beta})", k_nodal)):
        limit = 2.0 / np.sqrt(largest_eigenvalue(k, inv_sqrt_mass))
        print(f"  {name}: limit 2/omega_max = {limit * 1e12:.1f} ps = {limit / estimate:.2f} h/c;"
              f" the step taken is {cfl * estimate / limit:.2f} of it")


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for path in sys.argv[1:]:
        margins(path)


if __name__ == "__main__":
    main()
