// Fields of a 3-D (tetrahedral) result for GetField: a planar slice of the deformed body, as a
// 2-D triangle mesh in the plane's coordinates that field_raster.hpp then rasterises like a 2-D
// result; and the deformed boundary surface, decimated by vertex clustering.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace softshock::server {

// A plane through `point` with normal `normal` (need not be unit; not zero), and its in-plane
// axes: u the coordinate axis least aligned with the normal projected onto the plane, v =
// normal x u; for the normal +z: u = +x, v = +y.
struct SlicePlane {
  std::array<double, 3> origin{}, normal{}, u{}, v{};
};
// Throws std::invalid_argument for a zero or non-finite normal or a non-finite point.
SlicePlane make_slice_plane(const std::array<double, 3>& point,
                            const std::array<double, 3>& normal);

// The section of the tetrahedra by the plane, as triangles in (u, v) with the field on them:
// node fields interpolated linearly to each cut edge's point, element fields constant on each
// tetrahedron's section (a triangle or a quadrilateral split in two). `values` has `components`
// per node (node_field) or per tetrahedron.
struct SliceMesh {
  std::vector<double> u, v;                       // section vertices
  std::vector<std::array<int32_t, 3>> triangles;  // section triangles
  std::vector<double> values;                     // per vertex (node fields) or per triangle
};
SliceMesh slice_tetrahedra(const std::vector<double>& x, const std::vector<double>& y,
                           const std::vector<double>& z,
                           const std::vector<std::array<int32_t, 4>>& tetrahedra,
                           const std::vector<double>& values, int components, bool node_field,
                           const SlicePlane& plane);

// The boundary surface (outward faces of the deformed positions), decimated by clustering its
// vertices on a uniform grid until it has at most max_triangles triangles (Rossignac and
// Borrel's vertex clustering: a cluster's vertex is the mean of its members, triangles whose
// corners fall in fewer than three clusters disappear). Node fields are averaged per cluster,
// element fields (one value per face: the tetrahedron's it bounds) kept per surviving triangle.
struct SurfaceMesh {
  std::vector<double> xyz;                        // 3 per vertex
  std::vector<std::array<int32_t, 3>> triangles;  // vertex indices
  std::vector<double> values;                     // per vertex (node fields) or per triangle
};
SurfaceMesh decimated_surface(const std::vector<double>& x, const std::vector<double>& y,
                              const std::vector<double>& z,
                              const std::vector<std::array<int32_t, 3>>& faces,
                              const std::vector<double>& values, int components, bool node_field,
                              std::size_t max_triangles);

}  // namespace softshock::server
