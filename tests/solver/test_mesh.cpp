// Mesh layer: finalize_mesh checks and boundary extraction, structured rectangles, Gmsh disks
// and rounded squares, and .msh reading.
#include <gtest/gtest.h>
#include <stdlib.h>  // mkdtemp

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "solver/continuum.hpp"
#include "solver/gmsh_mesher.hpp"
#include "solver/mesh.hpp"
#include "solver/ring_mesher.hpp"

namespace softshock {
namespace {

constexpr double kPi = std::numbers::pi;

double twice_signed_area(const Mesh& m, const std::array<int32_t, 3>& t) {
  return (m.x[t[1]] - m.x[t[0]]) * (m.y[t[2]] - m.y[t[0]]) -
         (m.x[t[2]] - m.x[t[0]]) * (m.y[t[1]] - m.y[t[0]]);
}

// Shoelace area of a closed polygon given by node indices.
double polygon_signed_area(const Mesh& m, const std::vector<int32_t>& loop) {
  double twice = 0.0;
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const int32_t a = loop[i], b = loop[(i + 1) % loop.size()];
    twice += m.x[a] * m.y[b] - m.x[b] * m.y[a];
  }
  return 0.5 * twice;
}

// Area of the circular segment cut off by a chord of length c on a circle of radius r: the
// part of the exact domain an inscribed polygon edge misses.
double circular_segment_area(double r, double c) {
  const double theta = 2.0 * std::asin(std::min(1.0, c / (2.0 * r)));
  return 0.5 * r * r * (theta - std::sin(theta));
}

double edge_length(const Mesh& m, int32_t a, int32_t b) {
  return std::hypot(m.x[b] - m.x[a], m.y[b] - m.y[a]);
}

// Checks the invariants finalize_mesh promises, recomputing the boundary independently.
void expect_consistent(const Mesh& m) {
  ASSERT_EQ(m.x.size(), m.y.size());
  std::map<std::pair<int32_t, int32_t>, int> directed_uses;
  for (const auto& t : m.triangles) {
    EXPECT_GT(twice_signed_area(m, t), 0.0) << "triangle not counter-clockwise";
    for (int k = 0; k < 3; ++k) ++directed_uses[{t[k], t[(k + 1) % 3]}];
  }
  // Boundary edges: directed triangle edges whose reverse is not also a triangle edge. Their
  // direction is the one in their counter-clockwise triangle, i.e. body on the left.
  std::set<std::pair<int32_t, int32_t>> expected;
  for (const auto& [edge, uses] : directed_uses) {
    if (!directed_uses.contains({edge.second, edge.first})) expected.insert(edge);
  }
  std::set<std::pair<int32_t, int32_t>> got;
  for (const auto& e : m.boundary_edges) got.insert({e[0], e[1]});
  EXPECT_EQ(got.size(), m.boundary_edges.size()) << "duplicate boundary edges";
  EXPECT_EQ(got, expected);
  // The outer loop walks boundary edges in order and closes.
  ASSERT_GE(m.boundary_nodes.size(), 3u);
  for (std::size_t i = 0; i < m.boundary_nodes.size(); ++i) {
    const std::pair e{m.boundary_nodes[i], m.boundary_nodes[(i + 1) % m.boundary_nodes.size()]};
    EXPECT_TRUE(expected.contains(e)) << "loop step " << e.first << "->" << e.second;
  }
  EXPECT_GT(polygon_signed_area(m, m.boundary_nodes), 0.0) << "outer loop not CCW";
}

template <class Exception>
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

// Unit square as two triangles around the diagonal 0-2.
Mesh unit_square_two_triangles() {
  Mesh m;
  m.x = {0, 1, 1, 0};
  m.y = {0, 0, 1, 1};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

// ---------------------------------------------------------------------------------------------
// make_rectangle_mesh

TEST(RectangleMesh, CountsAreaCentroidAndOrientation) {
  {  // counts
    const Mesh m = make_rectangle_mesh(2.0, 1.0, 7, 4);
    EXPECT_EQ(m.node_count(), 8u * 5u);
    EXPECT_EQ(m.element_count(), 2u * 7u * 4u);
    EXPECT_EQ(m.boundary_edges.size(), 2u * (7u + 4u));
    EXPECT_EQ(m.boundary_nodes.size(), 2u * (7u + 4u));
    expect_consistent(m);
  }
  {  // area and centroid
    const double lx = 3e-4, ly = 1e-4;
    const Mesh m = make_rectangle_mesh(lx, ly, 30, 10);
    // 600 triangle areas from coordinates rounded to 1 ulp, summed: relative error of order
    // 600 * 2^-53 ~ 1e-13 at worst; 1e-12 leaves margin and still catches any missing triangle.
    EXPECT_NEAR(mesh_area(m), lx * ly, 1e-12 * lx * ly);
    const auto c = mesh_centroid(m);
    EXPECT_NEAR(c[0], lx / 2, 1e-12 * lx);
    EXPECT_NEAR(c[1], ly / 2, 1e-12 * ly);
  }
  {  // every triangle a counter-clockwise half cell
    const double lx = 3.0, ly = 2.0;
    const int nx = 6, ny = 5;
    const Mesh m = make_rectangle_mesh(lx, ly, nx, ny);
    const double half_cell = lx * ly / (2.0 * nx * ny);
    for (const auto& t : m.triangles) {
      // Coordinate differences of nearby nodes lose ~log2(n) bits; 1e-12 is far above that.
      EXPECT_NEAR(0.5 * twice_signed_area(m, t), half_cell, 1e-12 * half_cell);
    }
  }
  {  // centroid of a non-symmetric shape is area-weighted
    // L-shape of three unit squares: centroid (5/6, 5/6), whatever the triangle sizes.
    Mesh m = make_rectangle_mesh(2.0, 2.0, 2, 2);
    m.triangles.erase(m.triangles.begin() + 6, m.triangles.begin() + 8);  // cell (1, 1)
    m.x.pop_back();  // its corner (2, 2), node 8, is now used by no triangle
    m.y.pop_back();
    finalize_mesh(m);
    EXPECT_NEAR(mesh_area(m), 3.0, 1e-14);
    const auto c = mesh_centroid(m);
    EXPECT_NEAR(c[0], 5.0 / 6.0, 1e-14);
    EXPECT_NEAR(c[1], 5.0 / 6.0, 1e-14);
  }
}

TEST(RectangleMesh, DiagonalsAlternateLikeACheckerboard) {
  const int nx = 4, ny = 4;
  const Mesh m = make_rectangle_mesh(1.0, 1.0, nx, ny);
  std::set<std::pair<int32_t, int32_t>> edges;
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) {
      edges.insert(std::minmax(t[k], t[(k + 1) % 3]));
    }
  }
  auto node = [&](int i, int j) { return static_cast<int32_t>(j * (nx + 1) + i); };
  int rising = 0, falling = 0;  // SW-NE and SE-NW diagonals
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const bool r = edges.contains(std::minmax(node(i, j), node(i + 1, j + 1)));
      const bool f = edges.contains(std::minmax(node(i + 1, j), node(i, j + 1)));
      ASSERT_NE(r, f) << "cell " << i << "," << j << " must have exactly one diagonal";
      // Neighbouring cells differ: a cell's diagonal is set by the parity of i + j.
      EXPECT_EQ(r, (i + j) % 2 == 0) << "cell " << i << "," << j;
      (r ? rising : falling)++;
    }
  }
  EXPECT_EQ(rising, falling);  // no preferred direction overall
}

TEST(RectangleMesh, OuterLoopRunsCounterClockwiseFromTheOrigin) {
  const double lx = 2.0, ly = 1.5;
  const int nx = 4, ny = 3;
  const Mesh m = make_rectangle_mesh(lx, ly, nx, ny);
  ASSERT_EQ(m.boundary_nodes.size(), 14u);
  EXPECT_EQ(m.boundary_nodes[0], 0);  // loops start at their smallest node index
  EXPECT_EQ(m.boundary_nodes[1], 1);  // along the bottom first: counter-clockwise
  for (std::size_t i = 0; i < m.boundary_nodes.size(); ++i) {
    const int32_t a = m.boundary_nodes[i];
    const int32_t b = m.boundary_nodes[(i + 1) % m.boundary_nodes.size()];
    const bool on_boundary = m.x[a] == 0.0 || m.x[a] == lx || m.y[a] == 0.0 || m.y[a] == ly;
    EXPECT_TRUE(on_boundary) << "node " << a;
    // Consecutive loop nodes are neighbours on the boundary: one cell side apart.
    const double step = edge_length(m, a, b);
    EXPECT_TRUE(std::abs(step - lx / nx) < 1e-12 || std::abs(step - ly / ny) < 1e-12) << step;
  }
  // For a convex polygonal domain the loop polygon is the domain itself.
  EXPECT_NEAR(polygon_signed_area(m, m.boundary_nodes), lx * ly, 1e-12 * lx * ly);
  expect_consistent(m);
}

TEST(MeshGenerators, RejectBadArguments) {
  {  // make_rectangle_mesh
    EXPECT_THROW(make_rectangle_mesh(0.0, 1.0, 2, 2), std::invalid_argument);
    EXPECT_THROW(make_rectangle_mesh(1.0, -1.0, 2, 2), std::invalid_argument);
    EXPECT_THROW(make_rectangle_mesh(NAN, 1.0, 2, 2), std::invalid_argument);
    EXPECT_THROW(make_rectangle_mesh(1.0, 1.0, 0, 2), std::invalid_argument);
    EXPECT_THROW(make_rectangle_mesh(1.0, 1.0, 2, -3), std::invalid_argument);
    EXPECT_THROW(make_rectangle_mesh(1.0, 1.0, 100000, 100000), std::invalid_argument);
  }
  {  // mesh_disk
    EXPECT_THROW(mesh_disk(0.0, 100), std::invalid_argument);
    EXPECT_THROW(mesh_disk(-1.0, 100), std::invalid_argument);
    EXPECT_THROW(mesh_disk(NAN, 100), std::invalid_argument);
    EXPECT_THROW(mesh_disk(INFINITY, 100), std::invalid_argument);
    EXPECT_THROW(mesh_disk(1.0, 0), std::invalid_argument);
  }
  {  // mesh_rounded_square
    EXPECT_THROW(mesh_rounded_square(0.0, 0.0, 100), std::invalid_argument);
    EXPECT_THROW(mesh_rounded_square(1.0, -0.1, 100), std::invalid_argument);
    EXPECT_THROW(mesh_rounded_square(1.0, 0.5, 100), std::invalid_argument);
    EXPECT_THROW(mesh_rounded_square(1.0, NAN, 100), std::invalid_argument);
    EXPECT_THROW(mesh_rounded_square(1.0, 1e-7, 100), std::invalid_argument);  // below tolerance
    EXPECT_THROW(mesh_rounded_square(1.0, 0.1, 0), std::invalid_argument);
  }
}

// ---------------------------------------------------------------------------------------------
// finalize_mesh

TEST(FinalizeMesh, FlipsClockwiseTrianglesAndIsIdempotent) {
  {  // flip
    Mesh m = unit_square_two_triangles();
    m.triangles = {{0, 2, 1}, {0, 3, 2}};  // both clockwise
    finalize_mesh(m);
    expect_consistent(m);
    EXPECT_DOUBLE_EQ(mesh_area(m), 1.0);
    EXPECT_EQ(m.boundary_nodes, (std::vector<int32_t>{0, 1, 2, 3}));
    // The same node sets survive the flip.
    EXPECT_EQ((std::set<int32_t>{m.triangles[0].begin(), m.triangles[0].end()}),
              (std::set<int32_t>{0, 1, 2}));
  }
  {  // idempotent
    Mesh m = make_rectangle_mesh(1.0, 1.0, 3, 2);
    const Mesh before = m;
    finalize_mesh(m);
    EXPECT_EQ(m.triangles, before.triangles);
    EXPECT_EQ(m.boundary_edges, before.boundary_edges);
    EXPECT_EQ(m.boundary_nodes, before.boundary_nodes);
  }
}

TEST(FinalizeMesh, RejectsBadIndicesArraysAndUnusedNodes) {
  {  // indices out of range
    Mesh m = unit_square_two_triangles();
    m.triangles[1] = {0, 2, 4};
    expect_rejected(m, {"triangle 1", "out of range", "4"});
    m.triangles[1] = {0, -1, 3};
    expect_rejected(m, {"triangle 1", "out of range", "-1"});
  }
  {  // malformed arrays
    Mesh m = unit_square_two_triangles();
    m.y.pop_back();
    expect_rejected(m, {"x has 4", "y has 3"});
    Mesh empty;
    expect_rejected(empty, {"no triangles"});
    Mesh not_finite = unit_square_two_triangles();
    not_finite.x[2] = INFINITY;
    expect_rejected(not_finite, {"node 2", "non-finite"});
  }
  {  // unused nodes
    Mesh m = unit_square_two_triangles();
    m.x.push_back(0.5);
    m.y.push_back(0.5);
    expect_rejected(m, {"node 4", "not used"});
  }
}

TEST(FinalizeMesh, RejectsDegenerateTrianglesRelativeToMeshScale) {
  {  // collinear and repeated nodes
    Mesh m = unit_square_two_triangles();
    m.x.push_back(2.0);
    m.y.push_back(2.0);  // node 4 on the line through 0 and 2
    m.triangles.push_back({0, 2, 4});
    expect_rejected(m, {"degenerate", "triangle 2"});

    Mesh repeated = unit_square_two_triangles();
    repeated.triangles[0] = {0, 1, 1};
    expect_rejected(repeated, {"degenerate", "triangle 0", "repeated"});
  }
  {  // relative to the mesh scale
    // A flat but genuine sliver (area 5e-10 of the squared mesh size, above the 1e-12 cut) passes
    // at any physical scale; one at 1e-14 does not.
    for (const double scale : {1.0, 1e-6}) {
      Mesh sliver;
      sliver.x = {0.0, scale, 0.5 * scale};
      sliver.y = {0.0, 0.0, 1e-9 * scale};
      sliver.triangles = {{0, 1, 2}};
      EXPECT_NO_THROW(finalize_mesh(sliver)) << "scale " << scale;
      sliver.y[2] = 1e-14 * scale;
      expect_rejected(sliver, {"degenerate"});
    }
  }
}

TEST(FinalizeMesh, RejectsNonManifoldAndOverlappingEdges) {
  {  // more than two triangles on an edge
    Mesh m;
    m.x = {0.0, 1.0, 0.5, 0.5, 0.6};
    m.y = {0.0, 0.0, 1.0, -1.0, 2.0};
    m.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};  // three triangles on edge 0-1
    expect_rejected(m, {"edge (0, 1)", "more than two"});
  }
  {  // two triangles on the same side of an edge
    Mesh m;
    m.x = {0.0, 1.0, 0.5, 0.5};
    m.y = {0.0, 0.0, 1.0, 0.5};
    m.triangles = {{0, 1, 2}, {0, 1, 3}};  // both above edge 0-1
    expect_rejected(m, {"overlap", "edge (0, 1)"});
  }
}

TEST(FinalizeMesh, HoleLoopIsNotTheOuterBoundary) {
  // 3 x 3 cells without the centre cell: outer loop of 12 nodes, hole loop of 4.
  Mesh m = make_rectangle_mesh(3.0, 3.0, 3, 3);
  m.triangles.erase(m.triangles.begin() + 8, m.triangles.begin() + 10);  // cell (1, 1)
  finalize_mesh(m);
  expect_consistent(m);
  EXPECT_EQ(m.boundary_edges.size(), 16u);
  EXPECT_EQ(m.boundary_nodes.size(), 12u);
  EXPECT_NEAR(polygon_signed_area(m, m.boundary_nodes), 9.0, 1e-12);
  EXPECT_NEAR(mesh_area(m), 8.0, 1e-12);
  // Outer loop's edges come first; the hole's follow and run clockwise (body on the left).
  std::vector<int32_t> hole;
  for (std::size_t e = 12; e < 16; ++e) hole.push_back(m.boundary_edges[e][0]);
  EXPECT_NEAR(polygon_signed_area(m, hole), -1.0, 1e-12);
}

TEST(FinalizeMesh, OuterLoopOfDisjointAndTouchingParts) {
  {  // disjoint parts
    Mesh m;
    m.x = {0, 1, 1, 0, 5, 8, 8, 5};
    m.y = {0, 0, 1, 1, 0, 0, 3, 3};
    m.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
    finalize_mesh(m);
    expect_consistent(m);
    EXPECT_EQ(m.boundary_nodes, (std::vector<int32_t>{4, 5, 6, 7}));
    EXPECT_EQ(m.boundary_edges.size(), 8u);
  }
  {  // parts touching at one node
    // Two triangles sharing only node 0 (a pinch): each must keep its own loop rather than the
    // walk jumping from one to the other through the shared node.
    Mesh m;
    m.x = {0, 1, 1, -2, -2};
    m.y = {0, 0, 1, 0, -2};
    m.triangles = {{0, 1, 2}, {0, 3, 4}};
    finalize_mesh(m);
    expect_consistent(m);
    EXPECT_EQ(m.boundary_edges.size(), 6u);
    EXPECT_EQ(m.boundary_nodes.size(), 3u);
    EXPECT_NEAR(polygon_signed_area(m, m.boundary_nodes), 2.0, 1e-12);  // the larger triangle
  }
}

// ---------------------------------------------------------------------------------------------
// Gmsh meshes

// Boundary nodes on the circle, and the exact area bookkeeping of an inscribed polygon.
void expect_disk_geometry(const Mesh& m, double radius) {
  expect_consistent(m);
  // One loop only (no holes), so every boundary edge belongs to the outer loop.
  EXPECT_EQ(m.boundary_edges.size(), m.boundary_nodes.size());
  double missed = 0.0, perimeter = 0.0;
  for (std::size_t i = 0; i < m.boundary_nodes.size(); ++i) {
    const int32_t a = m.boundary_nodes[i];
    const int32_t b = m.boundary_nodes[(i + 1) % m.boundary_nodes.size()];
    // Gmsh places curve nodes by evaluating the circle, so they sit on it to rounding.
    EXPECT_NEAR(std::hypot(m.x[a], m.y[a]), radius, 1e-9 * radius) << "node " << a;
    const double c = edge_length(m, a, b);
    perimeter += c;
    missed += circular_segment_area(radius, c);
  }
  const double area = mesh_area(m);
  // The mesh is exactly the inscribed polygon, so its area is pi R^2 less the circular
  // segments cut off by the boundary chords. Both sides are sums of up to ~2e4 rounded terms,
  // worst case ~2e4 * 2^-53 ~ 2e-12 relative; 1e-11 is above that yet ~1e-7 of the polygonal
  // error itself, so a single misplaced node or missing triangle would show.
  EXPECT_NEAR(area, kPi * radius * radius - missed, 1e-11 * area);
  // Size of that error: a chord h subtends theta = h / R and misses R^2 (theta - sin theta) / 2
  // = h^3 / (12 R) (1 + O(theta^2 / 20)); n = 2 pi R / h chords miss pi h^2 / 6, a relative
  // h^2 / (6 R^2) (7e-5 at the baseline). Gmsh spaces nodes evenly on the circle (checked: all
  // chords within 1 % of their mean), so the estimate holds to ~1e-3 even for 40 chords.
  const double h = perimeter / static_cast<double>(m.boundary_nodes.size());
  for (std::size_t i = 0; i < m.boundary_nodes.size(); ++i) {
    const double c =
        edge_length(m, m.boundary_nodes[i], m.boundary_nodes[(i + 1) % m.boundary_nodes.size()]);
    EXPECT_NEAR(c, h, 0.01 * h) << "boundary chord " << i;
  }
  EXPECT_NEAR(missed, kPi * h * h / 6.0, 0.01 * kPi * h * h / 6.0);
  EXPECT_NEAR(polygon_signed_area(m, m.boundary_nodes), area, 1e-11 * area);
  // Centroid: 0 for the disk; removing the segments (area `missed`, all within R of the
  // origin) moves it by at most missed * R / area.
  const auto centroid = mesh_centroid(m);
  EXPECT_LE(std::hypot(centroid[0], centroid[1]), missed * radius / area + 1e-12 * radius);
}

double smallest_angle_deg(const Mesh& m) {
  double smallest = 180.0;
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) {
      const double a = edge_length(m, t[(k + 1) % 3], t[(k + 2) % 3]);  // opposite side
      const double b = edge_length(m, t[k], t[(k + 1) % 3]);
      const double c = edge_length(m, t[k], t[(k + 2) % 3]);
      const double cos_angle = std::clamp((b * b + c * c - a * a) / (2 * b * c), -1.0, 1.0);
      smallest = std::min(smallest, std::acos(cos_angle) * 180.0 / kPi);
    }
  }
  return smallest;
}

TEST(DiskMesh, BaselineSizeCountAreaBoundaryAndQuality) {
  const double radius = 90e-6;
  const int target = 16500;
  const auto start = std::chrono::steady_clock::now();
  const Mesh m = mesh_disk(radius, target);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << "[ baseline ] mesh_disk(90e-6 m, 16500): " << m.element_count() << " triangles, "
            << m.node_count() << " nodes, " << m.boundary_nodes.size() << " boundary nodes, "
            << seconds << " s, smallest angle " << smallest_angle_deg(m) << " deg\n";
  RecordProperty("elements", static_cast<int>(m.element_count()));
  RecordProperty("milliseconds", static_cast<int>(seconds * 1e3));
  EXPECT_NEAR(static_cast<double>(m.element_count()), target, 0.05 * target);
  expect_disk_geometry(m, radius);
  // Frontal-Delaunay keeps triangles near equilateral; slivers would cut the explicit time
  // step. 25 degrees is a loose floor for it (the worst seen here is ~37).
  EXPECT_GT(smallest_angle_deg(m), 25.0);
}

// The ring mesher (the default disk's): a valid disk at every size, and no element much thinner
// than the rest. Its explicit step is the smallest altitude over the wave speed, so the worst
// element sets the run's step wherever the flow is uniform -- at the centre, where the
// converging shock focuses. The hexagonal centre (ring_mesher.cpp) keeps the smallest altitude
// >= 0.8 of the median (measured 0.80-0.82); zipping the inner rings by rounded counts gave 0.64.
TEST(RingDiskMesh, ValidAtEverySizeAndNoElementMuchThinnerThanTheMedian) {
  for (const int target : {1000, 4000, 16500, 66000}) {
    const Mesh m = mesh_disk_rings(90e-6, target);
    // Whole rings: K rings hold ~ pi sqrt(3) K^2 triangles, so the count moves in steps of ~2/K
    // (1000: K = 14, 1,074 triangles).
    EXPECT_NEAR(static_cast<double>(m.element_count()), target, 0.08 * target);
    expect_disk_geometry(m, 90e-6);
    std::vector<double> altitude;
    for (const auto& t : m.triangles)
      altitude.push_back(
          std::sqrt(continuum::smallest_altitude_sq(m.x[t[1]] - m.x[t[0]], m.y[t[1]] - m.y[t[0]],
                                                    m.x[t[2]] - m.x[t[0]], m.y[t[2]] - m.y[t[0]])));
    const double smallest = *std::min_element(altitude.begin(), altitude.end());
    std::nth_element(altitude.begin(), altitude.begin() + altitude.size() / 2, altitude.end());
    const double median = altitude[altitude.size() / 2];
    std::cout << "[ rings ] " << target << ": " << m.element_count()
              << " triangles, smallest altitude / median " << smallest / median << "\n";
    EXPECT_GE(smallest / median, 0.78) << "target " << target;
  }
}

TEST(DiskMesh, CountWithinFivePercentAcrossTargets) {
  for (const int target : {300, 1000, 4000}) {
    const Mesh m = mesh_disk(1e-3, target);
    EXPECT_NEAR(static_cast<double>(m.element_count()), target, 0.05 * target)
        << "target " << target;
    expect_disk_geometry(m, 1e-3);
  }
}

TEST(DiskMesh, RepeatedMeshingIsIdenticalAtAnyScale) {
  {  // repeated calls
    const Mesh first = mesh_disk(90e-6, 3000);
    const Mesh second = mesh_disk(90e-6, 3000);
    EXPECT_EQ(first.x, second.x);
    EXPECT_EQ(first.y, second.y);
    EXPECT_EQ(first.triangles, second.triangles);
    EXPECT_EQ(first.boundary_nodes, second.boundary_nodes);
  }
  {  // physical scale
    // Gmsh works on the unit disk, so only the final scaling depends on the radius.
    const Mesh unit = mesh_disk(1.0, 1500);
    const Mesh micro = mesh_disk(90e-6, 1500);
    ASSERT_EQ(unit.node_count(), micro.node_count());
    EXPECT_EQ(unit.triangles, micro.triangles);
    for (std::size_t n = 0; n < unit.node_count(); ++n) {
      EXPECT_DOUBLE_EQ(unit.x[n] * 90e-6, micro.x[n]);
      EXPECT_DOUBLE_EQ(unit.y[n] * 90e-6, micro.y[n]);
    }
  }
}

TEST(DiskMesh, ConcurrentCallsAreSerialisedAndReproducible) {
  const Mesh reference = mesh_disk(50e-6, 800);
  std::vector<Mesh> results(4);
  std::vector<std::thread> threads;
  for (auto& result : results) {
    threads.emplace_back([&result] { result = mesh_disk(50e-6, 800); });
  }
  for (auto& t : threads) t.join();
  for (const auto& result : results) {
    EXPECT_EQ(result.x, reference.x);
    EXPECT_EQ(result.triangles, reference.triangles);
  }
}

TEST(RoundedSquareMesh, AreaMatchesUpToPolygonalError) {
  const double side = 200e-6, r = 30e-6;
  const int target = 3000;
  const Mesh m = mesh_rounded_square(side, r, target);
  expect_consistent(m);
  EXPECT_NEAR(static_cast<double>(m.element_count()), target, 0.05 * target);
  const double half = 0.5 * side, inner = half - r;  // corner-arc centres at (+-inner, +-inner)
  double missed = 0.0;
  for (std::size_t i = 0; i < m.boundary_nodes.size(); ++i) {
    const int32_t a = m.boundary_nodes[i];
    const int32_t b = m.boundary_nodes[(i + 1) % m.boundary_nodes.size()];
    const double ax = std::abs(m.x[a]), ay = std::abs(m.y[a]);
    if (ax > inner && ay > inner) {
      // In a corner: on the arc.
      EXPECT_NEAR(std::hypot(ax - inner, ay - inner), r, 1e-9 * side) << "node " << a;
    } else {
      // On a straight side.
      EXPECT_NEAR(std::max(ax, ay), half, 1e-9 * side) << "node " << a;
    }
    // A chord whose midpoint lies in a corner region spans part of an arc and misses its
    // circular segment; chords along the straight sides miss nothing.
    const double mx = std::abs(0.5 * (m.x[a] + m.x[b])), my = std::abs(0.5 * (m.y[a] + m.y[b]));
    if (mx > inner && my > inner) missed += circular_segment_area(r, edge_length(m, a, b));
  }
  EXPECT_GT(missed, 0.0);
  const double exact = side * side - (4.0 - kPi) * r * r;
  EXPECT_LT(missed, 1e-3 * exact);  // the polygonal error is small...
  // ...and accounts for the whole difference (same rounding argument as for the disk).
  EXPECT_NEAR(mesh_area(m), exact - missed, 1e-11 * exact);
  EXPECT_NEAR(polygon_signed_area(m, m.boundary_nodes), mesh_area(m), 1e-11 * exact);
  const auto c = mesh_centroid(m);
  EXPECT_LE(std::hypot(c[0], c[1]), missed * side / exact + 1e-12 * side);
}

TEST(RoundedSquareMesh, ZeroRadiusGivesTheSquare) {
  const double side = 1e-4;
  const Mesh m = mesh_rounded_square(side, 0.0, 800);
  expect_consistent(m);
  // A polygonal domain is meshed exactly: only summation rounding remains.
  EXPECT_NEAR(mesh_area(m), side * side, 1e-12 * side * side);
  EXPECT_NEAR(static_cast<double>(m.element_count()), 800, 0.05 * 800);
}

// ---------------------------------------------------------------------------------------------
// read_gmsh_file

class GmshMeshFile : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (std::filesystem::temp_directory_path() / "test_mesh-XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) {
    const auto path = dir_ / name;
    std::ofstream(path) << text;
    return path.string();
  }

  std::filesystem::path dir_;
};

// Unit square: corners tagged 10..40, centre 50; an unused node 99 at z = 0.5; a point and
// boundary lines that must be ignored; two of the four triangles clockwise.
constexpr const char* kMsh22Square = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
6
10 0 0 0.25
20 1 0 0.25
30 1 1 0.25
40 0 1 0.25
50 0.5 0.5 0.25
99 7 7 0.5
$EndNodes
$Elements
7
1 15 2 0 1 10
2 1 2 0 1 10 20
3 1 2 0 1 20 30
4 2 2 0 1 10 20 50
5 2 2 0 1 20 50 30
6 2 2 0 1 30 40 50
7 2 2 0 1 40 50 10
$EndElements
)";

// Square of 2 um side in MSH 4.1, its triangles on two surfaces that share nodes.
constexpr const char* kMsh41TwoSurfaces = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
0 0 2 0
1 0 0 0 2e-6 2e-6 0 0 0
2 0 0 0 2e-6 2e-6 0 0 0
$EndEntities
$Nodes
1 5 1 5
2 1 0 5
1
2
3
4
5
0 0 0
2e-6 0 0
2e-6 2e-6 0
0 2e-6 0
1e-6 1e-6 0
$EndNodes
$Elements
2 4 1 4
2 1 2 2
1 1 2 5
2 2 3 5
2 2 2 2
3 3 4 5
4 4 1 5
$EndElements
)";

// A line element and no triangles.
constexpr const char* kMsh22LinesOnly = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
2
1 0 0 0
2 1 0 0
$EndNodes
$Elements
1
1 1 2 0 1 1 2
$EndElements
)";

TEST_F(GmshMeshFile, ReadsMsh22AndMsh41) {
  {  // MSH 2.2
    const Mesh m = read_gmsh_file(write("square.msh", kMsh22Square));
    expect_consistent(m);
    EXPECT_EQ(m.node_count(), 5u);  // node 99 is used by no triangle and is dropped
    EXPECT_EQ(m.element_count(), 4u);
    // Tag order is kept: 10, 20, 30, 40, 50 -> 0..4.
    EXPECT_EQ(m.x, (std::vector<double>{0, 1, 1, 0, 0.5}));
    EXPECT_EQ(m.y, (std::vector<double>{0, 0, 1, 1, 0.5}));
    EXPECT_DOUBLE_EQ(mesh_area(m), 1.0);
    EXPECT_EQ(m.boundary_nodes, (std::vector<int32_t>{0, 1, 2, 3}));
  }
  {  // MSH 4.1
    const Mesh m = read_gmsh_file(write("two_surfaces.msh", kMsh41TwoSurfaces));
    expect_consistent(m);
    EXPECT_EQ(m.node_count(), 5u);
    EXPECT_EQ(m.element_count(), 4u);
    EXPECT_NEAR(mesh_area(m), 4e-12, 1e-26);  // coordinates are taken as metres, as written
    EXPECT_EQ(m.boundary_nodes, (std::vector<int32_t>{0, 1, 2, 3}));
  }
}

TEST_F(GmshMeshFile, BadFilesThrowNamingThePath) {
  {  // missing file or directory
    const std::string path = (dir_ / "no_such_mesh.msh").string();
    expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(path); }, {path});
    const std::string directory = dir_.string();
    expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(directory); }, {directory});
  }
  {  // no triangles
    const std::string path = write("lines.msh", kMsh22LinesOnly);
    expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(path); },
                                                {path, "no 3-node triangles"});
  }
  {  // invalid mesh
    std::string text = kMsh22Square;
    text.replace(text.find("7 2 2 0 1 40 50 10"), 18, "7 2 2 0 1 10 20 50");  // duplicate
    const std::string path = write("overlap.msh", text);
    expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(path); }, {path, "overlap"});
  }
}

TEST_F(GmshMeshFile, CorruptFileThrowsAndLaterReadsStillWork) {
  const std::string bad = write("bad.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\nxx\n");
  expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(bad); }, {bad});
  // Gmsh 4.8 stays "busy" after a read error; each call must start from a clean Gmsh.
  EXPECT_EQ(read_gmsh_file(write("square.msh", kMsh22Square)).element_count(), 4u);
}

TEST_F(GmshMeshFile, ScriptsAreNeverExecuted) {
  // Gmsh reads a non-MSH file as a .geo script whatever its name, and merges "<file>.opt"
  // scripts next to a mesh; the script language can run shell commands.
  const auto marker = dir_ / "script_ran";
  const std::string script = "SystemCall \"touch " + marker.string() + "\";\n";
  const std::string disguised = write("script.msh", script);
  expect_throw_containing<std::runtime_error>([&] { read_gmsh_file(disguised); },
                                              {disguised, "$MeshFormat"});
  const std::string mesh = write("with_opt.msh", kMsh22Square);
  write("with_opt.msh.opt", script);
  EXPECT_EQ(read_gmsh_file(mesh).element_count(), 4u);
  EXPECT_FALSE(std::filesystem::exists(marker));
}

}  // namespace
}  // namespace softshock
