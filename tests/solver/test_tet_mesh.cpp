// 3-D meshes (part of test_mesh): finalize_mesh on tetrahedra (orientation, outward boundary
// faces, refusals), structured and corrugated boxes, Morton order, Gmsh cylinders and spheres,
// and .msh files with tetrahedra.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "scratch_dir.hpp"
#include "solver/gmsh_mesher.hpp"
#include "solver/mesh.hpp"

// LeakSanitizer (the sanitized unit-test stage): Gmsh 4.8.4 itself leaks a few kB per 3-D mesh
// of curved OCC surfaces (in meshGFace with the frontal and Delaunay surface algorithms, and
// 64 B in tetgenBR::tetgenmesh::reconstructmesh); not ours to fix. Only allocations made under a
// libgmsh frame are excused. Read by LSan when it is linked in; otherwise an unused function.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libgmsh.so\n";
}

namespace softshock {
namespace {

constexpr double kPi = std::numbers::pi;
using Vec = std::array<double, 3>;

Vec node(const Mesh& m, int32_t i) {
  return {m.x[i], m.y[i], m.z[i]};
}
Vec sub(const Vec& a, const Vec& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec& a, const Vec& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

double six_volume(const Mesh& m, const std::array<int32_t, 4>& t) {
  const Vec a = node(m, t[0]);
  return dot(sub(node(m, t[1]), a), cross(sub(node(m, t[2]), a), sub(node(m, t[3]), a)));
}

// Twice the area vector (b - a) x (c - a) of a face.
Vec twice_area_vector(const Mesh& m, const std::array<int32_t, 3>& f) {
  const Vec a = node(m, f[0]);
  return cross(sub(node(m, f[1]), a), sub(node(m, f[2]), a));
}

std::array<int32_t, 3> sorted_face(std::array<int32_t, 3> f) {
  std::sort(f.begin(), f.end());
  return f;
}

// Checks what finalize_mesh promises for tetrahedra, recomputing the boundary independently:
// every tetrahedron positive; the boundary faces are exactly the faces of one tetrahedron, each
// pointing away from that tetrahedron's fourth node; and, as a whole, they close around the
// volume (sum of area vectors 0, divergence theorem for the position: (1/3) sum c . A = V).
void expect_consistent(const Mesh& m) {
  ASSERT_EQ(m.dimension(), 3);
  ASSERT_EQ(m.x.size(), m.y.size());
  ASSERT_EQ(m.x.size(), m.z.size());
  EXPECT_TRUE(m.triangles.empty() && m.boundary_edges.empty() && m.boundary_nodes.empty());
  std::map<std::array<int32_t, 3>, std::vector<int32_t>> fourth_nodes;  // face -> opposite nodes
  double volume = 0.0;
  for (const auto& t : m.tetrahedra) {
    EXPECT_GT(six_volume(m, t), 0.0) << "tetrahedron not positively oriented";
    volume += six_volume(m, t) / 6.0;
    for (int k = 0; k < 4; ++k) {
      std::array<int32_t, 3> f{};
      for (int i = 0, j = 0; i < 4; ++i)
        if (i != k) f[j++] = t[i];
      fourth_nodes[sorted_face(f)].push_back(t[k]);
    }
  }
  std::set<std::array<int32_t, 3>> expected, got;
  for (const auto& [face, opposite] : fourth_nodes) {
    EXPECT_LE(opposite.size(), 2u);
    if (opposite.size() == 1) expected.insert(face);
  }
  Vec area_sum{0, 0, 0};
  double flux = 0.0, area_scale = 0.0;
  for (const auto& f : m.boundary_faces) {
    got.insert(sorted_face(f));
    const auto found = fourth_nodes.find(sorted_face(f));
    ASSERT_NE(found, fourth_nodes.end()) << "boundary face of no tetrahedron";
    const Vec n = twice_area_vector(m, f);
    EXPECT_LT(dot(n, sub(node(m, found->second[0]), node(m, f[0]))), 0.0) << "face points inward";
    const Vec c{(m.x[f[0]] + m.x[f[1]] + m.x[f[2]]) / 3.0,
                (m.y[f[0]] + m.y[f[1]] + m.y[f[2]]) / 3.0,
                (m.z[f[0]] + m.z[f[1]] + m.z[f[2]]) / 3.0};
    for (int k = 0; k < 3; ++k) area_sum[k] += 0.5 * n[k];
    flux += dot(c, n) / 6.0;  // (1/3) c . A with A = n / 2
    area_scale += 0.5 * std::sqrt(dot(n, n));
  }
  EXPECT_EQ(got.size(), m.boundary_faces.size()) << "duplicate boundary faces";
  EXPECT_EQ(got, expected);
  // Rounding: each term carries ~1e-16 of its size; 1e-12 of the total area is far above that.
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(area_sum[k], 0.0, 1e-12 * area_scale);
  EXPECT_NEAR(flux, volume, 1e-11 * volume);
  EXPECT_NEAR(mesh_volume(m), volume, 1e-12 * volume);
}

template <typename Exception>
void expect_throw_containing(const std::function<void()>& f,
                             const std::vector<std::string>& fragments) {
  try {
    f();
    ADD_FAILURE() << "no exception thrown";
  } catch (const Exception& e) {
    for (const auto& fragment : fragments) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
          << "message \"" << e.what() << "\" lacks \"" << fragment << "\"";
    }
  }
}

void expect_rejected(Mesh m, const std::vector<std::string>& fragments) {
  expect_throw_containing<std::invalid_argument>([&] { finalize_mesh(m); }, fragments);
}

// The unit right tetrahedron, given negatively oriented.
Mesh one_flipped_tetrahedron() {
  Mesh m;
  m.x = {0, 1, 0, 0};
  m.y = {0, 0, 1, 0};
  m.z = {0, 0, 0, 1};
  m.tetrahedra = {{0, 2, 1, 3}};
  return m;
}

// Two tetrahedra on either side of face (0, 1, 2), apexes 3 (above) and 4 (below).
Mesh two_tetrahedra() {
  Mesh m;
  m.x = {0, 1, 0, 0.2, 0.2};
  m.y = {0, 0, 1, 0.2, 0.2};
  m.z = {0, 0, 0, 1, -1};
  m.tetrahedra = {{0, 1, 2, 3}, {0, 2, 1, 4}};
  return m;
}

// ---------------------------------------------------------------------------------------------
// finalize_mesh on tetrahedra

TEST(FinalizeTetMesh, OrientsOneTetrahedronAndFindsItsOutwardFaces) {
  Mesh m = one_flipped_tetrahedron();
  ASSERT_LT(six_volume(m, m.tetrahedra[0]), 0.0);
  finalize_mesh(m);
  expect_consistent(m);
  EXPECT_EQ(m.boundary_faces.size(), 4u);
  EXPECT_DOUBLE_EQ(mesh_volume(m), 1.0 / 6.0);
  // Ordered by local face: the first is the face opposite node 0, (1, 2, 3) in some rotation,
  // whose outward normal is (1, 1, 1).
  const Vec n = twice_area_vector(m, m.boundary_faces[0]);
  EXPECT_EQ(sorted_face(m.boundary_faces[0]), (std::array<int32_t, 3>{1, 2, 3}));
  EXPECT_GT(n[0], 0.0);
  EXPECT_GT(n[1], 0.0);
  EXPECT_GT(n[2], 0.0);
}

TEST(FinalizeTetMesh, FlipsNegativeTetrahedraBackAndIsIdempotent) {
  const Mesh box = make_box_mesh(1.0, 2.0, 3.0, 2, 2, 2);
  Mesh flipped = box;
  for (std::size_t t = 0; t < flipped.tetrahedra.size(); t += 3) {
    std::swap(flipped.tetrahedra[t][0], flipped.tetrahedra[t][1]);
  }
  finalize_mesh(flipped);
  expect_consistent(flipped);
  // The same node sets and the same boundary, as sets of faces.
  for (std::size_t t = 0; t < box.tetrahedra.size(); ++t) {
    EXPECT_EQ((std::set<int32_t>(flipped.tetrahedra[t].begin(), flipped.tetrahedra[t].end())),
              (std::set<int32_t>(box.tetrahedra[t].begin(), box.tetrahedra[t].end())));
  }
  std::set<std::array<int32_t, 3>> a, b;
  for (const auto& f : box.boundary_faces) a.insert(sorted_face(f));
  for (const auto& f : flipped.boundary_faces) b.insert(sorted_face(f));
  EXPECT_EQ(a, b);
  EXPECT_DOUBLE_EQ(mesh_volume(flipped), 6.0);
  // Idempotent.
  Mesh again = box;
  finalize_mesh(again);
  EXPECT_EQ(again.tetrahedra, box.tetrahedra);
  EXPECT_EQ(again.boundary_faces, box.boundary_faces);
}

TEST(FinalizeTetMesh, RejectsBadIndicesArraysAndUnusedNodes) {
  {  // indices out of range
    Mesh m = two_tetrahedra();
    m.tetrahedra[1] = {0, 2, 1, 5};
    expect_rejected(m, {"tetrahedron 1", "out of range", "5"});
    m.tetrahedra[1] = {0, -1, 1, 4};
    expect_rejected(m, {"tetrahedron 1", "out of range", "-1"});
  }
  {  // malformed arrays
    Mesh m = two_tetrahedra();
    m.z.pop_back();
    expect_rejected(m, {"x, y and z have 5, 5 and 4"});
    Mesh no_tets = two_tetrahedra();
    no_tets.tetrahedra.clear();  // z alone makes it 3-D
    expect_rejected(no_tets, {"no tetrahedra"});
    Mesh mixed = two_tetrahedra();
    mixed.triangles = {{0, 1, 2}};
    expect_rejected(mixed, {"both triangles and tetrahedra"});
    Mesh not_finite = two_tetrahedra();
    not_finite.z[3] = NAN;
    expect_rejected(not_finite, {"node 3", "non-finite"});
  }
  {  // unused nodes
    Mesh m = two_tetrahedra();
    m.x.push_back(0.5), m.y.push_back(0.5), m.z.push_back(0.5);
    expect_rejected(m, {"node 5", "not used by any tetrahedron"});
  }
}

TEST(FinalizeTetMesh, RejectsDegenerateTetrahedraRelativeToMeshScale) {
  {  // coplanar and repeated nodes
    Mesh m = two_tetrahedra();
    m.x.push_back(0.5), m.y.push_back(0.5), m.z.push_back(0.0);  // node 5 in the plane z = 0
    m.tetrahedra.push_back({0, 1, 2, 5});
    expect_rejected(m, {"degenerate", "tetrahedron 2"});
    Mesh repeated = two_tetrahedra();
    repeated.tetrahedra[0] = {0, 1, 1, 3};
    expect_rejected(repeated, {"degenerate", "tetrahedron 0", "repeated"});
  }
  {  // relative to the mesh scale: |6 V| = 1e-9 L^3 passes at any size; 1e-14 L^3 does not
    for (const double scale : {1.0, 1e-6}) {
      Mesh sliver = one_flipped_tetrahedron();
      for (auto* c : {&sliver.x, &sliver.y, &sliver.z})
        for (double& v : *c) v *= scale;
      sliver.z[3] = 1e-9 * scale;
      EXPECT_NO_THROW(finalize_mesh(sliver)) << "scale " << scale;
      sliver.z[3] = 1e-14 * scale;
      expect_rejected(sliver, {"degenerate", "tetrahedron 0"});
    }
  }
}

TEST(FinalizeTetMesh, RejectsOverSharedAndOverlappingFaces) {
  {  // three tetrahedra on face (0, 1, 2)
    Mesh m = two_tetrahedra();
    m.x.push_back(0.3), m.y.push_back(0.3), m.z.push_back(2.0);
    m.tetrahedra.push_back({0, 1, 2, 5});
    expect_rejected(m, {"face (0, 1, 2)", "more than two tetrahedra"});
  }
  {  // two tetrahedra on the same side of face (0, 1, 2)
    Mesh m = two_tetrahedra();
    m.z[4] = 0.5;  // the second apex moves above the face too
    expect_rejected(m, {"overlap", "face (0, 1, 2)"});
  }
}

// ---------------------------------------------------------------------------------------------
// Structured boxes

TEST(BoxMesh, CountsVolumeCentroidAndBoundary) {
  const double lx = 1.0 / 3.0, ly = 0.7, lz = 1.1;
  const int nx = 3, ny = 4, nz = 5;
  const Mesh m = make_box_mesh(lx, ly, lz, nx, ny, nz);
  EXPECT_EQ(m.dimension(), 3);
  EXPECT_EQ(m.node_count(), 4u * 5u * 6u);
  EXPECT_EQ(m.element_count(), 6u * nx * ny * nz);
  // Each boundary square is two triangles; any face left unmatched inside (a non-conforming
  // split) would add to the count.
  EXPECT_EQ(m.boundary_faces.size(), 4u * (nx * ny + ny * nz + nz * nx));
  expect_consistent(m);
  // Every tetrahedron is a sixth of a cell: 360 terms of relative rounding ~1e-16 each.
  const double cell = lx * ly * lz / (nx * ny * nz);
  for (const auto& t : m.tetrahedra) EXPECT_NEAR(six_volume(m, t), cell, 1e-12 * cell);
  EXPECT_NEAR(mesh_volume(m), lx * ly * lz, 1e-13 * lx * ly * lz);
  const auto c = tet_mesh_centroid(m);
  EXPECT_NEAR(c[0], lx / 2, 1e-13 * lx);
  EXPECT_NEAR(c[1], ly / 2, 1e-13 * ly);
  EXPECT_NEAR(c[2], lz / 2, 1e-13 * lz);
  // The last layer sits exactly on the far faces.
  EXPECT_EQ(*std::max_element(m.x.begin(), m.x.end()), lx);
  EXPECT_EQ(*std::max_element(m.z.begin(), m.z.end()), lz);
}

TEST(BoxMesh, CentroidIsVolumeWeighted) {
  // An L-shaped prism of three unit cubes (cell (1, 1, 0) removed from a 2 x 2 x 1 box):
  // centroid (5/6, 5/6, 1/2).
  Mesh m = make_box_mesh(2.0, 2.0, 1.0, 2, 2, 1);
  m.tetrahedra.erase(m.tetrahedra.begin() + 18, m.tetrahedra.begin() + 24);
  // Node (2, 2, 0) and (2, 2, 1) are now unused: 8 and 17, the last of their layers.
  for (auto* c : {&m.x, &m.y, &m.z}) c->erase(c->begin() + 17), c->erase(c->begin() + 8);
  for (auto& t : m.tetrahedra)
    for (int32_t& n : t) n -= (n > 8) + (n > 17);
  finalize_mesh(m);
  expect_consistent(m);
  EXPECT_NEAR(mesh_volume(m), 3.0, 1e-14);
  const auto c = tet_mesh_centroid(m);
  EXPECT_NEAR(c[0], 5.0 / 6.0, 1e-14);
  EXPECT_NEAR(c[1], 5.0 / 6.0, 1e-14);
  EXPECT_NEAR(c[2], 0.5, 1e-14);
  EXPECT_THROW(tet_mesh_centroid(Mesh{}), std::invalid_argument);
}

TEST(BoxMesh, RejectsBadArguments) {
  expect_throw_containing<std::invalid_argument>([] { make_box_mesh(0, 1, 1, 1, 1, 1); },
                                                 {"make_box_mesh", "positive and finite"});
  expect_throw_containing<std::invalid_argument>([] { make_box_mesh(1, 1, NAN, 1, 1, 1); },
                                                 {"make_box_mesh", "positive and finite"});
  expect_throw_containing<std::invalid_argument>([] { make_box_mesh(1, 1, 1, 1, 0, 1); },
                                                 {"make_box_mesh", "at least 1"});
  expect_throw_containing<std::invalid_argument>([] { make_box_mesh(1, 1, 1, 2000, 2000, 2000); },
                                                 {"make_box_mesh", "32-bit"});
  expect_throw_containing<std::invalid_argument>(
      [] { make_corrugated_box_mesh(1, 1, 1, 0.5, 1, 1, 1000); },
      {"make_corrugated_box_mesh", "amplitude"});
  expect_throw_containing<std::invalid_argument>(
      [] { make_corrugated_box_mesh(1, 1, 1, 0.1, 1, 1, 0); },
      {"make_corrugated_box_mesh", "target_elements"});
}

// z_top(x, y) = lz + a cos(kx x) cos(ky y) on [0, lx] x [0, ly]; its exact volume.
struct Corrugation {
  double lx = 1.0, ly = 0.8, lz = 1.0, a = 0.2, kx = 2.0, ky = 3.0;
  double top(double x, double y) const { return lz + a * std::cos(kx * x) * std::cos(ky * y); }
  double volume() const {
    return lx * ly * lz + a * std::sin(kx * lx) * std::sin(ky * ly) / (kx * ky);
  }
  Mesh mesh(int target) const { return make_corrugated_box_mesh(lx, ly, lz, a, kx, ky, target); }
};

TEST(CorrugatedBoxMesh, TopFollowsTheCorrugationAndVolumeConvergesAtSecondOrder) {
  const Corrugation c;
  const Mesh m = c.mesh(3000);
  expect_consistent(m);
  // Aspect ~1 cells: h = cbrt(6 V / N) = 0.117 gives ~9 x 7 cells across, rounded to even counts
  // (8 x 6: the mirrored cells' symmetry), and nz = 10 takes up the count.
  EXPECT_EQ(m.element_count(), 6u * 8 * 6 * 10);
  // The top (faces whose outward normal is mostly +z) lies on the corrugation, to rounding.
  std::set<int32_t> top_nodes;
  for (const auto& f : m.boundary_faces) {
    const Vec n = twice_area_vector(m, f);
    if (n[2] > 0.5 * std::sqrt(dot(n, n))) top_nodes.insert(f.begin(), f.end());
  }
  EXPECT_EQ(top_nodes.size(), 9u * 7u);
  for (const int32_t i : top_nodes) EXPECT_NEAR(m.z[i], c.top(m.x[i], m.y[i]), 1e-15 * c.lz);
  // The mesh's top is the piecewise-linear interpolant of z_top on the top's triangles, whose
  // volume error is O(h^2 |grad^2 z_top|): halving h (8x the elements) divides it by ~4.
  const double coarse = std::abs(mesh_volume(c.mesh(3000)) - c.volume());
  const double fine = std::abs(mesh_volume(c.mesh(24000)) - c.volume());
  std::cout << "corrugated box volume error: " << coarse / c.volume() << " at 3k tetrahedra, "
            << fine / c.volume() << " at 24k\n";
  EXPECT_LT(fine, 1e-3 * c.volume());
  EXPECT_GT(coarse / fine, 3.0);
  EXPECT_LT(coarse / fine, 5.5);
}

TEST(CorrugatedBoxMesh, SteepCorrugationStillGivesPositiveTetrahedra) {
  // 8 cells across and kx = 8 pi / lx: neighbouring columns stretch by 1 - 2a and 1 + 2a
  // (a = 0.49 lz), yet every Kuhn tetrahedron keeps its volume's sign (tet_mesh.cpp).
  const double lz = 1.0, a = 0.49;
  Mesh m = make_corrugated_box_mesh(1.0, 1.0, lz, a, 8.0 * kPi, 0.0, 6 * 8 * 8 * 8);
  EXPECT_EQ(m.element_count(), 6u * 8 * 8 * 8);
  expect_consistent(m);
  // Columns alternate between heights lz + a and lz - a, so the volume is lz exactly, up to the
  // piecewise-linear top: each cell's top is two triangles over a +a / -a zigzag, mean 0.
  EXPECT_NEAR(mesh_volume(m), 1.0 * 1.0 * lz, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Morton order

TEST(TetMeshLocality, MortonSortKeepsTheMeshAndShortensIndexSpans) {
  Mesh m = make_corrugated_box_mesh(1.0, 1.0, 0.5, 0.1, kPi, kPi, 6000);
  // Shuffle nodes and elements so the structured order cannot help.
  std::mt19937 random(7);
  std::vector<int32_t> perm(m.node_count());
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), random);
  Mesh shuffled = m;
  for (std::size_t i = 0; i < perm.size(); ++i) {
    shuffled.x[perm[i]] = m.x[i], shuffled.y[perm[i]] = m.y[i], shuffled.z[perm[i]] = m.z[i];
  }
  for (auto& t : shuffled.tetrahedra)
    for (int32_t& n : t) n = perm[n];
  std::shuffle(shuffled.tetrahedra.begin(), shuffled.tetrahedra.end(), random);
  finalize_mesh(shuffled);
  // The median over tetrahedra of the spread of their node indices (the mean is dominated by
  // the few that straddle the curve's coarsest jumps).
  auto median_span = [](const Mesh& mesh) {
    std::vector<int32_t> spans;
    for (const auto& t : mesh.tetrahedra)
      spans.push_back(*std::max_element(t.begin(), t.end()) -
                      *std::min_element(t.begin(), t.end()));
    std::nth_element(spans.begin(), spans.begin() + spans.size() / 2, spans.end());
    return spans[spans.size() / 2];
  };
  Mesh sorted = shuffled;
  sort_for_locality(sorted);  // dispatches to sort_tet_mesh_for_locality
  expect_consistent(sorted);
  EXPECT_EQ(sorted.node_count(), m.node_count());
  EXPECT_EQ(sorted.element_count(), m.element_count());
  EXPECT_NEAR(mesh_volume(sorted), mesh_volume(m), 1e-13 * mesh_volume(m));
  // The same points (as a set).
  auto points = [](const Mesh& mesh) {
    std::vector<Vec> p;
    for (std::size_t i = 0; i < mesh.node_count(); ++i) p.push_back(node(mesh, int32_t(i)));
    std::sort(p.begin(), p.end());
    return p;
  };
  EXPECT_EQ(points(sorted), points(m));
  std::cout << "median node index span per tetrahedron: shuffled " << median_span(shuffled)
            << ", Morton " << median_span(sorted) << " (of " << sorted.node_count() << " nodes)\n";
  EXPECT_LT(median_span(sorted), 0.1 * median_span(shuffled));
  // A mesh the keys cannot be computed for is refused with finalize_mesh's message.
  Mesh bad = two_tetrahedra();
  bad.tetrahedra[1][3] = 7;
  expect_throw_containing<std::invalid_argument>([&] { sort_for_locality(bad); },
                                                 {"finalize_mesh", "out of range"});
  bad = two_tetrahedra();
  bad.x[2] = INFINITY;
  expect_throw_containing<std::invalid_argument>([&] { sort_for_locality(bad); },
                                                 {"finalize_mesh", "non-finite"});
  // Sorting again changes nothing.
  Mesh again = sorted;
  sort_for_locality(again);
  EXPECT_EQ(again.x, sorted.x);
  EXPECT_EQ(again.z, sorted.z);
  EXPECT_EQ(again.tetrahedra, sorted.tetrahedra);
  EXPECT_EQ(again.boundary_faces, sorted.boundary_faces);
}

// ---------------------------------------------------------------------------------------------
// Gmsh: cylinders and spheres

// Mean edge length of the tetrahedra: the mesh's own size h.
double mean_edge(const Mesh& m) {
  double sum = 0.0;
  for (const auto& t : m.tetrahedra)
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const Vec d = sub(node(m, t[i]), node(m, t[j]));
        sum += std::sqrt(dot(d, d));
      }
  return sum / (6.0 * static_cast<double>(m.tetrahedra.size()));
}

// Volume, count, and the mid-plane: meshed inside (an interface, no boundary face in it) with
// nodes on its rim r = R, z = 0.
void check_cylinder(double thickness) {
  const double radius = 90e-6;
  const int target = 5000;
  const auto start = std::chrono::steady_clock::now();
  const Mesh m = mesh_cylinder(radius, thickness, target);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  expect_consistent(m);
  const double exact = kPi * radius * radius * thickness;
  // The lateral surface is inscribed facets: chords of length h miss ~(h / R)^2 / 6 of the
  // area, 0.1-0.4 % here (measured -0.21 % and -0.12 %).
  EXPECT_NEAR(mesh_volume(m), exact, 0.01 * exact);
  EXPECT_NEAR(static_cast<double>(m.element_count()), target, 0.1 * target);
  const double h = mean_edge(m);
  std::size_t rim = 0, mid_plane = 0;
  for (std::size_t i = 0; i < m.node_count(); ++i) {
    const double r = std::hypot(m.x[i], m.y[i]);
    EXPECT_LE(r, radius * (1 + 1e-9));
    EXPECT_LE(std::abs(m.z[i]), 0.5 * thickness * (1 + 1e-9));
    if (std::abs(m.z[i]) > 0.01 * h) continue;
    // Near the mid-plane: on it exactly, to the geometry's tolerance.
    EXPECT_LT(std::abs(m.z[i]), 1e-9 * radius);
    ++mid_plane;
    if (r > radius - 0.01 * h) {
      EXPECT_NEAR(r, radius, 1e-9 * radius);
      ++rim;
    }
  }
  std::cout << "cylinder H = " << thickness << ": " << m.element_count() << " tetrahedra for "
            << target << ", h = " << h / radius << " R, " << rim
            << " rim nodes at z = 0 (2 pi R / h = " << 2 * kPi * radius / h << "), " << mid_plane
            << " nodes in the mid-plane, " << seconds << " s\n";
  EXPECT_GE(static_cast<double>(rim), kPi * radius / h);
  EXPECT_GT(mid_plane, rim);  // the mid-plane is meshed inside too: an interface
  // It is an interface, not a boundary: no boundary face lies in it.
  for (const auto& f : m.boundary_faces) {
    EXPECT_FALSE(std::abs(m.z[f[0]]) < 1e-9 * radius && std::abs(m.z[f[1]]) < 1e-9 * radius &&
                 std::abs(m.z[f[2]]) < 1e-9 * radius);
  }
}

TEST(CylinderMesh, ThickDiskVolumeCountAndMidPlaneRim) {
  check_cylinder(50e-6);
}
TEST(CylinderMesh, ThinDiskVolumeCountAndMidPlaneRim) {
  check_cylinder(20e-6);
}

TEST(CylinderMesh, ReproducibleAndArgumentsChecked) {
  const Mesh a = mesh_cylinder(90e-6, 20e-6, 1000);
  const Mesh b = mesh_cylinder(90e-6, 20e-6, 1000);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.z, b.z);
  EXPECT_EQ(a.tetrahedra, b.tetrahedra);
  EXPECT_EQ(a.boundary_faces, b.boundary_faces);
  expect_throw_containing<std::invalid_argument>([] { mesh_cylinder(-1.0, 1.0, 100); },
                                                 {"mesh_cylinder", "radius"});
  expect_throw_containing<std::invalid_argument>([] { mesh_cylinder(1.0, INFINITY, 100); },
                                                 {"mesh_cylinder", "thickness"});
  expect_throw_containing<std::invalid_argument>([] { mesh_cylinder(1.0, 1e-6, 100); },
                                                 {"mesh_cylinder", "1e-5"});
  expect_throw_containing<std::invalid_argument>([] { mesh_cylinder(1.0, 1.0, 0); },
                                                 {"mesh_cylinder", "target_elements"});
  expect_throw_containing<std::invalid_argument>([] { mesh_sphere(0.0, 100); },
                                                 {"mesh_sphere", "radius"});
  expect_throw_containing<std::invalid_argument>([] { mesh_sphere(1.0, -3); },
                                                 {"mesh_sphere", "target_elements"});
}

TEST(SphereMesh, VolumeAndCount) {
  const double radius = 90e-6;
  const int target = 5000;
  const Mesh m = mesh_sphere(radius, target);
  expect_consistent(m);
  const double exact = 4.0 / 3.0 * kPi * radius * radius * radius;
  EXPECT_NEAR(mesh_volume(m), exact, 0.015 * exact);
  EXPECT_NEAR(static_cast<double>(m.element_count()), target, 0.1 * target);
  const auto c = tet_mesh_centroid(m);
  for (const double v : c) EXPECT_NEAR(v, 0.0, 0.01 * radius);
  for (std::size_t i = 0; i < m.node_count(); ++i) {
    EXPECT_LE(std::sqrt(dot(node(m, int32_t(i)), node(m, int32_t(i)))), radius * (1 + 1e-9));
  }
  std::cout << "sphere: " << m.element_count() << " tetrahedra for " << target << ", volume "
            << mesh_volume(m) / exact - 1 << " relative to the ball's\n";
}

// ---------------------------------------------------------------------------------------------
// .msh files with tetrahedra

class TetMeshFile : public ::testing::Test {
 protected:
  std::string write(const std::string& name, const std::string& text) {
    const auto path = dir_.path() / name;
    std::ofstream(path) << text;
    return path.string();
  }
  testing::ScratchDir dir_{"tet-mesh-file"};
};

// Two tetrahedra on either side of the triangle 10-20-30 (apexes 40 above, 50 below), the
// second one negatively oriented; a boundary triangle, a line and an unused node 99 to ignore.
constexpr const char* kMsh22TwoTets = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
6
10 0 0 0
20 1e-6 0 0
30 0 1e-6 0
40 2e-7 2e-7 1e-6
50 2e-7 2e-7 -1e-6
99 5 5 5
$EndNodes
$Elements
4
1 1 2 0 1 10 20
2 2 2 0 1 10 20 40
3 4 2 0 1 10 20 30 40
4 4 2 0 1 10 20 30 50
$EndElements
)";

// The same two tetrahedra in MSH 4.1, in two volume entities.
constexpr const char* kMsh41TwoTets = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
0 0 0 2
1 0 0 0 1e-6 1e-6 1e-6 0 0
2 0 0 -1e-6 1e-6 1e-6 0 0 0
$EndEntities
$Nodes
1 5 1 5
3 1 0 5
1
2
3
4
5
0 0 0
1e-6 0 0
0 1e-6 0
2e-7 2e-7 1e-6
2e-7 2e-7 -1e-6
$EndNodes
$Elements
2 2 1 2
3 1 4 1
1 1 2 3 4
3 2 4 1
2 1 3 2 5
$EndElements
)";

// One triangle with non-zero z: still a 2-D mesh.
constexpr const char* kMsh22Triangle = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
3
1 0 0 0.5
2 1 0 0.5
3 0 1 0.5
$EndNodes
$Elements
1
1 2 2 0 1 1 2 3
$EndElements
)";

TEST_F(TetMeshFile, ReadsTetrahedraFromMsh22AndMsh41) {
  const double volume = 2.0 * (0.5e-12 * 1e-6) / 3.0;  // two pyramids on a 0.5e-12 m^2 base
  for (const char* text : {kMsh22TwoTets, kMsh41TwoTets}) {
    const Mesh m = read_gmsh_file(write("two_tets.msh", text));
    EXPECT_EQ(m.dimension(), 3);
    expect_consistent(m);
    EXPECT_EQ(m.node_count(), 5u);  // node 99 is used by no tetrahedron and is dropped
    EXPECT_EQ(m.element_count(), 2u);
    EXPECT_EQ(m.boundary_faces.size(), 6u);
    // Tag order is kept and z with it; coordinates as written, in metres.
    EXPECT_EQ(m.z, (std::vector<double>{0, 0, 0, 1e-6, -1e-6}));
    EXPECT_NEAR(mesh_volume(m), volume, 1e-12 * volume);
  }
}

TEST_F(TetMeshFile, TrianglesStillReadAsTwoDAndNeitherIsRefused) {
  const Mesh m = read_gmsh_file(write("triangle.msh", kMsh22Triangle));
  EXPECT_EQ(m.dimension(), 2);
  EXPECT_TRUE(m.z.empty());
  EXPECT_TRUE(m.tetrahedra.empty() && m.boundary_faces.empty());
  EXPECT_EQ(m.element_count(), 1u);
  EXPECT_EQ(m.boundary_nodes.size(), 3u);

  std::string lines_only = kMsh22TwoTets;
  lines_only = lines_only.substr(0, lines_only.find("$Elements")) +
               "$Elements\n1\n1 1 2 0 1 10 20\n$EndElements\n";
  const std::string path = write("lines.msh", lines_only);
  expect_throw_containing<std::runtime_error>(
      [&] { read_gmsh_file(path); }, {path, "contains no 3-node triangles or 4-node tetrahedra"});

  std::string overlapping = kMsh22TwoTets;
  overlapping.replace(overlapping.find("2e-7 2e-7 -1e-6"), 15, "2e-7 2e-7 5e-7");
  const std::string bad = write("overlap.msh", overlapping);
  expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(bad); }, {bad, "overlap"});
}

}  // namespace
}  // namespace softshock
