// Meshes built or read with Gmsh's C++ API. Gmsh keeps global state, so every function here
// serialises on one process-wide mutex; meshing is single-threaded and deterministic.
// gmsh_mesher.cpp is compiled into a module loaded on first use (gmsh_plugin.hpp); the solver
// library's gmsh_loader.cpp provides these functions by forwarding to it.
#pragma once

#include <string>

#include "mesh.hpp"

namespace softshock {

// Unstructured frontal-Delaunay mesh of the disk of given radius centred at the origin, with
// about target_elements triangles (within ~5 %; no imposed symmetry).
Mesh mesh_disk(double radius_m, int target_elements);

// Square of given side centred at the origin with corners rounded at corner_radius.
Mesh mesh_rounded_square(double side_m, double corner_radius_m, int target_elements);

// Unstructured 3-D Delaunay mesh of the cylinder r <= R, -H/2 <= z <= H/2 (thickness H), with
// about target_elements tetrahedra (within 3 % from ~5k elements; a few layers through the
// thickness make the count jump, e.g. -6 % at 2k for H = 0.56 R). The mid-plane z = 0 is a
// meshed interface: nodes lie on its rim, the circle r = R, z = 0 (~2 pi R / h of them, h the
// size Gmsh is given; ~1.3 x 2 pi R / (mean edge length)). Morton-sorted and finalized.
Mesh mesh_cylinder(double radius_m, double thickness_m, int target_elements);

// Unstructured 3-D Delaunay mesh of the ball of given radius centred at the origin, with about
// target_elements tetrahedra. Morton-sorted and finalized.
Mesh mesh_sphere(double radius_m, int target_elements);

// Reads a .msh file; coordinates are taken in metres. If it holds any 4-node tetrahedra (Gmsh
// type 4), a 3-D mesh of those (other elements ignored); otherwise a 2-D mesh of its 3-node
// triangles (type 2), z ignored. Nodes renumbered in tag order; finalized, not sorted. Throws
// std::runtime_error naming the file on any failure.
Mesh read_gmsh_file(const std::string& path);

// Whether this process has loaded the mesher module (and with it libgmsh).
bool gmsh_mesher_loaded();
// The Gmsh release the module is built against (e.g. "4.8.4"), known without loading it.
std::string gmsh_version();

}  // namespace softshock
