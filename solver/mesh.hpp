// Unstructured 2D triangle mesh (P1), reference configuration, SI units.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace softshock {

struct Mesh {
  std::vector<double> x, y;                            // reference node coordinates, m
  std::vector<std::array<int32_t, 3>> triangles;       // node indices, counter-clockwise
  std::vector<std::array<int32_t, 2>> boundary_edges;  // every boundary edge, body on the left
  std::vector<int32_t> boundary_nodes;  // the outer boundary loop, counter-clockwise, no repeat

  std::size_t node_count() const { return x.size(); }
  std::size_t element_count() const { return triangles.size(); }
};

// Orients every triangle counter-clockwise, finds the boundary edges (edges used by exactly one
// triangle) and orders the outer loop (the loop enclosing the largest area). Throws
// std::invalid_argument on degenerate triangles, out-of-range indices, nodes used by no
// triangle, or edges shared by more than two triangles.
void finalize_mesh(Mesh& mesh);

// Renumbers nodes along a Morton (Z-order) curve and elements by the curve position of their
// centroid, then finalizes again. Neighbouring elements then share cache lines, which keeps the
// element loop's gathers and the nodal-force gather cache-friendly on large meshes.
void sort_for_locality(Mesh& mesh);

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
