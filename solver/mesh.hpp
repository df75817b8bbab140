// Unstructured mesh of linear simplices, reference configuration, SI units: 2-D triangles (Tri3,
// plane strain) or 3-D tetrahedra (Tet4). A mesh is one or the other: tetrahedra and z are empty
// in 2-D, triangles and boundary_edges in 3-D.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace softshock {

struct Mesh {
  std::vector<double> x, y;  // reference node coordinates, m
  std::vector<double> z;     // 3-D only
  // 2-D: node indices, counter-clockwise; every boundary edge, body on the left; the outer
  // boundary loop, counter-clockwise, no repeat.
  std::vector<std::array<int32_t, 3>> triangles;
  std::vector<std::array<int32_t, 2>> boundary_edges;
  std::vector<int32_t> boundary_nodes;
  // 3-D: node indices with positive volume (det [X1 - X0, X2 - X0, X3 - X0] > 0); every boundary
  // face (a face of exactly one tetrahedron), ordered so that (b - a) x (c - a) points out of the
  // body.
  std::vector<std::array<int32_t, 4>> tetrahedra;
  std::vector<std::array<int32_t, 3>> boundary_faces;

  int dimension() const { return tetrahedra.empty() && z.empty() ? 2 : 3; }
  std::size_t node_count() const { return x.size(); }
  std::size_t element_count() const {
    return dimension() == 3 ? tetrahedra.size() : triangles.size();
  }
};

// 2-D: orients every triangle counter-clockwise, finds the boundary edges (edges used by exactly
// one triangle) and orders the outer loop (the loop enclosing the largest area). 3-D: orients
// every tetrahedron positively and finds the boundary faces (faces of exactly one tetrahedron),
// oriented outwards. Throws std::invalid_argument on degenerate elements, out-of-range indices,
// non-finite coordinates, nodes used by no element, or edges (faces) shared by more than two
// elements.
void finalize_mesh(Mesh& mesh);

// Renumbers nodes along a Morton (Z-order) curve and elements by the curve position of their
// centroid, then finalizes again. Neighbouring elements then share cache lines, which keeps the
// element loop's gathers and the nodal-force gather cache-friendly on large meshes.
void sort_for_locality(Mesh& mesh);

// ---- 3-D (tet_mesh.cpp) ------------------------------------------------------------------

// finalize_mesh's and sort_for_locality's 3-D halves.
void finalize_tet_mesh(Mesh& mesh);
void sort_tet_mesh_for_locality(Mesh& mesh);

// Structured box [0, lx] x [0, ly] x [0, lz] of nx x ny x nz cells, each split into six
// tetrahedra (Kuhn's subdivision along the cell's main diagonal: conforming across cells).
// Finalized. For tests and benchmarks.
Mesh make_box_mesh(double lx, double ly, double lz, int nx, int ny, int nz);

// The box 0 <= x <= lx, 0 <= y <= ly, 0 <= z <= lz + amplitude cos(kx x) cos(ky y) (the 3-D
// planar Richtmyer-Meshkov target): make_box_mesh with about target_elements tetrahedra of
// aspect ~1, stretched in z so its top follows the corrugation exactly (at the nodes; linear
// between them). Requires |amplitude| < lz / 2; no tetrahedron turns over, however steep the
// corrugation. Morton-sorted (sort_for_locality) and finalized.
Mesh make_corrugated_box_mesh(double lx, double ly, double lz, double amplitude, double kx,
                              double ky, int target_elements);

// The 2-D mesh `base` extruded along z from z_bottom to z_top in `layers` layers of prisms, each
// split into three tetrahedra by its vertices' order in `base` (every vertical face then takes the
// diagonal from the lower-numbered vertex's top to the other's bottom, so neighbouring prisms
// agree). Layer k's nodes are base's at z_bottom + k (z_top - z_bottom) / layers, numbered
// k * N + i. Finalized, not sorted.
Mesh extrude_mesh(const Mesh& base, double z_bottom, double z_top, int layers);

// Volume-weighted centroid and total volume of a 3-D mesh.
std::array<double, 3> tet_mesh_centroid(const Mesh& mesh);
double mesh_volume(const Mesh& mesh);

// Structured rectangle [0,lx] x [0,ly] with nx x ny cells, each split into two triangles
// (diagonals alternating so the mesh has no preferred direction). For tests and benchmarks.
Mesh make_rectangle_mesh(double lx, double ly, int nx, int ny);

// The strip 0 <= x <= wavelength / 2, 0 <= y <= height + amplitude cos(2 pi x / wavelength)
// (a planar Richtmyer-Meshkov target): a rectangle mesh of about target_elements triangles of
// aspect ~1, stretched vertically so its top follows the corrugation exactly.
Mesh make_corrugated_strip_mesh(double wavelength, double height, double amplitude,
                                int target_elements);

// Turns every node about the origin by angle_rad (counter-clockwise).
void rotate_mesh(Mesh& mesh, double angle_rad);

// Area-weighted centroid and total area of the mesh.
std::array<double, 2> mesh_centroid(const Mesh& mesh);
double mesh_area(const Mesh& mesh);

}  // namespace softshock
