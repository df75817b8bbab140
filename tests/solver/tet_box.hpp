// A small tetrahedral box built by hand, for tests of 3-D result files and the sample result
// that tests/paraview renders. It needs neither a 3-D mesher nor finalize_mesh's 3-D half (this
// code must work without them), so it orients the tetrahedra and finds the outward boundary
// faces itself. Header-only, no test framework: the sample writer includes it too.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "solver/mesh.hpp"

namespace softshock::testing {

// (b - a) . ((c - a) x (d - a)) for nodes a, b, c, d: six times the signed volume.
inline double tet_triple_product(const Mesh& m, int32_t a, int32_t b, int32_t c, int32_t d) {
  const double ux = m.x[b] - m.x[a], uy = m.y[b] - m.y[a], uz = m.z[b] - m.z[a];
  const double vx = m.x[c] - m.x[a], vy = m.y[c] - m.y[a], vz = m.z[c] - m.z[a];
  const double wx = m.x[d] - m.x[a], wy = m.y[d] - m.y[a], wz = m.z[d] - m.z[a];
  return ux * (vy * wz - vz * wy) - uy * (vx * wz - vz * wx) + uz * (vx * wy - vy * wx);
}

// The box [0, lx] x [0, ly] x [0, lz] of nx x ny x nz cells, nodes numbered x fastest. Each cell
// is split into Kuhn's six tetrahedra around its diagonal from (0,0,0) to (1,1,1): one per order
// of stepping along the three axes, so that neighbouring cells split their shared face the same
// way (the mesh is conforming). Tetrahedra have positive volume; boundary_faces are the faces of
// exactly one tetrahedron, (b - a) x (c - a) pointing out, in the order their tetrahedra come.
inline Mesh tet_box(double lx, double ly, double lz, int nx, int ny, int nz) {
  Mesh mesh;
  const auto node = [&](int i, int j, int k) { return (k * (ny + 1) + j) * (nx + 1) + i; };
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        mesh.x.push_back(lx * i / nx);
        mesh.y.push_back(ly * j / ny);
        mesh.z.push_back(lz * k / nz);
      }
    }
  }
  constexpr int kOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        for (const auto& order : kOrders) {
          std::array<int, 3> at{i, j, k};
          std::array<int32_t, 4> tet{};
          tet[0] = node(at[0], at[1], at[2]);
          for (int s = 0; s < 3; ++s) {
            ++at[order[s]];
            tet[s + 1] = node(at[0], at[1], at[2]);
          }
          if (tet_triple_product(mesh, tet[0], tet[1], tet[2], tet[3]) < 0) {
            std::swap(tet[2], tet[3]);
          }
          mesh.tetrahedra.push_back(tet);
        }
      }
    }
  }
  // Every face with its sorted nodes as the key; a key seen once is on the boundary.
  struct Face {
    std::array<int32_t, 3> key, oriented;
    std::size_t order;
  };
  std::vector<Face> faces;
  for (const auto& t : mesh.tetrahedra) {
    for (int opposite = 0; opposite < 4; ++opposite) {
      std::array<int32_t, 3> f{};
      for (int v = 0, n = 0; v < 4; ++v) {
        if (v != opposite) f[n++] = t[v];
      }
      // Outward: the opposite vertex lies behind the face's normal.
      if (tet_triple_product(mesh, f[0], f[1], f[2], t[opposite]) > 0) std::swap(f[1], f[2]);
      std::array<int32_t, 3> key = f;
      std::sort(key.begin(), key.end());
      faces.push_back({key, f, faces.size()});
    }
  }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.key < b.key; });
  std::vector<Face> boundary;
  for (std::size_t a = 0; a < faces.size();) {
    std::size_t b = a;
    while (b < faces.size() && faces[b].key == faces[a].key) ++b;
    if (b - a == 1) boundary.push_back(faces[a]);
    a = b;
  }
  std::sort(boundary.begin(), boundary.end(),
            [](const Face& a, const Face& b) { return a.order < b.order; });
  for (const Face& f : boundary) mesh.boundary_faces.push_back(f.oriented);
  return mesh;
}

}  // namespace softshock::testing
