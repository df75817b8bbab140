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

// Reads the 2D triangles (3-node, Gmsh type 2) of a .msh file; z is ignored, coordinates are
// taken in metres. Throws std::runtime_error naming the file on any failure.
Mesh read_gmsh_file(const std::string& path);

// Whether this process has loaded the mesher module (and with it libgmsh).
bool gmsh_mesher_loaded();
// The Gmsh release the module is built against (e.g. "4.8.4"), known without loading it.
std::string gmsh_version();

}  // namespace softshock
