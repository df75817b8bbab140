// Writes a small synthetic 3-D result (result.h5 + result.xdmf) with the real ResultWriter, for
// scripts/test-paraview to open in ParaView while the solver cannot run 3-D problems yet. The
// body is a 100 x 100 x 200 um box of 2,592 tetrahedra (tests/solver/tet_box.hpp) that twists
// about its axis and shortens over 100 ns; its fields follow from that motion, so ParaView's
// warped points can be checked against reference + displacement and the colours vary:
//   displacement, velocity  the motion and its time derivative (z is data: the box shortens)
//   J                       deformed / reference volume of each tetrahedron
//   mean_stress             K (J - 1), K = 2.2 GPa (a water-like bulk modulus)
//   von_mises               sqrt(3) mu gamma for the twist's shear gamma, mu = 1 MPa
//   radial_stress, hoop_stress  the mean stress (the sample has no radial structure)
//   aspect_ratio            longest edge / smallest altitude of the deformed tetrahedron
// Not physics: a file-format sample. No time series (the file's /timeseries are empty).
//
// Usage: write_tet_result OUT_DIR
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "../solver/tet_box.hpp"
#include "solver/io/result_file.hpp"

namespace {

using softshock::FieldFrame;
using softshock::Mesh;

constexpr double kSide = 1e-4, kLength = 2e-4;               // m
constexpr double kEndTime = 1e-7;                            // s
constexpr double kTwist = 0.6;                               // rad at the top at kEndTime
constexpr double kShortening = 0.1;                          // axial strain at kEndTime
constexpr double kBulkModulus = 2.2e9, kShearModulus = 1e6;  // Pa
constexpr int kFrames = 6;

// The motion at time t of the node at (x, y, z): twist angle growing with z and t, shortening
// growing with t. Returns u and writes du/dt to v.
std::array<double, 3> motion(double x, double y, double z, double t, std::array<double, 3>& v) {
  const double dx = x - kSide / 2, dy = y - kSide / 2;
  const double theta = kTwist * (t / kEndTime) * (z / kLength);
  const double theta_rate = kTwist / kEndTime * (z / kLength);
  const double c = std::cos(theta), s = std::sin(theta);
  v = {theta_rate * (-s * dx - c * dy), theta_rate * (c * dx - s * dy),
       -kShortening / kEndTime * z};
  return {c * dx - s * dy - dx, s * dx + c * dy - dy, -kShortening * (t / kEndTime) * z};
}

double norm(const std::array<double, 3>& a) {
  return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}
std::array<double, 3> sub(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
std::array<double, 3> cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// Volume, longest edge and largest face area of the tetrahedron p.
struct TetShape {
  double volume, longest_edge, largest_face;
};
TetShape shape(const std::array<std::array<double, 3>, 4>& p) {
  TetShape s{dot(sub(p[1], p[0]), cross(sub(p[2], p[0]), sub(p[3], p[0]))) / 6, 0, 0};
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b)
      s.longest_edge = std::max(s.longest_edge, norm(sub(p[b], p[a])));
    // The face opposite vertex a.
    std::array<int, 3> f{};
    for (int v = 0, n = 0; v < 4; ++v) {
      if (v != a) f[n++] = v;
    }
    s.largest_face =
        std::max(s.largest_face, norm(cross(sub(p[f[1]], p[f[0]]), sub(p[f[2]], p[f[0]]))) / 2);
  }
  return s;
}

FieldFrame frame_at(const Mesh& mesh, double t) {
  FieldFrame f;
  f.time_s = t;
  f.dimension = 3;
  const std::size_t n = mesh.node_count();
  std::vector<std::array<double, 3>> current(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::array<double, 3> v{};
    const auto u = motion(mesh.x[i], mesh.y[i], mesh.z[i], t, v);
    f.displacement.insert(f.displacement.end(), u.begin(), u.end());
    f.velocity.insert(f.velocity.end(), v.begin(), v.end());
    current[i] = {mesh.x[i] + u[0], mesh.y[i] + u[1], mesh.z[i] + u[2]};
  }
  for (const auto& tet : mesh.tetrahedra) {
    std::array<std::array<double, 3>, 4> ref{}, now{};
    double cx = 0, cy = 0;
    for (int k = 0; k < 4; ++k) {
      const auto i = static_cast<std::size_t>(tet[k]);
      ref[k] = {mesh.x[i], mesh.y[i], mesh.z[i]};
      now[k] = current[i];
      cx += mesh.x[i] / 4, cy += mesh.y[i] / 4;
    }
    const TetShape deformed = shape(now);
    const double J = deformed.volume / shape(ref).volume;
    const double r = std::hypot(cx - kSide / 2, cy - kSide / 2);
    const double gamma = kTwist * (t / kEndTime) * r / kLength;
    f.J.push_back(J);
    f.mean_stress.push_back(kBulkModulus * (J - 1));
    f.radial_stress.push_back(f.mean_stress.back());
    f.hoop_stress.push_back(f.mean_stress.back());
    f.von_mises.push_back(std::sqrt(3.0) * kShearModulus * gamma);
    f.aspect_ratio.push_back(deformed.longest_edge * deformed.largest_face / (3 * deformed.volume));
  }
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  try {
    const Mesh mesh = softshock::testing::tet_box(kSide, kSide, kLength, 6, 6, 12);
    softshock::ResultWriter writer(argv[1], mesh, R"({"sample":"twisting tetrahedral box"})",
                                   "write_tet_result");
    for (int k = 0; k < kFrames; ++k)
      writer.write_frame(frame_at(mesh, kEndTime * k / (kFrames - 1)));
    softshock::RunSummary summary;
    summary.nodes = mesh.node_count();
    summary.elements = mesh.element_count();
    summary.end_time_s = kEndTime;
    summary.status = "completed";
    writer.finish(softshock::History{}, summary, true, "");
    std::printf("write_tet_result: %zu nodes, %zu tetrahedra, %d frames in %s\n", mesh.node_count(),
                mesh.element_count(), kFrames, writer.xdmf_path().c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_tet_result: %s\n", e.what());
    return 1;
  }
  return 0;
}
