// 3-D (tetrahedral) meshes. (Placeholder until the mesh3d branch lands: centroid and volume.)
#include "solver/mesh.hpp"

namespace softshock {

namespace {
double six_volume(const Mesh& m, const std::array<int32_t, 4>& t) {
  const double ax = m.x[t[1]] - m.x[t[0]], ay = m.y[t[1]] - m.y[t[0]], az = m.z[t[1]] - m.z[t[0]];
  const double bx = m.x[t[2]] - m.x[t[0]], by = m.y[t[2]] - m.y[t[0]], bz = m.z[t[2]] - m.z[t[0]];
  const double cx = m.x[t[3]] - m.x[t[0]], cy = m.y[t[3]] - m.y[t[0]], cz = m.z[t[3]] - m.z[t[0]];
  return ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
}
}  // namespace

std::array<double, 3> tet_mesh_centroid(const Mesh& m) {
  double v = 0, c[3] = {0, 0, 0};
  for (const auto& t : m.tetrahedra) {
    const double w = six_volume(m, t) / 6.0;
    v += w;
    for (int32_t i : t) c[0] += w * m.x[i] / 4, c[1] += w * m.y[i] / 4, c[2] += w * m.z[i] / 4;
  }
  return {c[0] / v, c[1] / v, c[2] / v};
}

double mesh_volume(const Mesh& m) {
  double v = 0;
  for (const auto& t : m.tetrahedra) v += six_volume(m, t) / 6.0;
  return v;
}

}  // namespace softshock
